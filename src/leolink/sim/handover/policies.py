"""Beam-selection policies: a declared protocol, one registry, pure vectorized rules.

Every epoch the controller (:func:`leolink.sim.handover.controller.step`) hands a policy the
candidate table of every UT (:class:`~leolink.sim.candidates.table.Candidates`): the cells
``cell = sat_id * n_beam + beam_id`` a UT may be served by and their SNR, already masked:
NaN marks every unusable candidate (no link, or SNR below the service threshold).
:func:`best_candidate` and :func:`value_at` read a table (or a dense ``(n_ut, n_cand)``
matrix whose column index is the cell, as in the unit tests).

Policy protocol (:class:`Policy`)
---------------------------------
- ``choose(t_s, snr_db, state, future_snr_db=None) -> target (n_ut,) int``: pure (it must
  not mutate ``state``, a :class:`~leolink.sim.handover.controller.ControllerState`). ``target`` is
  the cell the UT should be served by now (``state.serving`` to stay). Wherever a UT
  has a usable candidate, ``target`` must be usable (or equal to a still-usable serving
  cell).
- ``lookahead_s`` [s]: 0, or the horizon at which the caller must evaluate
  ``future_snr_db`` (the same cells, the same masking) from the known ephemeris.
- ``time_to_trigger_s`` [s]: the controller switches to a target other than the serving
  cell only after the policy asked for that same target on every epoch during this
  long. A UT whose serving cell is unusable switches at once.
- ``neighbour_window_db`` [dB], optional (default ``inf``): the cells the decision can
  depend on besides the serving cell: those within this much of the UT's best cell.
  The simulator then evaluates only those (the table holds every cell within the
  window, and the serving cell); ``inf`` asks for every cell above the minimum
  elevation. A policy that looks only at its best and its serving cell declares 0.
- ``usable_cells_only`` (bool), optional (default False): the decision does not depend on
  cells below the service threshold (``controller.min_snr_db``) other than the serving
  cell; the simulator then leaves them out of the table too.
- ``same_as()``, optional: the name of a simpler registered policy that these parameters
  make this one (``hysteresis`` with 0 dB and 0 s is ``max_snr``), else None; ``leolink
  compare`` warns when a policy of its list is another one in disguise.

A new policy is one small class following this protocol, registered in :data:`POLICIES`
with its parameter model (``[controller.<name>]`` in the config); see docs/extending.md.
The paper (Palacios et al.) selects the best beam every epoch; it has no handover model,
so hysteresis, time-to-trigger and prediction are leolink additions.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.registry import Params, Registry
from leolink.sim.candidates.table import Candidates

__all__ = [
    "POLICIES",
    "Hysteresis",
    "MaxSnr",
    "Policy",
    "Predictive",
    "best_candidate",
    "neighbour_window_db",
    "predictive_score_db",
    "value_at",
]

# Predictive ranking: a candidate lost at t + lookahead ranks below every candidate that is
# still usable then; SNRs lie within +-1000 dB, so this offset keeps the order lexicographic.
_LOST_PENALTY_DB = 1.0e4


@runtime_checkable
class Policy(Protocol):
    """A beam-selection policy (module docstring)."""

    lookahead_s: float
    time_to_trigger_s: float

    def choose(self, t_s, snr_db, state, future_snr_db=None) -> np.ndarray: ...


#: Beam-selection policies by config name (``controller.policy``).
POLICIES: Registry[Policy] = Registry("controller.policy", protocol=Policy)


class HysteresisConfig(Params):
    margin_db: float = Field(
        0.0, ge=0.0, le=100.0, description="margin a new beam must win by [dB]"
    )
    time_to_trigger_s: float = Field(
        0.0, ge=0.0, le=3600.0, description="how long the margin must hold [s]"
    )


class PredictiveConfig(Params):
    lookahead_s: float = Field(10.0, gt=0.0, le=3600.0, description="prediction horizon [s]")
    margin_db: float = Field(
        0.0, ge=0.0, le=100.0, description="margin a new beam must win by [dB]"
    )


def neighbour_window_db(policy):
    """The policy's ``neighbour_window_db`` (module docstring), ``inf`` if it has none."""
    return float(getattr(policy, "neighbour_window_db", np.inf))


def best_candidate(snr_db):
    """Per-UT best cell ignoring NaN, of a :class:`Candidates` table or a dense matrix.

    Returns ``(cell (n_ut,) int64, value (n_ut,) float)``; -1 and NaN where every
    candidate is NaN. Ties go to the lowest cell (``numpy.argmax`` over a dense matrix).
    """
    if isinstance(snr_db, Candidates):
        return snr_db.best()
    snr_db = np.asarray(snr_db, float)
    if snr_db.shape[1] == 0:
        return np.full(snr_db.shape[0], -1, np.int64), np.full(snr_db.shape[0], np.nan)
    filled = np.where(np.isnan(snr_db), -np.inf, snr_db)
    idx = np.argmax(filled, axis=1)
    val = filled.reshape(-1)[np.arange(len(idx)) * filled.shape[1] + idx]
    ok = val > -np.inf
    return np.where(ok, idx, -1).astype(np.int64), np.where(ok, val, np.nan)


def value_at(snr_db, cand):
    """The SNR of cell ``cand[i]`` of UT ``i`` (a :class:`Candidates` table or a dense
    matrix ``snr_db[i, cand[i]]``), NaN where ``cand < 0`` or the cell is absent."""
    if isinstance(snr_db, Candidates):
        return snr_db.value_at(cand)
    snr_db = np.asarray(snr_db, float)
    cand = np.asarray(cand, np.int64)
    if snr_db.shape[1] == 0:
        return np.full(cand.shape, np.nan)
    # A flat gather: several times cheaper than take_along_axis for a few candidates.
    flat = np.ascontiguousarray(snr_db).reshape(-1)
    val = flat[np.arange(len(cand)) * snr_db.shape[1] + np.maximum(cand, 0)]
    return np.where(cand >= 0, val, np.nan)


def _values(x):
    """The SNR array of a table or a matrix."""
    return x.snr_db if isinstance(x, Candidates) else np.asarray(x, float)


def _table(x):
    return x if isinstance(x, Candidates) else np.asarray(x, float)


def _switch_or_stay(serving, score, margin_db):
    """Target = best by ``score`` if it strictly beats the serving one by >= margin."""
    best, best_score = best_candidate(score)
    serv_score = value_at(score, serving)
    beats = (best_score - serv_score >= margin_db) & (best_score > serv_score)
    keep = np.isfinite(serv_score) & ~beats
    return np.where(keep, serving, best)


@POLICIES.register("max_snr")
class MaxSnr:
    """The paper's rule: serve every UT by its best candidate, re-chosen every epoch."""

    lookahead_s = 0.0
    time_to_trigger_s = 0.0
    neighbour_window_db = 0.0  # the best cell only

    def choose(self, t_s, snr_db, state, future_snr_db=None):
        return best_candidate(snr_db)[0]

    def __repr__(self):
        return "MaxSnr()"


@POLICIES.register("hysteresis", config=HysteresisConfig)
class Hysteresis:
    """Switch only when a candidate beats the serving one by >= ``margin_db`` [dB].

    The switch happens once the same candidate has been ahead for ``time_to_trigger_s``
    [s] (bookkept by :func:`step`, as 3GPP event A3). A tie never triggers a switch. A UT
    whose serving candidate became unusable goes to its best candidate at once.
    """

    lookahead_s = 0.0
    #: The decision compares the best cell with the serving one (always in the table).
    neighbour_window_db = 0.0

    def __init__(self, margin_db=3.0, time_to_trigger_s=0.0):
        self.margin_db = float(margin_db)
        self.time_to_trigger_s = float(time_to_trigger_s)

    def choose(self, t_s, snr_db, state, future_snr_db=None):
        return _switch_or_stay(state.serving, _table(snr_db), self.margin_db)

    def same_as(self):
        """The simpler policy these parameters make this one (None: none): with no margin
        and no time-to-trigger it switches whenever a cell beats the serving one, which is
        :class:`MaxSnr` (but for exact ties, which keep the serving cell)."""
        return "max_snr" if self.margin_db == 0.0 and self.time_to_trigger_s == 0.0 else None

    def __repr__(self):
        return f"Hysteresis(margin_db={self.margin_db}, time_to_trigger_s={self.time_to_trigger_s})"


def predictive_score_db(snr_db, future_snr_db):
    """Rank of a candidate for :class:`Predictive`: ``min(snr now, snr at t + lookahead)``.

    A candidate unusable at ``t + lookahead`` (NaN there) scores its current SNR minus a
    large penalty, so it ranks below every candidate still usable then but is still
    chosen, by current SNR, when no candidate survives. NaN where unusable now.
    """
    now, future = _values(snr_db), _values(future_snr_db)
    score = np.where(np.isnan(future), now - _LOST_PENALTY_DB, np.minimum(now, future))
    return snr_db.like(score) if isinstance(snr_db, Candidates) else score


@POLICIES.register("predictive", config=PredictiveConfig)
class Predictive:
    """Hand over to the candidate with the best ``min(snr now, snr at t + lookahead_s)``.

    A switch is due when another candidate beats the serving one by >= ``margin_db`` by
    that metric (or the serving one became unusable); the UT then avoids a beam that it
    would leave right away. ``future_snr_db`` comes from the known ephemeris.
    """

    time_to_trigger_s = 0.0
    #: The best score, min(now, future), may belong to a cell far below the best now.
    neighbour_window_db = np.inf
    #: ... but never to one below the service threshold now: the controller masks it (NaN
    #: now scores NaN, :func:`predictive_score_db`), so the search may leave it out.
    usable_cells_only = True

    def __init__(self, lookahead_s=10.0, margin_db=0.0):
        self.lookahead_s = float(lookahead_s)
        self.margin_db = float(margin_db)

    def choose(self, t_s, snr_db, state, future_snr_db=None):
        if future_snr_db is None:
            raise ValueError("Predictive.choose needs future_snr_db evaluated at t + lookahead_s")
        score = predictive_score_db(snr_db, future_snr_db)
        return _switch_or_stay(state.serving, score, self.margin_db)

    def __repr__(self):
        return f"Predictive(lookahead_s={self.lookahead_s}, margin_db={self.margin_db})"
