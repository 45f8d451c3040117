"""The slotted policy: satellites reassigned on a fixed time grid, held in between.

Starlink's terminals are reassigned by a global controller on a 15 s grid: Mohan et al.
measured "globally synchronized 15-second reconfiguration intervals" [1], and third-party
tools place the instants 12, 27, 42 and 57 s past the UTC minute. ``controller.policy =
"slotted"`` models that schedule:

- **Slot boundaries** are the instants ``phase_s + k * slot_s`` (seconds past the UTC
  minute when ``run.start_utc`` is known, else of simulation time). The decision is taken
  at the first epoch at or after each boundary (the epoch ``t`` whose ``(t - epoch_s, t]``
  holds it; with ``epoch_s`` dividing ``slot_s`` and ``phase_s`` that is the boundary).
- **At a boundary** every UT is given a satellite by ``rule``, over its usable cells
  (SNR at or above ``controller.min_snr_db``):

  - ``"max_snr"``: the satellite of the best cell;
  - ``"through_slot"``: the best ``min(SNR now, SNR at the next boundary)``, a cell lost
    by then ranking below every cell that survives (the predictive score,
    :func:`~leolink.sim.handover.policies.predictive_score_db`, with the look-ahead
    ``slot_s``): the satellite that serves longest, to one slot's resolution;
  - ``"least_loaded"``: the satellite serving the fewest UTs at the previous epoch (the
    controller's view before this epoch's reassignment), ties by best SNR.

- **Between boundaries** the UT holds its satellite. The beam inside it follows the best
  SNR every epoch (beam management: with ``[cells] per = "satellite"`` a ``beam_switch``,
  with ``"beam"`` a ``beam_handover``).
- **Breaking the hold**: a UT whose held satellite has no usable cell left (it set below
  the mask, or its SNR fell below the service threshold) is reassigned at once by the
  same rule; after a radio link failure (``[controller.rlf]``) the UT has no serving cell
  and re-establishes on the rule's choice at once, not at the next boundary. Both are
  off-grid handovers, counted as any other.

References
----------
.. [1] N. Mohan et al., "A Multifaceted Look at Starlink Performance", Proc. ACM Web
   Conference (WWW) 2024, pp. 2723-2734, arXiv:2310.09242.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from leolink.registry import Params
from leolink.sim.candidates.table import Candidates
from leolink.sim.handover.policies import POLICIES, best_candidate, predictive_score_db

__all__ = ["RULES", "Slotted", "SlottedConfig", "slot_boundary"]

RULES = ("max_snr", "through_slot", "least_loaded")
# Epoch times accumulate float rounding (k * 0.1 s); 1 ns is far below any epoch length.
_TIME_TOL_S = 1e-9
# Lexicographic scores: SNRs lie within +-1000 dB, so a load step of 1e4 dB dominates.
_LOAD_STEP_DB = 1.0e4


class SlottedConfig(Params):
    slot_s: float = Field(15.0, gt=0.0, le=86_400.0, description="reassignment period [s]")
    phase_s: float = Field(
        12.0,
        ge=0.0,
        le=86_400.0,
        description="first boundary, seconds past the UTC minute (run time without "
        "run.start_utc) [s]; Starlink: 12 (12, 27, 42, 57)",
    )
    rule: Literal[RULES] = Field(  # type: ignore[valid-type]
        "max_snr",
        description="choice at a boundary: 'max_snr' best SNR, 'through_slot' best "
        "min(SNR now, SNR at the next boundary), 'least_loaded' fewest UTs on the satellite",
    )


def slot_boundary(t_s, epoch_s, slot_s, phase_s, offset_s=0.0):
    """True when a boundary ``phase_s + k slot_s`` lies in ``(t - epoch_s, t]``.

    ``offset_s``: seconds past the UTC minute of simulation time 0 (0 without UTC), so
    the grid is ``t + offset_s = phase_s (mod slot_s)``.
    """

    def index(t):
        return math.floor((t + offset_s - phase_s) / slot_s + _TIME_TOL_S / slot_s)

    return index(t_s) > index(t_s - epoch_s)


class Slotted:
    """Reassign satellites at slot boundaries by ``rule``, hold them between (module
    docstring). ``n_beam``, ``epoch_s`` and ``utc_offset_s`` come from the run."""

    time_to_trigger_s = 0.0
    #: The held satellite's beams and every satellite's best cell count, near the best or not.
    neighbour_window_db = np.inf
    usable_cells_only = True

    def __init__(self, slot_s, phase_s, rule, n_beam, epoch_s, utc_offset_s=0.0):
        if rule not in RULES:
            raise ValueError(f"rule = {rule!r}; use one of {RULES}")
        self.slot_s, self.phase_s, self.rule = float(slot_s), float(phase_s), rule
        self.n_beam, self.epoch_s = n_beam, epoch_s  # None: built without a run
        self.utc_offset_s = float(utc_offset_s)
        self.lookahead_s = self.slot_s if rule == "through_slot" else 0.0

    def choose(self, t_s, snr_db, state, future_snr_db=None):
        if self.n_beam is None or self.epoch_s is None:
            raise ValueError("Slotted.choose needs the run's n_beam and epoch_s (build context)")
        table = snr_db if isinstance(snr_db, Candidates) else Candidates.dense(snr_db)
        if slot_boundary(t_s, self.epoch_s, self.slot_s, self.phase_s, self.utc_offset_s):
            return self._by_rule(table, state, future_snr_db)
        held = self._best_in(table, np.where(state.serving >= 0, state.serving // self.n_beam, -1))
        if (held >= 0).all():  # (most epochs: every UT keeps its satellite)
            return held
        return np.where(held >= 0, held, self._by_rule(table, state, future_snr_db))

    def _by_rule(self, table, state, future):
        """The cell each UT gets at a boundary: the rule's satellite, its best beam."""
        if self.rule == "max_snr":
            return best_candidate(table)[0]
        if self.rule == "through_slot":
            if future is None:
                raise ValueError("Slotted(rule='through_slot') needs future_snr_db at t + slot_s")
            fut = future if isinstance(future, Candidates) else Candidates.dense(future)
            score = predictive_score_db(table, fut)
        else:
            sat = np.where(table.cell >= 0, table.cell // self.n_beam, 0)
            serving = state.serving[state.serving >= 0] // self.n_beam
            load = np.bincount(serving, minlength=int(sat.max(initial=0)) + 1)
            score = table.like(table.snr_db - _LOAD_STEP_DB * load[sat])
        unit = best_candidate(score)[0]
        return self._best_in(table, np.where(unit >= 0, unit // self.n_beam, -1))

    def _best_in(self, table, sat):
        """Best usable cell of each UT inside satellite ``sat`` (n_ut,); -1 where none."""
        inside = (
            (table.cell >= 0) & (sat[:, None] >= 0) & (table.cell // self.n_beam == sat[:, None])
        )
        return best_candidate(table.like(np.where(inside, table.snr_db, np.nan)))[0]

    def __repr__(self):
        return (f"Slotted(slot_s={self.slot_s}, phase_s={self.phase_s}, rule={self.rule!r}, "
                f"epoch_s={self.epoch_s}, utc_offset_s={self.utc_offset_s})")  # fmt: skip


def _build(params, context=None):
    """The policy of ``[controller.slotted]`` for the run of ``context`` (``n_beam``,
    ``epoch_s`` and ``utc_offset_s`` of ``leolink.app.scenario._policy_context``); without
    one (``leolink compare`` asks a policy for ``same_as``) it cannot choose."""
    return Slotted(params.slot_s, params.phase_s, params.rule,
                   getattr(context, "n_beam", None), getattr(context, "epoch_s", None),
                   getattr(context, "utc_offset_s", 0.0))  # fmt: skip


POLICIES.add(
    "slotted",
    _build,
    doc="Satellites reassigned at slot boundaries (Starlink: 15 s), held between them.",
    config=SlottedConfig,
)
