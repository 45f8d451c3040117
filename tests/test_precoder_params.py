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


# --- The survivors of the second run (issue 45, docs/testing.md) ---------------------


def test_defaults_are_unit_chain_power_and_the_configs_values():
    """Without ``p_rf`` the most loaded chain carries 1 (the unit of H); Peel's
    ``alpha = K / rho`` is then ``K / n_beam``; the precoder objects default to their
    configs' ``alpha_scale = 1`` and ``idle_beams = "silent"``."""
    from leolink.link.precoder import _Fixed, chain_power, mmse_regularization

    h = _channel(3, 4, seed=13)
    assert mmse_regularization(3, 4) == 0.75
    for kind in ("zf", "zf_normalized", "mmse"):
        assert np.max(chain_power(precoder_matrix(h, kind))) == pytest.approx(1.0, rel=RTOL)
        assert np.max(chain_power(_Fixed(kind)(h))) == pytest.approx(1.0, rel=RTOL)
    np.testing.assert_allclose(_Fixed("mmse")(h), _mmse(h, 0.75, 1.0), rtol=RTOL)
    fixed, cfg = _Fixed("mmse"), MmseConfig()
    assert (fixed.alpha_scale, fixed.idle_beams) == (cfg.alpha_scale, cfg.idle_beams)
    assert cfg.alpha_scale == 1.0 and cfg.idle_beams == "silent"


def test_mmse_alpha_scale_two_per_problem_of_a_batch():
    """alpha_scale = 2 on a batch of two problems: 3 UTs on 4 beams, and 2 UTs on a
    single lit beam (alpha = 2 x 2 / (1 p_rf)); each against Peel's formula alone."""
    h_full = np.stack([_channel(3, 4, seed=17), _channel(3, 4, seed=19)])
    ut_mask = np.array([[True, True, True], [True, False, True]])
    beam_mask = np.array([[True, True, True, True], [False, False, True, False]])
    p_rf = 0.8
    f = PRECODERS.build("mmse", MmseConfig(alpha_scale=2.0))(
        h_full, p_rf, ut_mask=ut_mask, beam_mask=beam_mask)  # fmt: skip
    for b, (n_ut, n_beam) in enumerate([(3, 4), (2, 1)]):
        h = h_full[b][np.ix_(ut_mask[b], beam_mask[b])]
        want = _mmse(h, 2.0 * n_ut / (n_beam * p_rf), p_rf)
        np.testing.assert_allclose(f[b][np.ix_(beam_mask[b], ut_mask[b])], want, rtol=RTOL)


def test_no_precoder_on_a_batch_is_the_selection_scaled_per_problem():
    """``"none"`` on a batch of two problems of 2 UTs and 3 beams: the 0/1 selection of each
    UT's beam; in the second both UTs share beam 1, whose chain then carries 2 before the
    scale, so each entry is 1 / sqrt(2)."""
    h = np.stack([_channel(2, 3, seed=23), _channel(2, 3, seed=29)])
    f = precoder_matrix(h, "none", serving_beam=np.array([[0, 2], [1, 1]]))
    want = np.zeros((2, 3, 2))
    want[0, 0, 0] = want[0, 2, 1] = 1.0
    want[1, 1, :] = 1 / np.sqrt(2)
    np.testing.assert_allclose(f, want, rtol=RTOL, atol=0)
