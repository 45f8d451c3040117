"""Tests of leolink.visibility: elevations of TLE satellites from WGS 84 sites."""

import numpy as np
import pytest
from sgp4.api import Satrec, jday

from leolink.visibility import gmst82_rad, tle_elevations_rad

ISS = (
    "1 25544U 98067A   19343.69339541  .00001764  00000-0  38792-4 0  9991",
    "2 25544  51.6439 211.2001 0007417  17.6667  85.6398 15.50103472202482",
)
# skyfield rotates TEME to ITRS by the same GMST82(UT1) (its TEME frame, no polar motion):
# the two agree to float rounding; 1e-6 deg (4 mas) leaves room for summation order.
SKYFIELD_DEG = 1e-6
SITES = ((49.69, -5.55, 0.0), (40.0, 0.0, 100.0), (-33.9, 151.2, 0.0), (52.0, -4.0, 2000.0))


def _jd(seconds):
    jd0, fr0 = jday(2019, 12, 9, 16, 30, 0.0)
    return np.full(seconds.shape, jd0), fr0 + seconds / 86_400.0


def test_gmst_equals_sgp4_gstime():
    from sgp4.propagation import gstime

    jd = np.array([2451545.0, 2458827.5, 2460000.5])
    fr = np.array([0.0, 0.1234, 0.9])
    expected = [gstime(a + b) for a, b in zip(jd, fr, strict=True)]
    np.testing.assert_allclose(gmst82_rad(jd, fr), expected, rtol=0, atol=1e-9)


def test_elevations_agree_with_skyfield():
    skyfield = pytest.importorskip("skyfield.api")
    ts = skyfield.load.timescale()
    seconds = np.arange(0.0, 1200.0, 30.0)
    t = ts.utc(2019, 12, 9, 16, 30, seconds)
    sat = skyfield.EarthSatellite(*ISS, "ISS", ts)
    sites = [skyfield.wgs84.latlon(la, lo, elevation_m=h) for la, lo, h in SITES]
    expected = np.array([(sat - s).at(t).altaz()[0].degrees for s in sites])
    lat, lon, h = (np.array(c, float) for c in zip(*SITES, strict=True))
    jd, fr = _jd(seconds)
    got = tle_elevations_rad(
        [Satrec.twoline2rv(*ISS)], np.radians(lat), np.radians(lon), h, jd, fr,
        ut1_minus_utc_s=float(np.mean(t.dut1)),
    )  # fmt: skip
    assert got.shape == (len(SITES), 1, seconds.size)
    assert expected.max() > 10.0  # the pass is seen above the horizon, not only below
    np.testing.assert_allclose(np.degrees(got[:, 0]), expected, rtol=0, atol=SKYFIELD_DEG)


def test_blocks_do_not_change_the_result():
    sats = [Satrec.twoline2rv(*ISS)] * 3
    seconds = np.arange(0.0, 300.0, 7.0)
    jd, fr = _jd(seconds)
    lat, lon = np.radians(np.linspace(-60, 60, 9)), np.radians(np.linspace(-180, 170, 9))
    whole = tle_elevations_rad(sats, lat, lon, 0.0, jd, fr)
    tiny = tle_elevations_rad(sats, lat, lon, 0.0, jd, fr, block_bytes=1)  # 1 site, 1 time
    np.testing.assert_array_equal(tiny, whole)


def test_satellite_straight_above_a_site_is_at_90_degrees():
    # The site is put under the satellite: its geodetic point at the first time.
    from leolink.geodesy import ecef_to_wgs84
    from leolink.visibility import _earth_fixed_states, _satrec_array

    jd, fr = _jd(np.array([0.0]))
    pos = _earth_fixed_states(_satrec_array([Satrec.twoline2rv(*ISS)]), jd, fr, 0.0).T
    lat, lon, _ = ecef_to_wgs84(pos)
    elev = tle_elevations_rad([Satrec.twoline2rv(*ISS)], lat, lon, 0.0, jd, fr)
    # asin of a value near 1: ~1e-8 rad of rounding (module docstring), 1e-6 deg = 1.7e-8 rad
    assert np.degrees(elev[0, 0, 0]) == pytest.approx(90.0, abs=1e-6)


def _walker_elevations(**kw):
    """Elevations of 40 ISS-like satellites (RAAN and mean anomaly spread) from 30 sites
    over 50 min."""
    base = Satrec.twoline2rv(*ISS)
    sats = []
    for k in range(40):
        s = Satrec()
        s.sgp4init(0, "i", k, base.jdsatepoch + base.jdsatepochF - 2433281.5, base.bstar,
                   0.0, 0.0, base.ecco, base.argpo, base.inclo, (base.mo + 0.7 * k) % 6.28,
                   base.no_kozai, (base.nodeo + 0.3 * k) % 6.28)  # fmt: skip
        sats.append(s)
    lat = np.radians(np.linspace(-60.0, 60.0, 30))
    lon = np.radians(np.linspace(-180.0, 170.0, 30))
    jd, fr = _jd(np.arange(0.0, 3000.0, 60.0))
    return tle_elevations_rad(sats, lat, lon, 50.0, jd, fr, **kw)


def test_elevations_do_not_depend_on_the_blocks():
    """Blocks of 7 times give the elevations of one block, bit for bit (elementwise
    arithmetic), float32 the float64 values rounded; many satellites from many sites."""
    ref = _walker_elevations()
    assert (ref > 0).sum() > 500 and (ref < 0).sum() > 10_000  # above and below
    assert ref.max() > np.radians(80.0)  # near the zenith too, where asin's slope is large
    np.testing.assert_array_equal(_walker_elevations(block_bytes=64 * 40 * 7), ref)
    single = _walker_elevations(dtype=np.float32)
    np.testing.assert_array_equal(single, ref.astype(np.float32))
