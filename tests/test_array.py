"""Tests of leolink.antenna.array: closed-form Dirichlet gains vs explicit steering vectors."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from leolink.antenna.array import (
    HybridArray,
    beam_gain_lin,
    explicit_gain,
    steering_vector,
    ula_gain,
    upa_gain,
)
from leolink.errors import ConfigError

# Closed form vs explicit sum: both are float64; the explicit sum of N unit phasors has
# rounding ~N eps ~ 1e-13 of the peak, far below 1e-9 relative.
REL_TOL = 1e-9
# Near a null the relative error of either side is unbounded; compare there in absolute
# terms against the peak (N eps of the explicit sum, with margin).
ABS_TOL_OF_PEAK = 1e-10


def test_ula_gain_matches_explicit_sum():
    rng = np.random.default_rng(1)
    du = rng.uniform(-2.0, 2.0, 500)
    for n in (1, 2, 7, 12, 24):
        k = np.arange(n)
        ref = np.abs(np.exp(1j * np.pi * k * du[:, None]).sum(-1)) ** 2 / n
        np.testing.assert_allclose(ula_gain(du, n), ref, rtol=REL_TOL, atol=ABS_TOL_OF_PEAK * n)


def test_ula_gain_peak_grating_lobes_and_nulls():
    n = 12
    assert ula_gain(0.0, n) == pytest.approx(n, rel=1e-15)
    # grating lobes of a half-wavelength array at du = +-2
    np.testing.assert_allclose(ula_gain(np.array([2.0, -2.0]), n), n, rtol=1e-12)
    # Dirichlet nulls at du = 2 m / n, m = 1..n-1
    m = np.arange(1, n)
    assert np.max(ula_gain(2.0 * m / n, n)) < 1e-25 * n


@settings(max_examples=300, deadline=None)
@given(n=st.integers(1, 128), du=st.floats(-2.0, 2.0))
@example(n=7, du=1.9999999999999)  # by a grating lobe: naive sin(nx)/(n sin x) overshoots
@example(n=128, du=-1.9999999999999998)
@example(n=24, du=1e-300)
def test_ula_gain_is_bounded_by_element_count(n, du):
    g = ula_gain(du, n)
    assert 0.0 <= g <= n


def test_ula_gain_is_accurate_next_to_grating_lobe():
    # exact: du = 2 - eps is a mirror of du = -eps, gain n (1 - (n^2 - 1) (pi eps / 2)^2 / 3)
    n, eps = 7, 1e-13
    assert ula_gain(2.0 - eps, n) == pytest.approx(ula_gain(-eps, n), rel=1e-12)
    assert ula_gain(2.0 - eps, n) == pytest.approx(n, rel=1e-12)


def test_upa_gain_matches_explicit_steering_vectors():
    rng = np.random.default_rng(2)
    nx, ny = 12, 24
    u = rng.uniform(-0.7, 0.7, (400, 2))
    beams = rng.uniform(-0.7, 0.7, (6, 2))
    ref = explicit_gain(u, steering_vector(beams, nx, ny).T, nx, ny)
    got = upa_gain(u[:, None, 0] - beams[:, 0], u[:, None, 1] - beams[:, 1], nx, ny)
    np.testing.assert_allclose(got, ref, rtol=REL_TOL, atol=ABS_TOL_OF_PEAK * nx * ny)


def _lattice_beams(kx, ky, ox, oy):
    bx, by = np.meshgrid(kx * ox, ky * oy, indexing="ij")
    return np.stack([bx.ravel(), by.ravel()], -1)


def test_beam_gain_lin_matches_hybrid_precoder():
    # 5 x 3 RF chains on a 60 x 72 array: subarrays 12 x 24, O = 1.2 (the paper's table).
    arr = HybridArray(60, 72, 5, 3)
    beams = _lattice_beams(np.arange(-2, 3), np.arange(-1, 2), 2 / 14.4, 2 / 28.8)
    rng = np.random.default_rng(3)
    u = rng.uniform(-0.6, 0.6, (300, 2))
    u = np.concatenate([u, beams])  # include exact boresights (0/0 path of the fast kernel)
    ref = explicit_gain(u, arr.precoder(beams), arr.n_x, arr.n_y)
    got = beam_gain_lin(u, beams, arr.n_sub_x, arr.n_sub_y)
    np.testing.assert_allclose(got, ref, rtol=REL_TOL, atol=ABS_TOL_OF_PEAK * 288)


def test_beam_gain_lin_random_beams_and_shapes():
    rng = np.random.default_rng(4)
    beams = rng.uniform(-0.8, 0.8, (7, 2))
    u = rng.uniform(-1, 1, (3, 5, 2)) * 0.7
    got = beam_gain_lin(u, beams, 9, 4)
    assert got.shape == (3, 5, 7)
    ref = explicit_gain(u, steering_vector(beams, 9, 4).T, 9, 4)
    np.testing.assert_allclose(got, ref, rtol=REL_TOL, atol=ABS_TOL_OF_PEAK * 36)


def test_peak_gain_is_number_of_driven_elements():
    arr = HybridArray(60, 72, 5, 3)
    beams = _lattice_beams(np.arange(-2, 3), np.arange(-1, 2), 2 / 14.4, 2 / 28.8)
    g = beam_gain_lin(beams, beams, arr.n_sub_x, arr.n_sub_y)
    np.testing.assert_allclose(np.diag(g), 288.0, rtol=1e-12)
    assert 10 * np.log10(288) == pytest.approx(24.59, abs=0.005)  # the paper's subarray peak
    ref = explicit_gain(beams, arr.precoder(beams), 60, 72)
    np.testing.assert_allclose(np.diag(ref), 288.0, rtol=1e-12)


def test_hybrid_array_structure():
    arr = HybridArray(60, 72, 5, 3)
    assert (arr.n_sub_x, arr.n_sub_y, arr.n_rf) == (12, 24, 15)
    idx = arr.rf_index()
    assert np.array_equal(np.bincount(idx), np.full(15, 288))
    f = arr.precoder(np.zeros((15, 2)))
    # block structure: exactly one non-zero per row, in the column I_RF(n)
    assert np.array_equal(np.count_nonzero(f, axis=1), np.ones(60 * 72))
    assert np.array_equal(np.argmax(np.abs(f), axis=1), idx)
    # element (i_x, i_y) = (13, 50) is in subarray (1, 2) -> chain 1 * 3 + 2
    assert idx[13 * 72 + 50] == 5


def test_hybrid_array_rejects_non_dividing_rf_chains():
    with pytest.raises(ConfigError, match="n_rf_x = 7 does not divide antenna.n_x = 60"):
        HybridArray(60, 72, 7, 3)
    with pytest.raises(ConfigError, match="n_rf = 15"):
        HybridArray(60, 72, 5, 3).precoder(np.zeros((4, 2)))
