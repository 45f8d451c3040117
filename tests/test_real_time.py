"""Real time and a real Earth: run.start_utc, TEME -> Earth-fixed with UT1 - UTC, the ROI
frame of a descending TLE pass, elevations from a WGS 84 site; all against skyfield
(an independent implementation of sgp4's frames, IERS data and WGS 84)."""

import math
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from leolink.config import load_config
from leolink.errors import ConfigError

skyfield_api = pytest.importorskip("skyfield.api")

ROOT = Path(__file__).resolve().parents[1]
TLE = ROOT / "configs" / "examples" / "tle.toml"
# sgp4 with GMST82(UT1) against skyfield's TEME -> ITRS: equal to a few mm (the Earth
# rotation rate constant vs. GMST82's rate over 2 min); UT1 ignored would be ~80 m.
ITRS_M = 0.05
ANGLE_DEG = 0.01  # the tolerance for elevation and azimuth


def _skyfield_sat(cfg):
    lines = Path(cfg.constellation.tle_file).read_text(encoding="utf-8").splitlines()
    ts = skyfield_api.load.timescale(builtin=True)
    return ts, skyfield_api.EarthSatellite(lines[1], lines[2], lines[0], ts)


@pytest.mark.parametrize("dut1", [True, False], ids=["with_ut1", "without_ut1"])
def test_tle_ephemeris_is_skyfields_itrs(dut1, monkeypatch):
    from skyfield.framelib import itrs

    import leolink.app.orbits as orbits
    from leolink.io.earth_orientation import EarthOrientation

    cfg = load_config(TLE)
    if not dut1:  # the same run as if UT1 were UTC: must be visibly off
        monkeypatch.setattr(orbits, "ut1_minus_utc", lambda when: EarthOrientation(0.0, False, ""))
    ts, sat = _skyfield_sat(cfg)
    times = np.array([0.0, 45.0, 119.0])
    pos, vel, _ = orbits.ephemeris_from_config(cfg)(times)
    t0 = cfg.utc_of_time_zero()
    for t_s, p, v in zip(times, pos[:, 0], vel[:, 0], strict=True):
        ref_p, ref_v = sat.at(ts.from_datetime(t0 + timedelta(seconds=t_s))).frame_xyz_and_velocity(
            itrs
        )
        err = np.linalg.norm(p - ref_p.m)
        assert (err < ITRS_M) if dut1 else (err > 30.0)
        if dut1:
            assert np.linalg.norm(v - ref_v.m_per_s) < 1e-3


def test_earth_orientation_is_stated_inside_and_outside_the_iers_table():
    from leolink.io.earth_orientation import ut1_minus_utc

    ts = skyfield_api.load.timescale(builtin=True)
    when = datetime(2019, 12, 9, 16, 37, 29, tzinfo=UTC)
    inside = ut1_minus_utc(when)
    assert inside.known and inside.ut1_minus_utc_s == pytest.approx(ts.from_datetime(when).dut1)
    assert "UT1-UTC = -0.17" in inside.note
    outside = ut1_minus_utc(datetime(2090, 1, 1, tzinfo=UTC))
    assert not outside.known and outside.ut1_minus_utc_s == 0.0
    assert "unknown on 2090-01-01" in outside.note and "0.42 km" in outside.note


def test_ut1_minus_utc_is_that_of_skyfields_builtin_timescale():
    """leolink builds skyfield's timescale without skyfield.api (start-up time): the same
    UT1 - UTC, bit for bit, as the public ``load.timescale(builtin=True)`` over the table."""
    from leolink.io import earth_orientation

    ts = skyfield_api.load.timescale(builtin=True)
    _, first, last = earth_orientation._table()
    span_s = (last - first).total_seconds()
    rng = np.random.default_rng(7)
    for offset_s in [0.0, span_s, *rng.uniform(0.0, span_s, 300)]:
        when = first + timedelta(seconds=float(offset_s))
        got = earth_orientation.ut1_minus_utc(when)
        assert got.known and got.ut1_minus_utc_s == float(ts.from_datetime(when).dut1), when


def _bearing_deg(lat1, lon1, lat2, lon2):
    """Initial great-circle bearing (aviation formulary), from north clockwise [deg]."""
    p1, p2, dl = math.radians(lat1), math.radians(lat2), math.radians(lon2 - lon1)
    y = math.sin(dl) * math.cos(p2)
    x = math.cos(p1) * math.sin(p2) - math.sin(p1) * math.cos(p2) * math.cos(dl)
    return math.degrees(math.atan2(y, x)) % 360.0


def test_descending_tle_pass_roi_x_axis_follows_the_ground_track():
    """The ISS of the TLE example descends over the ROI centre; the ROI x axis must be
    the direction of its ground track there (skyfield's sub-satellite points 1 s either
    side of the overhead instant), to 1 deg, not the ascending direction of old."""
    from leolink.app.orbits import roi_frame

    cfg = load_config(TLE)
    frame = roi_frame(cfg)
    ts, sat = _skyfield_sat(cfg)
    wgs84 = skyfield_api.wgs84
    t_over = cfg.utc_of_time_zero() + timedelta(seconds=frame.t_s)
    a, b = (
        wgs84.subpoint_of(sat.at(ts.from_datetime(t_over + timedelta(seconds=s)))) for s in (-1, 1)
    )
    assert b.latitude.degrees < a.latitude.degrees  # descending
    assert not frame.ascending and frame.t_s == pytest.approx(60.0, abs=1.0)
    track = _bearing_deg(
        a.latitude.degrees, a.longitude.degrees, b.latitude.degrees, b.longitude.degrees
    )
    heading = math.degrees(frame.heading_rad) % 360.0
    assert abs((heading - track + 180.0) % 360.0 - 180.0) < 1.0
    # an ascending pass over the same point would head ~70 deg away: the test can tell
    asc = math.degrees(
        roi_frame(
            load_config(ROOT / "configs" / "paper.toml", ["roi.center_lat_deg=49.69"])
        ).heading_rad
    )
    assert abs((asc - track + 180.0) % 360.0 - 180.0) > 30.0


def test_the_offset_ut_of_the_tle_example_is_cross_track():
    """UT 1 is 100 km cross-track: its distance to the ISS's ground track (skyfield's
    ITRS positions, as geocentric directions: leolink's sphere) is 100 km, not the 56 km
    of the ascending frame of old."""
    from skyfield.framelib import itrs

    from leolink.app.scenario import build_scenario

    cfg = load_config(TLE)
    sc = build_scenario(cfg)
    ts, sat = _skyfield_sat(cfg)
    t0 = cfg.utc_of_time_zero()
    when = ts.from_datetimes([t0 + timedelta(seconds=float(t)) for t in np.arange(40.0, 80.0, 0.1)])
    track = sat.at(when).frame_xyz(itrs).m.T
    track /= np.linalg.norm(track, axis=1, keepdims=True)

    def distance_m(model):
        pos = model.state(0.0).pos_m[0]
        return (
            cfg.earth.radius_m
            * np.arccos(np.clip(track @ (pos / np.linalg.norm(pos)), -1, 1)).min()
        )

    # The ROI centre is the sub-satellite point rounded to 0.01 deg: up to ~0.7 km off the
    # track, which moves the UT's distance by as much. ROI-plane y = 100 km is
    # R atan(100 km / R) = 99.99 km on the ground (gnomonic); the track is sampled every
    # 0.1 s (0.7 km), so its closest point is within 10 m.
    off_m = distance_m(sc.populations[0][1])
    assert off_m < 1e3
    expected_m = cfg.earth.radius_m * math.atan(100e3 / cfg.earth.radius_m)
    assert abs(distance_m(sc.populations[1][1]) - expected_m) < off_m + 50.0


def test_tle_elevation_and_azimuth_from_a_wgs84_site_equal_skyfield(tmp_path):
    """A WGS 84 run of the TLE example: every row's elevation and azimuth (the serving or
    best link) equal skyfield's altaz from the UT's geodetic site to 0.01 deg. The sphere
    run is off by ~0.1 deg (the geodetic vertical is 0.19 deg from the radial at 50 N),
    so the tolerance can tell the two apart."""
    from leolink.app.run import run

    ts, sat = _skyfield_sat(load_config(TLE))
    errors = {}
    for model in ("wgs84", "sphere"):
        cfg = load_config(TLE, [f'earth.model="{model}"', "output.plots.enabled=false"])
        tr = run(cfg).trace
        t0 = cfg.utc_of_time_zero()
        rows = tr.iloc[::7]
        t = ts.from_datetimes([t0 + timedelta(seconds=float(s)) for s in rows.time_s])
        site = skyfield_api.wgs84.latlon(
            rows.lat_deg.to_numpy(), rows.lon_deg.to_numpy(), rows.alt_m.to_numpy()
        )
        alt, az, _ = (sat - site).at(t).altaz()
        d_el = np.abs(rows.elevation_deg.to_numpy() - alt.degrees)
        d_az = np.abs((rows.azimuth_deg.to_numpy() - az.degrees + 180.0) % 360.0 - 180.0)
        errors[model] = max(d_el.max(), d_az.max())
    assert errors["wgs84"] < ANGLE_DEG
    assert errors["sphere"] > 5 * ANGLE_DEG


def test_start_utc_and_tle_epoch_utc_are_one_start():
    with pytest.raises(ConfigError, match="give the start once, as run.start_utc"):
        load_config(TLE, ['constellation.tle_epoch_utc="2019-12-09T16:37:29Z"'])
    with pytest.raises(
        ConfigError, match=r"run.start_utc = 'yesterday' is not allowed: use an ISO 8601"
    ):
        load_config(TLE, ['run.start_utc="yesterday"'])
    cfg = load_config(TLE, ["run.start_s=100.0"])  # start_utc is the first epoch's instant
    assert cfg.utc_of_time_zero() == datetime(2019, 12, 9, 16, 35, 49, 363000, tzinfo=UTC)
    naive = load_config(TLE, ['run.start_utc="2019-12-09T16:37:29.363"'])  # naive = UTC
    assert naive.utc_of_time_zero() == load_config(TLE).utc_of_time_zero()
