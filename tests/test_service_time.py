"""End of service from the look-ahead against a brute-force scan of the same SNR history."""

import sys
from types import SimpleNamespace

import numpy as np
import pytest

from leolink.sim.handover.local_axis import LocalAxis
from leolink.sim.handover.service_time import ServiceTimes
from service_helpers import TableLinks

# both paths of the first failures (compiled loop, numpy) against the brute-force scan
pytestmark = pytest.mark.usefixtures("compiled_and_numpy")

N_UT, N_SAT, N_BEAM, N_T, DT_S, MIN_SNR_DB = 3, 4, 2, 60, 1.0, 0.0


def _history(seed, n_ahead=40):
    """SNR (n_t + n_ahead, n_ut, n_sat, n_beam): smooth bumps, so cells serve in runs."""
    rng = np.random.default_rng(seed)
    t = np.arange(N_T + n_ahead)[:, None, None, None]
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


def _future(t_s, sats=None, uts=True):
    """The states at the times ``t_s (n_t,)``: the time [epochs] in each UT's row (None
    without ``uts``), the satellite's index in its row (of the satellites ``sats``; None:
    all)."""
    n_t = len(t_s)
    ut = np.zeros((n_t, N_UT, 3))
    ut[..., 0] = np.asarray(t_s)[:, None] / DT_S
    ids = np.arange(N_SAT) if sats is None else np.asarray(sats)
    pos = np.zeros((n_t, ids.size, 3))
    pos[..., 0] = ids
    return (ut if uts else None), pos, pos.copy()


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

    def future(t_s, sats, uts=True):
        ut, pos, vel = _future(t_s, sats, uts)
        return (ut[:, :1] if uts else None), pos, vel

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


class _CheckedLinks(TableLinks):
    """TableLinks that refuse a beam grid other than the engine's."""

    def __init__(self, values, engine):
        super().__init__(values)
        self.engine = engine

    def snr_db_bm(self, beam_ix, beam_iy):
        assert beam_ix is self.engine.beam_ix and beam_iy is self.engine.beam_iy
        return super().snr_db_bm(beam_ix, beam_iy)

    def best_beam(self, beam_ix, beam_iy, with_snr_db=False):
        assert beam_ix is self.engine.beam_ix and beam_iy is self.engine.beam_iy
        return super().best_beam(beam_ix, beam_iy, with_snr_db)


class _CheckedEngine:
    """Reads each combination's time [s] from its UT position, its UT from its local up
    and its satellite from its velocity (10 m/s per index), checks them against the
    position and the ids, and records every (epoch, UT, satellite) it evaluates."""

    n_beam = N_BEAM

    def __init__(self, snr, epoch_s):
        self.snr, self.epoch_s, self.seen = snr, epoch_s, []
        self.beam_ix, self.beam_iy = np.arange(N_BEAM), np.arange(N_BEAM) + 10

    def evaluate_pairs(self, ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up=None, ut_id=None,
                       sat_id=None):  # fmt: skip
        k = np.round(ut_pos_m[ut, 0] / self.epoch_s).astype(int)
        u = ut_up[ut, 0].astype(int)
        s = np.round(sat_vel_m_s[sat, 0] / 10.0).astype(int)
        assert np.array_equal(sat_pos_m[sat, 0], s) and np.array_equal(sat_id[sat], s)
        assert np.array_equal(ut_id[ut], u)
        self.seen += list(zip(k.tolist(), u.tolist(), s.tolist(), strict=True))
        return _CheckedLinks(self.snr[k, u, s], self)


def _checked_run(snr, epoch_s, horizon_s, n_step, per_cell):
    """Every epoch's ends against the brute-force scan of ``n_step`` steps; each
    (epoch, UT, satellite) evaluated once, later than now, but a pair re-scanned when one
    of its cells starts serving; each (future time, satellite) asked of ``future_state``
    once (the UTs at most 32 times a call, each time once), and only satellites some pair
    looks ahead. Returns the engine."""
    asked, asked_uts = [], []

    def future(t_s, sats, uts=True):
        t_s, sats = np.asarray(t_s), np.asarray(sats)
        assert t_s.size >= 1 and sats.size == np.unique(sats).size >= 1
        keys = np.round(t_s / epoch_s).astype(int)
        asked.extend((k, s) for k in keys.tolist() for s in sats.tolist())
        ut = np.zeros((t_s.size, N_UT, 3))
        ut[..., 0] = t_s[:, None]
        if uts:
            assert t_s.size <= 32
            asked_uts.extend(keys.tolist())
        pos = np.zeros((t_s.size, sats.size, 3))
        pos[..., 0] = sats
        return (ut if uts else None), pos, 10.0 * pos

    engine = _CheckedEngine(snr, epoch_s)
    times = ServiceTimes(engine, future, MIN_SNR_DB, epoch_s, horizon_s)
    axis = LocalAxis.union(
        N_UT, N_BEAM, np.repeat(np.arange(N_UT), N_SAT), np.tile(np.arange(N_SAT), N_UT)
    )
    up = np.zeros((N_UT, 3))
    up[:, 0], up[:, 2] = np.arange(N_UT), 1.0
    serves = snr >= MIN_SNR_DB
    for k in range(N_T):
        before = len(engine.seen)
        cell, sat = times.update(k * epoch_s, axis, serves[k].reshape(N_UT, -1), up, per_cell)
        ref_cell, ref_sat = _brute(snr, k, n_step)
        np.testing.assert_array_equal(sat, ref_sat * epoch_s)
        if per_cell:
            np.testing.assert_array_equal(cell, ref_cell * epoch_s)
        else:
            assert cell is None
        new = engine.seen[before:]
        assert all(j > k for j, _, _ in new)
        assert len(set(new)) == len(new)
        starts = serves[k] & ~serves[k - 1] if k and per_cell else np.zeros_like(serves[k])
        again = {(u, s) for j, u, s in new if (j, u, s) in set(engine.seen[:before])}
        assert all(starts[u, s].any() for u, s in again)
    assert len(asked) == len(set(asked)) and len(asked_uts) == len(set(asked_uts))
    assert {s for _, s in asked} == {s for _, _, s in engine.seen}
    return engine


@pytest.mark.parametrize("per_cell", [True, False])
def test_ends_with_another_epoch_a_horizon_off_the_grid_and_the_engines_inputs(per_cell):
    """Epoch 2.5 s, horizon 21 s: 9 steps (the 9th, 22.5 s, beyond it: a horizon is
    rounded up to whole epochs), so the first chunk of 8 steps leaves one; the UTs' local
    up, the satellites' velocities and ids reach the engine; a one-epoch dip in UT 2's
    service by satellite 2 at epoch 20 (it serves at 19 and 21) is that epoch."""
    snr = _history(5)
    serves = snr[:, 2, 2] >= MIN_SNR_DB
    assert serves[19].all() and serves[21].all()
    snr[20, 2, 2] = -10.0
    engine = _checked_run(snr, 2.5, 21.0, 9, per_cell)
    assert len(engine.seen) > 100


def test_a_one_epoch_horizon_looks_one_step_ahead():
    """A horizon of one epoch or less: one step, every epoch (the ends are seen one
    epoch ahead, the dip at epoch 20 too)."""
    snr = _history(5)
    snr[20, 2, 2] = -10.0
    _checked_run(snr, 1.0, 1.0, 1, True)
    _checked_run(snr, 2.0, 0.5, 1, False)


def test_a_long_horizon_evaluates_each_future_time_once():
    """Horizon 36 steps: chunks of 8, 16 and 12 steps; each future time asked once."""
    _checked_run(_history(6), 1.0, 36.0, 36, True)


def test_a_pass_longer_than_the_chunks_asks_every_future_time_in_batches():
    """One cell that serves throughout, horizon 90 steps: its look-ahead at the first epoch
    goes in chunks of 8, 16, 32 and 34 steps, the last two needing every one of their
    future times (a batch of 32, then 32 and 2): a time left out of a batch would hand the
    engine an unfilled state."""
    snr = _history(7, n_ahead=100)
    snr[:, 0, 0, 0] = 10.0
    engine = _checked_run(snr, 1.0, 90.0, 90, True)
    assert {j for j, u, s in engine.seen if (u, s) == (0, 0)} >= set(range(1, 91))


def test_satellites_first_looked_ahead_later_are_evaluated_at_the_held_times():
    """Satellites 2 and 3 serve no UT before epoch 12: their first look-ahead comes when
    the ring holds a horizon of times for the others; their states at every held time are
    evaluated then (in one call, without the UTs) into their own columns, and the engine
    reads each one's own position and velocity at each step (checked by
    ``_CheckedEngine``), the ends still the brute-force scan's."""
    snr = _history(8)
    snr[:12, :, 2:] = -30.0
    assert (snr[12:, :, 2] >= MIN_SNR_DB).any() and (snr[12:, :, 3] >= MIN_SNR_DB).any()
    engine = _checked_run(snr, 1.0, 20.0, 20, False)
    assert min(k for k, _, s in engine.seen if s >= 2) > 12


@pytest.mark.parametrize("n_sat", [4, 20])
def test_a_future_whose_subsets_cost_the_whole_set_is_asked_for_every_satellite(monkeypatch, n_sat):
    """``future_state.n_sat_whole`` set (TLEs, an ephemeris error: the runner's): every
    satellite is a column from the start (20: more at once than the ring's first 16
    columns), each new time asked once for all of them, never a satellite alone at the
    held times; the ends still the brute-force scan's."""
    import functools

    monkeypatch.setattr(sys.modules[__name__], "N_SAT", n_sat)

    snr = _history(8)
    snr[:12, :, 2:] = -30.0  # (satellites 2 and 3 first looked ahead late)
    calls = []

    def future(t_s, sats, uts=True):
        calls.append((np.round(np.asarray(t_s)).astype(int).tolist(), list(sats), uts))
        return _future(t_s, sats, uts)

    whole = functools.partial(future)
    whole.n_sat_whole = N_SAT
    times = ServiceTimes(_Engine(snr), whole, MIN_SNR_DB, DT_S, 20 * DT_S)
    axis = LocalAxis.union(
        N_UT, N_BEAM, np.repeat(np.arange(N_UT), N_SAT), np.tile(np.arange(N_SAT), N_UT)
    )
    serves = snr >= MIN_SNR_DB
    for k in range(N_T):
        _, sat = times.update(k * DT_S, axis, serves[k].reshape(N_UT, -1), None, False)
        np.testing.assert_array_equal(sat, _brute(snr, k, 20)[1] * DT_S)
    assert calls and all(sats == list(range(N_SAT)) and uts for _, sats, uts in calls)
    asked = [t for ts, _, _ in calls for t in ts]
    assert len(asked) == len(set(asked)) > 20


def test_the_ring_grows_past_its_first_columns_keeping_the_held_states(monkeypatch):
    """20 satellites, 17 of them first looked ahead once the ring holds a horizon of times
    for the other 3: the ring grows past its first 16 columns, the held states of the first
    3 carried into it (``_CheckedEngine`` checks each satellite's position and velocity at
    each step), the ends still the brute-force scan's."""
    monkeypatch.setattr(sys.modules[__name__], "N_SAT", 20)
    snr = _history(9)
    snr[:12, :, 3:] = -30.0
    engine = _checked_run(snr, 1.0, 20.0, 20, True)
    assert min(k for k, _, s in engine.seen if s >= 3) > 12
    assert {s for _, _, s in engine.seen} >= set(range(17))  # more than 16 columns
