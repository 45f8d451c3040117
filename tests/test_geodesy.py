"""Tests of leolink.geodesy and of UTs on the WGS 84 ellipsoid (earth.model = "wgs84"):
positions against PROJ (pyproj) and skyfield, velocities against finite differences."""

import math
from pathlib import Path

import numpy as np
import pytest

from leolink.geodesy import ecef_to_wgs84, radii_of_curvature_m, wgs84_to_ecef, wgs84_velocity

ROOT = Path(__file__).resolve().parents[1]
MM = 1e-3  # the tolerance for positions
# Geodetic grid: all latitudes (poles included), longitudes, heights from the Dead Sea
# shore to cruise altitude.
RNG = np.random.default_rng(84)
LAT_DEG = np.r_[90.0, -90.0, 0.0, RNG.uniform(-90, 90, 2000)]
LON_DEG = np.r_[0.0, 45.0, -180.0, RNG.uniform(-180, 180, 2000)]
H_M = np.r_[0.0, 100.0, -400.0, RNG.uniform(-430, 12_000, 2000)]


def test_wgs84_to_ecef_equals_proj_to_1_mm():
    pyproj = pytest.importorskip("pyproj")
    to_ecef = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    ref = np.stack(to_ecef.transform(LON_DEG, LAT_DEG, H_M), axis=-1)
    got = wgs84_to_ecef(np.radians(LAT_DEG), np.radians(LON_DEG), H_M)
    assert np.abs(got - ref).max() < MM


def test_wgs84_to_ecef_equals_skyfield_to_1_mm():
    wgs84 = pytest.importorskip("skyfield.api").wgs84
    ref = wgs84.latlon(LAT_DEG, LON_DEG, H_M).itrs_xyz.m.T
    got = wgs84_to_ecef(np.radians(LAT_DEG), np.radians(LON_DEG), H_M)
    assert np.abs(got - ref).max() < MM


def test_ecef_to_wgs84_inverts_proj():
    pyproj = pytest.importorskip("pyproj")
    to_geo = pyproj.Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    pos = wgs84_to_ecef(np.radians(LAT_DEG), np.radians(LON_DEG), H_M)
    lon, lat, h = to_geo.transform(*pos.T)
    got_lat, got_lon, got_h = ecef_to_wgs84(pos)
    ok = np.abs(LAT_DEG) < 90.0  # longitude is undefined at the poles
    assert np.abs(np.degrees(got_lat) - lat).max() * 111e3 < MM
    assert np.abs(np.degrees(got_lon[ok]) - lon[ok]).max() * 111e3 < MM
    assert np.abs(got_h - h).max() < MM


def test_radii_of_curvature_at_the_equator_and_pole():
    """TR8350.2: N(0) = a, M(0) = a (1 - e^2) = 6335439.327 m, M = N = a^2 / b at the poles."""
    a, b = 6378137.0, 6356752.314245
    m0, n0 = radii_of_curvature_m(0.0)
    mp, np_ = radii_of_curvature_m(math.pi / 2)
    assert n0 == pytest.approx(a, abs=1e-6) and m0 == pytest.approx(6335439.327, abs=1e-3)
    assert mp == pytest.approx(a * a / b, abs=1e-3) and np_ == pytest.approx(a * a / b, abs=1e-3)


def test_wgs84_velocity_is_the_derivative_of_the_position():
    lat, lon, h = np.radians(LAT_DEG[3:50]), np.radians(LON_DEG[3:50]), H_M[3:50]
    rates = (RNG.normal(0, 1e-5, 47), RNG.normal(0, 1e-5, 47), RNG.normal(0, 5, 47))
    dt = 1e-2  # central differences: error ~ dt^2 |p'''| ~ 1e-8 m/s
    fwd = wgs84_to_ecef(lat + rates[0] * dt, lon + rates[1] * dt, h + rates[2] * dt)
    bwd = wgs84_to_ecef(lat - rates[0] * dt, lon - rates[1] * dt, h - rates[2] * dt)
    got = wgs84_velocity(lat, lon, h, *rates)
    assert np.abs(got - (fwd - bwd) / (2 * dt)).max() < 1e-5


def _scenario(path, overrides):
    from leolink.app.scenario import build_scenario
    from leolink.config import load_config

    return build_scenario(load_config(path, overrides))


def test_ut_positions_on_wgs84_equal_proj_and_their_velocity_is_their_derivative():
    """Every population kind of the constellation config, moved onto the ellipsoid: at
    any time the position is PROJ's for the UT's geodetic (lat, lon, alt), and the
    velocity matches a central difference of the positions."""
    pyproj = pytest.importorskip("pyproj")
    to_ecef = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    over = ['earth.model="wgs84"', "population.0.count=5", "population.1.count=5",
            "population.2.count=5", "population.3.count=5"]  # fmt: skip
    sc = _scenario(ROOT / "configs" / "constellation.toml", over)
    for _, model in sc.populations:
        s = model.state(37.0)
        ref = np.stack(to_ecef.transform(*np.degrees([s.lon_rad, s.lat_rad]), s.alt_m), -1)
        assert np.abs(s.pos_m - ref).max() < MM
        fwd, bwd = model.state(37.05).pos_m, model.state(36.95).pos_m
        assert np.abs(s.vel_m_s - (fwd - bwd) / 0.1).max() < 1e-3  # a 250 m/s aircraft


def test_sphere_populations_stay_on_the_sphere():
    """The default model keeps the paper's sphere: |p| = R + alt (the WGS 84 positions
    differ by kilometres, so the two cannot be mixed up)."""
    sc = _scenario(ROOT / "configs" / "paper.toml", [])
    ell = _scenario(ROOT / "configs" / "paper.toml", ['earth.model="wgs84"'])
    for (_, sph), (_, wgs) in zip(sc.populations, ell.populations, strict=True):
        s, w = sph.state(10.0), wgs.state(10.0)
        np.testing.assert_allclose(np.linalg.norm(s.pos_m, axis=1), 6371e3 + s.alt_m, rtol=1e-13)
        assert np.all(np.linalg.norm(s.pos_m - w.pos_m, axis=1) > 1e3)


def test_inverse_reaches_the_documented_1e_15_rad():
    """The inverse's six fixed-point iterations reach 1e-15 rad from -10 km to 40,000 km
    (its docstring; pyproj above checks 1 mm): the forward map, checked against skyfield,
    gives the points (a worse starting latitude leaves 8e-15 rad: caught)."""
    rng = np.random.default_rng(45)
    lat = rng.uniform(-1.5707, 1.5707, 20_000)
    lon = rng.uniform(-np.pi, np.pi, 20_000)
    h = rng.uniform(-1e4, 4e7, 20_000)
    got_lat, _, got_h = ecef_to_wgs84(wgs84_to_ecef(lat, lon, h))
    assert np.abs(got_lat - lat).max() < 1e-15
    assert np.abs(got_h - h).max() < 1e-6  # 1 um (4e7 m carries 7e-9 m of rounding)
