"""Tests of leolink.link.fading: the Rician receive gain of Sec. 4.1."""

import numpy as np
import pytest

from leolink.link.fading import mean_rician_gain_lin, rician_gain_lin

N_SAMPLES = 400_000
N_SIGMA = 5.0  # Monte Carlo tolerance: 5 standard errors (false alarm ~ 6e-7)


@pytest.mark.parametrize("n_lin, k", [(576.0, 10.0), (1.0, 10.0), (4.0, 0.5), (100.0, 1e3)])
def test_mean_matches_monte_carlo(n_lin, k):
    rng = np.random.default_rng(1234)
    g = rician_gain_lin(n_lin, k, rng, size=N_SAMPLES)
    se = g.std(ddof=1) / np.sqrt(N_SAMPLES)
    assert abs(g.mean() - mean_rician_gain_lin(n_lin, k)) < N_SIGMA * se


def test_variance_is_rician():
    # |sqrt(N) + g/sqrt(K)|^2 is noncentral chi-square: Var = 2 N / K + 1 / K^2.
    n_lin, k = 9.0, 2.0
    g = rician_gain_lin(n_lin, k, np.random.default_rng(7), size=N_SAMPLES)
    expected = 2 * n_lin / k + 1 / k**2
    assert g.var() == pytest.approx(expected, rel=0.02)  # ~6 sigma of the var. estimator


def test_broadcast_shape_and_positivity():
    rng = np.random.default_rng(0)
    g = rician_gain_lin(np.array([[1.0], [4.0]]), np.array([1.0, 10.0, 100.0]), rng)
    assert g.shape == (2, 3)
    assert np.all(g >= 0)
    assert mean_rician_gain_lin(np.array([1.0, 2.0]), 10.0) == pytest.approx([1.1, 2.1])
