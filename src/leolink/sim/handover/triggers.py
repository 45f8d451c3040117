"""Handover trigger events of TS 38.331, evaluated for every (UT, candidate) pair at once.

Each event is one small frozen dataclass holding its parameters; ``conditions(epoch)``
returns its entering and leaving inequalities as boolean arrays ``(n_ut, n_cand)``, and
:func:`evaluate` advances a shared :class:`TriggerState` with the time-to-trigger
bookkeeping of TS 38.331 5.5.4.1. The candidate axis is whatever the caller chose: cells
``cand = sat * n_beam + beam`` or satellites (see :mod:`leolink.sim.handover.decisions`).

Bookkeeping (TS 38.331 5.5.4.1, and 5.3.5.13.4 for conditional handover)
------------------------------------------------------------------------
A cell enters the triggered list (``cellsTriggeredList``; "fulfilled" for a CondEvent)
when its entering condition holds at every measurement during ``time_to_trigger_s``; it
leaves it when its leaving condition holds at every measurement during the same time. A
condition that stops holding restarts the count at its next entry. With epochs ``t_k``
and a run that holds from ``t_a`` on, the cell triggers at the first ``t_k`` with
``t_k - t_a >= time_to_trigger_s`` (so ``time_to_trigger_s = 0`` triggers on ``t_a``).
Between the entering and leaving inequalities (the hysteresis band) the state is kept.

State representation: dense ``(n_ut, n_cand)`` arrays. The standard runs one TTT per
cell, so keeping only each UT's best candidate would restart a TTT that another cell
is legitimately running; dense arrays are exact. Memory: two float64 arrays, 16 bytes
per pair, i.e. 48 MB for 10 000 UTs x 300 cells (20 satellites x 15 beams); rows are
independent, so a caller may chunk UTs. A satellite-level trigger needs n_beam times less.

NaN: a comparison with NaN is false, so an unmeasurable quantity never enters; a NaN
in any quantity of the leaving inequality makes it hold (the cell can no longer be
measured and leaves after the TTT). This is a leolink decision; the standard assumes
the cell is measured.

References
----------
.. [1] 3GPP TS 38.331 V18.5.1, "NR; Radio Resource Control (RRC); Protocol
   specification", 5.5.4.1 General, 5.5.4.4 A3, 5.5.4.5 A4, 5.5.4.6 A5, 5.5.4.15 D1,
   5.5.4.15a D2, 5.5.4.16 CondEvent T1, 5.3.5.13.4 conditional reconfiguration
   evaluation, 5.5.6.1 actions upon handover.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, ClassVar, Protocol

import numpy as np

from leolink.errors import ConfigError, require_at_least

# Epoch times accumulate float rounding (k * 0.1 s); 1 ns is far below any epoch length.
TIME_TOL_S = 1e-9


@dataclasses.dataclass(frozen=True)
class Epoch:
    """What the triggers may read at one epoch; a trigger reads only the fields it needs.

    Attributes
    ----------
    t_s : float [s], epoch time (UE time ``Mt`` of T1).
    serving : int64 (n_ut,), serving index on the candidate axis, -1 for none.
    meas : float (n_ut, n_cand) or None, trigger quantity after layer-3 filtering
        (RSRP [dBm] or SINR [dB]; ``Mn``, and ``Mp`` at the serving index); NaN = not
        measurable.
    offset_db : float, (n_cand,) or (n_ut, n_cand) [dB], ``Ofn + Ocn`` of each candidate
        (``Ofp + Ocp`` at the serving index), default 0.
    ut_pos_m : (n_ut, 3) [m] or None, UT positions (D1, D2), any Cartesian frame.
    ref_pos_m : (n_cand, 3) [m] or None, D1 reference locations ``reference = "beam"``:
        the cells' ground centres now (the beams' boresight points).
    cell_ref_pos_m : the same, ``reference = "cell"``: the Earth-fixed cells of
        ``satellite_array.steering = "earth_fixed"``.
    point_ref_pos_m : the same, ``reference = "points"``: the configured referenceLocation
        of each cell (``[[controller.reference_points]]``), NaN for a cell without one.
    moving_ref_pos_m : (n_cand, 3) [m] or None, D2 moving reference locations at ``t_s``
        (one row per satellite when D2 runs on the satellite axis, its default).
    elevation_rad : (n_ut, n_cand) [rad] or None, elevation of each candidate seen by the UT
        (for a satellite-level policy the trigger run gives it per satellite, ``(n_ut,
        n_cand // n_beam)``, which :func:`~leolink.sim.handover.decisions.to_satellites`
        keeps).
    service_end_s : (n_ut, n_cand) or (n_cand,) [s] or None (per satellite likewise for a
        satellite-level policy), absolute time at which each
        candidate stops serving the UT (drops below the service threshold), from the
        ephemeris look-ahead; ``inf`` beyond the horizon, NaN if not serving now (T1,
        time_to_exit).
    """

    t_s: float
    serving: np.ndarray
    meas: np.ndarray | None = None
    offset_db: Any = 0.0
    ut_pos_m: np.ndarray | None = None
    ref_pos_m: np.ndarray | None = None
    cell_ref_pos_m: np.ndarray | None = None
    point_ref_pos_m: np.ndarray | None = None
    moving_ref_pos_m: np.ndarray | None = None
    elevation_rad: np.ndarray | None = None
    service_end_s: np.ndarray | None = None

    @property
    def n_ut(self):
        return len(self.serving)

    def need(self, name, who):
        """Field ``name`` as a float array; a clear error if the caller did not fill it."""
        value = getattr(self, name)
        if value is None:
            raise ValueError(f"{who} needs Epoch.{name}; the controller did not provide it")
        return np.asarray(value, float)

    @functools.cached_property
    def signal(self):
        """``(Mn + Ofn + Ocn, Mn, Mp + Ofp + Ocp, Mp)`` of the measurement events: ``meas``
        plus ``offset_db`` and ``meas`` ``(n_ut, n_cand)``, and their serving columns
        ``(n_ut, 1)``. Computed once per epoch: a policy's events read them several times
        (CHO: its prepare and execute conditions and their ranks)."""
        meas = np.asarray(self.meas, float)
        mn = meas + np.broadcast_to(np.asarray(self.offset_db, float), meas.shape)
        return mn, meas, self.at_serving(mn), self.at_serving(meas)

    def at_serving(self, values):
        """``values[i, serving[i]]`` per UT as a column ``(n_ut, 1)``; NaN without serving."""
        values = np.asarray(values, float)
        serving = np.asarray(self.serving, np.int64)
        if values.shape[-1] == 0:
            return np.full((len(serving), 1), np.nan)
        rows = np.broadcast_to(values, (len(serving), values.shape[-1]))
        got = rows[np.arange(len(serving)), np.maximum(serving, 0)]
        return np.where(serving >= 0, got, np.nan)[:, None]


@dataclasses.dataclass(frozen=True)
class TriggerState:
    """Per (UT, candidate) time-to-trigger state, arrays of shape ``(n_ut, n_cand)``.

    ``since_s`` [s]: start of the current run of the entering condition (cell not
    triggered) or of the leaving condition (cell triggered); NaN when no run.
    ``triggered_at_s`` [s]: time the cell entered the triggered list; NaN if not in it.
    """

    since_s: np.ndarray
    triggered_at_s: np.ndarray

    @classmethod
    def initial(cls, n_ut, n_cand):
        return cls(np.full((n_ut, n_cand), np.nan), np.full((n_ut, n_cand), np.nan))

    @property
    def triggered(self):
        """bool (n_ut, n_cand): the cell is in the triggered list (event fulfilled)."""
        return ~np.isnan(self.triggered_at_s)

    def reset(self, ut_mask):
        """Clear the rows of ``ut_mask`` (TS 38.331 5.5.6.1: upon handover the UE drops its
        measurement reporting entries, so every run and triggered cell starts afresh)."""
        rows = np.asarray(ut_mask, bool)
        if not rows.any():
            return self
        since, at = self.since_s.copy(), self.triggered_at_s.copy()
        since[rows] = np.nan
        at[rows] = np.nan
        return TriggerState(since, at)


@dataclasses.dataclass(frozen=True)
class TriggerReport:
    """What happened at one epoch, bool ``(n_ut, n_cand)`` each (for event accounting).

    ``entered``: the entering condition started to hold; ``lapsed``: it stopped holding
    before the time-to-trigger elapsed (the count restarts at the next entry);
    ``triggered``: the cell joined the triggered list; ``left``: it left the list after its
    leaving condition held for the time-to-trigger.
    """

    entered: np.ndarray
    lapsed: np.ndarray
    triggered: np.ndarray
    left: np.ndarray


#: Below this share of applicable pairs :func:`advance` works on those alone (a CHO
#: execution condition: the prepared candidates, ~1 % of the axis); the others' outcome is
#: known (no run, not triggered, nothing to report).
SPARSE_SHARE = 0.125


def advance(state, t_s, entering, leaving, time_to_trigger_s, applicable):
    """One epoch of the TS 38.331 5.5.4.1 bookkeeping; returns ``(state, report)``.

    ``entering``, ``leaving``, ``applicable``: bool ``(n_ut, n_cand)``. A cell that is not
    applicable (the serving cell itself, no serving cell, a CHO candidate not prepared)
    has no run and is not triggered. Where few cells are applicable (less than
    :data:`SPARSE_SHARE` of them) the rule runs on those alone.
    """
    applicable = np.asarray(applicable, bool)
    shape = state.since_s.shape
    if applicable.shape != shape or np.count_nonzero(applicable) >= SPARSE_SHARE * applicable.size:
        since, at, report = _advance_pairs(state.since_s, state.triggered_at_s, t_s, entering,
                                           leaving, time_to_trigger_s, applicable)  # fmt: skip
        return TriggerState(since, at), TriggerReport(*report)
    rows, cols = np.nonzero(applicable)
    since, at, report = _advance_pairs(
        state.since_s[rows, cols], state.triggered_at_s[rows, cols], t_s,
        np.broadcast_to(entering, shape)[rows, cols], np.broadcast_to(leaving, shape)[rows, cols],
        time_to_trigger_s, np.ones(rows.size, bool),
    )  # fmt: skip
    out = [np.full(shape, np.nan), np.full(shape, np.nan)] + [np.zeros(shape, bool) for _ in report]
    for full, values in zip(out, (since, at, *report), strict=True):
        full[rows, cols] = values
    return TriggerState(out[0], out[1]), TriggerReport(*out[2:])


def _advance_pairs(since_s, triggered_at_s, t_s, entering, leaving, time_to_trigger_s, applicable):
    """:func:`advance`'s rule on arrays of pairs (any shape, broadcast): the new
    ``since_s`` and ``triggered_at_s`` [s] and the report's four arrays."""
    was = ~np.isnan(triggered_at_s)
    running = ~np.isnan(since_s)
    cond = np.where(was, leaving, entering)
    cond &= applicable
    # (np.copyto where a mask says: a masked write, not a boolean index's gather)
    since = np.where(running, since_s, t_s)  # a run continues, or starts now
    np.copyto(since, np.nan, where=~cond)  # ... unless its condition lapsed
    done = t_s - since >= time_to_trigger_s - TIME_TOL_S  # NaN (no run) compares False
    now_in = done & ~was
    now_out = done & was
    triggered_at = np.where(now_in, t_s, triggered_at_s)
    np.copyto(triggered_at, np.nan, where=now_out | ~applicable)
    np.copyto(since, np.nan, where=done)
    entered = cond & ~running & ~was
    lapsed = running & ~cond & ~was & applicable
    return since, triggered_at, (entered, lapsed, now_in, now_out)


class Trigger(Protocol):
    """A trigger event: parameters, entering/leaving inequalities and a ranking."""

    time_to_trigger_s: float
    level: str  # default candidate axis: "cell" or "satellite" (leolink.sim.handover.decisions)
    needs: tuple[str, ...]  # the Epoch fields it reads
    # (optional) ``serving_only``: those of ``needs`` it reads at the serving index alone

    def conditions(self, epoch: Epoch) -> tuple[np.ndarray, np.ndarray]: ...

    def rank(self, epoch: Epoch) -> np.ndarray: ...


def neighbours(epoch, n_cand):
    """bool (n_ut, n_cand): candidates other than the serving one, for UTs with one."""
    serving = np.asarray(epoch.serving, np.int64)[:, None]
    return (serving >= 0) & (np.arange(n_cand)[None, :] != serving)


def evaluate(trigger, state, epoch):
    """Advance ``state`` by one epoch of ``trigger``; returns ``(state, report)``."""
    entering, leaving = trigger.conditions(epoch)
    applicable = neighbours(epoch, entering.shape[1])
    return advance(state, epoch.t_s, entering, leaving, trigger.time_to_trigger_s, applicable)


def any_nan(*arrays):
    """True where any input is NaN (broadcast)."""
    return np.logical_or.reduce([np.isnan(a) for a in np.broadcast_arrays(*arrays)])


def check_param(name, value, low, meaning):
    if not math.isfinite(value):
        raise ConfigError(f"controller.{name} = {value!r} is not allowed; use a finite number")
    require_at_least(f"controller.{name}", value, low, meaning)


def check_ttt(ttt_s):
    check_param("time_to_trigger_s", ttt_s, 0.0, "time-to-trigger [s]")


class _Signal:
    """Shared helpers of the measurement events (A3, A4, A5)."""

    level = "cell"
    needs = ("meas",)

    def rank(self, epoch):
        """Triggered cells rank by ``Mn + Ofn + Ocn``: an offset biases the choice as the
        trigger (the order is leolink's; the standard leaves the target to the network)."""
        return self._mn_mp(epoch)[0]

    def _mn_mp(self, epoch):
        epoch.need("meas", type(self).__name__)  # (a clear error without it)
        return epoch.signal


@dataclasses.dataclass(frozen=True)
class A3(_Signal):
    """Event A3, neighbour becomes offset better than SpCell (TS 38.331 5.5.4.4).

    Entering A3-1: ``Mn + Ofn + Ocn - Hys > Mp + Ofp + Ocp + Off``; leaving A3-2:
    ``Mn + Ofn + Ocn + Hys < Mp + Ofp + Ocp + Off``. ``offset_db`` = Off (a3-Offset,
    may be negative), ``hysteresis_db`` = Hys [dB]. Decides the cell (satellite and beam).
    """

    offset_db: float = 0.0
    hysteresis_db: float = 0.0
    time_to_trigger_s: float = 0.0

    def __post_init__(self):
        check_param("a3.hysteresis_db", self.hysteresis_db, 0.0, "hysteresis [dB]")
        check_param("a3.offset_db", self.offset_db, -math.inf, "a3-Offset [dB]")
        check_ttt(self.time_to_trigger_s)

    def conditions(self, epoch):
        mn, _, mp, _ = self._mn_mp(epoch)
        left, right = mn, mp + self.offset_db
        enter = left - self.hysteresis_db > right
        leave = (left + self.hysteresis_db < right) | any_nan(left, right)
        return enter, leave


@dataclasses.dataclass(frozen=True)
class _Threshold(_Signal):
    """The parameters of a one-threshold event (A2, A4) and their checks: ``threshold_db``
    (Thresh) and ``hysteresis_db`` (Hys) [dB], ``time_to_trigger_s`` [s]; ``_keys``: the
    config keys of the first two and the threshold's meaning, for the error message."""

    threshold_db: float = 0.0
    hysteresis_db: float = 0.0
    time_to_trigger_s: float = 0.0
    _keys: ClassVar[tuple[str, str, str]] = ("threshold_db", "hysteresis_db", "threshold")

    def __post_init__(self):
        threshold_key, hysteresis_key, meaning = self._keys
        check_param(threshold_key, self.threshold_db, -math.inf, meaning)
        check_param(hysteresis_key, self.hysteresis_db, 0.0, "hysteresis [dB]")
        check_ttt(self.time_to_trigger_s)


@dataclasses.dataclass(frozen=True)
class A2(_Threshold):
    """Event A2, serving becomes worse than threshold (TS 38.331 5.5.4.3).

    Entering A2-1: ``Ms + Hys < Thresh``; leaving A2-2: ``Ms - Hys > Thresh`` (``Ms``
    without offsets). A serving-cell event: its conditions are one column ``(n_ut, 1)``;
    no serving measurement leaves it.
    """

    _keys = ("a2a4.a2_threshold_db", "a2a4.hysteresis_db", "a2-Threshold")

    def conditions(self, epoch):
        ms = epoch.at_serving(epoch.need("meas", "A2"))
        enter = ms + self.hysteresis_db < self.threshold_db
        leave = (ms - self.hysteresis_db > self.threshold_db) | np.isnan(ms)
        return enter, leave


@dataclasses.dataclass(frozen=True)
class A4(_Threshold):
    """Event A4, neighbour becomes better than threshold (TS 38.331 5.5.4.5).

    Entering A4-1: ``Mn + Ofn + Ocn - Hys > Thresh``; leaving A4-2:
    ``Mn + Ofn + Ocn + Hys < Thresh``. Decides the cell.
    """

    _keys = ("a4.threshold_db", "a4.hysteresis_db", "a4-Threshold [dB or dBm]")

    def conditions(self, epoch):
        mn, _, _, _ = self._mn_mp(epoch)
        enter = mn - self.hysteresis_db > self.threshold_db
        leave = (mn + self.hysteresis_db < self.threshold_db) | np.isnan(mn)
        return enter, leave


@dataclasses.dataclass(frozen=True)
class A5(_Signal):
    """Event A5, SpCell worse than threshold1 and neighbour better than threshold2
    (TS 38.331 5.5.4.6).

    Entering: A5-1 ``Mp + Hys < Thresh1`` and A5-2 ``Mn + Ofn + Ocn - Hys > Thresh2``;
    leaving: A5-3 ``Mp - Hys > Thresh1`` or A5-4 ``Mn + Ofn + Ocn + Hys < Thresh2``.
    ``Mp`` is taken without offsets, as the clause says. Decides the cell.
    """

    threshold1_db: float = 0.0
    threshold2_db: float = 0.0
    hysteresis_db: float = 0.0
    time_to_trigger_s: float = 0.0

    def __post_init__(self):
        check_param("a5.threshold1_db", self.threshold1_db, -math.inf, "a5-Threshold1")
        check_param("a5.threshold2_db", self.threshold2_db, -math.inf, "a5-Threshold2")
        check_param("a5.hysteresis_db", self.hysteresis_db, 0.0, "hysteresis [dB]")
        check_ttt(self.time_to_trigger_s)

    def conditions(self, epoch):
        mn, _, _, mp = self._mn_mp(epoch)
        hys = self.hysteresis_db
        enter = (mp + hys < self.threshold1_db) & (mn - hys > self.threshold2_db)
        leave = (mp - hys > self.threshold1_db) | (mn + hys < self.threshold2_db)
        return enter, leave | any_nan(mn, mp)
