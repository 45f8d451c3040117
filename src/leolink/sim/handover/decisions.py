"""Handover policies built from trigger events: what the controller calls once per epoch.

Policy protocol (proposal for ``leolink.sim.handover.controller``)
--------------------------------------------------------
A policy has

- ``needs``: the :class:`~leolink.sim.handover.triggers.Epoch` fields the controller must fill
  (``meas``, ``ut_pos_m``, ``ref_pos_m``, ``moving_ref_pos_m``, ``elevation_rad``,
  ``service_end_s``);
- ``initial_state(n_ut, n_cand, n_beam) -> PolicyState``;
- ``decide(epoch, state, n_beam) -> (Decision, PolicyState)``: pure. ``epoch`` is on the
  cell axis ``cand = sat * n_beam + beam`` (per-satellite arrays, i.e. the moving
  reference locations, have one row per satellite); ``Decision.target`` is the cell to
  hand over to now (-1: stay). The policy owns its time-to-trigger: the controller
  executes a target at once (its own ``time_to_trigger_s`` is 0 for these policies).

The controller keeps execution time, outage, RLF and the first assignment, and calls
``decide`` every epoch; a policy notices a serving change itself (``epoch.serving``
differs from the serving it saw last) and clears its trigger rows (TS 38.331 5.5.6.1).

Level. A cell-level policy decides satellite and beam. A satellite-level policy runs its
trigger on satellites (cell arrays reduced by the maximum over each satellite's beams)
and leaves the beam to max-``meas`` inside the chosen satellite; inside the serving
satellite the beam follows max-``meas`` every epoch, and only a satellite change clears
its triggers (a beam switch is beam management, not an RRC handover). Defaults: A3, A4,
A5, D1: cell; D2, T1, elevation, time_to_exit: satellite.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.arrays import reduce_groups
from leolink.errors import require_at_least
from leolink.sim.handover.triggers import (
    A3,
    A4,
    A5,
    TIME_TOL_S,
    TriggerState,
    advance,
    evaluate,
    neighbours,
)
from leolink.sim.handover.triggers_ntn import D1, D2, T1, Elevation, TimeToExit

#: Trigger classes by config name (``controller.policy``).
TRIGGERS = {
    "a3": A3,
    "a4": A4,
    "a5": A5,
    "d1": D1,
    "d2": D2,
    "t1": T1,
    "elevation": Elevation,
    "time_to_exit": TimeToExit,
}
_PER_CELL = ("meas", "elevation_rad", "service_end_s")


@dataclasses.dataclass(frozen=True)
class Decision:
    """``target`` int64 (n_ut,): cell to hand over to now, -1 to stay. ``prepared``: bool
    (n_ut, n_unit) conditional-handover candidates on the policy's axis, or None.
    ``report``: the TriggerReport of the (first) deciding trigger, for accounting."""

    target: np.ndarray
    prepared: np.ndarray | None = None
    report: object = None


@dataclasses.dataclass(frozen=True)
class PolicyState:
    """``serving`` (n_ut,) seen at the last call; one TriggerState per trigger; ``prepared``
    (CHO only) the admitted candidates; ``gate`` (gated policies only) the serving-cell
    event's TriggerState, one column ``(n_ut, 1)``."""

    serving: np.ndarray
    triggers: tuple
    prepared: np.ndarray | None = None
    gate: object = None


def _reduce_beams(x, n_beam):
    """Max over the beams of each satellite on the last axis (NaN ignored):
    :func:`~leolink.arrays.reduce_groups` of ``fmax`` (exact in any order)."""
    x = np.asarray(x, float)
    return x if x.ndim == 0 else reduce_groups(np.fmax, x, n_beam)


def to_satellites(epoch, n_beam, needs=None):
    """The epoch on the satellite axis: serving satellite, per-cell arrays reduced by max.

    An array already on the satellite axis (``n_cand // n_beam`` wide, ``n_cand`` the
    width of ``meas``; with ``n_beam > 1`` a cell array is wider) is kept as it is: the
    run gives a satellite-level policy its per-satellite fields so (``elevation_rad``,
    ``service_end_s``), not repeated over the beams and reduced back.

    ``needs``: the fields the caller's triggers read (their ``needs``); the other fields
    of ``meas``, ``elevation_rad``, ``service_end_s`` are left out (None, so that a read
    of one fails in :meth:`Epoch.need <leolink.sim.handover.triggers.Epoch.need>`), not
    reduced: time-to-exit reads no measurement. None: all of them."""
    serving = np.asarray(epoch.serving, np.int64)
    changes = {"serving": np.where(serving >= 0, serving // n_beam, -1)}
    n_unit = None if epoch.meas is None else np.shape(epoch.meas)[-1] // n_beam
    for name in (*_PER_CELL, "offset_db"):
        value = getattr(epoch, name)
        if value is None or np.ndim(value) == 0:
            continue
        if needs is not None and name in _PER_CELL and name not in needs:
            changes[name] = None
            continue
        if n_beam > 1 and name != "meas" and np.shape(value)[-1] == n_unit:
            continue  # (already per satellite)
        changes[name] = _reduce_beams(value, n_beam)
    return dataclasses.replace(epoch, **changes)


def pick(mask, score):
    """Per UT the index of the best ``score`` where ``mask``; -1 where none (NaN never wins)."""
    s = np.where(np.asarray(mask, bool), np.asarray(score, float), -np.inf)
    s = np.where(np.isnan(s), -np.inf, s)
    if s.shape[1] == 0:
        return np.full(s.shape[0], -1, np.int64)
    best = np.argmax(s, axis=1)  # ties: the lowest index, as controller.best_candidate
    found = s[np.arange(s.shape[0]), best] > -np.inf
    return np.where(found, best, -1).astype(np.int64)


def best_beam(sat, meas, n_beam):
    """Cell of the best ``meas`` inside satellite ``sat`` (n_ut,); -1 where none usable."""
    meas = np.asarray(meas, float)
    if meas.shape[-1] == 0:  # no candidate on any UT's axis (every UT out of coverage)
        return np.full(len(sat), -1, np.int64)
    rows = meas.reshape(meas.shape[0], -1, n_beam)[np.arange(len(sat)), np.maximum(sat, 0)]
    beam = pick(np.ones(rows.shape, bool), rows)
    return np.where((sat >= 0) & (beam >= 0), np.maximum(sat, 0) * n_beam + beam, -1)


def _level_target(unit, epoch, level, n_beam):
    """Cell target from a unit (cell or satellite) choice; -1 when it is the serving cell."""
    serving = np.asarray(epoch.serving, np.int64)
    if level == "cell":
        cell = unit
    else:
        sat = np.where(unit >= 0, unit, np.where(serving >= 0, serving // n_beam, -1))
        cell = best_beam(sat, epoch.need("meas", "satellite-level beam choice"), n_beam)
    return np.where(cell == serving, -1, cell).astype(np.int64)


def _unit_serving(serving, level, n_beam):
    serving = np.asarray(serving, np.int64)
    return serving if level == "cell" else np.where(serving >= 0, serving // n_beam, -1)


def _changed(epoch, state, level, n_beam):
    """bool (n_ut,): the serving unit (cell, or satellite) differs from the last one seen."""
    now = _unit_serving(epoch.serving, level, n_beam)
    return now != _unit_serving(state.serving, level, n_beam)


def _check_level(level):
    if level not in ("cell", "satellite"):
        raise ValueError(f"level = {level!r}; use 'cell' or 'satellite'")
    return level


class TriggerPolicy:
    """Hand over to the best triggered candidate of one trigger event (its ``rank``)."""

    def __init__(self, trigger, level=None):
        self.trigger = trigger
        self.level = _check_level(level or trigger.level)
        self.needs = tuple(dict.fromkeys(trigger.needs + ("meas",)))

    def initial_state(self, n_ut, n_cand, n_beam):
        n_unit = n_cand if self.level == "cell" else n_cand // n_beam
        return PolicyState(np.full(n_ut, -1, np.int64), (TriggerState.initial(n_ut, n_unit),))

    def _axis(self, epoch, n_beam):
        """The epoch on the policy's axis, with the fields its events read."""
        if self.level == "cell":
            return epoch
        return to_satellites(epoch, n_beam, sum((t.needs for t in self._events()), ()))

    def _events(self):
        """The events whose conditions and rank read the epoch."""
        return (self.trigger,)

    def decide(self, epoch, state, n_beam):
        (trig,) = state.triggers
        trig = trig.reset(_changed(epoch, state, self.level, n_beam))
        ep = self._axis(epoch, n_beam)
        trig, report = evaluate(self.trigger, trig, ep)
        unit = pick(trig.triggered, self.trigger.rank(ep))
        target = _level_target(unit, epoch, self.level, n_beam)
        return Decision(target, None, report), PolicyState(
            np.asarray(epoch.serving, np.int64).copy(), (trig,)
        )

    def __repr__(self):
        return f"TriggerPolicy({self.trigger!r}, level={self.level!r})"


class GatedTriggerPolicy(TriggerPolicy):
    """A neighbour event measured only while a serving-cell event holds: A4 gated by A2.

    The network configures the neighbour measurement (``trigger``, e.g. A4) once the gate
    (``gate``, A2: serving worse than a threshold) has triggered, and removes it when the
    gate leaves (A2-2, what an A1 at the same threshold would report): while the gate is
    not triggered no neighbour has a run. A serving change clears both (38.331 5.5.6.1).
    """

    def __init__(self, gate, trigger, level=None):
        super().__init__(trigger, level)
        self.gate = gate

    def _events(self):
        return (self.gate, self.trigger)

    def initial_state(self, n_ut, n_cand, n_beam):
        state = super().initial_state(n_ut, n_cand, n_beam)
        return PolicyState(state.serving, state.triggers, gate=TriggerState.initial(n_ut, 1))

    def decide(self, epoch, state, n_beam):
        changed = _changed(epoch, state, self.level, n_beam)
        (trig,) = (s.reset(changed) for s in state.triggers)
        gate = state.gate.reset(changed)
        ep = self._axis(epoch, n_beam)
        enter, leave = self.gate.conditions(ep)
        served = (np.asarray(ep.serving) >= 0)[:, None]
        gate, _ = advance(gate, ep.t_s, enter, leave, self.gate.time_to_trigger_s, served)
        entering, leaving = self.trigger.conditions(ep)
        applicable = neighbours(ep, entering.shape[1]) & ~np.isnan(gate.triggered_at_s)
        trig, report = advance(trig, ep.t_s, entering, leaving, self.trigger.time_to_trigger_s,
                               applicable)  # fmt: skip
        unit = pick(trig.triggered, self.trigger.rank(ep))
        target = _level_target(unit, epoch, self.level, n_beam)
        serving = np.asarray(epoch.serving, np.int64).copy()
        return Decision(target, None, report), PolicyState(serving, (trig,), gate=gate)

    def __repr__(self):
        return f"GatedTriggerPolicy({self.gate!r}, {self.trigger!r}, level={self.level!r})"


def _admit(admitted, ready, score, max_prepared):
    """Keep admitted candidates still ready; admit the best new ones up to max_prepared
    (a NaN score never; -inf, as ``nan_to_num`` makes it, below every finite one)."""
    keep = admitted & ready
    room = max_prepared - keep.sum(axis=1)
    score = np.broadcast_to(np.asarray(score, float), keep.shape)
    new = ready & ~keep & ~np.isnan(score)
    # Only rows with more new candidates than room need an order (most have room for all).
    full = np.flatnonzero(new.sum(axis=1) > room)
    if full.size:
        s = np.where(new[full], np.nan_to_num(score[full], nan=-np.inf), -np.inf)
        order = np.argsort(-s, axis=1, kind="stable")
        rank = np.empty_like(order)
        np.put_along_axis(rank, order, np.arange(s.shape[1])[None, :], axis=1)
        new[full] &= rank < room[full, None]
    return keep | new


class ConditionalHandover:
    """Conditional handover (TS 38.331 5.3.5.13): prepare candidates, execute on a condition.

    A candidate is prepared once the ``prepare`` trigger has held it triggered for
    ``preparation_delay_s`` (the network's preparation time), up to ``max_prepared`` per
    UT (maxNrofCondCells = 8), best ``prepare.rank`` first; it stays prepared while the
    prepare trigger keeps it triggered. Execution conditions (``execute``: one or two
    CondEvents, all must be fulfilled, 5.3.5.13.4) are evaluated only on prepared
    candidates, so their time-to-trigger starts no earlier than the preparation. Among
    fulfilled candidates the UE picks the best by the first execution trigger's rank
    (the standard leaves the choice to the UE). Execution clears everything.
    """

    def __init__(self, prepare, execute, max_prepared=8, preparation_delay_s=0.0, level=None):
        self.prepare, self.execute = prepare, tuple(execute)
        if not 1 <= len(self.execute) <= 2:
            raise ValueError("conditional handover takes one or two execution conditions")
        require_at_least("controller.cho.max_prepared", max_prepared, 1, "candidates")
        require_at_least("controller.cho.preparation_delay_s", preparation_delay_s, 0.0, "[s]")
        self.max_prepared, self.preparation_delay_s = int(max_prepared), float(preparation_delay_s)
        self.level = _check_level(level or self.execute[0].level)
        needs = prepare.needs + sum((t.needs for t in self.execute), ()) + ("meas",)
        self.needs = tuple(dict.fromkeys(needs))

    def initial_state(self, n_ut, n_cand, n_beam):
        n_unit = n_cand if self.level == "cell" else n_cand // n_beam
        states = tuple(TriggerState.initial(n_ut, n_unit) for _ in range(1 + len(self.execute)))
        return PolicyState(np.full(n_ut, -1, np.int64), states, np.zeros((n_ut, n_unit), bool))

    def decide(self, epoch, state, n_beam):
        changed = _changed(epoch, state, self.level, n_beam)
        states = [s.reset(changed) for s in state.triggers]
        needs = self.prepare.needs + sum((t.needs for t in self.execute), ())
        ep = epoch if self.level == "cell" else to_satellites(epoch, n_beam, needs)
        states[0], _ = evaluate(self.prepare, states[0], ep)
        with np.errstate(invalid="ignore"):
            ready = ep.t_s - states[0].triggered_at_s >= self.preparation_delay_s - TIME_TOL_S
        admitted = np.where(changed[:, None], False, state.prepared)
        prepared = _admit(admitted, ready, self.prepare.rank(ep), self.max_prepared)
        applicable = neighbours(ep, prepared.shape[1]) & prepared
        fulfilled, report = prepared.copy(), None
        for i, trig in enumerate(self.execute, start=1):
            enter, leave = trig.conditions(ep)
            states[i], rep = advance(
                states[i], ep.t_s, enter, leave, trig.time_to_trigger_s, applicable
            )
            fulfilled &= states[i].triggered
            report = rep if report is None else report
        unit = pick(fulfilled, self.execute[0].rank(ep))
        target = _level_target(unit, epoch, self.level, n_beam)
        serving = np.asarray(epoch.serving, np.int64).copy()
        return Decision(target, prepared, report), PolicyState(serving, tuple(states), prepared)

    def __repr__(self):
        return (
            f"ConditionalHandover(prepare={self.prepare!r}, execute={self.execute!r}, "
            f"max_prepared={self.max_prepared}, preparation_delay_s={self.preparation_delay_s})"
        )
