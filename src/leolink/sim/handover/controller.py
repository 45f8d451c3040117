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

import collections
import dataclasses

import numpy as np

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


def _time_to_trigger(t_s, target, was_pending, was_since_s, wants, immediate, ttt_s):
    """Pending bookkeeping (``was_*``: the state's ``pending`` and ``pending_since_s``).
    Returns (fire, pending, pending_since_s)."""
    if not wants.any():  # (most epochs: nothing fires, nothing pends)
        n = wants.shape
        return np.zeros(n, bool), np.full(n, -1, np.int64), np.full(n, np.nan)
    pending = np.where(wants & ~immediate, target, -1)
    same = (pending >= 0) & (pending == was_pending)
    since = np.where(same, was_since_s, np.where(pending >= 0, t_s, np.nan))
    with np.errstate(invalid="ignore"):
        waited = t_s - since >= ttt_s - TIME_TOL_S
    fire = wants & (immediate | waited)
    return fire, np.where(fire, -1, pending), np.where(fire | (pending < 0), np.nan, since)


def _check_targets(policy, target, target_db, needs):
    """A policy must return a usable candidate wherever one is needed (``target_db``: the
    usable SNR of ``target``)."""
    ok = np.isfinite(target_db)
    bad = np.flatnonzero(needs & ~ok)
    if bad.size:
        _raise_unusable(policy, target, bad.size, bad[0])


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
    """
    snr_db = _as_table(snr_db)
    usable_db = snr_db.masked(min_snr_db)
    future_db = None if future_snr_db is None else _as_table(future_snr_db).masked(min_snr_db)
    if target is None:
        target = policy.choose(t_s, usable_db, state, future_db)
    target = np.asarray(target, np.int64)
    old = state.serving
    # The usable table has the cells of the full one: each cell's slot is found once.
    slot_old, slot_target = snr_db.slot_of(old, target)
    has_usable = np.isfinite(usable_db.snr_db).any(axis=1)
    first = has_usable & (old < 0) & ~state.in_outage
    interrupted = (old >= 0) & (t_s < state.interrupted_until_s - TIME_TOL_S)
    _check_targets(policy, target, usable_db.at(slot_target), has_usable & ~interrupted)

    current_db = snr_db.at(slot_old)
    with np.errstate(invalid="ignore"):  # the serving cell's usable SNR, as in usable_db
        immediate = ~np.isfinite(np.where(current_db >= min_snr_db, current_db, np.nan))
    wants = has_usable & (old >= 0) & ~interrupted & (target != old)
    outage_start = ~has_usable & ~state.in_outage
    outage_end = has_usable & state.in_outage
    res = _unchanged(t_s, state, current_db, n_beam)
    u = np.flatnonzero(wants | first | outage_start | outage_end)
    if u.size:  # (none in most epochs of small runs)
        # Every rule is per UT: applied to the UTs ``u`` that change, written over what the
        # rules give the others (:func:`_unchanged`'s result).
        sub = _Subset(old[u], target[u], wants[u], first[u], outage_start[u], outage_end[u],
                      immediate[u], slot_old[u], slot_target[u], current_db[u])  # fmt: skip
        ttt_s = float(policy.time_to_trigger_s)
        _apply_changes(res, t_s, state, u, snr_db, sub, ttt_s, handover_time_s, n_beam)
    return res


#: :func:`step`'s per-UT arrays of the UTs that change.
_Subset = collections.namedtuple("_Subset", "old target wants first outage_start outage_end "
                                 "immediate slot_old slot_target current_db")  # fmt: skip


def _apply_changes(res, t_s, state, u, snr_db, sub, ttt_s, handover_time_s, n_beam):
    """The rules of :func:`step` for the UTs ``u`` (their arrays ``sub``), written into
    ``res``, :func:`_unchanged`'s result: events, dwells, state, cells and service."""
    old, target = sub.old, sub.target
    handover, pending, pending_since = _time_to_trigger(
        t_s, target, state.pending[u], state.pending_since_s[u], sub.wants, sub.immediate, ttt_s
    )
    adopt = handover | sub.outage_end | sub.first
    new = np.where(adopt, target, np.where(sub.outage_start, -1, old))
    slot_new = np.where(adopt, sub.slot_target, np.where(sub.outage_start, -1, sub.slot_old))
    old_split, new_split = split_cells(old, n_beam), split_cells(new, n_beam)

    # A handover adopts the target: its satellite is the new one's.
    same_sat = new_split[0] == old_split[0]
    kind = np.full(old.shape, -1, np.int64)
    kind[handover] = np.where(same_sat[handover], 0, 1)
    kind[sub.outage_start] = 2
    kind[sub.outage_end] = 3
    last_db = _last_serving_db(state, sub.current_db, u)
    new_db = snr_db.rows(u).at(slot_new)
    res.events = events_table(t_s, kind, old, old_split, new_split, new_db, last_db, ut_id=u)
    closing = np.flatnonzero((handover | sub.outage_start) & (old >= 0))
    res.dwells = dwells_table(u[closing], old[closing], state.serving_since_s[u[closing]], t_s,
                              state.dwell_censored_start[u[closing]], False, n_beam,
                              (old_split[0][closing], old_split[1][closing]))  # fmt: skip
    dropped = adopt | sub.outage_start  # nothing pends for these
    new_state = res.state  # its arrays that are not the state's own are written in place
    new_state.pending[u] = np.where(dropped, -1, pending)
    new_state.pending_since_s[u] = np.where(dropped, np.nan, pending_since)
    new_state.serving_snr_db[u] = _serving_db(old, new, new_db, last_db)
    new_state.serving = _scattered(state.serving, u, new)
    until = np.where(sub.outage_start, -np.inf, state.interrupted_until_s[u])
    new_state.interrupted_until_s = _scattered(
        state.interrupted_until_s, u, np.where(handover, t_s + handover_time_s, until)
    )
    since = np.where(sub.outage_start, np.nan, state.serving_since_s[u])
    new_state.serving_since_s = _scattered(state.serving_since_s, u, np.where(adopt, t_s, since))
    new_state.in_outage = _scattered(
        state.in_outage, u, (state.in_outage[u] & ~sub.outage_end) | sub.outage_start
    )
    censored = np.where(adopt, False, state.dwell_censored_start[u])
    new_state.dwell_censored_start = _scattered(
        state.dwell_censored_start, u, np.where(sub.first, True, censored)
    )
    res.sat_id[u], res.beam_id[u] = new_split
    res.service = service_codes(t_s, new_state)


def _scattered(values, idx, new):
    """A copy of ``values`` with ``new`` at ``idx``."""
    out = values.copy()
    out[idx] = new
    return out


def _unchanged(t_s, state, current_db, n_beam):
    """:func:`step`'s result where no UT wants another cell, is assigned a first one,
    starts or ends an outage: every cell kept, nothing pending (a target no longer
    wanted stops pending, as in :func:`_time_to_trigger`), no events, no dwells; only the
    serving links' last SNR moves. Its ``pending``, ``pending_since_s``,
    ``serving_snr_db``, ``sat_id`` and ``beam_id`` are new arrays (:func:`step` writes the
    UTs that change into them); the other state arrays are the state's own."""
    n = state.serving.shape
    last_db = _last_serving_db(state, current_db)
    new_state = ControllerState(  # (not dataclasses.replace: ~5 us of introspection)
        serving=state.serving,
        pending=np.full(n, -1, np.int64),
        pending_since_s=np.full(n, np.nan),
        interrupted_until_s=state.interrupted_until_s,
        serving_since_s=state.serving_since_s,
        in_outage=state.in_outage,
        dwell_censored_start=state.dwell_censored_start,
        n_beam=int(n_beam),
        serving_snr_db=np.where(state.serving < 0, np.nan, last_db),
    )
    sat, beam = split_cells(state.serving, n_beam)
    return StepResult(new_state, no_events(), no_dwells(), service_codes(t_s, new_state),
                      sat, beam)  # fmt: skip


def _as_table(snr_db):
    """A :class:`Candidates` table (a dense matrix: the cells of its columns)."""
    return snr_db if isinstance(snr_db, Candidates) else Candidates.dense(snr_db)


def _last_serving_db(state, current_db, ut=slice(None)):
    """The serving link's SNR now if finite, else its last recorded value (of the UTs
    ``ut``, ``current_db`` theirs)."""
    last = state.serving_snr_db
    if last is None:
        last = np.full(state.n_ut, np.nan)
    return np.where(np.isfinite(current_db), current_db, last[ut])


def _serving_db(old, new, new_db, last_db):
    """``serving_snr_db`` of the new state."""
    kept = np.where(new == old, last_db, np.nan)
    return np.where(new < 0, np.nan, np.where(np.isfinite(new_db), new_db, kept))


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
