"""Layer-3 filter of TS 38.331 5.5.3.2 against the recursion written out sample by sample."""

import math

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.sim.handover.measurements import (
    FILTER_COEFFICIENTS,
    L3Filter,
    L3State,
    filter_weight,
    l3_update,
)

X_S = 0.2  # the reference sample period the coefficient assumes


def run(samples, params, dt_s=X_S):
    """Filter a (n_t, n_ut, n_cand) sequence; returns the filtered sequence."""
    state, out = L3State.initial(*samples.shape[1:]), []
    for k, sample in enumerate(samples):
        state, f = l3_update(state, k * dt_s, sample, params)
        out.append(f)
    return np.array(out)


def test_weight_is_one_over_two_to_the_k_over_four():
    # TS 38.331 5.5.3.2: a = 1 / 2^(k/4); fc4 (the default) gives 1/2, fc0 no filtering
    for k in FILTER_COEFFICIENTS:
        assert filter_weight(k) == pytest.approx(1.0 / 2 ** (k / 4), rel=1e-15)
    assert filter_weight(4) == 0.5 and filter_weight(0) == 1.0


def test_first_sample_initializes_then_the_recursion_of_the_standard():
    rng = np.random.default_rng(7)
    samples = rng.normal(-90, 6, (30, 4, 3))
    got = run(samples, L3Filter(k=8, reference_period_s=X_S))
    a = 2 ** (-8 / 4)
    ref = np.empty_like(samples)  # F_0 = M_1; F_n = (1 - a) F_{n-1} + a M_n, written out
    for i in range(4):
        for j in range(3):
            f = samples[0, i, j]
            for n in range(30):
                f = samples[0, i, j] if n == 0 else (1 - a) * f + a * samples[n, i, j]
                ref[n, i, j] = f
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


def test_step_response_is_the_closed_form_geometric_approach():
    # a step from M1 to M2 at n = 1: F_n = M2 + (M1 - M2) (1 - a)^n
    samples = np.full((12, 1, 1), -80.0)
    samples[0] = -100.0
    got = run(samples, L3Filter(k=4))[:, 0, 0]
    n = np.arange(12)
    np.testing.assert_allclose(got, -80.0 + (-100.0 + 80.0) * 0.5**n, atol=1e-12)


def test_half_the_sample_period_keeps_the_time_constant():
    # Two epochs of X/2 must weigh the past as one epoch of X: after a step the filters
    # agree at every common instant (1 - a_half)^2 = 1 - a.
    params = L3Filter(k=11, reference_period_s=X_S)
    coarse = np.full((6, 1, 1), 3.0)
    coarse[0] = -7.0
    fine = np.full((11, 1, 1), 3.0)
    fine[0] = -7.0
    f_coarse = run(coarse, params, dt_s=X_S)[:, 0, 0]
    f_fine = run(fine, params, dt_s=X_S / 2)[::2, 0, 0]
    np.testing.assert_allclose(f_fine, f_coarse, atol=1e-12)
    assert abs(f_coarse[1] - f_coarse[0]) > 1.0  # the filter does move: the test can see it


def test_adapted_weight_matches_the_standard_at_its_own_rate_only():
    a = filter_weight(6)
    assert filter_weight(6, X_S, X_S) == pytest.approx(a, rel=1e-14)
    assert filter_weight(6, 1.0, X_S) == pytest.approx(1 - (1 - a) ** 5, rel=1e-14)
    assert filter_weight(0, 1.0, X_S) == 1.0


def test_nan_resets_the_cell_and_the_next_sample_restarts_it():
    samples = np.array([[[-90.0]], [[-80.0]], [[np.nan]], [[-70.0]], [[-60.0]]])
    got = run(samples, L3Filter(k=4))[:, 0, 0]
    assert got[1] == pytest.approx(-85.0)
    assert math.isnan(got[2])
    assert got[3] == -70.0  # re-initialized, not mixed with the old -85
    assert got[4] == pytest.approx(-65.0)


def test_epochs_must_advance():
    state, _ = l3_update(L3State.initial(1, 1), 1.0, np.zeros((1, 1)), L3Filter())
    with pytest.raises(ValueError, match="not after"):
        l3_update(state, 1.0, np.zeros((1, 1)), L3Filter())


def test_invalid_filter_parameters_are_refused():
    with pytest.raises(ConfigError, match="controller.filter.k"):
        L3Filter(k=-1)
    with pytest.raises(ConfigError, match="reference_period_s"):
        L3Filter(reference_period_s=0.0)
