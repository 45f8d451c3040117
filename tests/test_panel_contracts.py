"""The UT panel frame and the element factor against independent constructions.

Written from the survivors of a mutation run (docs/testing.md): the references are built
another way than the code builds them. Local frames from cross products (east = z x r,
north = up x east); sky directions read back as angles with ``arcsin`` / ``arctan2``; the
pointing-error basis from a finite difference in elevation and a cross product with the
vertical; tilted panels by the properties that define them (orthonormal, right-handed, x
at its azimuth and dipping by the tilt); closed forms of the cosine element factor.
Tolerances: float64 rounding of unit vectors (1e-12) unless said.
"""

import warnings

import numpy as np
import pytest

from leolink.antenna.element import (
    element_factor_lin,
    flat_panel_scan_loss_db,
    scan_angle_rad,
    scan_loss_db,
)
from leolink.antenna.panel import (
    PanelOrientation,
    motion_azimuth_rad,
    oriented_panel_basis,
    panel_basis,
    panel_direction_cosines,
    panel_elevation_rad,
    pointing_offsets,
    sky_direction,
)

TOL = 1e-12
RNG = np.random.default_rng(16)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _enu_by_cross_products(pos_m):
    """East, north, up rows of the sphere from cross products (no angles)."""
    up = _unit(pos_m)
    east = _unit(np.cross([0.0, 0.0, 1.0], up))
    north = np.cross(up, east)
    return np.stack([east, north, up], axis=-2)


def _ut_positions(n):
    lat = RNG.uniform(-1.4, 1.4, n)  # away from the poles, where east is undefined
    lon = RNG.uniform(-np.pi, np.pi, n)
    r = 6.371e6 + RNG.uniform(0.0, 9e3, n)
    return r[:, None] * np.stack(
        [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1
    )


def test_panel_basis_is_east_north_up_from_cross_products():
    pos = _ut_positions(50)
    np.testing.assert_allclose(panel_basis(pos), _enu_by_cross_products(pos), atol=TOL)


def test_panel_direction_cosines_of_many_uts_and_satellites():
    n_ut, n_sat = 4, 5
    basis = _enu_by_cross_products(_ut_positions(n_ut))
    vec = _unit(RNG.normal(size=(n_ut, n_sat, 3)))
    got = panel_direction_cosines(basis, vec)
    assert got.shape == (n_ut, n_sat, 2)
    for u in range(n_ut):
        for s in range(n_sat):
            ref = [np.dot(vec[u, s], basis[u, 0]), np.dot(vec[u, s], basis[u, 1])]
            np.testing.assert_allclose(got[u, s], ref, atol=TOL)


def test_sky_direction_reads_back_as_its_angles_and_broadcasts():
    el = np.radians([[5.0], [30.0], [85.0]])  # (3, 1)
    az = np.radians([0.0, 90.0, 200.0, 330.0])  # (4,)
    d = sky_direction(el, az)
    assert d.shape == (3, 4, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=TOL)
    np.testing.assert_allclose(np.arcsin(d[..., 2]), np.broadcast_to(el, (3, 4)), atol=1e-9)
    az_back = np.mod(np.arctan2(d[..., 0], d[..., 1]), 2 * np.pi)  # from north, clockwise
    np.testing.assert_allclose(az_back, np.broadcast_to(az, (3, 4)), atol=1e-9)
    # Due east at the horizon is panel x; due north panel y.
    np.testing.assert_allclose(sky_direction(0.0, np.pi / 2), [1.0, 0.0, 0.0], atol=TOL)
    np.testing.assert_allclose(sky_direction(0.0, 0.0), [0.0, 1.0, 0.0], atol=TOL)


def _beam_by_construction(el, az, d, psi):
    """Beam direction ``cos(d) v + sin(d) (cos(psi) e_el + sin(psi) e_left)`` with e_el the
    finite difference of the sky direction in elevation and e_left = up x horizon."""
    v = sky_direction(el, az)
    h = 1e-6
    e_el = _unit((sky_direction(el + h, az) - sky_direction(el - h, az)) / (2 * h))
    e_left = np.cross([0.0, 0.0, 1.0], sky_direction(0.0, az))
    cp, sp = np.cos(psi)[..., None], np.sin(psi)[..., None]
    return v, np.cos(d) * v + np.sin(d) * (cp * e_el + sp * e_left)


@pytest.mark.parametrize("az_deg", [0.0, 37.0, 90.0, 180.0, 251.0])
def test_pointing_offsets_at_any_azimuth_against_the_constructed_beam(az_deg):
    el = np.radians([12.0, 40.0, 75.0])[:, None]
    psi = np.radians([0.0, 60.0, 90.0, 200.0, 300.0])
    d, az = np.radians(3.0), np.radians(az_deg)
    du_x, du_y = pointing_offsets(el, d, psi, az)
    assert du_x.shape == du_y.shape == (3, 5)
    v, b = _beam_by_construction(el, az, d, psi)
    np.testing.assert_allclose(du_x, (b - v)[..., 0], atol=1e-9)  # 1e-9: the difference
    np.testing.assert_allclose(du_y, (b - v)[..., 1], atol=1e-9)


@pytest.mark.parametrize("az_deg", [20.0, 90.0, 160.0])
def test_pointing_offsets_closed_forms(az_deg):
    el, d, az = np.radians(30.0), np.radians(4.0), np.radians(az_deg)
    v = sky_direction(el, az)[:2]
    # Towards higher elevation (psi = 0) the beam is at el + d, same azimuth; psi = pi: el - d.
    for psi, el_b in ((0.0, el + d), (np.pi, el - d)):
        got = np.array(pointing_offsets(el, d, psi, az))
        np.testing.assert_allclose(got, sky_direction(el_b, az)[:2] - v, atol=TOL)
    # At the horizon, sideways (psi = pi/2): azimuth az - d (to the left), elevation 0.
    got = np.array(pointing_offsets(0.0, d, np.pi / 2, az))
    np.testing.assert_allclose(got, sky_direction(0.0, az - d)[:2] - sky_direction(0.0, az)[:2],
                               atol=TOL)  # fmt: skip


def test_pointing_offsets_take_integer_inputs():
    np.testing.assert_allclose(pointing_offsets(0, 0, 0, 0), (0.0, 0.0), atol=0)
    du = pointing_offsets(np.int32(1), np.int32(0), np.int32(2), np.int32(1))
    np.testing.assert_allclose(du, (0.0, 0.0), atol=TOL)


def _check_oriented(basis, enu, tilt, az):
    east, north, up = enu[:, 0], enu[:, 1], enu[:, 2]
    x, y, n = basis[:, 0], basis[:, 1], basis[:, 2]
    eye = np.broadcast_to(np.eye(3), basis.shape)
    np.testing.assert_allclose(basis @ np.swapaxes(basis, 1, 2), eye, atol=TOL)
    np.testing.assert_allclose(np.linalg.det(basis), 1.0, atol=TOL)  # right-handed
    dot = lambda a, b: np.sum(a * b, axis=-1)  # noqa: E731
    # x at its azimuth (from north, clockwise) and dipping by the tilt; y horizontal.
    np.testing.assert_allclose(np.arctan2(dot(x, east), dot(x, north)),
                               np.angle(np.exp(1j * az)), atol=1e-9)  # fmt: skip
    np.testing.assert_allclose(dot(x, up), -np.sin(tilt), atol=TOL)
    np.testing.assert_allclose(dot(n, up), np.cos(tilt), atol=TOL)
    np.testing.assert_allclose(dot(y, up), 0.0, atol=TOL)


def test_oriented_panel_basis_by_its_defining_properties():
    n = 40
    enu = _enu_by_cross_products(_ut_positions(n))
    tilt = RNG.uniform(0.0, 1.2, n)
    az = RNG.uniform(-np.pi, np.pi, n)
    _check_oriented(oriented_panel_basis(enu, tilt, az), enu, tilt, az)
    # No tilt, x east: the panel frame of panel_basis (east, north, up).
    flat = oriented_panel_basis(enu, 0.0, np.pi / 2)
    np.testing.assert_allclose(flat, enu, atol=TOL)


def test_panel_elevation_of_a_tilted_panel_closed_form():
    # A panel tilted by t towards its x axis (azimuth a) sees a satellite at elevation el in
    # azimuth a at el + t above its plane (the plane turned about the horizontal y axis).
    enu = _enu_by_cross_products(_ut_positions(6))
    tilt = np.radians([0.0, 5.0, 10.0, 20.0, 30.0, 40.0])
    az = np.radians([0.0, 45.0, 90.0, 135.0, 250.0, 300.0])
    el = np.radians([10.0, 25.0, 60.0])
    basis = oriented_panel_basis(enu, tilt, az)
    local = sky_direction(el[None, :], az[:, None])  # (n_ut, n_sat, 3) in east, north, up
    vec = np.einsum("usk,ukj->usj", local, enu)  # Earth-centred
    got = panel_elevation_rad(basis, vec)
    expect = el[None, :] + tilt[:, None]
    expect = np.where(expect > np.pi / 2, np.pi - expect, expect)
    np.testing.assert_allclose(got, expect, atol=1e-9)


def test_panel_elevation_of_the_normal_itself_is_90_deg_not_nan():
    # |v . n| exceeds 1 by an ulp for some unit vectors: the clip keeps arcsin finite.
    enu = _enu_by_cross_products(_ut_positions(500))
    basis = oriented_panel_basis(enu, RNG.uniform(0, 1, 500), RNG.uniform(-3, 3, 500))
    got = panel_elevation_rad(basis, basis[:, 2:3, :])
    assert not np.isnan(got).any()
    np.testing.assert_allclose(got, np.pi / 2, atol=3e-8)  # arcsin(1 - 1 ulp) = pi/2 - 2e-8


def test_motion_azimuth_ignores_the_vertical_and_keeps_the_fallback_at_rest():
    n = 6
    enu = _enu_by_cross_products(_ut_positions(n))
    heading = np.radians([0.0, 30.0, 95.0, 180.0, -120.0, 0.0])
    speed = np.array([20.0, 0.5, 250.0, 3.0, 1e-6, 0.0])  # 1e-6 m/s still moves
    climb = np.array([5.0, -3.0, 40.0, 0.0, 0.0, 7.0])  # UT 5 only climbs
    vel = (
        (speed * np.sin(heading))[:, None] * enu[:, 0]
        + (speed * np.cos(heading))[:, None] * enu[:, 1]
        + climb[:, None] * enu[:, 2]
    )
    fallback = np.full(n, 1.25)
    got = motion_azimuth_rad(enu, vel, fallback)
    np.testing.assert_allclose(got[:5], heading[:5], atol=1e-9)
    assert got[5] == 1.25


def test_panel_orientation_follows_motion_only_where_asked():
    n = 4
    enu = _enu_by_cross_products(_ut_positions(n))
    heading = np.radians([10.0, 80.0, 200.0, 300.0])
    vel = 30.0 * (np.sin(heading)[:, None] * enu[:, 0] + np.cos(heading)[:, None] * enu[:, 1])
    vel[3] = 0.0  # follows its motion but stands still: its fixed azimuth
    tilt = np.radians([0.0, 10.0, 20.0, 30.0])
    fixed = np.radians([45.0, 45.0, 45.0, 45.0])
    po = PanelOrientation(tilt, fixed, [1, 0, 1, 1])  # 0/1 as bools
    expect_az = np.array([heading[0], fixed[1], heading[2], fixed[3]])
    _check_oriented(po.basis(enu, vel), enu, tilt, expect_az)


def test_scan_angle_of_direction_cosines():
    ux = np.array([0.0, 0.3, 0.6, 1.0, 0.8, 0.9])
    uy = np.array([0.0, 0.4, 0.8, 0.0, 0.6, 0.9])  # rho = 0, .5, 1, 1, 1, 1.27
    got = scan_angle_rad(ux, uy)
    np.testing.assert_allclose(got[:5], np.radians([0.0, 30.0, 90.0, 90.0, 90.0]), atol=1e-7)
    assert np.isnan(got[5])  # invisible region
    assert scan_angle_rad(1.0, 0.0) == np.pi / 2  # endfire is visible, exactly


def test_element_functions_keep_float64_for_float32_inputs():
    # float32 inputs (7 digits) must give the float64 result of the same values.
    u = np.array([0.11, 0.37, 0.52], np.float32)
    v = np.array([0.23, 0.41, 0.05], np.float32)
    ref = scan_angle_rad(u.astype(float), v.astype(float))
    np.testing.assert_allclose(scan_angle_rad(u, v), ref, rtol=1e-14, atol=0)
    np.testing.assert_allclose(scan_angle_rad(u, v.astype(float)), ref, rtol=1e-14, atol=0)
    np.testing.assert_allclose(scan_angle_rad(u.astype(float), v), ref, rtol=1e-14, atol=0)
    th = np.array([0.3, 0.9, 1.4], np.float32)
    ref = np.cos(th.astype(float)) ** 1.2
    np.testing.assert_allclose(element_factor_lin(th, 1.2), ref, rtol=1e-14)
    el = np.array([0.2, 0.7, 1.3], np.float32)
    ref = -12.0 * np.log10(np.sin(el.astype(float)))
    np.testing.assert_allclose(flat_panel_scan_loss_db(el, 1.2), ref, rtol=1e-13)


def test_flat_panel_scan_loss_uses_its_exponent():
    el = np.radians([10.0, 30.0, 60.0, 90.0])
    for q in (0.0, 1.0, 2.0, 3.5):
        np.testing.assert_allclose(
            flat_panel_scan_loss_db(el, q), -10.0 * q * np.log10(np.sin(el)), atol=1e-12
        )


def test_scan_loss_beyond_90_deg_is_inf_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = scan_loss_db(np.radians([90.0, 120.0, 60.0]), 2.0)
    assert np.isinf(got[:2]).all()
    assert got[2] == pytest.approx(-20.0 * np.log10(0.5), rel=1e-12)


def test_panel_frame_functions_keep_float64_for_float32_inputs():
    # float32 angles (7 digits) must give the float64 result of the same values.
    el = np.array([0.11, 0.52, 1.2], np.float32)
    az = np.array([0.3, 2.2, 5.1], np.float32)
    f64 = el.astype(float), az.astype(float)
    np.testing.assert_allclose(sky_direction(el, az), sky_direction(*f64), rtol=1e-14)
    np.testing.assert_allclose(sky_direction(el, f64[1]), sky_direction(*f64), rtol=1e-14)
    np.testing.assert_allclose(sky_direction(f64[0], az), sky_direction(*f64), rtol=1e-14)
    d, psi = np.float32(0.05), np.array([0.4, 1.9, 4.0], np.float32)
    got = np.array(pointing_offsets(el, d, psi, az))
    ref = np.array(pointing_offsets(*f64[:1], np.float64(d), psi.astype(float), f64[1]))
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-15)
    enu = _enu_by_cross_products(_ut_positions(3))
    np.testing.assert_allclose(oriented_panel_basis(enu, el, az),
                               oriented_panel_basis(enu, *f64), rtol=1e-13, atol=1e-15)  # fmt: skip


def test_panel_elevation_right_behind_the_panel_is_minus_90_deg_not_nan():
    enu = _enu_by_cross_products(_ut_positions(500))
    basis = oriented_panel_basis(enu, RNG.uniform(0, 1, 500), RNG.uniform(-3, 3, 500))
    got = panel_elevation_rad(basis, -basis[:, 2:3, :])
    assert not np.isnan(got).any()
    np.testing.assert_allclose(got, -np.pi / 2, atol=3e-8)
