"""Radio link failure of TS 38.331 5.3.10: N310 / T310 / N311 timing, event by event."""

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.sim.handover.rlf import RlfParams, RlfState, declare, reset, step

DT_S = 0.1
BAD, MID, GOOD = -12.0, -7.0, 0.0  # below Q_out = -8, between, above Q_in = -6


def drive(sinr_seq, params, n_ut=1, monitored=None):
    """Run step() over per-epoch SINR (scalars or (n_ut,)); returns (rlf times, recovery times)."""
    state, rlf_t, rec_t = RlfState.initial(n_ut), [], []
    for k, sinr in enumerate(sinr_seq):
        t = k * DT_S
        mon = None if monitored is None else monitored[k]
        state, rlf, rec = step(state, t, np.broadcast_to(sinr, (n_ut,)), params, mon)
        rlf_t += [round(t, 9)] * int(rlf.sum())
        rec_t += [round(t, 9)] * int(rec.sum())
    return rlf_t, rec_t, state


def test_defaults_are_the_standard_timers_and_study_thresholds():
    # TS 38.331 9.2.3: t310 ms1000, n310 n1, n311 n1 (as OpenAirInterface's NR UE sets them)
    p = RlfParams()
    assert (p.t310_s, p.n310, p.n311) == (1.0, 1, 1)
    assert (p.q_out_db, p.q_in_db) == (-8.0, -6.0)


def test_t310_starts_on_the_n310th_consecutive_out_of_sync_and_expiry_is_rlf():
    p = RlfParams(t310_s=0.5, n310=3, reestablishment_s=10.0)
    seq = [GOOD] * 10 + [BAD] * 20  # out-of-sync from 1.0 s: indications 1.0, 1.1, 1.2
    rlf_t, _, _ = drive(seq, p)
    assert rlf_t == [pytest.approx(1.2 + 0.5)]


def test_an_in_sync_indication_breaks_the_out_of_sync_run():
    p = RlfParams(t310_s=0.3, n310=3, reestablishment_s=10.0)
    seq = [BAD, BAD, GOOD, BAD, BAD, BAD] + [BAD] * 10
    rlf_t, _, _ = drive(seq, p)
    assert rlf_t == [pytest.approx(0.5 + 0.3)]  # the run restarts at 0.3 s, T310 at 0.5 s


def test_no_indication_between_qout_and_qin_breaks_neither_run():
    p = RlfParams(t310_s=0.3, n310=3, reestablishment_s=10.0)
    seq = [BAD, MID, BAD, BAD] + [BAD] * 10  # the 3rd out-of-sync comes at 0.3 s
    rlf_t, _, _ = drive(seq, p)
    assert rlf_t == [pytest.approx(0.3 + 0.3)]


def test_thresholds_are_strict_worse_than_qout_better_than_qin():
    p = RlfParams(t310_s=0.2, n310=1, n311=1, reestablishment_s=10.0)
    assert drive([p.q_out_db] * 10, p)[0] == []  # equal to Q_out: not out-of-sync
    # T310 running from 0.0; equal to Q_in is not in-sync, so it expires at 0.2 s
    assert drive([BAD, p.q_in_db, p.q_in_db, p.q_in_db], p)[0] == [pytest.approx(0.2)]


def test_n311_consecutive_in_sync_stop_t310():
    p = RlfParams(t310_s=0.5, n310=1, n311=2, reestablishment_s=10.0)
    assert drive([BAD, GOOD, GOOD] + [MID] * 10, p)[0] == []  # stopped at 0.2 s
    # in-sync, out-of-sync, in-sync: never 2 in a row -> T310 (started 0.0) expires at 0.5
    assert drive([BAD, GOOD, BAD, GOOD, BAD, GOOD, MID], p)[0] == [pytest.approx(0.5)]


def test_expiry_is_checked_before_the_indication_of_that_epoch():
    p = RlfParams(t310_s=0.3, n310=1, n311=1, reestablishment_s=10.0)
    assert drive([BAD, MID, MID, GOOD, GOOD], p)[0] == [pytest.approx(0.3)]
    assert drive([BAD, MID, GOOD, MID, MID], p)[0] == []  # in-sync at 0.2 s is in time


def test_t310_zero_declares_rlf_with_the_n310th_indication():
    p = RlfParams(t310_s=0.0, n310=2, reestablishment_s=10.0)
    assert drive([GOOD, BAD, BAD, BAD], p)[0] == [pytest.approx(0.2)]


def test_no_link_counts_as_out_of_sync():
    p = RlfParams(t310_s=0.2, n310=1, reestablishment_s=10.0)
    assert drive([np.nan] * 5, p)[0] == [pytest.approx(0.2)]


def test_reestablishment_takes_its_configured_time_then_monitoring_restarts():
    p = RlfParams(t310_s=0.2, n310=1, reestablishment_s=0.5)
    rlf_t, rec_t, _ = drive([BAD] * 20, p)
    # RLF at 0.2; service back at 0.7; the first indication on the new link is at 0.8,
    # so T310 runs again 0.8-1.0 and the next RLF is at 1.0, then recovery at 1.5
    assert rlf_t == [pytest.approx(0.2), pytest.approx(1.0), pytest.approx(1.8)]
    assert rec_t == [pytest.approx(0.7), pytest.approx(1.5)]


def test_handover_reset_stops_t310():
    p = RlfParams(t310_s=0.3, n310=1, reestablishment_s=10.0)
    state = RlfState.initial(2)
    state, rlf, _ = step(state, 0.0, np.array([BAD, BAD]), p)
    assert state.t310_running.all()
    state = reset(state, np.array([True, False]))
    for t in (0.1, 0.2, 0.3):
        state, rlf, _ = step(state, t, np.array([MID, MID]), p)
    assert rlf.tolist() == [False, True]


def test_unmonitored_uts_give_no_indication():
    p = RlfParams(t310_s=0.1, n310=2, reestablishment_s=10.0)
    monitored = [np.array([True])] * 2 + [np.array([False])] * 5 + [np.array([True])] * 3
    rlf_t, _, _ = drive([BAD] * 10, p, monitored=monitored)
    assert rlf_t == [pytest.approx(0.1 + 0.1)]  # T310 started at 0.1 keeps running
    monitored = [np.array([k % 2 == 0]) for k in range(10)]  # skipped epochs do not count
    rlf_t, _, _ = drive([BAD, GOOD] * 5, p, monitored=monitored)
    assert rlf_t == [pytest.approx(0.2 + 0.1)]


def reference_rlf(sinr, p, counters=None):
    """Scalar transcription of 5.3.10.1-5.3.10.3 for one UT: list of RLF epoch indices.

    ``counters``: a list that receives ``(n_oos, n_is, T310 running)`` after each epoch."""
    n_oos = n_is = 0
    t310 = rlf_at = None
    out = []
    for k, s in enumerate(sinr):
        if counters is not None and k:
            counters.append((n_oos, n_is, t310 is not None))
        t = k * DT_S
        if rlf_at is not None:
            if t - rlf_at >= p.reestablishment_s - 1e-9:
                rlf_at, n_oos, n_is = None, 0, 0
            continue
        if t310 is not None and t - t310 >= p.t310_s - 1e-9:
            out.append(k)
            rlf_at, t310, n_oos, n_is = t, None, 0, 0
            continue
        oos, ins = not s >= p.q_out_db, s > p.q_in_db
        if t310 is None:
            n_oos = 0 if ins else n_oos + oos
            if n_oos >= p.n310:
                t310, n_oos, n_is = t, 0, 0
                if p.t310_s <= 1e-9:
                    out.append(k)
                    rlf_at, t310 = t, None
        else:
            n_is = 0 if oos else n_is + ins
            if n_is >= p.n311:
                t310, n_oos, n_is = None, 0, 0
    if counters is not None:
        counters.append((n_oos, n_is, t310 is not None))
    return out


@pytest.mark.parametrize("n310, n311, t310_s", [(1, 1, 1.0), (3, 2, 0.4), (6, 4, 0.0), (2, 1, 0.2)])
def test_vectorized_step_matches_a_scalar_transcription(n310, n311, t310_s):
    rng = np.random.default_rng(n310 * 10 + n311)
    n_ut, n_t = 40, 300
    # a slow random walk around the thresholds plus dropouts (NaN)
    sinr = -7 + np.cumsum(rng.normal(0, 1.2, (n_t, n_ut)), axis=0) * 0.3
    sinr[rng.random(sinr.shape) < 0.03] = np.nan
    p = RlfParams(t310_s=t310_s, n310=n310, n311=n311, reestablishment_s=0.3)
    state, got = RlfState.initial(n_ut), [[] for _ in range(n_ut)]
    for k in range(n_t):
        state, rlf, _ = step(state, k * DT_S, sinr[k], p)
        for u in np.flatnonzero(rlf):
            got[u].append(k)
    total = 0
    for u in range(n_ut):
        assert got[u] == reference_rlf(sinr[:, u], p)
        total += len(got[u])
    assert total > 5  # the sequences do produce failures


def test_invalid_parameters_are_refused():
    with pytest.raises(ConfigError, match="q_in_db"):
        RlfParams(q_out_db=-5.0, q_in_db=-6.0)
    with pytest.raises(ConfigError, match="n310"):
        RlfParams(n310=0)


def test_a_serving_change_in_the_expiry_epoch_pre_empts_the_rlf():
    """docs/handover_notes.md: the controller decides first; an outage_start (SNR below the
    service threshold) or an immediate handover in the epoch T310 expires stops T310 (a
    serving change), so no RLF is declared for that UT. The other UT, unchanged, fails."""
    from leolink.sim.handover.controller import SERVICE_OUTAGE, SERVICE_SERVED, ControllerState
    from leolink.sim.handover.events import events_table, split_cells
    from leolink.sim.handover.rlf_run import RlfRun

    run = RlfRun(RlfParams(t310_s=1.0), n_ut=3, n_beam=4, reason_code=5)
    run.state = RlfState(np.zeros(3, np.int64), np.zeros(3, np.int64), np.zeros(3),
                         np.full(3, np.nan))  # T310 running since t = 0 for all  # fmt: skip
    c = ControllerState.initial(3)
    old, new = np.array([4, 4, 4]), np.array([-1, 8, 4])  # UT 0 outage, UT 1 handover
    c.serving = new
    kind = np.array([2, 1, -1])  # outage_start, sat_handover, nothing
    events = events_table(1.0, kind, old, split_cells(old, 4), split_cells(new, 4),
                          np.zeros(3), np.zeros(3))  # fmt: skip
    cols = {"service": np.array([SERVICE_OUTAGE, SERVICE_SERVED, SERVICE_SERVED], np.int8),
            "sinr_db": np.array([np.nan, 5.0, -20.0]), "snr_db": np.zeros(3),
            "outage_reason": np.zeros(3, np.int8), "sat_id": np.array([-1, 2, 1]),
            "beam_id": np.array([-1, 0, 0]), "interruption_s": np.zeros(3)}  # fmt: skip
    _, rlf_events, _ = run.after_links(1.0, c, events, cols, np.zeros(3, bool))
    assert rlf_events["ut_id"].tolist() == [2]


# --- Written from the survivors of a mutation run (issue 45, docs/testing.md) ----------


@pytest.mark.parametrize("n310, n311", [(3, 2), (2, 3)])
def test_counters_and_t310_follow_the_scalar_transcription_epoch_by_epoch(n310, n311):
    """The state itself (consecutive counts, T310 running), not only the RLF times: every
    start, stop, expiry and recovery clears both counts (5.3.10.1-5.3.10.3)."""
    rng = np.random.default_rng(7 * n310 + n311)
    n_ut, n_t = 12, 250
    # a slow walk plus fast jitter: in-sync indications arrive while T310 runs
    walk = np.cumsum(rng.normal(0, 1.2, (n_t, n_ut)), axis=0) * 0.3
    sinr = -7 + walk + rng.normal(0, 2.0, (n_t, n_ut))
    p = RlfParams(t310_s=0.5, n310=n310, n311=n311, reestablishment_s=0.3)
    state, got = RlfState.initial(n_ut), []
    for k in range(n_t):
        state, _, _ = step(state, k * DT_S, sinr[k], p)
        got.append(np.stack([state.n_oos, state.n_is, state.t310_running], axis=1).tolist())
    kinds = set()
    for u in range(n_ut):
        ref = []
        reference_rlf(sinr[:, u], p, ref)
        mine = [tuple(int(v) for v in got[k][u]) for k in range(n_t)]
        assert mine == [tuple(int(v) for v in r) for r in ref]
        kinds |= {(r[0] > 0, r[1] > 0, r[2]) for r in ref}
    # the walk visits counting out-of-sync, T310 with in-sync counted, and T310 idle
    assert {(True, False, False), (False, True, True), (False, False, True)} <= kinds


def test_a_handover_clears_the_out_of_sync_run_and_the_in_sync_count():
    """N310 = 3: two out-of-sync indications, a handover (reset) for UT 0 only, then one
    more. UT 1 reaches 3 and starts T310 at 0.2 s; UT 0 starts again from 0 and needs
    three more (T310 at 0.4 s). Both fail T310 = 0.2 s later."""
    p = RlfParams(t310_s=0.2, n310=3, n311=2, reestablishment_s=10.0)
    state, times = RlfState.initial(2), {0: [], 1: []}
    for k in range(8):
        if k == 2:
            state = reset(state, np.array([True, False]))
            assert state.n_oos.tolist() == [0, 2]
        state, rlf, _ = step(state, k * DT_S, np.array([BAD, BAD]), p)
        for u in np.flatnonzero(rlf):
            times[u].append(round(k * DT_S, 9))
    assert times == {0: [0.6], 1: [0.4]}
    # the in-sync count while T310 runs: one in-sync of N311 = 2, then a handover
    state = RlfState.initial(1)
    for k, s in enumerate([BAD, BAD, BAD, GOOD]):
        state, _, _ = step(state, k * DT_S, np.array([s]), p)
    assert state.n_is.tolist() == [1] and state.t310_running.all()
    state = reset(state, np.array([True]))
    assert (state.n_oos.tolist(), state.n_is.tolist(), bool(state.t310_running[0])) == (
        [0], [0], False)  # fmt: skip


def test_declare_starts_re_establishment_at_its_own_time_for_the_given_uts_only():
    """A handover failure declared at t_c = 0.35 s (between epochs, TS 38.331 5.3.7): the UT
    is re-establishing from 0.35 s with T310 stopped and its counts cleared, service back at
    the first epoch >= 0.35 + 0.3 = 0.65 s, i.e. 0.7 s; the other UTs keep their state."""
    p = RlfParams(t310_s=5.0, n310=2, n311=3, reestablishment_s=0.3)
    state = RlfState.initial(3)
    for k, s in enumerate([BAD, BAD, GOOD]):  # T310 since 0.1 s, one in-sync counted
        state, _, _ = step(state, k * DT_S, np.full(3, s), p)
    assert state.n_is.tolist() == [1, 1, 1] and state.t310_running.all()
    assert declare(state, np.zeros(3, bool), 0.35) is state  # nothing to declare
    state = declare(state, np.array([False, True, False]), np.array([9.0, 0.35, 9.0]))
    assert state.reestablishing.tolist() == [False, True, False]
    assert state.rlf_at_s[1] == 0.35
    assert state.t310_running.tolist() == [True, False, True]
    assert state.n_is.tolist() == [1, 0, 1] and state.n_oos.tolist() == [0, 0, 0]
    back = []
    for k in range(3, 9):
        state, rlf, rec = step(state, k * DT_S, np.full(3, GOOD), p)
        assert not rlf.any()
        back += [round(k * DT_S, 9)] * bool(rec[1])
        assert not rec[[0, 2]].any()
    assert back == [0.7]
    # UTs 0 and 2: 3 in-sync in a row (0.2, 0.3, 0.4 s) stopped T310; UT 1 is connected again
    assert not state.t310_running.any() and not state.reestablishing.any()
    # an out-of-sync run in progress (T310 not running) is cleared too
    state, _, _ = step(RlfState.initial(1), 0.0, np.array([BAD]), p)
    assert state.n_oos.tolist() == [1] and not state.t310_running.any()
    assert declare(state, np.array([True]), 0.05).n_oos.tolist() == [0]


def test_t310_below_the_time_tolerance_is_ms0():
    """A T310 under the 1 ns clock tolerance expires the moment it starts, as ms0 does."""
    p = RlfParams(t310_s=0.5e-9, n310=1, reestablishment_s=10.0)
    assert drive([GOOD, BAD, BAD], p)[0] == [pytest.approx(0.1)]
    p = RlfParams(t310_s=RlfParams().t310_s * 1e-9, n310=1, reestablishment_s=10.0)
    assert drive([GOOD, BAD, BAD], p)[0] == [pytest.approx(0.1)]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"q_out_db": -5.0, "q_in_db": -6.0},
         "rlf.q_in_db = -6.0 is not allowed; use a value >= -5.0 (Q_in >= Q_out [dB])"),
        ({"t310_s": -0.1}, "rlf.t310_s = -0.1 is not allowed; use a value >= 0.0 (timer T310 [s])"),
        ({"n310": 0},
         "rlf.n310 = 0 is not allowed; use a value >= 1 (consecutive out-of-sync indications)"),
        ({"n311": 0},
         "rlf.n311 = 0 is not allowed; use a value >= 1 (consecutive in-sync indications)"),
        ({"reestablishment_s": -1.0},
         "rlf.reestablishment_s = -1.0 is not allowed; use a value >= 0.0 ([s])"),
        ({"t310_s": float("inf")}, "rlf.t310_s = inf is not allowed; finite"),
        ({"q_out_db": float("nan")}, "rlf.q_out_db = nan is not allowed; finite"),
    ],
)  # fmt: skip
def test_each_refusal_names_the_key_the_value_and_what_is_allowed(kwargs, message):
    with pytest.raises(ConfigError) as err:
        RlfParams(**kwargs)
    assert str(err.value) == message
