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


def _walker_elevations(monkeypatch, compiled, threads="2", **kw):
    """Elevations of 40 ISS-like satellites (RAAN and mean anomaly spread) from 30 sites
    over 50 min, by the compiled kernel or the numpy code."""
    from leolink import compiled as flags

    monkeypatch.setenv("LEOLINK_JIT", "1" if compiled else "0")
    monkeypatch.setenv("LEOLINK_THREADS", threads)
    monkeypatch.setattr(flags, "SPLIT_MIN_ROWS", 97)  # (the sites split even at this size)
    flags.enabled.cache_clear()
    flags.n_threads.cache_clear()
    try:
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
    finally:
        flags.enabled.cache_clear()
        flags.n_threads.cache_clear()


#: The compiled kernel's arcsine (fdlibm's) against the C library's (numpy's, x86-64 without
#: AVX-512): both are within 1 ulp of the exact value (fdlibm's bound; glibc's
#: libm-test-ulps lists 1 for asin), and 1e7 points differ by at most 1 ulp of each other.
ASIN_ULP = 1


def test_the_kernels_arcsine_is_within_an_ulp_of_the_c_librarys():
    """Every branch of visibility_kernel.asin (|x| < 0.5, 0.5 .. 0.975, 0.975 .. 1), their
    edges, the ends, signed zeros and NaN against math.asin, value by value."""
    import math

    pytest.importorskip("leolink._kernels")  # (built at install: setup.py)
    from leolink.visibility_kernel import asin as each

    rng = np.random.default_rng(7)
    edges = np.array([0.0, 0.5, 0.975, 1.0, 1e-300, 5e-324, 2.0**-27, 1e-8])
    x = np.concatenate([rng.uniform(-1.0, 1.0, 100_000), 1.0 - rng.uniform(0, 1e-9, 10_000),
                        rng.uniform(0.4999, 0.5001, 10_000), rng.uniform(0.9749, 0.9751, 10_000),
                        edges, np.nextafter(edges, 2.0), np.nextafter(edges, -2.0)])  # fmt: skip
    x = np.concatenate([x, -x])
    x = x[np.abs(x) <= 1.0]  # (the next float above 1)
    got, expected = each(x), np.array([math.asin(v) for v in x])
    np.testing.assert_array_max_ulp(got, expected, maxulp=ASIN_ULP)
    assert np.array_equal(np.signbit(got), np.signbit(expected))  # asin(-0.0) = -0.0
    assert got[x == 1.0][0] == math.pi / 2 and np.isnan(each(np.array([np.nan]))[0])


def test_the_compiled_kernel_agrees_with_the_numpy_code(monkeypatch):
    """sin(elevation) has the numpy code's bits, the arcsine is within ASIN_ULP: so the
    elevations are within ASIN_ULP of numpy's, and equal bit for bit whatever the threads
    and blocks (a block of 7 times), and float32 within 1 ulp of float32; many satellites
    seen from many sites."""
    pytest.importorskip("leolink._kernels")
    ref = _walker_elevations(monkeypatch, compiled=False)
    assert (ref > 0).sum() > 500 and (ref < 0).sum() > 10_000  # above and below
    assert ref.max() > np.radians(80.0)  # near the zenith too, where asin's slope is large
    got = _walker_elevations(monkeypatch, compiled=True, threads="2")
    np.testing.assert_array_max_ulp(got, ref, maxulp=ASIN_ULP)
    one = _walker_elevations(monkeypatch, compiled=True, threads="1")
    np.testing.assert_array_equal(one, got)
    blocks = _walker_elevations(monkeypatch, compiled=True, block_bytes=64 * 40 * 7)
    np.testing.assert_array_equal(blocks, got)  # 7 times per block
    single = _walker_elevations(monkeypatch, compiled=True, dtype=np.float32)
    np.testing.assert_array_equal(single, got.astype(np.float32))
    np.testing.assert_array_max_ulp(single, ref.astype(np.float32), maxulp=1)
