"""Trigger events of TS 38.331, clause by clause, in event-accounting style.

Each test drives one trigger through a sequence of epochs whose entering and leaving
instants are known by hand (or in closed form for D1/D2) and checks the accounting:
when the condition entered, lapsed, triggered (after the time-to-trigger) and left.
Measurements are multiples of 0.5 dB so that equalities at thresholds are exact.
"""

import math

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.sim.handover.triggers import A3, A4, A5, Epoch, TriggerState, advance, evaluate
from leolink.sim.handover.triggers_ntn import D1, D2, T1, Elevation, TimeToExit

DT_S = 0.1


def epochs(n, dt_s=DT_S):
    """Epoch times as the simulator makes them (k * dt, not summed)."""
    return [k * dt_s for k in range(n)]


def run_trigger(trigger, steps, serving=0):
    """Drive ``trigger`` over ``steps`` = [(t_s, Epoch fields...)]; one UT.

    Returns the accounting as a list of (what, t_s, candidate) in time order.
    """
    state, log = None, []
    for t_s, fields in steps:
        ep = Epoch(t_s=t_s, serving=np.array([serving]), **fields)
        if state is None:
            state = TriggerState.initial(1, trigger.conditions(ep)[0].shape[1])
        state, rep = evaluate(trigger, state, ep)
        for what in ("entered", "lapsed", "triggered", "left"):
            for cand in np.flatnonzero(getattr(rep, what)[0]):
                log.append((what, round(t_s, 9), int(cand)))
    return log


def meas_steps(serving_db, neighbour_db):
    """Epochs with two cells: 0 serving, 1 neighbour; values per epoch."""
    return [
        (t, {"meas": np.array([[s, n]])})
        for t, s, n in zip(epochs(len(neighbour_db)), serving_db, neighbour_db, strict=True)
    ]


def times(log, what, cand=1):
    return [t for w, t, c in log if w == what and c == cand]


# ----------------------------------------------------------------------------- A3 5.5.4.4


def test_a3_enters_only_when_neighbour_beats_serving_by_offset_plus_hysteresis():
    # Mn - Hys > Mp + Off with Off = 1, Hys = 1: Mn = 2.0 is the equality (no entry), 2.5 enters
    neighbour = [0.0, 1.0, 2.0, 2.0, 2.5, 2.5]
    log = run_trigger(A3(offset_db=1.0, hysteresis_db=1.0), meas_steps([0.0] * 6, neighbour))
    assert times(log, "entered") == [0.4]
    assert times(log, "triggered") == [0.4]  # time_to_trigger 0: triggers on entry


def test_a3_time_to_trigger_counts_from_the_first_epoch_of_the_condition():
    # condition holds from 0.2 s on; TTT 0.3 s -> triggered at 0.5 s, not before
    neighbour = [0.0, 0.0] + [4.0] * 6
    log = run_trigger(A3(offset_db=3.0, time_to_trigger_s=0.3), meas_steps([0.0] * 8, neighbour))
    assert times(log, "entered") == [0.2]
    assert times(log, "triggered") == [pytest.approx(0.5)]


def test_a3_lapsed_condition_restarts_time_to_trigger():
    # better 0.2-0.4 s, back below at 0.5 s, better again from 0.6 s: TTT 0.3 s counts from 0.6
    neighbour = [0, 0, 4, 4, 4, 0, 4, 4, 4, 4, 4]
    log = run_trigger(A3(offset_db=3.0, time_to_trigger_s=0.3), meas_steps([0] * 11, neighbour))
    assert times(log, "entered") == [0.2, 0.6]
    assert times(log, "lapsed") == [0.5]
    assert times(log, "triggered") == [pytest.approx(0.9)]


def test_a3_leaves_only_when_neighbour_is_hysteresis_below_the_offset():
    # Off = 1, Hys = 1: enter needs Mn > 2, leave needs Mn < 0; Mn = 0.0 is the leaving equality
    neighbour = [3.0, 1.5, 1.0, 0.5, 0.0, -0.5, -0.5]
    log = run_trigger(A3(offset_db=1.0, hysteresis_db=1.0), meas_steps([0.0] * 7, neighbour))
    assert times(log, "triggered") == [0.0]
    assert times(log, "left") == [0.5]  # stays triggered through the band 0 <= Mn <= 2


def test_a3_leaving_condition_also_waits_the_time_to_trigger():
    neighbour = [4, 4, 4, 4, 0, 0, 4, 0, 0, 0, 0]
    log = run_trigger(A3(offset_db=3.0, time_to_trigger_s=0.2), meas_steps([0] * 11, neighbour))
    assert times(log, "triggered") == [pytest.approx(0.2)]
    # leaving holds 0.4-0.5 (lapses at 0.6), then from 0.7 on: left at 0.9
    assert times(log, "left") == [pytest.approx(0.9)]


def test_a3_cell_offsets_enter_both_sides_of_the_inequality():
    # Ocn = +2 dB for the neighbour, Ocp = -1 dB for the serving: Mn + 2 > Mp - 1 + Off(=4)
    steps = [(0.0, {"meas": np.array([[0.0, 1.0]]), "offset_db": np.array([-1.0, 2.0])})]
    assert times(run_trigger(A3(offset_db=4.0), steps), "triggered") == []  # 3 = 3: equality
    steps = [(0.0, {"meas": np.array([[0.0, 1.5]]), "offset_db": np.array([-1.0, 2.0])})]
    assert times(run_trigger(A3(offset_db=4.0), steps), "triggered") == [0.0]


def test_the_events_share_one_signal_per_epoch_and_a_replaced_epoch_its_own():
    ep = Epoch(t_s=0.0, serving=np.array([1]), meas=np.array([[2.0, 5.0]]),
               offset_db=np.array([1.0, -1.0]))  # fmt: skip
    mn, meas, mp, ms = ep.signal
    assert mn.tolist() == [[3.0, 4.0]] and mp.tolist() == [[4.0]] and ms.tolist() == [[5.0]]
    assert A3().rank(ep) is mn and A4().rank(ep) is mn  # computed once, read by both
    import dataclasses

    other = dataclasses.replace(ep, meas=np.array([[0.0, 1.0]]))
    assert A3().rank(other).tolist() == [[1.0, 0.0]]  # (not the first epoch's)


def test_a3_never_triggers_the_serving_cell_itself():
    log = run_trigger(A3(offset_db=-10.0), meas_steps([0.0] * 3, [0.0] * 3))
    assert [c for _, _, c in log] == [1, 1]  # entered + triggered of cell 1 only


def test_a3_unmeasurable_neighbour_never_enters_and_leaves_after_ttt():
    neighbour = [4.0, 4.0, 4.0, np.nan, np.nan, np.nan]
    log = run_trigger(A3(offset_db=3.0, time_to_trigger_s=0.1), meas_steps([0.0] * 6, neighbour))
    assert times(log, "triggered") == [pytest.approx(0.1)]
    assert times(log, "left") == [pytest.approx(0.4)]
    log = run_trigger(A3(offset_db=-50.0), meas_steps([0.0] * 2, [np.nan] * 2))
    assert log == []


# ----------------------------------------------------------------------------- A4 5.5.4.5


def test_a4_enters_above_threshold_plus_hysteresis_and_leaves_below_threshold_minus_it():
    # Thresh = -100 dBm, Hys = 1: enter Mn > -99 (-99.0 is the equality), leave Mn < -101
    neighbour = [-100.0, -99.0, -98.5, -101.0, -101.5]
    trig = A4(threshold_db=-100.0, hysteresis_db=1.0)
    log = run_trigger(trig, meas_steps([-50.0] * 5, neighbour))
    assert times(log, "triggered") == [0.2]
    assert times(log, "left") == [0.4]


def test_a4_ignores_the_serving_cell_quality():
    neighbour = [-90.0] * 2
    for serving in (-150.0, -40.0):
        log = run_trigger(A4(threshold_db=-100.0), meas_steps([serving] * 2, neighbour))
        assert times(log, "triggered") == [0.0]


def test_a4_lapse_restarts_time_to_trigger():
    neighbour = [-90, -90, -110, -90, -90, -90]
    log = run_trigger(A4(threshold_db=-100, time_to_trigger_s=0.2), meas_steps([0] * 6, neighbour))
    assert times(log, "lapsed") == [0.2]
    assert times(log, "triggered") == [pytest.approx(0.5)]


# ----------------------------------------------------------------------------- A5 5.5.4.6


def test_a5_needs_serving_below_threshold1_and_neighbour_above_threshold2():
    # Th1 = -100, Th2 = -95, Hys = 0.5: enter Mp < -100.5 and Mn > -94.5
    serving = [-99.0, -101.0, -100.5, -101.0]
    neighbour = [-90.0, -94.5, -90.0, -94.0]
    log = run_trigger(A5(-100.0, -95.0, 0.5), meas_steps(serving, neighbour))
    # 0.0: serving too good; 0.1: neighbour at its equality; 0.2: serving at its equality
    assert times(log, "triggered") == [pytest.approx(0.3)]


def test_a5_leaves_when_either_serving_recovers_or_neighbour_drops():
    th = dict(threshold1_db=-100.0, threshold2_db=-95.0, hysteresis_db=0.5)
    # serving recovers: Mp - Hys > Th1 -> Mp > -99.5 (equality -99.5 keeps it triggered)
    log = run_trigger(A5(**th), meas_steps([-105, -99.5, -99.0], [-90, -90, -90]))
    assert times(log, "triggered") == [0.0] and times(log, "left") == [0.2]
    # neighbour drops: Mn + Hys < Th2 -> Mn < -95.5 (equality -95.5 keeps it)
    log = run_trigger(A5(**th), meas_steps([-105, -105, -105], [-90, -95.5, -96.0]))
    assert times(log, "triggered") == [0.0] and times(log, "left") == [0.2]


def test_a5_offsets_apply_to_the_neighbour_only():
    # Ofn + Ocn = +3 dB lifts Mn over Thresh2; Mp is taken without offsets (an offset of
    # -5 dB on the serving cell would otherwise push it below Thresh1)
    offset = np.array([-5.0, 3.0])
    step = [(0.0, {"meas": np.array([[-98.0, -97.0]]), "offset_db": offset})]
    assert times(run_trigger(A5(-100.0, -95.0), step), "triggered") == []  # Mp = -98 > Th1
    step = [(0.0, {"meas": np.array([[-101.0, -97.0]]), "offset_db": offset})]
    assert times(run_trigger(A5(-100.0, -95.0), step), "triggered") == [0.0]  # -94 > -95


# ----------------------------------------------------------------------------- D1 5.5.4.15

V_M_S, L_M, H_M = 100.0, 10_000.0, 3_000.0  # UT speed; candidate reference at (L, H, 0)


def d1_steps(t_end_s, dt_s=0.5):
    """UT on the x axis at v t; serving reference at the origin, the candidate's at (L, H)."""
    ref = np.array([[0.0, 0.0, 0.0], [L_M, H_M, 0.0]])
    return [
        (t, {"ut_pos_m": np.array([[V_M_S * t, 0.0, 0.0]]), "ref_pos_m": ref})
        for t in epochs(int(t_end_s / dt_s) + 1, dt_s)
    ]


def first_epoch_after(t_s, dt_s=0.5):
    """The first epoch strictly after an analytic instant (conditions are strict)."""
    return (math.floor(t_s / dt_s + 1e-9) + 1) * dt_s


def test_d1_enters_and_leaves_at_the_closed_form_distances():
    th1, th2, hys = 4_000.0, 7_000.0, 500.0
    log = run_trigger(D1(th1, th2, hys), d1_steps(250.0))
    # D1-1: v t - Hys > Th1  ->  t > 45 s (binding); D1-2: Ml2 + Hys < Th2 -> t > 42.34 s.
    t_d1_2 = (L_M - math.sqrt((th2 - hys) ** 2 - H_M**2)) / V_M_S
    assert t_d1_2 < 45.0
    assert times(log, "triggered") == [45.5]  # 45.0 is the exact equality of D1-1
    # D1-4: Ml2 - Hys > Th2 after passing the candidate: t > (L + sqrt((Th2 + Hys)^2 - H^2)) / v
    t_leave = (L_M + math.sqrt((th2 + hys) ** 2 - H_M**2)) / V_M_S
    assert times(log, "left") == [first_epoch_after(t_leave)]


def test_d1_candidate_distance_binds_when_it_is_the_later_condition():
    th1, th2, hys = 1_000.0, 5_000.0, 300.0
    log = run_trigger(D1(th1, th2, hys), d1_steps(100.0))
    # D1-2: Ml2 + Hys < Th2, later than D1-1: Ml1 - Hys > Th1
    t_enter = (L_M - math.sqrt((th2 - hys) ** 2 - H_M**2)) / V_M_S
    assert t_enter > (th1 + hys) / V_M_S
    assert times(log, "triggered") == [first_epoch_after(t_enter)]


def test_d1_hysteresis_on_leaving_as_on_entering():
    # Entering Ml1 > Th1 + Hys, leaving Ml1 < Th1 - Hys: a UT that walks back leaves later.
    ref = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    xs = [1200.0, 1400.0, 1500.0, 1600.0, 1000.0, 800.0, 500.0, 400.0]
    steps = [
        (t, {"ut_pos_m": np.array([[x, 0.0, 0.0]]), "ref_pos_m": ref})
        for t, x in zip(epochs(len(xs)), xs, strict=True)
    ]
    log = run_trigger(D1(threshold1_m=1000.0, threshold2_m=1e6, hysteresis_m=500.0), steps)
    assert times(log, "triggered") == [0.3]  # 1500 is the equality 1500 - 500 = 1000
    assert times(log, "left") == [0.7]  # 500 + 500 = 1000 is the equality; 400 leaves


# ----------------------------------------------------------------------------- D2 5.5.4.15a


def test_d2_follows_the_moving_reference_locations():
    # UT at the origin; both references move along x at 7 km/s; the serving's starts at
    # the UT, the candidate's 300 km behind: Ml1 = v t, Ml2 = |d0 - v t|.
    v, d0, th1, th2 = 7_000.0, 300_000.0, 150_000.0, 120_000.0
    fixed = np.array([[0.0, 0.0, 0.0], [-d0, 0.0, 0.0]])
    steps = [
        (
            t,
            {
                "ut_pos_m": np.zeros((1, 3)),
                "moving_ref_pos_m": fixed + np.array([v * t, 0.0, 0.0]),
                "ref_pos_m": fixed,  # what D1 would read: must be ignored by D2
            },
        )
        for t in epochs(141, 0.5)
    ]
    log = run_trigger(D2(th1, th2, 0.0), steps)
    t_enter = max(th1 / v, (d0 - th2) / v)  # both Ml1 > Th1 and Ml2 < Th2
    t_leave = (d0 + th2) / v  # Ml2 > Th2 again once the candidate's reference passes
    assert times(log, "triggered") == [first_epoch_after(t_enter)]
    assert times(log, "left") == [first_epoch_after(t_leave)]
    assert run_trigger(D1(th1, th2, 0.0), steps) == []  # fixed references never qualify


# ----------------------------------------------------------------------------- T1 5.5.4.16


def test_t1_fires_after_threshold_and_leaves_after_the_duration():
    # serving cell ends service at 100 s, lead 10 s -> Thresh1 = 90 s; duration 5 s
    end = np.array([[100.0, 400.0]])
    steps = [(float(t), {"service_end_s": end, "meas": np.zeros((1, 2))}) for t in range(85, 100)]
    log = run_trigger(T1(duration_s=5.0, lead_s=10.0), steps)
    assert times(log, "triggered") == [91.0]  # Mt > Thresh1: 90.0 is the equality
    assert times(log, "left") == [96.0]  # Mt > Thresh1 + Duration: 95.0 still inside


def test_t1_has_no_time_to_trigger():
    assert T1().time_to_trigger_s == 0.0


# ----------------------------------------------------------------------------- extensions


def test_elevation_trigger_serving_below_and_candidate_above_with_hysteresis():
    deg = math.radians
    # serving sinks 1 deg per epoch from 40, candidate rises 1 deg per epoch from 20
    steps = [
        (t, {"elevation_rad": np.array([[deg(40.0 - k), deg(20.0 + k)]])})
        for k, t in enumerate(epochs(20))
    ]
    trig = Elevation(deg(30.0), deg(25.0), hysteresis_rad=deg(2.0))
    log = run_trigger(trig, steps)
    # serving + 2 < 30 -> 40 - k < 28 -> k >= 13 (k = 12 is the equality); candidate k > 7
    assert times(log, "triggered") == [pytest.approx(1.3)]


def test_time_to_exit_enters_when_serving_runs_out_sooner_than_the_threshold():
    end = np.array([[100.0, 300.0]])
    steps = [(float(t), {"service_end_s": end}) for t in range(60, 80)]
    log = run_trigger(TimeToExit(serving_below_s=30.0, hysteresis_s=5.0), steps)
    assert times(log, "triggered") == [76.0]  # 100 - t + 5 < 30: t = 75 is the equality
    log = run_trigger(TimeToExit(offset_s=250.0), steps)
    assert log == []  # 300 - t > 100 - t + 250 never holds


# ----------------------------------------------------------------------------- state, vectorized


@pytest.mark.parametrize("share", [1.0, 0.06])  # every pair applicable; a few (CHO's)
def test_advance_is_independent_per_pair_and_matches_a_scalar_reference(share):
    """The vectorized bookkeeping against 5.5.4.1 written for one pair, with every pair
    applicable and with a few (below ``SPARSE_SHARE``: the rule then runs on those alone),
    the applicable set changing every 10 epochs: the report, the runs and the list."""
    from leolink.sim.handover import triggers

    rng = np.random.default_rng(3)
    n_ut, n_cand, n_t, ttt = 20, 12, 60, 0.3
    enter = rng.random((n_t, n_ut, n_cand)) < 0.6
    leave = ~enter & (rng.random((n_t, n_ut, n_cand)) < 0.5)
    applicable = rng.random((n_t // 10, n_ut, n_cand)) < share
    assert (applicable.mean(axis=(1, 2)) < triggers.SPARSE_SHARE).all() == (share < 1.0)
    state = TriggerState.initial(n_ut, n_cand)
    got = []
    for k, t in enumerate(epochs(n_t)):
        state, rep = advance(state, t, enter[k], leave[k], ttt, applicable[k // 10])
        got.append((rep.triggered.copy(), rep.left.copy(), state.since_s, state.triggered))
    n_fired = 0
    for i in range(n_ut):  # scalar re-implementation of 5.5.4.1, one pair at a time
        for j in range(n_cand):
            trig, since = False, None
            for k, t in enumerate(epochs(n_t)):
                if not applicable[k // 10, i, j]:  # no run, not in the list
                    trig, since = False, None
                    assert not got[k][0][i, j] and not got[k][1][i, j]
                    assert np.isnan(got[k][2][i, j]) and not got[k][3][i, j]
                    continue
                cond = leave[k, i, j] if trig else enter[k, i, j]
                since = (t if since is None else since) if cond else None
                fired = cond and t - since >= ttt - 1e-9
                assert got[k][0][i, j] == (fired and not trig)
                assert got[k][1][i, j] == (fired and trig)
                if fired:
                    trig, since = not trig, None
                    n_fired += 1
                assert got[k][3][i, j] == trig
                assert np.isnan(got[k][2][i, j]) if since is None else got[k][2][i, j] == since
    assert n_fired > 20


def test_reset_clears_only_the_given_uts():
    state = TriggerState(np.zeros((3, 2)), np.ones((3, 2)))
    out = state.reset(np.array([False, True, False]))
    assert np.isnan(out.since_s[1]).all() and not out.triggered[1].any()
    assert out.triggered[[0, 2]].all()


def test_missing_epoch_field_names_the_field():
    with pytest.raises(ValueError, match="D1 needs Epoch.ref_pos_m"):
        D1(1.0, 2.0).conditions(Epoch(0.0, np.array([0]), ut_pos_m=np.zeros((1, 3))))


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: A3(hysteresis_db=-1.0), "a3.hysteresis_db = -1.0"),
        (lambda: A3(time_to_trigger_s=-0.1), "time_to_trigger_s"),
        (lambda: A4(threshold_db=math.nan), "a4.threshold_db = nan"),
        (lambda: D1(threshold1_m=-5.0), "d1.threshold1_m"),
        (lambda: T1(duration_s=-1.0), "t1.duration_s"),
        (lambda: TimeToExit(serving_below_s=0.0), "serving_below_s"),
    ],
)
def test_invalid_parameters_are_refused_with_the_field_name(make, match):
    with pytest.raises(ConfigError, match=match):
        make()
