"""Tests of leolink.orbit: published speed/period, properties, Walker phasing, sgp4 agreement."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sgp4.api import WGS72, Satrec, jday
from sgp4.earth_gravity import wgs72

from leolink.constants import EARTH_RADIUS_M, EARTH_ROTATION_RAD_S
from leolink.errors import ConfigError, LeolinkError
from leolink.geometry import ecef_to_geodetic
from leolink.io.tle import read_tle_file
from leolink.orbit import (
    CentralBody,
    Elements,
    Ephemeris,
    angular_rate_rad_s,
    circular_state,
    eci_to_ecef,
    orbital_period_s,
    orbital_speed_m_s,
    pass_over,
    tle_state,
    walker_delta,
)

DATA = Path(__file__).parent / "data"
ROUND_M = 1e-5  # float64 on 7e6 m positions after trig: ~1e-12 relative
# Central differences with step dt have truncation error ~ |x'''| dt^2 / 6 (~n^2 v dt^2);
# with n ~ 1e-3 rad/s, v ~ 7.5 km/s, dt = 0.5 s: ~3e-3 m/s, and rounding ~1e-9 m / dt.
DERIV_DT_S = 0.5
DERIV_VEL_TOL_M_S = 5e-3
DERIV_ACC_TOL_M_S2 = 1e-4

alt_st = st.floats(300e3, 2000e3)
ang_st = st.floats(0.0, 6.28)
inc_st = st.floats(0.0, 3.14)


def test_speed_and_period_at_1000_km_reference():
    # No published reference here (the former "7353.59 m/s, 6298.06 s" had no source and
    # did not follow from its own GM): Kepler's third law T^2 GM = 4 pi^2 a^3 and v T = 2 pi a
    # checked as identities, plus the hand value sqrt(3.986e14 / 7.371e6) = 7353.69 m/s.
    kw = dict(radius_m=6371e3, gm_m3_s2=3.986e14)
    a = 7371e3
    t = orbital_period_s(1000e3, **kw)
    assert t**2 * 3.986e14 == pytest.approx(4 * np.pi**2 * a**3, rel=1e-14)
    assert orbital_speed_m_s(1000e3, **kw) * t == pytest.approx(2 * np.pi * a, rel=1e-14)
    assert orbital_speed_m_s(1000e3, **kw) == pytest.approx(7353.69, abs=0.01)
    assert np.isclose(
        angular_rate_rad_s(1000e3, **kw) * a, orbital_speed_m_s(1000e3, **kw), rtol=1e-14
    )


def test_leo_period_against_the_iss_tle():
    """The ISS TLE of configs/examples/tles/iss.tle (NORAD element set, epoch 2019-12-09)
    gives 15.50103472 rev/day: with the semi-major axis from that mean motion, the
    circular period must be 86400 / 15.50103472 s = 92.898 min. The TLE's mean motion is
    a Kozai mean (J2-averaged), the orbit's the Keplerian one: 0.1 % covers that."""
    n_rev_day = 15.50103472
    n_rad_s = n_rev_day * 2 * np.pi / 86400.0
    a_m = (3.986004418e14 / n_rad_s**2) ** (1 / 3)
    t = orbital_period_s(a_m - 6371e3, 6371e3, 3.986004418e14)
    assert t == pytest.approx(86400.0 / n_rev_day, rel=1e-3)


@settings(max_examples=100, deadline=None)
@given(h=alt_st, inc=inc_st, raan=ang_st, u0=ang_st, t0=st.floats(0.0, 1e5))
def test_circular_state_properties(h, inc, raan, u0, t0):
    t = t0 + np.array([-DERIV_DT_S, 0.0, DERIV_DT_S])
    pos, vel, acc = circular_state(t, h, inc, raan, u0)
    assert pos.shape == (3, 1, 3)
    a = EARTH_RADIUS_M + h
    assert np.allclose(np.linalg.norm(pos, axis=-1), a, rtol=0, atol=ROUND_M)
    assert np.allclose(np.sum(pos * vel, -1), 0.0, atol=1e-3 * a)  # r.v = 0 (m^2/s, relative)
    assert np.allclose(np.linalg.norm(vel, axis=-1), orbital_speed_m_s(h), atol=1e-8)
    # angular momentum along (sin i sin W, -sin i cos W, cos i)
    normal = np.cross(pos[1, 0], vel[1, 0])
    expected = [np.sin(inc) * np.sin(raan), -np.sin(inc) * np.cos(raan), np.cos(inc)]
    assert np.allclose(normal / np.linalg.norm(normal), expected, atol=1e-9)
    # velocity and acceleration as numerical derivatives of position
    num_vel = (pos[2] - pos[0]) / (2 * DERIV_DT_S)
    num_acc = (pos[2] - 2 * pos[1] + pos[0]) / DERIV_DT_S**2
    assert np.allclose(vel[1], num_vel, atol=DERIV_VEL_TOL_M_S)
    assert np.allclose(acc[1], num_acc, atol=DERIV_ACC_TOL_M_S2)
    # period: state at t + T equals state at t
    p2, v2, _ = circular_state(t0 + orbital_period_s(h), h, inc, raan, u0)
    assert np.allclose(p2[0], pos[1], atol=1e-3)  # 1 mm: u = n t with t ~ 1e5 s, float64
    assert np.allclose(v2[0], vel[1], atol=1e-6)


def test_circular_state_shapes_and_broadcast():
    el = walker_delta(12, 3, 1, np.radians(53), 550e3)
    pos, vel, acc = circular_state(
        np.arange(5.0), el.altitude_m, el.inclination_rad, el.raan_rad, el.arg_lat0_rad
    )
    assert pos.shape == vel.shape == acc.shape == (5, 12, 3)
    assert circular_state(0.0, 550e3, 0.9, 0.0, 0.0)[0].shape == (1, 1, 3)


@settings(max_examples=60, deadline=None)
@given(h=alt_st, inc=inc_st, raan=ang_st, u0=ang_st, t0=st.floats(0.0, 1e5), g=ang_st)
def test_eci_to_ecef_matches_numerical_derivatives(h, inc, raan, u0, t0, g):
    t = t0 + np.array([-DERIV_DT_S, 0.0, DERIV_DT_S])
    pos, vel, acc = eci_to_ecef(*circular_state(t, h, inc, raan, u0), t, gmst0_rad=g)
    assert np.allclose(np.linalg.norm(pos, axis=-1), EARTH_RADIUS_M + h, atol=ROUND_M)
    num_vel = (pos[2] - pos[0]) / (2 * DERIV_DT_S)
    num_acc = (pos[2] - 2 * pos[1] + pos[0]) / DERIV_DT_S**2
    assert np.allclose(vel[1], num_vel, atol=DERIV_VEL_TOL_M_S)
    assert np.allclose(acc[1], num_acc, atol=DERIV_ACC_TOL_M_S2)


def test_eci_to_ecef_geostationary_is_fixed():
    # A 0-inclination orbit at the sidereal rate stays over one longitude in ECEF.
    a = (3.986004418e14 / EARTH_ROTATION_RAD_S**2) ** (1 / 3)
    t = np.linspace(0, 86164.0, 7)
    pos, vel, _ = eci_to_ecef(*circular_state(t, a - EARTH_RADIUS_M, 0.0, 0.0, 0.4), t, 0.4)
    assert np.allclose(pos, pos[:1], atol=1.0)  # 1 m: GM/omega rounding
    assert np.allclose(vel, 0.0, atol=1e-4)


def test_walker_toy_6_3_1_counted_by_hand():
    el = walker_delta(6, 3, 1, np.radians(60), 500e3)
    assert el.n_sat == 6
    # planes at 0, 120, 240 deg; two sats per plane 180 deg apart; plane j shifted F*360/T*j
    assert np.allclose(np.degrees(el.raan_rad), [0, 0, 120, 120, 240, 240])
    assert np.allclose(np.degrees(el.arg_lat0_rad), [0, 180, 60, 240, 120, 300])


def test_walker_galileo_like_53_24_3_1():
    el = walker_delta(24, 3, 1, np.radians(56), 23_222e3)
    assert el.n_sat == 24
    raan = np.unique(np.round(np.degrees(el.raan_rad), 9))
    assert np.allclose(raan, [0, 120, 240])
    u = np.degrees(el.arg_lat0_rad).reshape(3, 8)
    assert np.allclose(np.diff(u[0]), 45.0)  # 8 per plane
    assert np.allclose(u[:, 0], [0, 15, 30])  # F * 360 / T = 15 deg between planes
    assert np.allclose(el.inclination_rad, np.radians(56))


def test_walker_rejects_bad_pattern():
    with pytest.raises(ConfigError, match="multiple of n_planes"):
        walker_delta(10, 3, 0, 0.9, 550e3)
    with pytest.raises(ConfigError, match="phasing = 3"):
        walker_delta(6, 3, 3, 0.9, 550e3)


def test_elements_concat_and_n_sat():
    a = walker_delta(6, 3, 1, 0.9, 550e3)
    b = Elements(1200e3, 1.5, [0.1, 0.2], 0.0)
    c = a.concat(b)
    assert c.n_sat == 8 and np.allclose(c.altitude_m[-2:], 1200e3)
    assert Elements.concat(a, b).n_sat == 8


@pytest.mark.parametrize("earth_rotation", [False, True])
@pytest.mark.parametrize("ascending", [True, False])
@pytest.mark.parametrize("lat_deg,lon_deg", [(40.4, -3.7), (-52.9, 170.0), (0.0, 0.0), (53.0, 10)])
def test_pass_over_sub_satellite_point(earth_rotation, ascending, lat_deg, lon_deg):
    t_pass = 321.0
    el = pass_over(
        np.radians(lat_deg),
        np.radians(lon_deg),
        t_pass,
        1300e3,
        np.radians(53.0),
        ascending=ascending,
        earth=CentralBody(rotation=earth_rotation),
    )
    eph = Ephemeris.from_elements(el, earth_rotation=earth_rotation)
    pos, vel, _ = eph(np.array([t_pass - 1.0, t_pass]))
    lat, lon, alt = ecef_to_geodetic(pos[1, 0])
    assert abs(np.degrees(lat) - lat_deg) < 1e-9 and abs(np.degrees(lon) - lon_deg) < 1e-9
    assert abs(alt - 1300e3) < ROUND_M
    # ascending: latitude increasing at the pass (except at the northernmost point)
    if abs(lat_deg) < 53.0:
        lat_before = ecef_to_geodetic(pos[0, 0])[0]
        assert (lat[()] > lat_before) == ascending


def test_pass_over_unreachable_latitude():
    with pytest.raises(ConfigError, match="not reachable with inclination 53.000 deg"):
        pass_over(np.radians(60.0), 0.0, 0.0, 550e3, np.radians(53.0))


def _circular_satrec(h_m, inc, raan, u0, jd, fr):
    """sgp4 Satrec of a (nearly) circular orbit, WGS72, mean motion from the two-body orbit."""
    n = angular_rate_rad_s(h_m, wgs72.radiusearthkm * 1e3, wgs72.mu * 1e9)
    sat = Satrec()
    epoch = jd + fr - 2433281.5  # days since 1949 Dec 31 00:00 UT
    sat.sgp4init(WGS72, "i", 1, epoch, 0.0, 0.0, 0.0, 1e-9, 0.0, inc, u0, n * 60.0, raan)
    return sat


@pytest.mark.parametrize(
    "h_m,inc_deg", [(340e3, 53.0), (1300e3, 53.0), (550e3, 97.6), (800e3, 0.5)]
)
def test_circular_orbit_agrees_with_sgp4(h_m, inc_deg):
    # sgp4 adds J2 (eps = J2 (R/a)^2 ~ 1e-3): short-period terms and the mean-vs-osculating
    # offset are O(eps a) (a few km), and the secular rates of node, perigee and mean anomaly
    # shift the argument of latitude by at most ~3 eps n t. Bound: eps a (3 + 3 n t). At
    # 1300 km over 10 min that is 27 km; a 0.3 deg phase error alone would be 40 km.
    r_m, mu = wgs72.radiusearthkm * 1e3, wgs72.mu * 1e9
    inc, raan, u0 = np.radians(inc_deg), 0.7, 0.3
    jd, fr = jday(2024, 1, 1, 0, 0, 0)
    sat = _circular_satrec(h_m, inc, raan, u0, jd, fr)
    t = np.linspace(0.0, 600.0, 61)
    pos, vel, acc, err = tle_state([sat], np.full_like(t, jd), fr + t / 86400.0, mu)
    assert not err.any()
    ref, ref_vel, _ = circular_state(t, h_m, inc, raan, u0, radius_m=r_m, gm_m3_s2=mu)
    a = r_m + h_m
    eps = wgs72.j2 * (r_m / a) ** 2
    n = angular_rate_rad_s(h_m, r_m, mu)
    bound = eps * a * (3.0 + 3.0 * n * t)
    assert np.all(np.linalg.norm(pos - ref, axis=-1)[:, 0] < bound)
    # radius: J2 short-period radial terms are below eps a
    assert np.all(np.abs(np.linalg.norm(pos, axis=-1) - a) < eps * a)
    # velocity: same bound scaled by n
    assert np.all(np.linalg.norm(vel - ref_vel, axis=-1)[:, 0] < n * bound)
    # two-body acceleration from the sgp4 position: |a| = mu / r^2
    assert np.allclose(np.linalg.norm(acc, axis=-1), mu / np.linalg.norm(pos, axis=-1) ** 2)


def test_read_tle_file_and_ephemeris_from_tles():
    tles = read_tle_file(DATA / "geo_iss.tle")
    assert len(tles) == 1 and tles[0][0] == "ISS (ZARYA)"
    sat = Satrec.twoline2rv(tles[0][1], tles[0][2])
    eph = Ephemeris.from_tles(tles, sat.jdsatepoch, sat.jdsatepochF, earth_rotation=False)
    t = np.array([0.0, 600.0])
    pos, vel, _ = eph(t)
    assert pos.shape == (2, 1, 3) and eph.n_sat == 1
    e, r_km, v_km_s = sat.sgp4(sat.jdsatepoch, sat.jdsatepochF + 600.0 / 86400.0)
    assert e == 0
    assert np.allclose(pos[1, 0], np.array(r_km) * 1e3, atol=1e-3)  # km -> m conversion
    assert np.allclose(vel[1, 0], np.array(v_km_s) * 1e3, atol=1e-6)
    # ISS altitude 400-430 km in 2019
    alt = np.linalg.norm(pos, axis=-1) - 6378.137e3
    assert np.all((alt > 380e3) & (alt < 440e3))


def test_ephemeris_from_tles_with_rotation_matches_skyfield():
    # skyfield's ITRS adds polar motion (~10 m) and rotates by the UT1 angle; leolink uses sgp4's
    # GMST of the UTC date. On 2019-12-09 UT1 - UTC = -0.17 s, i.e. w_E * 0.17 s * 6.8e6 m = 85 m
    # of rotation (measured: 55-83 m). 150 m still catches a wrong GMST (1 s of rotation = 0.5 km).
    skyfield_api = pytest.importorskip("skyfield.api")
    from skyfield.framelib import itrs

    tles = read_tle_file(DATA / "geo_iss.tle")
    ts = skyfield_api.load.timescale(builtin=True)
    sat = skyfield_api.EarthSatellite(tles[0][1], tles[0][2], tles[0][0], ts)
    jd, fr = sat.model.jdsatepoch, sat.model.jdsatepochF
    eph = Ephemeris.from_tles(tles, jd, fr, earth_rotation=True)
    t = np.array([0.0, 300.0, 900.0])
    pos, _, _ = eph(t)
    # sgp4 epochs are UTC: ask skyfield for the same UTC instants
    tt = ts.utc(2019, 12, 9, 0, 0, (jd + fr - 2458826.5) * 86400.0 + t)
    ref = sat.at(tt).frame_xyz(itrs).m.T
    assert np.all(np.linalg.norm(pos[:, 0] - ref, axis=-1) < 150.0)


def test_tle_state_error_codes_are_masks():
    # Perigee below the surface (e = 0.9): at perigee (t = 0) sgp4 reports error 6 (decayed);
    # we get NaN and a code, not an exception.
    jd, fr = jday(2024, 1, 1, 0, 0, 0)
    good = _circular_satrec(550e3, 0.9, 0.0, 0.0, jd, fr)
    bad = Satrec()
    bad.sgp4init(WGS72, "i", 2, jd + fr - 2433281.5, 0.0, 0.0, 0.0, 0.9, 0.0, 0.9, 0.0, 0.06, 0.0)
    pos, _, _, err = tle_state([good, bad], [jd, jd], [fr, fr + 1e-7])
    assert err.shape == (2, 2) and not err[:, 0].any() and err[:, 1].all()
    assert np.isnan(pos[:, 1]).all() and np.isfinite(pos[:, 0]).all()


def test_read_tle_file_names_the_bad_line(tmp_path):
    lines = (DATA / "geo_iss.tle").read_text().splitlines()
    broken = tmp_path / "bad.tle"
    broken.write_text("\n".join([lines[0], lines[1], lines[2][:40]]) + "\n")
    with pytest.raises(LeolinkError, match=r"bad.tle:3: TLE line 2 is malformed \(40 columns\)"):
        read_tle_file(broken)
    bad_sum = tmp_path / "sum.tle"
    bad_sum.write_text("\n".join([lines[1][:-1] + "0", lines[2]]) + "\n")
    with pytest.raises(LeolinkError, match=r"sum.tle:1: TLE line 1: checksum \(column 69\) fails"):
        read_tle_file(bad_sum)
