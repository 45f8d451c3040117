"""Trigger events of TS 38.331: the clauses that mutation testing found unchecked (issue 45,
docs/testing.md): event A2 (5.5.4.3), the leaving conditions of A3 and A5 when one side
can no longer be measured, the elevation and time-to-exit events at each boundary, and
the refusal messages of every parameter.

Expected instants are worked out by hand from the clause's inequalities (measurements are
multiples of 0.5 dB so that equalities are exact); the accounting helpers are those of
``tests/test_triggers.py``.
"""

import math

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.sim.handover.triggers import A2, A3, A4, A5, Epoch, TriggerState, advance
from leolink.sim.handover.triggers_ntn import D1, D2, T1, Elevation, TimeToExit
from test_triggers import meas_steps, run_trigger, times

NAN = math.nan


def a2_log(trigger, serving_db):
    """A2 is a serving-cell event: one condition column per UT (candidate 0)."""
    state, log = TriggerState.initial(1, 1), []
    for k, ms in enumerate(serving_db):
        t = round(k * 0.1, 9)
        ep = Epoch(t_s=t, serving=np.array([1]), meas=np.array([[-80.0, ms]]))
        enter, leave = trigger.conditions(ep)
        assert enter.shape == leave.shape == (1, 1)
        was = state.triggered.copy()
        state, _ = advance(state, t, enter, leave, trigger.time_to_trigger_s, np.ones((1, 1), bool))
        if state.triggered[0, 0] != was[0, 0]:
            log.append(("triggered" if state.triggered[0, 0] else "left", t))
    return log


def test_a2_enters_below_threshold_minus_hysteresis_and_leaves_above_threshold_plus_it():
    """A2-1 ``Ms + Hys < Thresh``, A2-2 ``Ms - Hys > Thresh``; Thresh = -100, Hys = 1.5: it
    enters below -101.5 (the equality -101.5 does not), leaves above -98.5 (the equality
    keeps it); between the two the state holds. The neighbour (-80 dB) plays no part."""
    a2 = A2(threshold_db=-100.0, hysteresis_db=1.5)
    serving = [-99.0, -101.0, -101.5, -102.0, -100.0, -98.5, -98.0, -101.0, -102.0]
    assert a2_log(a2, serving) == [("triggered", 0.3), ("left", 0.6), ("triggered", 0.8)]


def test_a2_time_to_trigger_and_no_serving_measurement_leaves():
    """TTT = 0.2 s: the run from 0.1 s triggers at 0.3 s; the serving cell becomes
    unmeasurable (NaN) at 0.5 s: the leaving condition holds and the event leaves 0.2 s
    later, at 0.7 s."""
    a2 = A2(threshold_db=-100.0, hysteresis_db=0.0, time_to_trigger_s=0.2)
    serving = [-99.0, -101.0, -101.0, -101.0, -101.0, NAN, NAN, NAN, NAN]
    assert a2_log(a2, serving) == [("triggered", 0.3), ("left", 0.7)]


def test_a2_reads_the_serving_cell_only_and_names_itself_without_measurements():
    a2 = A2(threshold_db=-100.0)
    ep = Epoch(t_s=0.0, serving=np.array([0, 1]), meas=np.array([[-120.0, -90.0]] * 2))
    enter, _ = a2.conditions(ep)
    assert enter[:, 0].tolist() == [True, False]  # UT 0 is served by the -120 dB cell
    with pytest.raises(ValueError, match="^A2 needs Epoch.meas; the controller"):
        a2.conditions(Epoch(t_s=0.0, serving=np.array([0])))


def test_a3_leaves_when_the_serving_cell_can_no_longer_be_measured():
    """A triggered neighbour leaves after the TTT once ``Mp`` is NaN (the serving cell is
    unmeasurable), as it does when ``Mn`` is NaN (tests/test_triggers.py)."""
    a3 = A3(offset_db=1.0, hysteresis_db=0.5, time_to_trigger_s=0.1)
    log = run_trigger(a3, meas_steps([-100.0, -100.0, NAN, NAN, NAN], [-95.0] * 5))
    assert times(log, "triggered") == [0.1] and times(log, "left") == [0.3]


@pytest.mark.parametrize("which", ["serving", "neighbour"])
def test_a5_leaves_when_either_side_can_no_longer_be_measured(which):
    """Th1 = -100, Th2 = -95: triggered at 0.0 s; from 0.1 s on ``Mp`` (or ``Mn``) is NaN,
    so A5-3 or A5-4 cannot be evaluated and the cell leaves at 0.1 s (TTT 0)."""
    serving, neighbour = [-105.0] * 3, [-90.0] * 3
    (serving if which == "serving" else neighbour)[1:] = [NAN, NAN]
    log = run_trigger(A5(-100.0, -95.0), meas_steps(serving, neighbour))
    assert times(log, "triggered") == [0.0] and times(log, "left") == [0.1]


FINITE = "is not allowed; use a finite number"


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: A3(hysteresis_db=-0.5),
         "controller.a3.hysteresis_db = -0.5 is not allowed; use a value >= 0.0 "
         "(hysteresis [dB])"),
        (lambda: A3(offset_db=math.inf), f"controller.a3.offset_db = inf {FINITE}"),
        (lambda: A3(time_to_trigger_s=-0.1),
         "controller.time_to_trigger_s = -0.1 is not allowed; use a value >= 0.0 "
         "(time-to-trigger [s])"),
        (lambda: A3(time_to_trigger_s=math.nan), f"controller.time_to_trigger_s = nan {FINITE}"),
        (lambda: A2(threshold_db=math.nan), f"controller.a2a4.a2_threshold_db = nan {FINITE}"),
        (lambda: A2(hysteresis_db=-1.0),
         "controller.a2a4.hysteresis_db = -1.0 is not allowed; use a value >= 0.0 "
         "(hysteresis [dB])"),
        (lambda: A2(time_to_trigger_s=-1.0), "controller.time_to_trigger_s = -1.0"),
        (lambda: A4(threshold_db=-math.inf), f"controller.a4.threshold_db = -inf {FINITE}"),
        (lambda: A4(hysteresis_db=-1.0),
         "controller.a4.hysteresis_db = -1.0 is not allowed; use a value >= 0.0 "
         "(hysteresis [dB])"),
        (lambda: A4(time_to_trigger_s=-1.0), "controller.time_to_trigger_s = -1.0"),
        (lambda: A5(threshold1_db=math.nan), f"controller.a5.threshold1_db = nan {FINITE}"),
        (lambda: A5(threshold2_db=math.inf), f"controller.a5.threshold2_db = inf {FINITE}"),
        (lambda: A5(hysteresis_db=-2.0),
         "controller.a5.hysteresis_db = -2.0 is not allowed; use a value >= 0.0 "
         "(hysteresis [dB])"),
        (lambda: A5(time_to_trigger_s=-1.0), "controller.time_to_trigger_s = -1.0"),
    ],
)  # fmt: skip
def test_each_refusal_names_the_key_the_value_and_what_is_allowed(make, message):
    with pytest.raises(ConfigError) as err:
        make()
    assert str(err.value).startswith(message)


def test_no_candidate_at_all_and_a_single_candidate():
    """An empty candidate axis (no UT has a satellite): the serving quantity is NaN per
    UT, so A2 leaves and A3 has nothing to compare; with one candidate, the serving
    value is that candidate's."""
    empty = Epoch(t_s=0.0, serving=np.array([-1, -1]), meas=np.zeros((2, 0)))
    np.testing.assert_array_equal(empty.at_serving(empty.meas), np.full((2, 1), np.nan))
    enter, leave = A2(threshold_db=-100.0).conditions(empty)
    assert enter.tolist() == [[False], [False]] and leave.tolist() == [[True], [True]]
    assert A3().conditions(empty)[0].shape == (2, 0)
    one = Epoch(t_s=0.0, serving=np.array([0, -1]), meas=np.array([[-101.0], [-120.0]]))
    assert one.at_serving(one.meas)[:, 0].tolist()[0] == -101.0
    enter, _ = A2(threshold_db=-100.0).conditions(one)
    assert enter.tolist() == [[True], [False]]  # UT 1 has no serving cell


@pytest.mark.parametrize("trigger", [A3(), A4(), A5()], ids=["A3", "A4", "A5"])
def test_a_measurement_event_without_measurements_names_itself(trigger):
    name = type(trigger).__name__
    with pytest.raises(ValueError, match=f"^{name} needs Epoch.meas; the controller did not"):
        trigger.conditions(Epoch(t_s=0.0, serving=np.array([0])))


# --- The NTN and leolink events (triggers_ntn.py): each inequality at its boundary ------


def _cand(trigger, field, serving_value, candidate_value, t_s=0.0):
    """(enter, leave) of candidate 1 for one UT served by candidate 0."""
    values = np.array([[serving_value, candidate_value]])
    enter, leave = trigger.conditions(Epoch(t_s=t_s, serving=np.array([0]), **{field: values}))
    return bool(enter[0, 1]), bool(leave[0, 1])


@pytest.mark.parametrize(
    ("el_p", "el_n", "want"),
    [
        (0.375, 0.5, (False, False)),  # El_p + Hys = Thresh1: not below
        (0.25, 0.375, (False, False)),  # El_n - Hys = Thresh2: not above
        (0.25, 0.5, (True, False)),
        (0.625, 0.5, (False, False)),  # El_p - Hys = Thresh1: not leaving
        (0.75, 0.5, (False, True)),
        (0.25, 0.125, (False, False)),  # El_n + Hys = Thresh2: not leaving
        (0.25, 0.0625, (False, True)),
        (NAN, 0.5, (False, True)),  # no serving elevation
        (0.25, NAN, (False, True)),
    ],
)
def test_elevation_entering_and_leaving_at_each_boundary(el_p, el_n, want):
    """Thresh1 = 0.5 rad (serving below), Thresh2 = 0.25 rad (candidate above), Hys =
    0.125 rad: enters for El_p < 0.375 and El_n > 0.375, leaves for El_p > 0.625 or
    El_n < 0.125 (values exact in binary)."""
    trigger = Elevation(serving_below_rad=0.5, candidate_above_rad=0.25, hysteresis_rad=0.125)
    assert _cand(trigger, "elevation_rad", el_p, el_n) == want


@pytest.mark.parametrize(
    ("r_p", "r_n", "want"),
    [
        (40.0, 52.0, (False, False)),  # R_n - Hys = R_p + Off: not better
        (40.0, 53.0, (True, False)),
        (40.0, 48.0, (False, False)),  # R_n + Hys = R_p + Off: not leaving
        (40.0, 47.0, (False, True)),
        (48.0, 70.0, (False, False)),  # R_p + Hys = below: not running out
        (52.0, 70.0, (False, False)),  # R_p - Hys = below: not leaving
        (53.0, 70.0, (False, True)),
        (NAN, 70.0, (False, True)),  # not served now
        (40.0, NAN, (False, True)),
    ],
)
def test_time_to_exit_entering_and_leaving_at_each_boundary(r_p, r_n, want):
    """Off = 10 s, Hys = 2 s, serving_below = 50 s, at t = 100 s (R = end - t): enters for
    R_n > R_p + 12 and R_p < 48, leaves for R_n < R_p + 8 or R_p > 52."""
    trigger = TimeToExit(offset_s=10.0, hysteresis_s=2.0, serving_below_s=50.0)
    assert _cand(trigger, "service_end_s", 100.0 + r_p, 100.0 + r_n, t_s=100.0) == want


def test_service_ends_given_per_candidate_for_every_ut():
    """``service_end_s`` of shape (n_cand,) is every UT's: the remaining times and T1's
    window are per UT from it."""
    end = np.array([30.0, 90.0])
    ep = Epoch(t_s=10.0, serving=np.array([0, 1]), service_end_s=end)
    np.testing.assert_array_equal(TimeToExit().rank(ep), [[20.0, 80.0], [20.0, 80.0]])
    enter, leave = TimeToExit().conditions(ep)
    assert enter.tolist() == [[False, True], [False, False]] and not leave[0, 1]
    ep = Epoch(t_s=29.5, serving=np.array([0, 1]), service_end_s=end, meas=np.zeros((2, 2)))
    enter, _ = T1(duration_s=1.0, lead_s=1.0).conditions(ep)  # window (29, 30] for UT 0
    assert enter.tolist() == [[True, True], [False, False]]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: D1(threshold1_m=-1.0),
         "controller.d1.threshold1_m = -1.0 is not allowed; use a value >= 0.0 "
         "(distanceThreshFromReference1)"),
        (lambda: D1(threshold2_m=-1.0),
         "controller.d1.threshold2_m = -1.0 is not allowed; use a value >= 0.0 "
         "(distanceThreshFromReference2)"),
        (lambda: D2(hysteresis_m=-1.0),
         "controller.d2.hysteresis_m = -1.0 is not allowed; use a value >= 0.0 "
         "(hysteresisLocation [m])"),
        (lambda: D1(time_to_trigger_s=-1.0), "controller.time_to_trigger_s = -1.0"),
        (lambda: T1(duration_s=-1.0),
         "controller.t1.duration_s = -1.0 is not allowed; use a value >= 0.0 (duration [s])"),
        (lambda: T1(lead_s=math.nan), f"controller.t1.lead_s = nan {FINITE}"),
        (lambda: Elevation(serving_below_rad=-2.0),
         "controller.elevation.serving_below_rad = -2.0 is not allowed; use a value >= "
         f"{-math.pi / 2} ([rad])"),
        (lambda: Elevation(candidate_above_rad=-2.0),
         "controller.elevation.candidate_above_rad = -2.0 is not allowed; use a value >= "
         f"{-math.pi / 2} ([rad])"),
        (lambda: Elevation(hysteresis_rad=-0.1),
         "controller.elevation.hysteresis_rad = -0.1 is not allowed; use a value >= 0.0 "
         "(hysteresis [rad])"),
        (lambda: Elevation(time_to_trigger_s=-1.0), "controller.time_to_trigger_s = -1.0"),
        (lambda: TimeToExit(offset_s=math.inf), f"controller.time_to_exit.offset_s = inf {FINITE}"),
        (lambda: TimeToExit(hysteresis_s=-1.0),
         "controller.time_to_exit.hysteresis_s = -1.0 is not allowed; use a value >= 0.0 "
         "(hysteresis [s])"),
        (lambda: TimeToExit(time_to_trigger_s=-1.0), "controller.time_to_trigger_s = -1.0"),
        (lambda: TimeToExit(serving_below_s=0.0),
         "controller.time_to_exit.serving_below_s = 0.0 is not allowed; use a value > 0 [s] "
         "(or inf)"),
    ],
)  # fmt: skip
def test_each_ntn_refusal_names_the_key_the_value_and_what_is_allowed(make, message):
    with pytest.raises(ConfigError) as err:
        make()
    assert str(err.value).startswith(message)


@pytest.mark.parametrize(
    ("trigger", "epoch_fields"),
    [
        (T1(), {"service_end_s": np.zeros((1, 2))}),  # rank reads meas
        (Elevation(), {}),
        (TimeToExit(), {}),
        (D1(), {"ref_pos_m": np.zeros((2, 3))}),
        (D2(), {"moving_ref_pos_m": np.zeros((2, 3))}),
    ],
    ids=["T1", "Elevation", "TimeToExit", "D1", "D2"],
)
def test_an_ntn_event_without_its_inputs_names_itself(trigger, epoch_fields):
    name = type(trigger).__name__
    ep = Epoch(t_s=0.0, serving=np.array([0]), **epoch_fields)
    with pytest.raises(ValueError, match=f"^{name} needs Epoch\\."):
        trigger.rank(ep)
    if name != "T1":
        with pytest.raises(ValueError, match=f"^{name} needs Epoch\\."):
            trigger.conditions(ep)


@pytest.mark.parametrize(
    ("ml1", "ml2", "want"),
    [
        (2000.0, 400.0, (False, False)),  # Ml2 + Hys = Thresh2: not inside
        (2000.0, 300.0, (True, False)),
        (NAN, 300.0, (False, True)),  # the serving reference unknown
        (2000.0, NAN, (False, True)),  # the candidate's unknown
    ],
)
def test_d1_entering_at_the_candidate_boundary_and_leaving_without_a_reference(ml1, ml2, want):
    """UT at the origin, serving reference at (Ml1, 0, 0), the candidate's at (0, Ml2, 0);
    Thresh1 = 1000 m, Thresh2 = 500 m, Hys = 100 m: enters for Ml1 > 1100 and Ml2 < 400."""
    ref = np.array([[ml1, 0.0, 0.0], [0.0, ml2, 0.0]])
    ep = Epoch(t_s=0.0, serving=np.array([0]), ut_pos_m=np.zeros((1, 3)), ref_pos_m=ref)
    enter, leave = D1(1000.0, 500.0, 100.0).conditions(ep)
    assert (bool(enter[0, 1]), bool(leave[0, 1])) == want


def test_d1_reference_locations_per_ut():
    """References of shape (n_ut, n_cand, 3): each UT measures its own. UT 0 at the origin
    sees the candidate 300 m away, UT 1 at (0, 0, 1000) sees its own candidate reference
    (0, 0, 1000 + 2000) 2000 m away; both serving references are 3000 m away."""
    ut = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1000.0]])
    ref = np.array([[[3000.0, 0.0, 0.0], [0.0, 300.0, 0.0]],
                    [[0.0, 3000.0, 1000.0], [0.0, 0.0, 3000.0]]])  # fmt: skip
    ep = Epoch(t_s=0.0, serving=np.array([0, 0]), ut_pos_m=ut, ref_pos_m=ref)
    np.testing.assert_allclose(D1().rank(ep), -np.array([[3000.0, 300.0], [3000.0, 2000.0]]))
    enter, _ = D1(1000.0, 500.0).conditions(ep)
    assert enter[:, 1].tolist() == [True, False]


def test_t1_conditions_name_t1_and_any_positive_serving_below_is_allowed():
    with pytest.raises(ValueError, match="^T1 needs Epoch.service_end_s"):
        T1().conditions(Epoch(t_s=0.0, serving=np.array([0]), meas=np.zeros((1, 2))))
    assert TimeToExit(serving_below_s=0.5).serving_below_s == 0.5
