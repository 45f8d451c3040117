"""link/precoder.py with non-default parameters, against explicit numpy.linalg formulas.

Mutation testing (issue 45, docs/testing.md) found the MMSE ``alpha_scale`` and
``noise_lin``, padded ZF-normalized batches, non-square selections and the refusal message
exercised by no test. Each case below is written from the formula of the reference, not
from leolink's code: Peel, Hochwald and Swindlehurst's ``F = H^H (H H^H + alpha I)^-1`` with
``alpha = K / rho`` (``rho = n_beam p_rf / noise``, the total transmit SNR), the
pseudo-inverse with unit-norm columns, the 0/1 selection matrix, then the common scale
that puts the most loaded chain at ``p_rf``.
"""

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.link.precoder import PRECODERS, MmseConfig, precoder_matrix

#: Float rounding of a 4 x 4 complex inverse (condition numbers below 1e3 here).
RTOL = 1e-10


def _channel(n_ut, n_beam, seed=3):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n_ut, n_beam)) + 1j * rng.standard_normal((n_ut, n_beam))


def _scaled(f, p_rf):
    return f * np.sqrt(p_rf / np.max(np.sum(np.abs(f) ** 2, axis=1)))


def _mmse(h, alpha, p_rf):
    hh = h.conj().T
    return _scaled(hh @ np.linalg.inv(h @ hh + alpha * np.eye(h.shape[0])), p_rf)


def test_mmse_alpha_scale_on_a_padded_batch():
    """alpha_scale = 3 times Peel's K / rho; padding rows and dark beams ignored."""
    h_full = _channel(4, 5)
    ut_mask = np.array([True, True, False, True])
    beam_mask = np.array([True, True, True, False, True])
    p_rf = 2.5
    precoder = PRECODERS.build("mmse", MmseConfig(alpha_scale=3.0))
    f = precoder(h_full, p_rf, ut_mask=ut_mask, beam_mask=beam_mask)
    h = h_full[np.ix_(ut_mask, beam_mask)]
    want = _mmse(h, 3.0 * 3 / (4 * p_rf), p_rf)
    np.testing.assert_allclose(f[np.ix_(beam_mask, ut_mask)], want, rtol=RTOL)
    assert not f[~beam_mask].any() and not f[:, ~ut_mask].any()


def test_mmse_regularization_counts_the_noise_power():
    """noise_lin = 4: alpha = K noise / (n_beam p_rf) (rho is the transmit SNR)."""
    h = _channel(3, 4, seed=5)
    f = precoder_matrix(h, "mmse", p_rf=0.5, noise_lin=4.0)
    np.testing.assert_allclose(f, _mmse(h, 3 * 4.0 / (4 * 0.5), 0.5), rtol=RTOL)


def test_mmse_with_one_active_beam_and_two_uts():
    """One chain, two UTs (alpha = 2 / (1 p_rf)): the 2 x 2 Gram matrix is regularized."""
    h = _channel(2, 1, seed=7)
    f = precoder_matrix(h, "mmse", p_rf=1.5)
    np.testing.assert_allclose(f, _mmse(h, 2 / 1.5, 1.5), rtol=RTOL)


def test_zf_normalized_with_a_padded_ut_is_finite_and_equals_the_unpadded_problem():
    h_full = _channel(3, 3, seed=11)
    ut_mask = np.array([True, False, True])
    f = precoder_matrix(h_full, "zf_normalized", p_rf=1.0, ut_mask=ut_mask)
    assert np.all(np.isfinite(f)) and not f[:, 1].any()
    f0 = np.linalg.pinv(h_full[ut_mask])
    want = _scaled(f0 / np.linalg.norm(f0, axis=0), 1.0)
    np.testing.assert_allclose(f[:, ut_mask], want, rtol=RTOL)


def test_selection_with_more_beams_than_uts():
    """'none' on 2 UTs and 3 beams: F = sqrt(p_rf) E, E[m, k] = 1 where beam m serves k."""
    f = precoder_matrix(_channel(2, 3), "none", p_rf=4.0, serving_beam=np.array([2, 0]))
    want = np.zeros((3, 2))
    want[2, 0] = want[0, 1] = 2.0
    np.testing.assert_array_equal(f, want)


def test_selection_without_serving_beams_is_refused_in_words():
    with pytest.raises(
        ConfigError, match=r"^precoder 'none' needs serving_beam \(the beam of each UT\)$"
    ):
        precoder_matrix(_channel(2, 2), "none")


@pytest.mark.parametrize("kind", ["zf", "zf_normalized", "mmse"])
def test_idle_beams_option_reaches_the_precoder(kind):
    """[link.<kind>] idle_beams: 'silent' by default, 'transmit' when asked; 'none' is the
    full-buffer path (every lit beam radiates)."""
    entry = PRECODERS[kind]
    assert PRECODERS.build(kind).idle_beams == "silent"
    assert PRECODERS.build(kind, entry.config(idle_beams="transmit")).idle_beams == "transmit"
    assert PRECODERS.build("none").idle_beams == "transmit"
