"""Contracts of leolink.sim.handover.controller, each checked by a second computation.

The main check drives :func:`step` over random candidate tables with the policy's choice
given (``target``), and compares every output with a reference written here from the
documented rules (``step``'s docstring, the module docstring), one UT and one epoch at a
time with plain Python scalars: no array code of the module is reused. The other tests
are hand-built sequences whose handover times, interruptions and dwells are known in
closed form. Written from the mutants of ``sim/controller`` that survived
``tests/test_controller.py`` and the run tests (docs/testing_log.md, fifth pass).
"""

import math

import numpy as np
import pytest

from leolink.sim.candidates.table import Candidates
from leolink.sim.handover.controller import (
    SERVICE_HANDOVER,
    SERVICE_OUTAGE,
    SERVICE_SERVED,
    ControllerState,
    close_dwells,
    interruption_s,
    resumed_events,
    service_codes,
    step,
)
from leolink.sim.handover.policies import Hysteresis, MaxSnr

TOL_S = 1e-9  # the documented epoch-time tolerance (1 ns)

# controller._rules runs compiled (numba) and as numpy code: both must pass.
pytestmark = pytest.mark.usefixtures("compiled_and_numpy")


class Given:
    """A policy whose choice is passed to step() as ``target`` (never asked)."""

    lookahead_s = 0.0

    def __init__(self, time_to_trigger_s):
        self.time_to_trigger_s = time_to_trigger_s

    def choose(self, *args):  # pragma: no cover - step() must not call it
        raise AssertionError("step() asked the policy although a target was given")


class RefUT:
    """One UT's controller, scalar, from the documented rules."""

    def __init__(self):
        self.serving, self.pending, self.since = -1, -1, math.nan
        self.until, self.start, self.outage, self.censored = -math.inf, math.nan, False, False
        self.last_db = math.nan

    def step(self, t, snr, target, min_db, ttt_s, ho_s, n_beam):
        """snr: {cell: SNR dB} of this epoch. Returns (event or None, closed dwell or None)."""
        usable = {c for c, v in snr.items() if v == v and v >= min_db}
        old, event, dwell = self.serving, None, None
        cur = snr.get(old, math.nan) if old >= 0 else math.nan
        before = cur if cur == cur else self.last_db
        interrupted = old >= 0 and t < self.until - TOL_S
        kind = None
        if not usable:
            self.pending, self.since = -1, math.nan
            if not self.outage:
                kind = "outage_start"
                if old >= 0:
                    dwell = (old, self.start, t, self.censored)
                self.serving, self.outage, self.until, self.start = -1, True, -math.inf, math.nan
        elif self.outage:
            kind, self.outage = "outage_end", False
            self.serving, self.start, self.censored = target, t, False
            self.pending, self.since = -1, math.nan
        elif old < 0:  # the first assignment: no event
            self.serving, self.start, self.censored = target, t, True
        elif not interrupted and target != old:
            fire = old not in usable  # the serving link is gone: no time-to-trigger
            if not fire:
                if self.pending != target:
                    self.pending, self.since = target, t
                fire = t - self.since >= ttt_s - TOL_S
            if fire:
                kind = "beam_handover" if target // n_beam == old // n_beam else "sat_handover"
                dwell = (old, self.start, t, self.censored)
                self.serving, self.start, self.censored = target, t, False
                self.until, self.pending, self.since = t + ho_s, -1, math.nan
        else:
            self.pending, self.since = -1, math.nan
        new = self.serving
        after = snr.get(new, math.nan) if new >= 0 else math.nan
        if new < 0:
            self.last_db = math.nan
        elif after == after:
            self.last_db = after
        elif new != old:
            self.last_db = math.nan
        else:
            self.last_db = before
        if kind is not None:
            event = (kind, old, new, before if old >= 0 else math.nan, after)
        return event, dwell

    def service(self, t):
        if self.outage or self.serving < 0:
            return SERVICE_OUTAGE
        return SERVICE_HANDOVER if t < self.until - TOL_S else SERVICE_SERVED


def _scenario(seed, n_ut=24, n_epoch=60, n_cell=8):
    """Random-walk SNR per (epoch, UT, cell) with gaps (NaN) and stretches of no link."""
    rng = np.random.default_rng(seed)
    snr = 6.0 + np.cumsum(rng.normal(0.0, 2.0, (n_epoch, n_ut, n_cell)), axis=0)
    snr[rng.random(snr.shape) < 0.15] = np.nan
    for u in range(0, n_ut, 5):  # some UTs lose every link for a while
        k0 = int(rng.integers(0, n_epoch - 8))
        snr[k0 : k0 + int(rng.integers(1, 8)), u] = np.nan
    snr[0, 3] = np.nan  # one UT in outage at the run start
    return rng, snr


def _table(rng, row_snr):
    """A sparse Candidates table of one epoch: the listed cells in a random slot order,
    with an unused slot (-1) and a listed cell without link (NaN) here and there."""
    n_ut, n_cell = row_snr.shape
    n_slot = n_cell + 1
    cell = np.full((n_ut, n_slot), -1, np.int64)
    val = np.full((n_ut, n_slot), np.nan)
    listed = []
    for u in range(n_ut):
        cells = [c for c in range(n_cell) if row_snr[u, c] == row_snr[u, c] or rng.random() < 0.3]
        order = rng.permutation(len(cells))
        for s, j in enumerate(order):
            cell[u, s], val[u, s] = cells[j], row_snr[u, cells[j]]
        listed.append({cells[j]: row_snr[u, cells[j]] for j in order})
    return Candidates(cell, val), listed


def _choose(rng, ref, snr, min_db):
    """The policy's choice: often the serving cell, often the last target, else random."""
    usable = [c for c, v in snr.items() if v == v and v >= min_db]
    if not usable:
        return -1
    for keep in (ref.serving, ref.pending):
        if keep in usable and rng.random() < 0.45:
            return keep
    return int(rng.choice(usable))


@pytest.mark.parametrize(
    ("seed", "ttt_s", "ho_s", "n_beam"),
    [(0, 0.3, 0.25, 3), (1, 0.0, 0.0, 2), (2, 0.2, 0.35, 4), (3, 0.5, 0.1, 1)],
)
def test_step_equals_a_scalar_reference_on_random_tables(seed, ttt_s, ho_s, n_beam):
    """Events, dwells, service codes, serving cells and the state, epoch by epoch."""
    dt_s, min_db = 0.1, 2.0
    rng, snr = _scenario(seed)
    n_epoch, n_ut, _ = snr.shape
    refs = [RefUT() for _ in range(n_ut)]
    state, t_s, policy = ControllerState.initial(n_ut), 0.0, Given(ttt_s)
    for k in range(n_epoch):
        table, listed = _table(rng, snr[k])
        target = np.array([_choose(rng, refs[u], listed[u], min_db) for u in range(n_ut)])
        res = step(t_s, table, state, policy, min_db, ho_s, n_beam, target=target)
        want = [refs[u].step(t_s, listed[u], int(target[u]), min_db, ttt_s, ho_s, n_beam)
                for u in range(n_ut)]  # fmt: skip
        ev = [(u, e) for u, (e, _) in enumerate(want) if e is not None]
        assert res.events["ut_id"].tolist() == [u for u, _ in ev]
        assert res.events["kind"].tolist() == [e[0] for _, e in ev]
        assert res.events["time_s"].tolist() == [t_s] * len(ev)
        for col, i in (("from", 1), ("to", 2)):
            cells = [e[i] for _, e in ev]
            assert res.events[f"{col}_sat"].tolist() == [
                c // n_beam if c >= 0 else -1 for c in cells
            ]
            assert res.events[f"{col}_beam"].tolist() == [
                c % n_beam if c >= 0 else -1 for c in cells
            ]
        for col, i in (("snr_before_db", 3), ("snr_after_db", 4)):
            assert res.events[col].dtype == np.float64
            np.testing.assert_array_equal(res.events[col], [e[i] for _, e in ev])
        dw = [(u, d) for u, (_, d) in enumerate(want) if d is not None]
        assert res.dwells["ut_id"].tolist() == [u for u, _ in dw]
        assert res.dwells["sat_id"].tolist() == [d[0] // n_beam for _, d in dw]
        assert res.dwells["beam_id"].tolist() == [d[0] % n_beam for _, d in dw]
        np.testing.assert_array_equal(res.dwells["start_s"], [d[1] for _, d in dw])
        assert res.dwells["end_s"].tolist() == [t_s] * len(dw)
        assert res.dwells["censored_start"].tolist() == [d[3] for _, d in dw]
        assert not res.dwells["censored_end"].any()
        serving = [r.serving for r in refs]
        assert res.state.serving.tolist() == serving
        assert res.sat_id.tolist() == [c // n_beam if c >= 0 else -1 for c in serving]
        assert res.beam_id.tolist() == [c % n_beam if c >= 0 else -1 for c in serving]
        assert res.service.tolist() == [r.service(t_s) for r in refs]
        assert res.state.pending.tolist() == [r.pending for r in refs]
        np.testing.assert_array_equal(res.state.pending_since_s, [r.since for r in refs])
        np.testing.assert_array_equal(res.state.serving_since_s, [r.start for r in refs])
        assert res.state.in_outage.tolist() == [r.outage for r in refs]
        np.testing.assert_array_equal(res.state.serving_snr_db, [r.last_db for r in refs])
        served = res.state.serving >= 0
        until = np.array([r.until for r in refs])
        np.testing.assert_array_equal(res.state.interrupted_until_s[served], until[served])
        for name in ("serving", "pending"):
            assert getattr(res.state, name).dtype == np.int64
        for name in ("pending_since_s", "interrupted_until_s", "serving_since_s"):
            assert getattr(res.state, name).dtype == np.float64
        for name in ("in_outage", "dwell_censored_start"):
            assert getattr(res.state, name).dtype == np.bool_
        assert res.service.dtype == np.int8 and res.state.serving_snr_db.dtype == np.float64
        state, t_s = res.state, t_s + dt_s
    tail = close_dwells(state, t_s)
    open_ = [u for u in range(n_ut) if refs[u].serving >= 0]
    assert tail["ut_id"].tolist() == open_
    assert tail["sat_id"].tolist() == [refs[u].serving // n_beam for u in open_]
    assert tail["beam_id"].tolist() == [refs[u].serving % n_beam for u in open_]
    assert tail["censored_start"].tolist() == [refs[u].censored for u in open_]
    assert tail["censored_end"].all() and (tail["end_s"] == t_s).all()
    np.testing.assert_array_equal(tail["start_s"], [refs[u].start for u in open_])


def _state(serving, until, in_outage=None, n_beam=3):
    n = len(serving)
    s = ControllerState.initial(n)
    s.serving[:] = serving
    s.interrupted_until_s[:] = until
    if in_outage is not None:
        s.in_outage[:] = in_outage
    s.n_beam = n_beam
    return s


def test_interruption_and_resume_times_of_a_hand_built_state():
    """Epoch [0.3, 0.4): handovers ending at 0.37, 0.33, 0.37, at the epoch end (0.4),
    at its start (0.3), later (0.45); a UT in outage and an unserved one."""
    until = [0.37, 0.33, 0.37, 0.4, 0.3, 0.45, 0.35, 0.35]
    serving = [1, 4, 0, 8, 2, 5, 7, -1]
    state = _state(serving, until, in_outage=[False] * 6 + [True, False])
    t_s, epoch_s = 0.1 + 0.1 + 0.1, 0.1  # 0.30000000000000004, as the epochs accumulate
    got = interruption_s(t_s, epoch_s, state)
    np.testing.assert_allclose(got, [0.07, 0.03, 0.07, 0.1, 0, 0.1, 0, 0], rtol=0, atol=1e-12)
    assert got[[4, 6, 7]].tolist() == [0.0, 0.0, 0.0]  # exactly: nothing to remove
    assert service_codes(t_s, state).tolist() == [SERVICE_HANDOVER] * 4 + [
        SERVICE_SERVED,
        SERVICE_HANDOVER,
        SERVICE_OUTAGE,
        SERVICE_OUTAGE,
    ]
    snr = np.arange(8 * 9, dtype=float).reshape(8, 9)  # cell j of UT i: 9 i + j dB
    ev = resumed_events(t_s, epoch_s, state, snr)
    assert ev["ut_id"].tolist() == [1, 0, 2, 3]  # by time, then UT
    np.testing.assert_allclose(ev["time_s"], [0.33, 0.37, 0.37, 0.4], rtol=0, atol=1e-15)
    assert ev["kind"].tolist() == ["service_resumed"] * 4
    assert ev["to_sat"].tolist() == [1, 0, 0, 2] and ev["to_beam"].tolist() == [1, 1, 0, 2]
    assert ev["from_sat"].tolist() == [-1] * 4 and ev["from_beam"].tolist() == [-1] * 4
    assert np.isnan(ev["snr_before_db"]).all()
    assert ev["snr_after_db"].tolist() == [13.0, 1.0, 18.0, 35.0]
    # the same through a sparse table: the serving cell's value wherever its slot is
    cells = np.tile([7, 4, 1, 0, 8, 2, 5, 3, 6], (8, 1))
    table = Candidates(cells, -cells.astype(float))
    ev = resumed_events(t_s, epoch_s, state, table)
    assert ev["snr_after_db"].tolist() == [-4.0, -1.0, -0.0, -8.0]
    for col in ("from_sat", "to_sat", "from_beam", "to_beam", "ut_id"):
        assert ev[col].dtype == np.int64


def test_time_to_trigger_waits_for_the_end_of_the_handover_execution():
    """dt 1 s, time-to-trigger 2 s, execution 3 s. Cell 1 is asked for from t = 1 s: the
    handover at t = 3 s; cell 2 is asked for from t = 4 s, during the execution (until
    6 s): its clock starts when the controller decides again, at 6 s, so it fires at 8 s."""
    snr = np.full((1, 3), 10.0)
    targets = [0, 1, 1, 1] + [2] * 8
    state, times, service = ControllerState.initial(1), [], []
    for k, target in enumerate(targets):
        res = step(float(k), snr, state, Given(2.0), 0.0, 3.0, 3, target=np.array([target]))
        times += res.events["time_s"].tolist()
        service.append(int(res.service[0]))
        state = res.state
    assert times == [3.0, 8.0]
    assert service == [0, 0, 0, 1, 1, 1, 0, 0, 1, 1, 1, 0]


def test_close_dwells_splits_cells_by_the_given_beam_count():
    state = _state([5, -1, 7], -np.inf, n_beam=None)
    state.serving_since_s[:] = [1.0, np.nan, 2.0]
    with pytest.raises(
        ValueError, match=r"^close_dwells needs n_beam \(no step\(\) has recorded it\)$"
    ):
        close_dwells(state, 10.0)
    d = close_dwells(state, 10, n_beam=2)  # an int end time: the dwells' times are floats
    assert d["ut_id"].tolist() == [0, 2]
    assert d["sat_id"].tolist() == [2, 3] and d["beam_id"].tolist() == [1, 1]
    assert d["end_s"].dtype == np.float64 and d["end_s"].tolist() == [10.0, 10.0]
    state.n_beam = 4  # recorded by step(): the given count still wins
    assert close_dwells(state, 10.0, n_beam=2)["sat_id"].tolist() == [2, 3]
    assert close_dwells(state, 10.0)["sat_id"].tolist() == [1, 1]
    empty = close_dwells(_state([-1], -np.inf, n_beam=None), 3.0)
    assert all(v.size == 0 for v in empty.values())


def test_a_state_without_a_recorded_serving_snr_reports_nan_before():
    """A state built without ``serving_snr_db`` (None, the dataclass default): a handover
    away from a link that is gone has ``snr_before_db`` NaN, as a float."""
    state = _state([0, 1], -np.inf, n_beam=2)
    state.serving_snr_db = None
    snr = np.array([[np.nan, 9.0, 12.0], [np.nan, 8.0, 11.0]])  # UT 0's link is gone
    res = step(5.0, snr, state, MaxSnr(), 0.0, 0.0, 2)
    assert res.events["kind"].tolist() == ["sat_handover", "sat_handover"]
    assert res.events["snr_before_db"].dtype == np.float64
    assert np.isnan(res.events["snr_before_db"][0]) and res.events["snr_before_db"][1] == 8.0
    assert res.state.serving_snr_db.tolist() == [12.0, 11.0]


def test_an_outage_event_has_no_serving_beam():
    """Losing every link: ``to_*`` is -1 (the documented 'none'), not a beam of cell -1."""
    snr = np.array([[[12.0, 11.0]], [[np.nan, np.nan]], [[np.nan, 15.0]]])
    state, kinds = ControllerState.initial(1), []
    for k in range(3):
        res = step(float(k), snr[k], state, Hysteresis(1.0, 0.0), 0.0, 0.0, 4)
        kinds.append((res.events["kind"].tolist(), res.events["to_beam"].tolist(),
                      res.events["from_beam"].tolist(), res.beam_id.tolist()))  # fmt: skip
        state = res.state
    assert kinds == [([], [], [], [0]), (["outage_start"], [-1], [0], [-1]),
                     (["outage_end"], [1], [-1], [1])]  # fmt: skip


class Probe:
    """A policy that records what step() hands it and asks for the best usable cell."""

    lookahead_s, time_to_trigger_s = 2.0, 0.0

    def __init__(self, bad=False):
        self.calls, self.bad = [], bad

    def __repr__(self):
        return "Probe()"

    def choose(self, t_s, snr_db, state, future_snr_db=None):
        self.calls.append((t_s, snr_db, state, future_snr_db))
        if self.bad:  # cell 1 for every UT, usable or not
            return np.ones(snr_db.n_ut, np.int64)
        v = np.where(np.isnan(snr_db.snr_db), -np.inf, snr_db.snr_db)
        return np.where(np.isfinite(v).any(axis=1), snr_db.cell[0, v.argmax(axis=1)], -1)


def test_the_policy_gets_the_epoch_time_and_the_tables_masked_at_min_snr():
    """The policy protocol: ``choose(t_s, usable table, state, usable future table)``,
    cells below ``min_snr_db`` NaN; a choice that is not usable names the policy."""
    probe, state = Probe(), ControllerState.initial(2)
    now = np.array([[1.0, 5.0, 3.0], [4.0, 2.5, np.nan]])
    future = np.array([[2.0, 2.9, 7.0], [np.nan, 3.5, 1.0]])
    res = step(7.25, now, state, probe, 3.0, 0.0, 2, future)
    ((t_s, got_now, got_state, got_future),) = probe.calls
    assert t_s == 7.25 and got_state is state
    np.testing.assert_array_equal(got_now.snr_db, [[np.nan, 5.0, 3.0], [4.0, np.nan, np.nan]])
    np.testing.assert_array_equal(got_future.snr_db, [[np.nan, np.nan, 7.0], [np.nan, 3.5, np.nan]])
    assert res.state.serving.tolist() == [1, 0]
    message = r"^policy Probe\(\) returned an unusable candidate for 1 UT\(s\), first ut_id 1 -> 1$"
    with pytest.raises(ValueError, match=message):
        step(0.0, now, state, Probe(bad=True), 3.0, 0.0, 2)


def test_the_controller_decides_again_at_the_epoch_the_execution_ends():
    """Epochs accumulate 0.1 s steps and the execution lasts 3 x 0.1 s: the handover at
    epoch 3 ends at t_3 + 0.3, one ulp after t_6 (the 1 ns tolerance): the switch back
    asked for at epoch 6 happens at epoch 6, not one epoch late."""
    snr, ho_s = np.full((1, 2), 10.0), 3 * 0.1
    t_s, times, state = [0.0], [], ControllerState.initial(1)
    for _ in range(9):
        t_s.append(t_s[-1] + 0.1)
    assert t_s[6] < t_s[3] + ho_s  # the rounding this test is about
    for k, target in enumerate([0, 0, 0, 1, 1, 1, 0, 0, 0]):
        res = step(t_s[k], snr, state, Given(0.0), 0.0, ho_s, 2, target=np.array([target]))
        times += [k] * res.events["time_s"].size
        state = res.state
    assert times == [3, 6]


def test_an_epoch_without_resumed_service_gives_an_empty_table_of_the_same_dtypes():
    """resumed_events of an epoch where no execution ends is empty, with the columns and
    dtypes of one where a UT resumes (the decider joins the two tables only when the
    second has rows, so an empty table must not be what fixes a dtype)."""
    state = ControllerState.initial(2)
    state.serving[:] = [3, -1]
    state.interrupted_until_s[:] = [0.5, -np.inf]
    state.n_beam = 2
    snr = np.array([[0.0, 0.0, 0.0, 7.0], [0.0, 0.0, 0.0, 0.0]])
    some = resumed_events(0.0, 1.0, state, snr)
    none = resumed_events(1.0, 1.0, state, snr)  # the execution ended at 0.5 s
    assert some["ut_id"].tolist() == [0] and some["snr_after_db"].tolist() == [7.0]
    assert list(none) == list(some)
    for k in some:
        assert none[k].shape == (0,) and none[k].dtype == some[k].dtype, k


def test_an_epoch_where_nobody_moves_keeps_the_state_and_the_dtypes_of_the_tables():
    """An epoch where no UT wants another cell, gets a first one or starts or ends an
    outage takes step's shortcut: its (empty) event and dwell tables have the columns and
    dtypes of non-empty ones; its state keeps every field but the serving SNR."""
    snr = np.array([[9.0, 3.0, np.nan, np.nan], [np.nan] * 4])
    moved = np.array([[3.0, 9.0, np.nan, np.nan], [np.nan] * 4])
    first = step(0.0, snr, ControllerState.initial(2), MaxSnr(), 0.0, 0.0, 2)
    assert first.events["kind"].tolist() == ["outage_start"]  # UT 1; UT 0 gets cell 0
    quiet = step(1.0, snr, first.state, MaxSnr(), 0.0, 0.0, 2)
    hand = step(2.0, moved, quiet.state, MaxSnr(), 0.0, 0.0, 2)
    assert hand.events["kind"].tolist() == ["beam_handover"] and hand.dwells["ut_id"].size == 1
    for name, full in (("events", first.events), ("dwells", hand.dwells)):
        empty = getattr(quiet, name)
        assert list(empty) == list(full), name
        for k in full:
            assert empty[k].shape == (0,) and empty[k].dtype == full[k].dtype, (name, k)
    assert quiet.state.serving.tolist() == [0, -1] and quiet.service.tolist() == [0, 2]
    assert quiet.sat_id.tolist() == [0, -1] and quiet.beam_id.tolist() == [0, -1]
    assert quiet.state.serving_snr_db.tolist()[0] == 9.0
    assert math.isnan(quiet.state.serving_snr_db[1])
    for field in ("pending", "pending_since_s", "serving_since_s", "interrupted_until_s",
                  "in_outage", "dwell_censored_start", "n_beam"):  # fmt: skip
        np.testing.assert_array_equal(getattr(quiet.state, field), getattr(first.state, field))


def test_empty_tables_are_new_dicts_of_arrays_nobody_can_write():
    """Most epochs return the empty event and dwell tables, whose arrays are shared: each
    call gives its own dict (a caller may add or replace a column), and writing into a
    shared array fails instead of reaching every later epoch's table."""
    from leolink.sim.handover.events import DWELL_COLUMNS, EVENT_COLUMNS, no_dwells, no_events

    for make, columns in ((no_events, EVENT_COLUMNS), (no_dwells, DWELL_COLUMNS)):
        a, b = make(), make()
        assert a is not b and list(a) == list(columns)
        a["extra"] = np.zeros(0)
        assert "extra" not in make()
        for values in b.values():
            assert values.size == 0 and not values.flags.writeable
            with pytest.raises(ValueError, match="read-only"):
                values[...] = 0
