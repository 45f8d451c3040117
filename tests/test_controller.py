"""Tests of leolink.sim.handover.controller against hand-computed sequences and brute force."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.config import parse_config
from leolink.errors import ConfigError
from leolink.sim.handover.controller import (
    SERVICE_HANDOVER,
    SERVICE_OUTAGE,
    SERVICE_SERVED,
    ControllerState,
    close_dwells,
    step,
)
from leolink.sim.handover.policies import Hysteresis, MaxSnr, Predictive

HANDOVER_KINDS = ("beam_handover", "sat_handover")

# controller._rules runs compiled (numba) and as numpy code: both must pass.
pytestmark = pytest.mark.usefixtures("compiled_and_numpy")


def run(policy, snr_seq, dt_s=1.0, min_snr_db=0.0, handover_time_s=0.0, n_beam=1, future=None):
    """Drive step() over snr_seq (n_epoch, n_ut, n_cand); t accumulated like SimPy does."""
    state = ControllerState.initial(snr_seq.shape[1], 0.0)
    results, t_s = [], 0.0
    for k in range(snr_seq.shape[0]):
        fut = None if future is None else future[k]
        res = step(t_s, snr_seq[k], state, policy, min_snr_db, handover_time_s, n_beam, fut)
        results.append(res)
        state = res.state
        t_s += dt_s
    events = {k: np.concatenate([r.events[k] for r in results]) for k in results[0].events}
    tail = close_dwells(state, t_s)
    dwells = {k: np.concatenate([r.dwells[k] for r in results] + [tail[k]]) for k in tail}
    return results, events, dwells


def n_handovers(events, n_ut):
    is_ho = np.isin(events["kind"], HANDOVER_KINDS)
    return np.bincount(events["ut_id"][is_ho], minlength=n_ut)


def test_max_snr_picks_argmax_ignoring_nan():
    rng = np.random.default_rng(1)
    snr = rng.normal(10, 5, (50, 7))
    snr[rng.random(snr.shape) < 0.3] = np.nan
    snr[3] = np.nan  # a UT with no link at all
    got = MaxSnr().choose(0.0, snr, ControllerState.initial(50))
    for i, row in enumerate(snr):  # brute force, one UT at a time
        finite = [(v, j) for j, v in enumerate(row) if not np.isnan(v)]
        expected = max(finite, key=lambda p: (p[0], -p[1]))[1] if finite else -1
        assert got[i] == expected


def test_max_snr_step_follows_argmax_and_counts_every_change():
    rng = np.random.default_rng(2)
    snr = rng.normal(10, 3, (40, 6, 4))  # all above min_snr_db = 0 dB -> no outage
    results, events, _ = run(MaxSnr(), snr, n_beam=2)
    argmax = snr.argmax(axis=2)  # (n_epoch, n_ut)
    for k, res in enumerate(results):
        np.testing.assert_array_equal(res.state.serving, argmax[k])
        np.testing.assert_array_equal(res.sat_id, argmax[k] // 2)
        np.testing.assert_array_equal(res.beam_id, argmax[k] % 2)
    expected = (np.diff(argmax, axis=0) != 0).sum(axis=0)
    np.testing.assert_array_equal(n_handovers(events, 6), expected)
    same_sat = argmax[1:] // 2 == argmax[:-1] // 2
    changed = np.diff(argmax, axis=0) != 0
    assert (events["kind"] == "beam_handover").sum() == (changed & same_sat).sum()
    assert (events["kind"] == "sat_handover").sum() == (changed & ~same_sat).sum()


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    margin_db=st.floats(0.0, 6.0),
    ttt_epochs=st.integers(0, 3),
    n_cand=st.integers(2, 4),
)
def test_hysteresis_never_adds_handovers(seed, margin_db, ttt_epochs, n_cand):
    # Random-walk SNR (1 dB steps) with link gaps and min-SNR crossings.
    rng = np.random.default_rng(seed)
    walk = 8.0 + np.cumsum(rng.normal(0.0, 1.0, (40, 3, n_cand)), axis=0)
    walk[rng.random(walk.shape) < 0.05] = np.nan
    _, ev_max, _ = run(MaxSnr(), walk, min_snr_db=0.0)
    _, ev_hys, _ = run(Hysteresis(margin_db, ttt_epochs * 1.0), walk, min_snr_db=0.0)
    assert np.all(n_handovers(ev_hys, 3) <= n_handovers(ev_max, 3))
    # outage depends on the SNR only, not on the policy
    for kind in ("outage_start", "outage_end"):
        assert (ev_max["kind"] == kind).sum() == (ev_hys["kind"] == kind).sum()


def test_hysteresis_removes_ping_pong():
    k = np.arange(20)
    wobble = 0.5 * (-1.0) ** k
    snr = np.stack([10 + wobble, 10 - wobble], axis=-1)[:, None, :]  # (20, 1, 2)
    _, ev_max, _ = run(MaxSnr(), snr, n_beam=2)
    _, ev_hys, _ = run(Hysteresis(margin_db=3.0), snr, n_beam=2)
    assert n_handovers(ev_max, 1)[0] == 19  # every epoch after the first
    assert n_handovers(ev_hys, 1)[0] == 0


@pytest.mark.parametrize("ttt_epochs", [0, 1, 3])
def test_time_to_trigger_delays_by_exactly_the_configured_epochs(ttt_epochs):
    dt_s, step_epoch = 0.1, 5
    snr = np.zeros((15, 1, 2))
    snr[:, 0, 0] = np.where(np.arange(15) < step_epoch, 10.0, 5.0)
    snr[:, 0, 1] = np.where(np.arange(15) < step_epoch, 7.0, 12.0)
    policy = Hysteresis(margin_db=3.0, time_to_trigger_s=ttt_epochs * dt_s)
    results, events, _ = run(policy, snr, dt_s=dt_s, n_beam=2)
    assert list(events["kind"]) == ["beam_handover"]
    handover_epoch = step_epoch + ttt_epochs
    assert events["time_s"][0] == pytest.approx(handover_epoch * dt_s, abs=1e-9)
    serving = [r.state.serving[0] for r in results]
    assert serving == [0] * handover_epoch + [1] * (15 - handover_epoch)


def test_time_to_trigger_restarts_when_the_condition_breaks():
    snr = np.zeros((10, 1, 2))
    snr[:, 0, 0] = 10.0
    snr[:, 0, 1] = [5, 14, 14, 9, 14, 14, 14, 14, 14, 14]  # ahead from 1, broken at 3
    _, events, _ = run(Hysteresis(3.0, time_to_trigger_s=2.0), snr, n_beam=2)
    assert events["time_s"].tolist() == [6.0]  # ahead again from 4, waits 2 epochs


def test_immediate_switch_when_serving_becomes_unusable():
    snr = np.zeros((6, 1, 2))
    snr[:, 0, 0] = [10, 10, np.nan, np.nan, 10, 10]
    snr[:, 0, 1] = 8.0
    _, events, _ = run(Hysteresis(3.0, time_to_trigger_s=100.0), snr, n_beam=2)
    assert events["time_s"].tolist() == [2.0]
    assert events["to_beam"].tolist() == [1]
    # the serving link vanished (NaN at t = 2): snr_before_db is its last value, 10 dB at t = 1
    assert events["snr_before_db"][0] == 10.0 and events["snr_after_db"][0] == 8.0
    # below min_snr_db (not NaN) is unusable too
    snr[:, 0, 0] = [10, 10, -1.0, -1.0, 10, 10]
    _, events, _ = run(Hysteresis(3.0, time_to_trigger_s=100.0), snr, n_beam=2)
    assert events["time_s"].tolist() == [2.0]
    assert events["snr_before_db"][0] == -1.0


def test_outage_events_when_snr_crosses_min_snr():
    snr = np.array([5.0, 5.0, -1.0, -2.0, np.nan, 3.0, 4.0])[:, None, None]
    results, events, dwells = run(MaxSnr(), snr, min_snr_db=0.0, n_beam=1)
    assert events["kind"].tolist() == ["outage_start", "outage_end"]
    assert events["time_s"].tolist() == [2.0, 5.0]
    assert events["from_sat"].tolist() == [0, -1] and events["to_sat"].tolist() == [-1, 0]
    assert events["snr_before_db"][0] == -1.0 and np.isnan(events["snr_after_db"][0])
    assert events["snr_after_db"][1] == 3.0
    codes = [r.service[0] for r in results]
    assert codes == [SERVICE_SERVED] * 2 + [SERVICE_OUTAGE] * 3 + [SERVICE_SERVED] * 2
    assert [r.sat_id[0] for r in results] == [0, 0, -1, -1, -1, 0, 0]
    assert dwells["start_s"].tolist() == [0.0, 5.0] and dwells["end_s"].tolist() == [2.0, 7.0]
    assert dwells["censored_start"].tolist() == [True, False]
    assert dwells["censored_end"].tolist() == [False, True]


def test_an_snr_exactly_at_min_snr_is_usable():
    """Usable means ``snr >= min_snr_db``: a UT whose only cell sits exactly at the minimum
    stays served, with no outage event."""
    snr = np.array([5.0, 0.0, 0.0, 5.0])[:, None, None]
    results, events, _ = run(MaxSnr(), snr, min_snr_db=0.0, n_beam=1)
    assert len(events["kind"]) == 0
    assert [r.service[0] for r in results] == [SERVICE_SERVED] * 4
    assert [r.sat_id[0] for r in results] == [0, 0, 0, 0]


def test_a_serving_snr_exactly_at_min_snr_still_waits_the_time_to_trigger():
    """The serving cell at exactly the minimum is usable, so a better target does not
    switch at once: it pends for its time to trigger (100 s, beyond the run)."""
    snr = np.zeros((5, 1, 2))
    snr[:, 0, 0] = [5.0, 0.0, 0.0, 0.0, 0.0]
    snr[:, 0, 1] = [1.0, 8.0, 8.0, 8.0, 8.0]
    results, events, _ = run(Hysteresis(3.0, time_to_trigger_s=100.0), snr, n_beam=2)
    assert len(events["kind"]) == 0
    assert [r.beam_id[0] for r in results] == [0] * 5


def test_outage_at_run_start_is_reported():
    snr = np.array([np.nan, 4.0, 4.0])[:, None, None]
    _, events, dwells = run(MaxSnr(), snr)
    assert events["kind"].tolist() == ["outage_start", "outage_end"]
    assert events["from_sat"][0] == -1
    assert dwells["censored_start"].tolist() == [False]  # began after the run start


@pytest.mark.parametrize("n_interrupt", [1, 3])
def test_handover_execution_interrupts_service_for_configured_epochs(n_interrupt):
    dt_s = 0.1  # t accumulates 0.1 s steps: checks the time tolerance
    snr = np.zeros((12, 1, 2))
    snr[:, 0, 0] = np.where(np.arange(12) < 4, 10.0, 2.0)
    snr[:, 0, 1] = np.where(np.arange(12) < 4, 2.0, 10.0)
    results, events, _ = run(MaxSnr(), snr, dt_s=dt_s, handover_time_s=n_interrupt * dt_s, n_beam=2)
    codes = [int(r.service[0]) for r in results]
    expected = [SERVICE_SERVED] * 4 + [SERVICE_HANDOVER] * n_interrupt
    expected += [SERVICE_SERVED] * (12 - len(expected))
    assert codes == expected
    assert len(events["kind"]) == 1


def test_dwell_times_of_a_constructed_sequence():
    # n_beam = 2: cand 0, 1 on satellite 0, cand 2 on satellite 1.
    serving_seq = [0, 0, 0, 1, 1, 2, 2, 2, 2, 0]
    snr = np.full((10, 1, 3), 10.0)
    snr[np.arange(10), 0, serving_seq] = 20.0
    _, events, dwells = run(MaxSnr(), snr, n_beam=2)
    assert events["kind"].tolist() == ["beam_handover", "sat_handover", "sat_handover"]
    assert events["time_s"].tolist() == [3.0, 5.0, 9.0]
    order = np.argsort(dwells["start_s"])
    d = {k: v[order].tolist() for k, v in dwells.items()}
    assert d["start_s"] == [0.0, 3.0, 5.0, 9.0]
    assert d["end_s"] == [3.0, 5.0, 9.0, 10.0]
    assert d["sat_id"] == [0, 0, 1, 0] and d["beam_id"] == [0, 1, 0, 0]
    assert d["censored_start"] == [True, False, False, False]
    assert d["censored_end"] == [False, False, False, True]


def test_predictive_avoids_a_beam_it_would_leave():
    # serving 0 fades; 1 is best now but gone at t + lookahead; 2 stays good.
    now = np.array([[np.nan, 12.0, 10.0]])
    future = np.array([[np.nan, np.nan, 11.0]])
    state = ControllerState.initial(1)
    state.serving[:] = 0
    assert MaxSnr().choose(0.0, now, state)[0] == 1
    assert Predictive(lookahead_s=5.0).choose(0.0, now, state, future)[0] == 2
    # stays when the serving candidate is still the best by min(now, future)
    now2, future2 = np.array([[11.0, 12.0, 10.0]]), np.array([[11.0, 9.0, 10.5]])
    assert Predictive(lookahead_s=5.0).choose(0.0, now2, state, future2)[0] == 0
    # no candidate survives: falls back to the best one now
    lost = np.full((1, 3), np.nan)
    assert Predictive(5.0).choose(0.0, np.array([[np.nan, 3.0, 4.0]]), state, lost)[0] == 2


def test_predictive_through_step_uses_masked_future():
    now = np.array([[[8.0, 12.0, 10.0]]])
    future = np.array([[[8.0, -5.0, 11.0]]])  # cand 1 falls below min_snr_db = 0
    results, _, _ = run(Predictive(5.0), now, future=future)
    assert results[0].state.serving[0] == 2


def test_policies_and_step_do_not_mutate_state():
    rng = np.random.default_rng(3)
    snr = rng.normal(10, 3, (5, 4))
    state = ControllerState.initial(5)
    state.serving[:] = [0, 1, 2, 3, 0]
    before = {k: np.copy(v) for k, v in vars(state).items() if isinstance(v, np.ndarray)}
    for policy in (MaxSnr(), Hysteresis(2.0, 1.0), Predictive(3.0)):
        policy.choose(0.0, snr, state, snr)
        step(0.0, snr, state, policy, 0.0, 1.0, 2, snr)
    for k, v in before.items():
        np.testing.assert_array_equal(getattr(state, k), v)


def test_policies_from_the_config_tables():
    def policy(**controller):
        return parse_config({"controller": controller}).controller.build()

    assert isinstance(policy(), MaxSnr)
    h = policy(policy="hysteresis", hysteresis={"margin_db": 2.0, "time_to_trigger_s": 0.5})
    assert isinstance(h, Hysteresis) and (h.margin_db, h.time_to_trigger_s) == (2.0, 0.5)
    assert policy(policy="predictive", predictive={"lookahead_s": 4.0}).lookahead_s == 4.0
    with pytest.raises(
        ConfigError, match="'max_snr', 'hysteresis', 'predictive', .*'cho', 'a2a4' or 'slotted'"
    ):
        policy(policy="greedy")
    with pytest.raises(ConfigError, match="controller.hysteresis.lookahead_s is not a known key"):
        policy(policy="hysteresis", hysteresis={"lookahead_s": 3.0})
    with pytest.raises(ConfigError, match="controller.hysteresis.margin_db = -1"):
        policy(policy="hysteresis", hysteresis={"margin_db": -1})


def test_a_policy_returning_an_unusable_candidate_is_an_error():
    class Bad:  # (the Policy protocol's attributes: the compiled step reads them all)
        lookahead_s = 0.0
        time_to_trigger_s = 0.0

        def choose(self, t_s, snr_db, state, future_snr_db=None):
            return np.zeros(snr_db.shape[0], np.int64)

    snr = np.array([[np.nan, 5.0]])
    with pytest.raises(ValueError, match="unusable candidate for 1 UT"):
        step(0.0, snr, ControllerState.initial(1), Bad(), 0.0, 0.0, 2)


def _flat(n_epoch, *rows):
    """SNR sequence of one UT: ``rows`` = (from_epoch, [snr per candidate]) steps."""
    snr = np.zeros((n_epoch, 1, len(rows[0][1])))
    for start, values in rows:
        snr[start:, 0, :] = values
    return snr


def test_candidate_zero_is_an_ordinary_target_for_interruption_and_time_to_trigger():
    """Candidate 0 (satellite 0, beam 0) is a valid id: a handover *to* it interrupts
    service, and a pending switch to it keeps its time-to-trigger clock (ids >= 0, not > 0)."""
    # Served by candidate 1, candidate 0 becomes better at epoch 3: with handover_time 2 s
    # the epochs 3 and 4 are interrupted, service resumes at 5.
    snr = _flat(8, (0, [5.0, 10.0]), (3, [12.0, 10.0]))
    res, _, _ = run(MaxSnr(), snr, handover_time_s=2.0)
    service = [int(r.service[0]) for r in res]
    assert service == [SERVICE_SERVED] * 3 + [SERVICE_HANDOVER] * 2 + [SERVICE_SERVED] * 3
    assert [int(r.state.serving[0]) for r in res][3:] == [0] * 5
    # While the handover to candidate 0 executes (epochs 3-4), candidate 1 turning better
    # at epoch 4 must wait for the end of the interruption: no switch before epoch 5.
    snr = _flat(8, (0, [5.0, 10.0]), (3, [12.0, 10.0]), (4, [12.0, 15.0]))
    res, _, _ = run(MaxSnr(), snr, handover_time_s=2.0)
    assert [int(r.state.serving[0]) for r in res] == [1, 1, 1, 0, 0, 1, 1, 1]
    # Hysteresis with a 2 s time-to-trigger towards candidate 0: ahead from epoch 2, the
    # switch fires at epoch 4 (t = 4 s), not later (a pending id 0 must not be dropped).
    snr = _flat(8, (0, [0.0, 10.0]), (2, [20.0, 10.0]))
    res, events, _ = run(Hysteresis(margin_db=3.0, time_to_trigger_s=2.0), snr)
    ho = events["time_s"][np.isin(events["kind"], HANDOVER_KINDS)]
    assert ho.tolist() == [4.0]
    assert [int(r.state.serving[0]) for r in res] == [1] * 4 + [0] * 4


def test_initial_state_is_unserved_with_nothing_pending():
    s = ControllerState.initial(3)
    assert s.serving.tolist() == [-1, -1, -1] and s.pending.tolist() == [-1, -1, -1]
    assert s.serving.dtype == np.int64 and s.pending.dtype == np.int64
    assert np.isnan(s.pending_since_s).all() and np.isnan(s.serving_since_s).all()
