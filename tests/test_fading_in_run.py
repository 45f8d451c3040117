"""Rician fading inside the simulator (``link.fading = "rician"``), Sec. 4.1 of the paper.

The run draws ``G = |sqrt(N) + g / sqrt(K)|^2``, ``g ~ CN(0, 1)``, per UT and epoch, and
scales the serving link's receive power by ``G / E[G]``. So, row by row, the effective
receive gain ``G_rx,mean x 10^((snr_rician - snr_mean) / 10)`` must have the paper's mean
``N + 1/K`` and the paper's distribution (a noncentral chi-square,
``2 K G ~ chi'^2(2, 2 K N)``). Tolerances: 5 standard errors of the mean; KS at p > 1e-4.
"""

import numpy as np
import pytest
from scipy import stats

from leolink.app.run import run
from leolink.config import load_config
from scopes import shared_run_scope

PAPER = "configs/paper.toml"
N_SIGMA = 5.0


@pytest.fixture(scope=shared_run_scope)
def runs():
    common = ["output.plots.enabled=false", "run.duration_s=300", "run.start_s=-90"]
    mean = run(load_config(PAPER, common)).trace
    fading = run(load_config(PAPER, [*common, 'link.fading="rician"'])).trace
    cfg = load_config(PAPER)
    return cfg, mean, fading


def _effective_gain(cfg, mean, fading):
    ok = np.isfinite(mean.snr_db.to_numpy()) & np.isfinite(fading.snr_db.to_numpy())
    ratio = 10 ** ((fading.snr_db.to_numpy()[ok] - mean.snr_db.to_numpy()[ok]) / 10)
    return 10 ** (mean.gain_rx_db.to_numpy()[ok] / 10) * ratio


def test_same_links_only_the_power_fades(runs):
    cfg, mean, fading = runs
    for col in ("sat_id", "beam_id", "elevation_deg", "gain_tx_db", "gain_rx_db", "doppler_hz"):
        np.testing.assert_array_equal(mean[col], fading[col])
    assert len(mean) > 1500


def test_mean_receive_gain_is_the_papers_n_plus_one_over_k(runs):
    cfg, mean, fading = runs
    n = cfg.terminal.upa.n_x * cfg.terminal.upa.n_y  # LoS gain of the matched 24 x 24 UPA
    k = cfg.link.rician_k
    g = _effective_gain(cfg, mean, fading)
    se = g.std(ddof=1) / np.sqrt(len(g))
    assert abs(g.mean() - (n + 1 / k)) < N_SIGMA * se, (g.mean(), n + 1 / k, se)
    # The spread is the paper's: Var G = 2 N / K + 1 / K^2 (within 10 %: ~4 sigma of the
    # variance estimator at 2000 samples); an unfaded or unnormalized run fails here.
    assert g.var(ddof=1) == pytest.approx(2 * n / k + 1 / k**2, rel=0.1)


def test_receive_gain_is_noncentral_chi_square(runs):
    cfg, mean, fading = runs
    n = cfg.terminal.upa.n_x * cfg.terminal.upa.n_y
    k = cfg.link.rician_k
    g = _effective_gain(cfg, mean, fading)
    # leolink puts N + 1/K where the paper has N (a 1.7e-4 relative shift, far below what
    # 2000 samples resolve; see link/fading.py).
    assert stats.kstest(2 * k * g, stats.ncx2(df=2, nc=2 * k * n).cdf).pvalue > 1e-4
    # Independent draws epoch to epoch: lag-1 correlation of the fading of one UT.
    ut0 = (mean.ut_id == 0).to_numpy()
    d = _effective_gain(cfg, mean[ut0], fading[ut0])
    d = d - d.mean()
    rho = np.sum(d[1:] * d[:-1]) / np.sum(d * d)
    assert abs(rho) < N_SIGMA / np.sqrt(len(d))
