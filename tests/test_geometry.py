"""Tests of leolink.geometry: published slant ranges, two independent computations, properties."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.constants import EARTH_RADIUS_M as R
from leolink.geometry import (
    body_frame,
    direction_cosines,
    ecef_to_geodetic,
    elevation_from_nadir_rad,
    enu_basis,
    geodetic_to_ecef,
    ground_to_roi,
    look_angles,
    nadir_angle_rad,
    ray_to_ground,
    roi_to_ground,
    slant_range_from_elevation_m,
)
from leolink.greatcircle import destination_point, great_circle_velocity

# Published slant ranges are printed to 10 m (0.01 km); allow half a digit.
PRINTED_KM_ROUNDING_M = 5.0
# Round trips in float64 on Earth-sized numbers (~7e6 m): 1e-6 m is 1e-13 relative.
ROUND_TRIP_M = 1e-6
UNIT_TOL = 1e-12

lat_st = st.floats(-1.55, 1.55)
lon_st = st.floats(-3.14, 3.14)
alt_st = st.floats(300e3, 2000e3)


def _sat_state(lat, lon, alt, heading):
    """A satellite position and a velocity with a radial part (as an eccentric orbit has)."""
    pos = geodetic_to_ecef(lat, lon, alt)
    vel = great_circle_velocity(lat, lon, heading, 7500.0) + 30.0 * pos / np.linalg.norm(pos)
    return pos, vel


def test_slant_range_35_deg_at_340_km():
    assert abs(slant_range_from_elevation_m(np.radians(35.0), 340e3) - 564.92e3) < (
        PRINTED_KM_ROUNDING_M
    )


def test_slant_range_85_26_deg_at_1200_km():
    assert abs(slant_range_from_elevation_m(np.radians(85.26), 1200e3) - 1203.46e3) < (
        PRINTED_KM_ROUNDING_M
    )


def test_slant_range_limits():
    # zenith: the altitude; horizon: sqrt((R+h)^2 - R^2) (Pythagoras).
    h = 550e3
    assert abs(slant_range_from_elevation_m(np.pi / 2, h) - h) < ROUND_TRIP_M
    assert abs(slant_range_from_elevation_m(0.0, h) - np.sqrt((R + h) ** 2 - R**2)) < 1e-3


def test_look_angles_agree_with_closed_form_slant_range():
    # Two independent ways: vectors (look_angles) vs law of cosines from the elevation.
    rng = np.random.default_rng(1)
    n = 2000
    ut = geodetic_to_ecef(rng.uniform(-1.5, 1.5, n), rng.uniform(-np.pi, np.pi, n))
    h = rng.uniform(300e3, 2000e3, n)
    sat = geodetic_to_ecef(rng.uniform(-1.5, 1.5, n), rng.uniform(-np.pi, np.pi, n), h)
    el, _, rng_m = look_angles(ut, sat)
    visible = el > 0.0
    assert visible.sum() > 50
    closed = slant_range_from_elevation_m(el[visible], h[visible])
    assert np.allclose(closed, rng_m[visible], rtol=0, atol=1e-4)
    # Nadir angle from the law of sines vs the angle between nadir and the UT seen from the sat.
    to_ut = ut[visible] - sat[visible]
    cos_eta = -np.sum(to_ut * sat[visible], -1) / (
        np.linalg.norm(to_ut, axis=-1) * np.linalg.norm(sat[visible], axis=-1)
    )
    assert np.allclose(nadir_angle_rad(el[visible], h[visible]), np.arccos(cos_eta), atol=1e-9)
    assert np.allclose(
        elevation_from_nadir_rad(np.arccos(cos_eta), h[visible]), el[visible], atol=1e-7
    )


def test_azimuth_convention_north_then_east_clockwise():
    lat, lon = np.radians(40.0), np.radians(-3.0)
    ut = geodetic_to_ecef(lat, lon)
    for heading_deg in (0.0, 90.0, 180.0, 270.0, 33.0):
        lat2, lon2 = destination_point(lat, lon, np.radians(heading_deg), 500e3)
        el, az, _ = look_angles(ut, geodetic_to_ecef(lat2, lon2, 800e3))
        assert el > 0
        # destination_point keeps the initial heading; the azimuth of a point along that great
        # circle seen from the start is that heading.
        assert abs(np.degrees(az) - heading_deg) < 1e-9 or abs(np.degrees(az) - 360) < 1e-9


def test_zenith_satellite_has_90_deg_elevation():
    ut = geodetic_to_ecef(0.3, 1.2)
    el, _, d = look_angles(ut, geodetic_to_ecef(0.3, 1.2, 600e3))
    assert abs(el - np.pi / 2) < 1e-7 and abs(d - 600e3) < ROUND_TRIP_M


@settings(max_examples=200, deadline=None)
@given(lat=lat_st, lon=lon_st, alt=st.floats(-1000.0, 3e6))
def test_geodetic_ecef_round_trip(lat, lon, alt):
    lat2, lon2, alt2 = ecef_to_geodetic(geodetic_to_ecef(lat, lon, alt))
    assert abs(lat2 - lat) < UNIT_TOL and abs(lon2 - lon) < UNIT_TOL
    assert abs(alt2 - alt) < ROUND_TRIP_M


def test_enu_basis_matches_numerical_derivatives():
    # east = d pos / d lon normalized, north = d pos / d lat normalized.
    lat, lon, eps = 0.7, -2.0, 1e-6
    basis = enu_basis(lat, lon)
    d_lon = geodetic_to_ecef(lat, lon + eps) - geodetic_to_ecef(lat, lon - eps)
    d_lat = geodetic_to_ecef(lat + eps, lon) - geodetic_to_ecef(lat - eps, lon)
    assert np.allclose(basis[0], d_lon / np.linalg.norm(d_lon), atol=1e-8)
    assert np.allclose(basis[1], d_lat / np.linalg.norm(d_lat), atol=1e-8)
    assert np.allclose(basis[2], geodetic_to_ecef(lat, lon) / R, atol=UNIT_TOL)


@settings(max_examples=200, deadline=None)
@given(lat=lat_st, lon=lon_st, alt=alt_st, heading=st.floats(0.0, 6.28))
def test_body_frame_orthonormal_right_handed(lat, lon, alt, heading):
    pos, vel = _sat_state(lat, lon, alt, heading)
    frame = body_frame(pos, vel)
    assert np.allclose(frame @ frame.T, np.eye(3), atol=UNIT_TOL)
    assert abs(np.linalg.det(frame) - 1.0) < UNIT_TOL
    assert np.allclose(frame[2], pos / np.linalg.norm(pos), atol=UNIT_TOL)
    assert frame[0] @ vel > 0.0
    assert np.allclose(frame[1], np.cross(frame[2], frame[0]), atol=UNIT_TOL)


@settings(max_examples=200, deadline=None)
@given(
    lat=lat_st,
    lon=lon_st,
    alt=alt_st,
    heading=st.floats(0.0, 6.28),
    x=st.floats(-3e6, 3e6),
    y=st.floats(-3e6, 3e6),
)
def test_roi_plane_ground_round_trip(lat, lon, alt, heading, x, y):
    pos, vel = _sat_state(lat, lon, alt, heading)
    ground = roi_to_ground(x, y, pos, vel)
    assert abs(np.linalg.norm(ground) - R) < ROUND_TRIP_M
    x2, y2 = ground_to_roi(ground, pos, vel)
    assert abs(x2 - x) < ROUND_TRIP_M and abs(y2 - y) < ROUND_TRIP_M


def test_roi_is_gnomonic_projection():
    # A central projection keeps great circles straight: points on the x axis lie in the plane
    # spanned by u_z and u_x, and x = R tan(central angle) (stereographic would be 2R tan(a/2)).
    pos, vel = _sat_state(0.2, 0.4, 1300e3, 0.9)
    frame = body_frame(pos, vel)
    x = 534.1e3
    ground = roi_to_ground(x, 0.0, pos, vel)
    angle = np.arccos(ground @ frame[2] / R)
    assert abs(R * np.tan(angle) - x) < ROUND_TRIP_M
    assert abs(ground @ frame[1]) < ROUND_TRIP_M


@settings(max_examples=200, deadline=None)
@given(
    lat=lat_st,
    lon=lon_st,
    alt=alt_st,
    heading=st.floats(0.0, 6.28),
    r=st.floats(0.0, 0.99),
    phi=st.floats(0.0, 6.28),
)
def test_direction_cosines_ray_to_ground_round_trip(lat, lon, alt, heading, r, phi):
    pos, vel = _sat_state(lat, lon, alt, heading)
    sin_max = R / (R + alt)  # edge of the visible cap (horizon)
    u = r * sin_max * np.array([np.cos(phi), np.sin(phi)])
    ground = ray_to_ground(pos, vel, u)
    assert abs(np.linalg.norm(ground) - R) < ROUND_TRIP_M
    assert np.allclose(direction_cosines(pos, vel, ground), u, atol=1e-9)
    # and back again: the ground point is recovered (to < 1 mm except grazing rays)
    if r < 0.9:
        assert np.allclose(
            ray_to_ground(pos, vel, direction_cosines(pos, vel, ground)), ground, atol=1e-3
        )


def test_ray_to_ground_nan_beyond_horizon_and_nadir():
    pos, vel = _sat_state(0.0, 0.0, 1000e3, 0.0)
    sin_max = R / (R + 1000e3)
    out = ray_to_ground(pos, vel, np.array([[0.0, 0.0], [1.01 * sin_max, 0.0], [0.0, 1.2]]))
    assert np.allclose(out[0], pos * R / np.linalg.norm(pos), atol=ROUND_TRIP_M)
    assert np.all(np.isnan(out[1:]))


def test_direction_cosines_signs():
    # A target ahead along-track has u_x > 0; to the left (y = z x x) has u_y > 0.
    pos, vel = _sat_state(0.0, 0.0, 1000e3, 0.0)  # at (0,0) heading north
    ahead = geodetic_to_ecef(np.radians(2.0), 0.0)
    left = geodetic_to_ecef(0.0, np.radians(-2.0))  # west is left when heading north
    assert direction_cosines(pos, vel, ahead)[0] > 0.1
    assert direction_cosines(pos, vel, left)[1] > 0.1


def test_direction_cosines_broadcast_shapes():
    pos = geodetic_to_ecef(np.zeros((4, 1)), np.zeros((4, 1)), 1e6)
    vel = np.broadcast_to([0.0, 0.0, 7e3], (4, 1, 3))
    ut = geodetic_to_ecef(np.linspace(-0.1, 0.1, 5), 0.0)
    assert direction_cosines(pos, vel, ut).shape == (4, 5, 2)
    assert roi_to_ground(np.zeros(5), np.zeros(5), pos, vel).shape == (4, 5, 3)


@settings(max_examples=100, deadline=None)
@given(lat=st.floats(-1.4, 1.4), lon=lon_st, heading=st.floats(0.0, 6.28), d=st.floats(0.0, 5e6))
def test_destination_point_distance_and_velocity(lat, lon, heading, d):
    lat2, lon2 = destination_point(lat, lon, heading, d)
    p1, p2 = geodetic_to_ecef(lat, lon), geodetic_to_ecef(lat2, lon2)
    # great-circle distance by the chord (independent of the heading formulas)
    chord = np.linalg.norm(p2 - p1)
    assert abs(2 * R * np.arcsin(min(chord / (2 * R), 1.0)) - d) < 1e-3
    # velocity = numerical derivative of the great-circle position at the start
    dt, speed = 1e-2, 30.0
    la, lo = destination_point(lat, lon, heading, speed * dt)
    num = (geodetic_to_ecef(la, lo) - p1) / dt
    assert np.allclose(great_circle_velocity(lat, lon, heading, speed), num, atol=1e-5)


def test_ground_to_roi_far_side_is_nan():
    pos, vel = _sat_state(0.0, 0.0, 1000e3, 0.0)
    x, y = ground_to_roi(-pos, pos, vel)
    assert np.isnan(x) and np.isnan(y)


@pytest.mark.parametrize("el_deg", [10.0, 45.0, 89.0])
def test_nadir_elevation_inverse(el_deg):
    el = np.radians(el_deg)
    assert abs(elevation_from_nadir_rad(nadir_angle_rad(el, 700e3), 700e3) - el) < 1e-9


def test_direction_cosines_of_many_targets_match_the_explicit_body_frame():
    """Vectorized over targets and satellites: each row equals the body-frame projection
    written out (x = v_perp / |v_perp|, z = r / |r|, y = z x x), target by target."""
    from leolink.geometry import direction_cosines

    rng = np.random.default_rng(3)
    sat = rng.normal(size=(6, 3)) * 7.0e6
    vel = rng.normal(size=(6, 3)) * 7.0e3
    tgt = rng.normal(size=(6, 3)) * 6.4e6
    u = direction_cosines(sat, vel, tgt)
    for i in range(6):
        z = sat[i] / np.linalg.norm(sat[i])
        x = vel[i] - (vel[i] @ z) * z
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        d = (tgt[i] - sat[i]) / np.linalg.norm(tgt[i] - sat[i])
        np.testing.assert_allclose(u[i], [d @ x, d @ y], rtol=0, atol=1e-14)
