"""The per-epoch controller step: policy, time-to-trigger, outage, handover execution.

Every epoch the simulator hands :func:`step` the candidate table of every UT
(:class:`~leolink.sim.candidates.table.Candidates`: cells ``cell = sat_id * n_beam + beam_id``
and their SNR, NaN where there is no usable link; a dense ``(n_ut, n_cand)`` matrix is
read as the table of cells ``0 .. n_cand - 1``). :func:`step` picks the serving cell of
every UT in one vectorized call with a policy of :mod:`leolink.sim.handover.policies` and returns
the handover/outage events and the closed beam dwells. Cell ids are global and stable,
so the state (serving, pending) needs no translation from one epoch to the next.

Handover execution is an event of its own: a handover at ``t`` interrupts service until
``t + handover_time_s`` exactly (not until the next epoch). The end time is known at the
decision, so it is computed, not simulated: :func:`resumed_events` stamps a
``service_resumed`` event with it (written with the epoch that contains it) and
:func:`interruption_s` gives the interrupted part of each epoch, ``[t, t + epoch)``, which
the simulator removes from the epoch's throughput. An interruption may span epochs.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink import compiled
from leolink.compiled import select
from leolink.sim.candidates.table import Candidates
from leolink.sim.handover.events import (  # noqa: F401  (the tables' names, re-exported)
    DWELL_COLUMNS,
    EVENT_COLUMNS,
    EVENT_KINDS,
    SERVICE_RESUMED,
    concat_events,
    dwells_table,
    events_table,
    kind_column,
    no_dwells,
    no_events,
    split_cells,
)
from leolink.sim.handover.policies import best_candidate, value_at  # noqa: F401  (re-exported)

# Epoch times accumulate float rounding (k * 0.1 s); 1 ns is far below any epoch length.
TIME_TOL_S = 1e-9

SERVICE_SERVED, SERVICE_HANDOVER, SERVICE_OUTAGE = 0, 1, 2
#: Trace ``service`` code -> name (index = code).
SERVICE_NAMES = ("served", "handover", "outage")


@dataclasses.dataclass
class ControllerState:
    """Per-UT controller state, every array of shape ``(n_ut,)``.

    Attributes
    ----------
    serving : int64, serving candidate, -1 for none (outage or not yet assigned).
    pending : int64, candidate waiting for the time-to-trigger, -1 for none.
    pending_since_s : float64 [s], first epoch at which ``pending`` was asked for.
    interrupted_until_s : float64 [s], handover execution: no service while t < this.
    serving_since_s : float64 [s], start of the current dwell (NaN without one).
    in_outage : bool, no usable candidate since the last ``outage_start``.
    dwell_censored_start : bool, the current dwell began with the run.
    n_beam : int or None, beams per satellite, recorded by :func:`step`.
    serving_snr_db : float64 [dB], the serving link's last finite SNR (NaN without one):
        the ``snr_before_db`` of the next handover even if that link is gone by then.
    """

    serving: np.ndarray
    pending: np.ndarray
    pending_since_s: np.ndarray
    interrupted_until_s: np.ndarray
    serving_since_s: np.ndarray
    in_outage: np.ndarray
    dwell_censored_start: np.ndarray
    n_beam: int | None = None
    serving_snr_db: np.ndarray | None = None

    @classmethod
    def initial(cls, n_ut, t0_s=0.0):
        """State before the first epoch: nothing assigned (``serving = -1``, not in outage)."""
        del t0_s  # the first step() call is the run start; kept for the documented signature
        return cls(
            serving=np.full(n_ut, -1, np.int64),
            pending=np.full(n_ut, -1, np.int64),
            pending_since_s=np.full(n_ut, np.nan),
            interrupted_until_s=np.full(n_ut, -np.inf),
            serving_since_s=np.full(n_ut, np.nan),
            in_outage=np.zeros(n_ut, bool),
            dwell_censored_start=np.zeros(n_ut, bool),
            serving_snr_db=np.full(n_ut, np.nan),
        )

    @property
    def n_ut(self):
        return self.serving.shape[0]


@dataclasses.dataclass
class StepResult:
    """Outcome of one :func:`step`.

    ``state``: the new state; ``events`` / ``dwells``: dicts of equal-length 1-D arrays
    (``EVENT_COLUMNS`` / ``DWELL_COLUMNS``), sorted by ``ut_id``; ``service``: int8
    ``(n_ut,)`` codes indexing ``SERVICE_NAMES``; ``sat_id``, ``beam_id``: serving
    satellite and beam ``(n_ut,)``, -1 in outage.
    """

    state: ControllerState
    events: dict
    dwells: dict
    service: np.ndarray
    sat_id: np.ndarray
    beam_id: np.ndarray


@compiled.jitable
def _rules(t_s, limits, n_beam, ut, was):
    """Every rule of :func:`step` after the policy's choice, written once: on every UT's
    arrays at once (the numpy code), or on one UT's scalars (:func:`_rules_rows`, the loop
    numba compiles from this source). Comparisons, ``&``, ``|``, ``~`` and
    :func:`~leolink.compiled.select` only.

    Parameters
    ----------
    t_s : float [s]
    limits : (min_snr_db, handover_time_s, time_to_trigger_s, time tolerance) [dB, s, s, s]
    n_beam : int
    ut : (has_usable, current_db, target, target_db), each (n_ut,) or one UT's: whether a
        UT has a usable candidate, its serving cell's SNR [dB] (NaN without one), the
        policy's target and the target's SNR [dB] (NaN where absent), both from the full
        table.
    was : the state's values (serving, pending, pending_since_s, interrupted_until_s,
        serving_since_s, in_outage, dwell_censored_start, serving_snr_db).

    Returns
    -------
    tuple of 16
        The new state's eight values (``was``'s order), then ``sat_id``, ``beam_id`` and
        the service code of the new serving cell, the event kind (index of
        ``EVENT_KINDS``, -1: none), the new serving cell's SNR and the old link's last
        [dB] (the event's columns), whether a dwell closes, and whether the target is
        unusable where one is needed (``step`` raises).
    """
    min_snr_db, handover_time_s, ttt_s, tol = limits
    has_usable, current_db, target, target_db = ut
    old, was_pending, was_since_s, until, since_s, in_outage, censored, last_snr_db = was
    first = has_usable & (old < 0) & ~in_outage
    interrupted = (old >= 0) & (t_s < until - tol)
    bad = has_usable & ~interrupted & ~(np.isfinite(target_db) & (target_db >= min_snr_db))
    immediate = ~(np.isfinite(current_db) & (current_db >= min_snr_db))
    wants = has_usable & (old >= 0) & ~interrupted & (target != old)
    outage_start = ~has_usable & ~in_outage
    outage_end = has_usable & in_outage
    # Time to trigger: a target pends until it has been wanted for ttt_s (at once where
    # the serving link is no longer usable).
    pending = select(wants & ~immediate, target, -1)
    since = select((pending >= 0) & (pending == was_pending), was_since_s,
                   select(pending >= 0, t_s, np.nan))  # fmt: skip
    handover = wants & (immediate | (t_s - since >= ttt_s - tol))
    adopt = handover | outage_end | first
    dropped = adopt | outage_start  # nothing pends for these
    new = select(adopt, target, select(outage_start, -1, old))
    new_db = select(adopt, target_db, select(outage_start, np.nan, current_db))
    last_db = select(np.isfinite(current_db), current_db, last_snr_db)
    # A handover adopts the target: its satellite is the new one's.
    kind = select(handover, select(new // n_beam == old // n_beam, 0, 1), -1)
    kind = select(outage_end, 3, select(outage_start, 2, kind))
    until = select(handover, t_s + handover_time_s, select(outage_start, -np.inf, until))
    in_outage = (in_outage & ~outage_end) | outage_start
    kept = select(new == old, last_db, np.nan)
    service = select((new >= 0) & (t_s < until - tol), SERVICE_HANDOVER, SERVICE_SERVED)
    return (
        new,
        select(dropped, -1, pending),
        select(dropped | (pending < 0), np.nan, since),
        until,
        select(adopt, t_s, select(outage_start, np.nan, since_s)),
        in_outage,
        select(first, True, select(adopt, False, censored)),
        select(new < 0, np.nan, select(np.isfinite(new_db), new_db, kept)),
        select(new >= 0, new // n_beam, -1),
        select(new >= 0, new % n_beam, -1),
        select(in_outage | (new < 0), SERVICE_OUTAGE, service),
        kind,
        new_db,
        last_db,
        (handover | outage_start) & (old >= 0),
        bad,
    )


#: The dtypes of :func:`_rules`' outputs.
_OUT_DTYPES = (np.int64, np.int64, float, float, float, bool, bool, float,
               np.int64, np.int64, np.int8, np.int8, float, float, bool, bool)  # fmt: skip
#: Where :func:`_rules_rows` writes each output: (int64, float, int8, bool array, row).
_OUT_ROWS = ((0, 0), (0, 1), (1, 0), (1, 1), (1, 2), (3, 0), (3, 1), (1, 3),
             (0, 2), (0, 3), (2, 0), (2, 1), (1, 4), (1, 5), (3, 2), (3, 3))  # fmt: skip


@compiled.jit
def _rules_rows(t_s, limits, n_beam, table, target, was, out):
    """:func:`_rules` UT by UT into ``out``, its outputs grouped by dtype (int64, float,
    int8, bool: rows in :data:`_OUT_ROWS`' order), each UT's facts read from its row of
    ``table`` ``(cell, snr_db)`` as :func:`_table_facts` reads them (the first slot
    holding a cell; a usable SNR is finite and >= the minimum)."""
    cell, snr_db = table
    ints, floats, codes, flags = out
    for i in range(target.size):
        old, has_usable, current_db, target_db = was[0][i], False, np.nan, np.nan
        for j in range(cell.shape[1]):
            v = snr_db[i, j]
            has_usable |= np.isfinite(v) and v >= limits[0]
        for j in range(cell.shape[1]):
            if old >= 0 and cell[i, j] == old:
                current_db = snr_db[i, j]
                break
        for j in range(cell.shape[1]):
            if target[i] >= 0 and cell[i, j] == target[i]:
                target_db = snr_db[i, j]
                break
        r = _rules(t_s, limits, n_beam, (has_usable, current_db, target[i], target_db),
                   (old, was[1][i], was[2][i], was[3][i], was[4][i], was[5][i], was[6][i],
                    was[7][i]))  # fmt: skip
        ints[0, i], ints[1, i], ints[2, i], ints[3, i] = r[0], r[1], r[8], r[9]
        floats[0, i], floats[1, i], floats[2, i] = r[2], r[3], r[4]
        floats[3, i], floats[4, i], floats[5, i] = r[7], r[12], r[13]
        codes[0, i], codes[1, i] = r[10], r[11]
        flags[0, i], flags[1, i], flags[2, i], flags[3, i] = r[5], r[6], r[14], r[15]


def _table_facts(table, usable, target, serving):
    """Per UT (numpy): whether it has a usable candidate (``usable``: the table masked
    below the minimum), its serving cell's SNR and its target's [dB] (NaN where absent)."""
    # The usable table has the cells of the full one: each cell's slot is found once.
    slot_old, slot_target = table.slot_of(serving, target)
    has_usable = np.isfinite(usable.snr_db).any(axis=1)
    return has_usable, table.at(slot_old), target, table.at(slot_target)


def _applied_rules(t_s, limits, n_beam, tables, target, was):
    """:func:`_rules` of every UT, as arrays of :data:`_OUT_DTYPES`: compiled, UT by UT,
    or numpy's on the arrays (``LEOLINK_JIT=0``). ``tables``: the candidate table and
    that table masked below the minimum SNR."""
    n, (table, usable) = target.size, tables
    if compiled.use(n):
        # Four arrays, not sixteen: a compiled call's cost grows with its arguments.
        out = (np.empty((4, n), np.int64), np.empty((6, n)), np.empty((2, n), np.int8),
               np.empty((4, n), bool))  # fmt: skip
        _rules_rows(t_s, limits, n_beam, (table.cell, table.snr_db), target, was, out)
        return tuple(out[group][row] for group, row in _OUT_ROWS)
    ut = _table_facts(table, usable, target, was[0])
    with np.errstate(invalid="ignore"):  # (NaN times compared: never pending)
        out = _rules(t_s, limits, n_beam, ut, was)
    return tuple(np.asarray(v, dtype) for v, dtype in zip(out, _OUT_DTYPES, strict=True))


def _raise_unusable(policy, target, n_bad, first):
    raise ValueError(
        f"policy {policy!r} returned an unusable candidate for {n_bad} UT(s), "
        f"first ut_id {first} -> {target[first]}"
    )


def step(
    t_s,
    snr_db,
    state,
    policy,
    min_snr_db,
    handover_time_s,
    n_beam,
    future_snr_db=None,
    target=None,
):
    """Apply ``policy`` to every UT at epoch ``t_s``; returns a :class:`StepResult`.

    Pure: ``state`` is not mutated; the new state is ``result.state``.

    Parameters
    ----------
    t_s : float [s], epoch time (the first call is the run start).
    snr_db : Candidates, or ndarray (n_ut, n_cand) [dB] whose column is the cell
        ``sat * n_beam + beam``; NaN = no link.
    state : ControllerState
    policy : object following the policy protocol (module docstring).
    min_snr_db : float [dB], a candidate below it is unusable; a UT with no usable
        candidate is in outage (``serving = -1``).
    handover_time_s : float [s], handover execution: after a (beam or satellite) handover
        at ``t`` the UT has no service while ``t' < t + handover_time_s`` and the
        controller does not re-decide for it (an outage still ends it). Leaving an outage
        and the first assignment have no execution time.
    n_beam : int, beams per satellite.
    future_snr_db : Candidates (the same cells) or ndarray (n_ut, n_cand) [dB] at
        ``t_s + policy.lookahead_s``, or None.
    target : int64 (n_ut,) or None, the policy's choice made by the caller (policies with
        per-cell state, :mod:`leolink.sim.handover.trigger_run`); None asks ``policy.choose``.

    Notes
    -----
    The first assignment is not a handover: no event; its dwell has ``censored_start``.
    A UT with no usable candidate at the run start gets an ``outage_start`` event.
    Dwells run from the epoch a candidate became serving to the epoch it stopped.
    ``snr_before_db`` of an event is the serving link's last finite SNR (this epoch's, or
    the last epoch's if its satellite has set), NaN only without a serving link.
    The rules themselves are :func:`_rules` (numpy, or compiled from the same source).
    """
    snr_db = _as_table(snr_db)
    usable_db = snr_db.masked(min_snr_db)
    future_db = None if future_snr_db is None else _as_table(future_snr_db).masked(min_snr_db)
    if target is None:
        target = policy.choose(t_s, usable_db, state, future_db)
    target = np.asarray(target, np.int64)
    limits = (float(min_snr_db), float(handover_time_s), float(policy.time_to_trigger_s),
              TIME_TOL_S)  # fmt: skip
    out = _applied_rules(float(t_s), limits, int(n_beam), (snr_db, usable_db), target,
                         _state_arrays(state))  # fmt: skip
    new_state = ControllerState(*out[:7], n_beam=int(n_beam), serving_snr_db=out[7])
    sat, beam, service, kind, new_db, last_db, closing, bad = out[8:]
    n_bad = int(np.count_nonzero(bad))
    if n_bad:
        _raise_unusable(policy, target, n_bad, int(np.argmax(bad)))
    res = StepResult(new_state, no_events(), no_dwells(), service, sat, beam)
    if kind.max(initial=-1) >= 0:
        old = state.serving
        res.events = events_table(t_s, kind, old, split_cells(old, n_beam), (sat, beam), new_db,
                                  last_db)  # fmt: skip
    if closing.any():
        u = np.flatnonzero(closing)
        old = state.serving[u]
        res.dwells = dwells_table(u, old, state.serving_since_s[u], t_s,
                                  state.dwell_censored_start[u], False, n_beam,
                                  split_cells(old, n_beam))  # fmt: skip
    return res


def _state_arrays(state):
    """The state's arrays in :func:`_rules`' order (the serving SNR NaN if unrecorded)."""
    last = state.serving_snr_db
    return (state.serving, state.pending, state.pending_since_s, state.interrupted_until_s,
            state.serving_since_s, state.in_outage, state.dwell_censored_start,
            np.full(state.n_ut, np.nan) if last is None else last)  # fmt: skip


def _as_table(snr_db):
    """A :class:`Candidates` table (a dense matrix: the cells of its columns)."""
    return snr_db if isinstance(snr_db, Candidates) else Candidates.dense(snr_db)


def interruption_s(t_s, epoch_s, state):
    """Time of the epoch ``[t_s, t_s + epoch_s)`` without service because of handover
    execution, per UT [s] (``state`` after :func:`step` at ``t_s``); 0 in outage."""
    until = state.interrupted_until_s
    active = (state.serving >= 0) & ~state.in_outage & (until > t_s + TIME_TOL_S)
    return np.where(active, np.minimum(until, t_s + epoch_s) - t_s, 0.0)


def resumed_events(t_s, epoch_s, state, snr_db):
    """``service_resumed`` events of the UTs whose handover execution ends within
    ``(t_s, t_s + epoch_s]``, stamped with that exact time; sorted by time, then UT.

    ``state`` is the state after :func:`step` at ``t_s``; ``snr_db`` that epoch's
    candidate table or SNR matrix (``snr_after_db`` is the serving link's SNR at ``t_s``).
    """
    until = state.interrupted_until_s
    due = (state.serving >= 0) & ~state.in_outage & (until > t_s + TIME_TOL_S)
    due &= until <= t_s + epoch_s + TIME_TOL_S
    ut = np.flatnonzero(due)
    if ut.size == 0:  # (most epochs)
        return no_events()
    ut = ut[np.lexsort((ut, until[ut]))]
    to_sat, to_beam = split_cells(state.serving[ut], state.n_beam or 1)
    none = np.full(ut.size, -1, np.int64)
    return {
        "time_s": until[ut].astype(float),
        "ut_id": ut.astype(np.int64),
        "kind": kind_column(EVENT_KINDS[SERVICE_RESUMED], ut.size),
        "from_sat": none,
        "from_beam": none.copy(),
        "to_sat": to_sat,
        "to_beam": to_beam,
        "snr_before_db": np.full(ut.size, np.nan),
        "snr_after_db": value_at(_as_table(snr_db).rows(ut), state.serving[ut]),
    }


def service_codes(t_s, state):
    """Trace ``service`` code per UT (``SERVICE_NAMES``): served, handover or outage."""
    code = np.full(state.n_ut, SERVICE_SERVED, np.int8)
    code[(state.serving >= 0) & (t_s < state.interrupted_until_s - TIME_TOL_S)] = SERVICE_HANDOVER
    code[state.in_outage | (state.serving < 0)] = SERVICE_OUTAGE
    return code


def close_dwells(state, t_end_s, n_beam=None):
    """Close every open dwell at the run end (``censored_end = True``).

    ``n_beam`` defaults to the one recorded in ``state`` by :func:`step`.
    """
    n_beam = state.n_beam if n_beam is None else n_beam
    ut = np.flatnonzero(state.serving >= 0)
    if ut.size and n_beam is None:
        raise ValueError("close_dwells needs n_beam (no step() has recorded it)")
    return dwells_table(
        ut,
        state.serving[ut],
        state.serving_since_s[ut],
        t_end_s,
        state.dwell_censored_start[ut],
        True,
        n_beam or 1,
    )
