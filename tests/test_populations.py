"""sim.mobility.populations: relative headings against the ROI axes, placement in the ROI plane.

The ROI x axis is the ground track at the centre (azimuth ``track_heading_rad``); its y
axis is ``up x x``, to the left of the track. ``along_track`` moves along +x,
``against_track`` along -x, ``cross_track`` 90 deg clockwise of the track: to its right
(the paper's +y, ``u_x x u_sat``; leolink's ROI -y, see docs/errata.md). Each UT's
initial velocity is compared with those axes built here from east/north vectors.
"""

import math

import numpy as np
import pytest

from leolink.sim.mobility.populations import MOBILITY, PopulationContext

R_M = 6_371_000.0


def _axes(lat, lon, track_rad):
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    north = np.array(
        [-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)]
    )
    up = np.cross(east, north)
    ex = math.sin(track_rad) * east + math.cos(track_rad) * north
    return up, ex, np.cross(up, ex)


def _build(heading, track_rad, lat=0.7, lon=-0.15, seed=0, **extra):
    ctx = PopulationContext(
        center_lat_rad=lat,
        center_lon_rad=lon,
        semi_axes_m=(534e3, 170e3),
        track_heading_rad=track_rad,
        rng=np.random.default_rng(seed),
        t0_s=0.0,
        radius_m=R_M,
    )
    params = MOBILITY["constant_velocity"].config(
        name="p", placement="center", count=3, speed_m_s=30.0, heading_deg=heading, **extra
    )
    return MOBILITY.build("constant_velocity", params, ctx)


EXPECTED = {"along_track": (1, 0), "against_track": (-1, 0), "cross_track": (0, -1)}


@pytest.mark.parametrize("track_deg", [0.0, 23.5, 90.0, 161.0, 250.0, 344.0])
@pytest.mark.parametrize("heading", list(EXPECTED))
def test_relative_headings_follow_the_roi_axes(heading, track_deg):
    track = math.radians(track_deg)
    model = _build(heading, track)
    s = model.state(0.0)
    up, ex, ey = _axes(0.7, -0.15, track)
    unit = s.vel_m_s / np.linalg.norm(s.vel_m_s, axis=1, keepdims=True)
    want_x, want_y = EXPECTED[heading]
    np.testing.assert_allclose(unit @ ex, want_x, atol=1e-12)
    np.testing.assert_allclose(unit @ ey, want_y, atol=1e-12)
    np.testing.assert_allclose(unit @ up, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(s.vel_m_s, axis=1), 30.0, rtol=1e-12)


@pytest.mark.parametrize("heading_deg", [0.0, 90.0, 135.0, -60.0])
def test_numeric_heading_is_from_north_whatever_the_track(heading_deg):
    model = _build(heading_deg, math.radians(40.0))
    v = model.state(0.0).vel_m_s[0]
    lat, lon = 0.7, -0.15
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    north = np.array(
        [-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)]
    )
    az = math.degrees(math.atan2(v @ east, v @ north))
    assert (az - heading_deg + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)


def test_random_headings_are_uniform_and_seeded():
    from scipy import stats

    ctx_model = _build("random", 0.3, seed=5)
    v = ctx_model.state(0.0).vel_m_s
    assert len(np.unique(np.round(v, 9), axis=0)) == 3
    # Many UTs: azimuths uniform on the circle.
    params = MOBILITY["constant_velocity"].config(
        name="p", placement="center", count=4000, speed_m_s=1.0, heading_deg="random"
    )
    ctx = PopulationContext(0.7, -0.15, (534e3, 170e3), 0.3, np.random.default_rng(5), 0.0, R_M)
    vel = MOBILITY.build("constant_velocity", params, ctx).state(0.0).vel_m_s
    up, ex, ey = _axes(0.7, -0.15, 0.0)
    az = np.arctan2(vel @ -ey, vel @ ex) % (2 * np.pi)  # ex = north, -ey = east
    assert stats.kstest(az, "uniform", args=(0, 2 * np.pi)).pvalue > 1e-4
