"""The closed-form complex beam response against the explicit product a(u)^H F_RF."""

import numpy as np
import pytest

from leolink.antenna.array import HybridArray, beam_gain_lin, steering_vector
from leolink.antenna.response import chain_response, subarray_origins

# The closed form and the explicit sum of 4320 unit phasors agree to ~1e-14 of the peak
# amplitude; relative to |h| they agree to 1e-9 except within ~1e-5 of a null, where
# any finite-precision sum has a relative error ~ 1e-16 sqrt(N) / |h|. The absolute floor
# is 1e-12 of the peak amplitude (-240 dB), far below any gain leolink reports.
REL = 1e-9
ABS_OF_PEAK = 1e-12

PAPER = HybridArray(60, 72, 5, 3)  # Sec. 5: 5 x 3 subarrays of 12 x 24


def _explicit(u_xy, beams, array):
    """a(u)^H f_m / ||f_m|| with F_RF from HybridArray.precoder (beam m on chain m)."""
    f = array.precoder(beams)
    a = steering_vector(u_xy, array.n_x, array.n_y)
    return (a.conj() @ f) / np.sqrt(np.sum(np.abs(f) ** 2, axis=0))


def _assert_close(h, ref, n_sub):
    err = np.abs(h - ref)
    assert np.all(err <= REL * np.abs(ref) + ABS_OF_PEAK * np.sqrt(n_sub)), err.max()


def _directions(rng, n):
    u = rng.uniform(-0.7, 0.7, (n, 2))
    return u[np.hypot(u[:, 0], u[:, 1]) < 0.95]


def test_response_matches_explicit_steering_product_paper_array():
    rng = np.random.default_rng(11)
    beams = rng.uniform(-0.4, 0.4, (PAPER.n_rf, 2))
    u = _directions(rng, 500)
    h = chain_response(u, beams, np.arange(PAPER.n_rf), PAPER)
    _assert_close(h, _explicit(u, beams, PAPER), 288)


def test_response_at_peaks_and_grating_lobes():
    # d = 0 (the 0/0 of the kernel) and d = +-2 (grating lobes): |h| = sqrt(N), exact.
    beams = np.array([[0.1, -0.2], [0.0, 0.0], [-0.3, 0.25]] + [[0.5, 0.5]] * 12)
    u = np.array([[0.1, -0.2], [0.0, 0.0], [-0.3, 0.25], [0.1 - 2.0, -0.2], [0.1, 1.8]])
    h = chain_response(u, beams, np.arange(PAPER.n_rf), PAPER)
    _assert_close(h, _explicit(u, beams, PAPER), 288)
    assert abs(h[0, 0]) == pytest.approx(np.sqrt(288), rel=1e-12)
    assert abs(h[3, 0]) == pytest.approx(np.sqrt(288), rel=1e-12)


def test_beam_on_another_subarray_has_that_subarray_phase_centre():
    # Beam k radiated by chain perm[k]: the explicit F_RF puts beam k in column perm[k].
    rng = np.random.default_rng(3)
    perm = rng.permutation(PAPER.n_rf)
    beams = rng.uniform(-0.3, 0.3, (PAPER.n_rf, 2))
    by_chain = np.empty_like(beams)
    by_chain[perm] = beams
    u = _directions(rng, 300)
    ref = _explicit(u, by_chain, PAPER)[:, perm]
    h = chain_response(u, beams, perm, PAPER)
    _assert_close(h, ref, 288)
    # The gain does not depend on the chain, the phase does (the precoder sees it).
    h_id = chain_response(u, beams, np.arange(PAPER.n_rf), PAPER)
    np.testing.assert_allclose(np.abs(h), np.abs(h_id), rtol=1e-12, atol=1e-13)
    assert np.max(np.abs(np.angle(h / h_id))) > 1.0


@pytest.mark.parametrize("shape", [(6, 4, 2, 2), (9, 10, 3, 5), (7, 3, 7, 1)])
def test_response_matches_explicit_for_odd_subarrays(shape):
    array = HybridArray(*shape)
    rng = np.random.default_rng(sum(shape))
    beams = rng.uniform(-0.9, 0.9, (array.n_rf, 2))
    u = rng.uniform(-1.0, 1.0, (200, 2))  # includes |u| > 1: the formula is algebraic
    h = chain_response(u, beams, np.arange(array.n_rf), array)
    _assert_close(h, _explicit(u, beams, array), array.n_sub_x * array.n_sub_y)


def test_squared_response_is_leolink_normalized_gain():
    rng = np.random.default_rng(5)
    beams = rng.uniform(-0.4, 0.4, (PAPER.n_rf, 2))
    u = _directions(rng, 400)
    g = np.abs(chain_response(u, beams, np.arange(PAPER.n_rf), PAPER)) ** 2
    ref = beam_gain_lin(u, beams, PAPER.n_sub_x, PAPER.n_sub_y)
    np.testing.assert_allclose(g, ref, rtol=1e-9, atol=1e-12 * 288)


def test_subarray_origins_follow_rf_index():
    origin = subarray_origins(PAPER)
    chain = PAPER.rf_index()
    ix, iy = np.meshgrid(np.arange(PAPER.n_x), np.arange(PAPER.n_y), indexing="ij")
    for m in range(PAPER.n_rf):
        sel = chain == m
        assert (ix.ravel()[sel].min(), iy.ravel()[sel].min()) == tuple(origin[m])


def test_dark_beam_has_zero_response_and_batches_broadcast():
    rng = np.random.default_rng(8)
    n_sat, n_ut = 3, 7
    beams = rng.uniform(-0.3, 0.3, (n_sat, PAPER.n_rf, 2))
    chain = np.tile(np.arange(PAPER.n_rf), (n_sat, 1))
    chain[1, 4] = -1
    u = rng.uniform(-0.3, 0.3, (n_sat, n_ut, 2))
    h = chain_response(u, beams[:, None], chain[:, None], PAPER)
    assert h.shape == (n_sat, n_ut, PAPER.n_rf)
    assert np.all(h[1, :, 4] == 0.0)
    for s in range(n_sat):
        ref = _explicit(u[s], beams[s], PAPER)
        ref[:, chain[s] < 0] = 0.0
        _assert_close(h[s], ref, 288)
