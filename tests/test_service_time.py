"""End of service from the look-ahead against a brute-force scan of the same SNR history."""

from types import SimpleNamespace

import numpy as np
import pytest

from leolink.sim.handover.local_axis import LocalAxis
from leolink.sim.handover.service_time import ServiceTimes
from service_helpers import TableLinks

# both paths of the first failures (compiled loop, numpy) against the brute-force scan
pytestmark = pytest.mark.usefixtures("compiled_and_numpy")

N_UT, N_SAT, N_BEAM, N_T, DT_S, MIN_SNR_DB = 3, 4, 2, 60, 1.0, 0.0


def _history(seed):
    """SNR (n_t + horizon, n_ut, n_sat, n_beam): smooth bumps, so cells serve in runs."""
    rng = np.random.default_rng(seed)
    t = np.arange(N_T + 40)[:, None, None, None]
    centre = rng.uniform(0, N_T, (1, N_UT, N_SAT, N_BEAM))
    width = rng.uniform(3, 25, (1, N_UT, N_SAT, N_BEAM))
    return 10.0 - 20.0 * ((t - centre) / width) ** 2 + rng.normal(0, 0.5, (1, N_UT, N_SAT, 1))


class _Engine:
    """evaluate_pairs reads the history at the time encoded in the UT positions."""

    n_beam, beam_ix, beam_iy = N_BEAM, None, None

    def __init__(self, snr):
        self.snr = snr

    def evaluate_pairs(self, ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up=None, ut_id=None,
                       sat_id=None):  # fmt: skip
        k = np.round(ut_pos_m[ut, 0]).astype(int)  # each pair's UT row: one step's time
        sats = sat_pos_m[sat, 0].astype(int)
        values = self.snr[k, ut if ut_id is None else ut_id[ut], sats]  # (m, n_beam)
        return TableLinks(values)


def _future(t_s):
    """The states at the times ``t_s (n_t,)``: the time [epochs] in each UT's row, the
    satellite's index in its row."""
    n_t = len(t_s)
    ut = np.zeros((n_t, N_UT, 3))
    ut[..., 0] = np.asarray(t_s)[:, None] / DT_S
    sats = np.zeros((n_t, N_SAT, 3))
    sats[..., 0] = np.arange(N_SAT)
    return ut, sats, sats.copy()


def _brute(snr, k, horizon):
    """First later epoch at which each cell / satellite stops serving, from epoch k."""
    serves = snr >= MIN_SNR_DB
    end_cell = np.full((N_UT, N_SAT, N_BEAM), np.nan)
    end_sat = np.full((N_UT, N_SAT), np.nan)
    for u in range(N_UT):
        for s in range(N_SAT):
            if serves[k, u, s].any():
                stop = [j for j in range(1, horizon + 1) if not serves[k + j, u, s].any()]
                end_sat[u, s] = (k + stop[0]) * DT_S if stop else np.inf
            for b in range(N_BEAM):
                if serves[k, u, s, b]:
                    stop = [j for j in range(1, horizon + 1) if not serves[k + j, u, s, b]]
                    end_cell[u, s, b] = (k + stop[0]) * DT_S if stop else np.inf
    return end_cell.reshape(N_UT, -1), end_sat


def test_end_of_service_equals_a_brute_force_scan_every_epoch():
    horizon = 12
    # the fourth in whole dB: SNRs exactly at the minimum, which serve (>=)
    rounded = np.round(_history(3))
    assert (rounded == MIN_SNR_DB).sum() > 10
    for snr in [*(_history(seed) for seed in range(3)), rounded]:
        times = ServiceTimes(_Engine(snr), _future, MIN_SNR_DB, DT_S, horizon * DT_S)
        axis = LocalAxis.union(
            N_UT, N_BEAM, np.repeat(np.arange(N_UT), N_SAT), np.tile(np.arange(N_SAT), N_UT)
        )
        n_finite = 0
        for k in range(N_T):
            now = (snr[k] >= MIN_SNR_DB).reshape(N_UT, -1)
            cell, sat = times.update(k * DT_S, axis, now)
            ref_cell, ref_sat = _brute(snr, k, horizon)
            np.testing.assert_array_equal(cell, ref_cell)
            np.testing.assert_array_equal(sat, ref_sat)
            n_finite += np.isfinite(sat).sum()
        assert n_finite > 20  # ends inside the horizon, not only inf


def test_satellite_ends_alone_stay_exact_without_per_cell_look_ahead():
    snr, horizon = _history(7), 8
    times = ServiceTimes(_Engine(snr), _future, MIN_SNR_DB, DT_S, horizon * DT_S)
    axis = LocalAxis.union(
        N_UT, N_BEAM, np.repeat(np.arange(N_UT), N_SAT), np.tile(np.arange(N_SAT), N_UT)
    )
    for k in range(N_T):
        now = (snr[k] >= MIN_SNR_DB).reshape(N_UT, -1)
        _, sat = times.update(k * DT_S, axis, now, per_cell=False)
        np.testing.assert_array_equal(sat, _brute(snr, k, horizon)[1])


def test_t1_hands_over_lead_s_before_the_serving_satellite_stops_serving():
    """One UT, two one-beam satellites: satellite 0 (better) serves until t = 10 s,
    satellite 1 all along. T1 with lead 4 s: Thresh1 = 10 - 4 = 6 s, the condition
    ``Mt > Thresh1`` first holds at t = 7 s: the handover to satellite 1. (Max-SNR would
    stay until satellite 0 is lost at t = 10 s.)"""
    from leolink.sim.candidates.table import Candidates
    from leolink.sim.handover.decisions import TriggerPolicy
    from leolink.sim.handover.measurements import L3Filter
    from leolink.sim.handover.trigger_run import TriggerRun
    from leolink.sim.handover.triggers_ntn import T1

    n_t = 16
    snr = np.full((n_t + 40, 1, 2, 1), 5.0)
    snr[:10, 0, 0, 0] = 12.0
    snr[10:, 0, 0, 0] = -30.0

    class Engine(_Engine):
        n_beam = 1
        codebook = SimpleNamespace(u_xy=np.zeros((1, 2)))

    def future(t_s):
        ut, sats, vel = _future(t_s)
        return ut[:, :1], sats[:, :2], vel[:, :2]

    for lead_s, expected_s in ((4.0, 7.0), (0.5, 10.0)):
        policy = TriggerPolicy(T1(duration_s=3.0, lead_s=lead_s), level="satellite")
        run = TriggerRun(
            policy, L3Filter(0, 1.0), Engine(snr), MIN_SNR_DB, 6.371e6, future, DT_S, 30.0
        )
        serving, moved = np.array([-1]), None
        for k in range(n_t):
            table = Candidates.dense(snr[k, :, :, 0])
            new = run.target(k * DT_S, table, serving, np.zeros((1, 3)), None, None)
            if serving[0] == 0 and new[0] == 1 and moved is None:
                moved = k * DT_S
            serving = new
        assert moved == expected_s  # lead 0.5 s: Thresh1 = 9.5 s, t = 10 s, when it is lost anyway


def test_a_pair_that_ends_early_does_not_stop_the_next_pairs():
    """Pair 0 ends at step 0; its step 1 is skipped, and pair 1 (after it, pair-major) is
    still scanned: beam 1 fails at step 0, every beam at step 1. Expected by hand (both
    paths: the module's fixture)."""
    from leolink.sim.handover.service_time import _first_failures

    pair, step = np.array([0, 0, 1, 1]), np.array([0, 1, 0, 1])
    snr_bm = np.array([[-1.0, 9.0, 5.0, -1.0],  # beam 0 of the four (pair, step)s [dB]
                       [-1.0, 9.0, -1.0, -1.0]])  # fmt: skip
    first_sat, first_beam = _first_failures(snr_bm, np.ones(4, bool), pair, step, 0.0, 2, 2)
    assert first_sat.tolist() == [0, 1]
    assert first_beam.tolist() == [[0, 0], [1, 0]]
