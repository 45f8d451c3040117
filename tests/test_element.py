"""Tests of leolink.antenna.element (flat-panel cos^q scan loss)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.antenna.element import (
    DEFAULT_SCAN_EXPONENT,
    element_factor_lin,
    flat_panel_scan_loss_db,
    panel_gain_lin,
    scan_angle_rad,
    scan_loss_db,
)

N_PANEL = 8  # 8 x 8 half-wavelength panel for the explicit sums


def _explicit_panel_gain(u_xy, beam_u_xy, n, exponent):
    """|sum_n w_n sqrt(g_e) e^{-i pi (n_x u_x + n_y u_y)}|^2 / ||w||^2, w steered at the beam.

    Element by element, with the element field pattern sqrt(cos^q theta) of every element
    (identical elements), theta from the direction cosines; no Dirichlet kernel involved.
    """
    u = np.atleast_2d(np.asarray(u_xy, dtype=float))
    b = np.atleast_2d(np.asarray(beam_u_xy, dtype=float))
    ix, iy = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    ix, iy = ix.ravel(), iy.ravel()
    w = np.exp(-1j * np.pi * (ix * b[:, :1] + iy * b[:, 1:2]))  # (k, n^2) steering weights
    a = np.exp(-1j * np.pi * (ix * u[:, :1] + iy * u[:, 1:2]))  # (k, n^2) element phases
    rho2 = np.sum(u**2, axis=1)
    cos_theta = np.sqrt(np.clip(1.0 - rho2, 0.0, None))
    field = np.sum(np.conj(a) * w, axis=1) * cos_theta ** (exponent / 2.0)
    return np.abs(field) ** 2 / np.sum(np.abs(w) ** 2, axis=1)


def _directions(rng, k, max_sin):
    r = max_sin * np.sqrt(rng.uniform(0.0, 1.0, k))
    phi = rng.uniform(0.0, 2 * np.pi, k)
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)


def test_panel_gain_equals_explicit_element_sum():
    rng = np.random.default_rng(20240611)
    u = _directions(rng, 400, 0.99)
    b = _directions(rng, 400, 0.9)
    for q in (0.0, 1.0, DEFAULT_SCAN_EXPONENT, 2.0):
        np.testing.assert_allclose(
            panel_gain_lin(u, b, N_PANEL, N_PANEL, q),
            _explicit_panel_gain(u, b, N_PANEL, q),
            rtol=1e-9,
            atol=1e-9,
        )


@pytest.mark.parametrize("scan_deg", [0.0, 15.0, 30.0, 45.0, 60.0, 75.0])
@pytest.mark.parametrize("q", [1.0, 1.2, 1.5])
def test_scan_loss_equals_explicit_array_peak_ratio(scan_deg, q):
    # Steer the explicit panel at theta_0 (azimuth 30 deg) and compare its peak with broadside.
    th, az = np.radians(scan_deg), np.radians(30.0)
    b = np.array([np.sin(th) * np.cos(az), np.sin(th) * np.sin(az)])
    g_scan = _explicit_panel_gain(b, b, N_PANEL, q)[0]
    g_broadside = _explicit_panel_gain([0.0, 0.0], [0.0, 0.0], N_PANEL, q)[0]
    assert g_broadside == pytest.approx(N_PANEL**2, rel=1e-12)
    assert 10 * np.log10(g_broadside / g_scan) == pytest.approx(scan_loss_db(th, q), abs=1e-9)


def test_matched_panel_directivity_falls_as_cos():
    # Physics behind q = 1: a matched half-wavelength panel (element gain pi cos(theta), i.e.
    # 4 pi A_cell / lambda^2 projected) radiates all its power, so its gain equals the
    # directivity 4 pi G(theta_0) / integral(G dOmega), and that falls as the projected area.
    # In direction cosines dOmega = du / cos(theta), so the integral is that of the Dirichlet
    # array factor over the visible disk. Finite-panel edge terms shrink as 1/N (0.09 dB at
    # 60 deg for N = 16, 0.045 dB for N = 32): 0.1 dB for a 32 x 32 panel.
    n = 32
    grid = np.linspace(-1.0, 1.0, 1201)
    ux, uy = np.meshgrid(grid, grid, indexing="ij")
    visible = ux**2 + uy**2 < 1.0
    du2 = (grid[1] - grid[0]) ** 2
    u = np.stack([ux[visible], uy[visible]], axis=-1)
    cos_theta = np.sqrt(1.0 - np.sum(u**2, axis=-1))
    directivity_db = []
    for th in np.radians([0.0, 20.0, 40.0, 60.0]):
        b = np.array([np.sin(th), 0.0])
        radiated = np.sum(panel_gain_lin(u, b, n, n, 1.0) / cos_theta) * du2
        peak = panel_gain_lin(b, b, n, n, 1.0)
        directivity_db.append(10 * np.log10(4 * np.pi * peak / radiated))
    directivity_db = np.array(directivity_db)
    assert directivity_db[0] == pytest.approx(10 * np.log10(np.pi * n * n), abs=0.01)
    np.testing.assert_allclose(
        directivity_db - directivity_db[0],
        -scan_loss_db(np.radians([0.0, 20.0, 40.0, 60.0]), 1.0),
        atol=0.1,
    )


def test_default_exponent_and_values():
    assert DEFAULT_SCAN_EXPONENT == 1.2  # the paper's Kymeta roll-off (Sec. 2.1)
    # 60 deg off normal: cos = 0.5 -> q 3.0103 dB.
    assert scan_loss_db(np.radians(60.0)) == pytest.approx(1.2 * 3.0103, abs=1e-4)
    assert scan_loss_db(0.0) == 0.0
    assert scan_loss_db(np.radians(90.0)) == np.inf
    assert element_factor_lin(np.radians(100.0)) == 0.0


def test_flat_panel_matches_the_papers_metasurface_rolloff():
    """Paper Sec. 2.1 (sign corrected, docs/errata.md): a flat panel loses cos^1.2 of the
    scan angle; the scan angle here from the law of cosines in the triangle
    panel-normal tip / panel / satellite direction (unit sides), not from 90 deg - el."""
    el = np.radians([10.0, 30.0, 60.0, 90.0])
    # chord between the unit normal (0, 0, 1) and the unit direction (cos el, 0, sin el)
    chord2 = np.cos(el) ** 2 + (1.0 - np.sin(el)) ** 2
    cos_scan = 1.0 - chord2 / 2.0  # law of cosines with two unit sides
    expected = -10 * np.log10(cos_scan**1.2)
    np.testing.assert_allclose(flat_panel_scan_loss_db(el), expected, atol=1e-12)
    assert flat_panel_scan_loss_db(np.radians(-5.0)) == np.inf


def test_scan_angle_from_direction_cosines():
    th = np.radians([0.0, 10.0, 45.0, 89.0])
    np.testing.assert_allclose(scan_angle_rad(np.sin(th) * 0.6, np.sin(th) * 0.8), th, atol=1e-12)
    assert np.isnan(scan_angle_rad(0.9, 0.9))  # invisible region


@settings(max_examples=100, deadline=None)
@given(th=st.floats(0.0, 1.5), q1=st.floats(0.0, 3.0), dq=st.floats(0.0, 2.0))
def test_loss_grows_with_exponent_and_angle(th, q1, dq):
    assert scan_loss_db(th, q1 + dq) >= scan_loss_db(th, q1) - 1e-12
    assert scan_loss_db(min(th + 0.05, 1.55), q1) >= scan_loss_db(th, q1) - 1e-12
    assert 0.0 <= element_factor_lin(th, q1) <= 1.0
