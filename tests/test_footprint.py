"""Half-power beam footprints: closed forms, the explicit steering-vector gain, and a
brute-force gain evaluation on a ground grid."""

import math

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from scipy.optimize import brentq

from leolink.antenna.array import explicit_gain, steering_vector, upa_gain
from leolink.antenna.footprint import (
    beam_contour_u,
    beam_footprints_ground,
    half_power_halfwidth_u,
)
from leolink.constants import EARTH_RADIUS_M
from leolink.geometry import direction_cosines, enu_basis, geodetic_to_ecef
from leolink.orbit import orbital_speed_m_s

N_SUB = (12, 24)  # the paper's 60 x 72 array in 5 x 3 subarrays
PAPER_BEAMS = np.array([[-0.2777777777777778, -0.06944444444444445], [0.0, 0.0], [0.1389, 0.0694]])
ALTITUDE_M = 1300e3


def _satellite(lat_deg=42.24, lon_deg=-8.72, heading_deg=35.0):
    """A satellite over (lat, lon) moving along ``heading`` (from north) at orbital speed."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    pos = geodetic_to_ecef(lat, lon, ALTITUDE_M)
    east, north, _ = enu_basis(lat, lon)
    h = math.radians(heading_deg)
    vel = float(orbital_speed_m_s(ALTITUDE_M)) * (math.sin(h) * east + math.cos(h) * north)
    return pos, vel


def test_half_width_of_two_and_three_elements_is_exact():
    # n = 2: g = cos^2(pi du / 2) -> du = 1/2. n = 3: sin(3x)/sin(x) = 3 - 4 sin^2 x = 3/sqrt 2.
    du3 = 2.0 / math.pi * math.asin(math.sqrt((3.0 - 3.0 / math.sqrt(2.0)) / 4.0))
    assert half_power_halfwidth_u(2) == pytest.approx(0.5, abs=1e-12)
    assert half_power_halfwidth_u(3) == pytest.approx(du3, abs=1e-12)


def test_half_width_tends_to_the_sinc_limit_for_large_arrays():
    # Balanis Sec. 6.3: sin(z)/z = 1/sqrt(2) at z = 1.3916; du = 2 z / (pi n). The O(1/n^2)
    # correction is ~1e-7 relative at n = 1000, far below the 1e-5 tolerance.
    z = brentq(lambda x: math.sin(x) / x - 1.0 / math.sqrt(2.0), 1.0, 2.0)
    for n in (500, 1000):
        assert half_power_halfwidth_u(n) * n == pytest.approx(2.0 * z / math.pi, rel=1e-5)


def test_contour_is_half_power_by_the_explicit_steering_vector_product():
    nx, ny = N_SUB
    contour = beam_contour_u(PAPER_BEAMS, nx, ny, n_points=48)  # (3, 48, 2)
    for b, pts in zip(PAPER_BEAMS, contour, strict=True):
        weights = steering_vector(b, nx, ny).reshape(-1, 1)
        g = explicit_gain(pts, weights, nx, ny)[:, 0] / (nx * ny)
        np.testing.assert_allclose(g, 0.5, atol=1e-9)


def test_contour_is_wider_along_the_shorter_subarray_axis():
    # 12 elements along x, 24 along y: the beam is twice as wide in u_x as in u_y.
    c = beam_contour_u([[0.0, 0.0]], *N_SUB, n_points=4)[0]  # angles 0, 90, 180, 270 deg
    assert c[0, 0] == pytest.approx(half_power_halfwidth_u(12), rel=1e-12)
    assert c[1, 1] == pytest.approx(half_power_halfwidth_u(24), rel=1e-12)


@pytest.mark.parametrize("beam", range(len(PAPER_BEAMS)))
def test_ground_footprint_matches_brute_force_gain_on_a_grid(beam):
    pos, vel = _satellite()
    lat, lon = beam_footprints_ground(pos, vel, PAPER_BEAMS[beam : beam + 1], *N_SUB, 144)
    ring = np.column_stack([lon[0, 0], lat[0, 0]])
    assert np.isfinite(ring).all()
    lo, hi = ring.min(axis=0), ring.max(axis=0)
    pad = 0.3 * (hi - lo)
    glon, glat = np.meshgrid(
        np.linspace(lo[0] - pad[0], hi[0] + pad[0], 160),
        np.linspace(lo[1] - pad[1], hi[1] + pad[1], 160),
    )
    ground = geodetic_to_ecef(np.radians(glat), np.radians(glon), 0.0, EARTH_RADIUS_M)
    u = direction_cosines(pos, vel, ground)
    b = PAPER_BEAMS[beam]
    g = upa_gain(u[..., 0] - b[0], u[..., 1] - b[1], *N_SUB) / (N_SUB[0] * N_SUB[1])
    inside = MplPath(ring).contains_points(np.column_stack([glon.ravel(), glat.ravel()]))
    inside = inside.reshape(glon.shape)
    # A 144-gon misses the smooth contour by a sagitta of ~2.4e-4 of its radius; near the
    # half-power level the gain changes by ~1.4 per unit radius, so only points within
    # 0.5 % of the level may disagree.
    clear = np.abs(g - 0.5) > 0.005
    assert np.array_equal(inside[clear], (g > 0.5)[clear])
    assert 0.1 < inside.mean() < 0.7  # the grid really straddles the footprint


def test_footprints_of_several_satellites_keep_their_order():
    p1, v1 = _satellite(42.0, -8.0)
    p2, v2 = _satellite(10.0, 100.0, heading_deg=-20.0)
    lat, lon = beam_footprints_ground(
        np.stack([p1, p2]), np.stack([v1, v2]), PAPER_BEAMS, *N_SUB, 36
    )
    assert lat.shape == (2, 3, 36)
    assert abs(np.nanmean(lat[0]) - 42.0) < 5 and abs(np.nanmean(lon[1]) - 100.0) < 5
