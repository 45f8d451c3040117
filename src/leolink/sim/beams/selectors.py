"""Active-beam selectors as a pluggable kind: ``satellite_array.active_beams``.

Each epoch a selector says which codebook beams every satellite lights (at most one per
RF chain, Sec. 2.1 of [1]); the physics is :mod:`leolink.sim.beams.active`. Only lit beams
radiate, so only they interfere (:meth:`leolink.engine.LinkEngine.serve_pairs` with
``lit``), and the controller chooses among lit beams (:meth:`BeamSelector.restrict`).

A UT whose best beam is dark (``dark_fallback``):

- ``"neighbour"``: it is served by its best *lit* beam, of any satellite (typically an
  adjacent cell a few dB down), if that beam passes the controller's SNR threshold;
- ``"wait"``: it gets no candidate this epoch and is in outage until its own beam is lit
  (the beam-hopping model: a UT is served during its beam's dwell).

Selectors (registry :data:`BEAM_SELECTORS`):

- ``"all"``: every beam, always (today's leolink; the codebook may not hold more beams
  than chains, and nothing of the run changes: the selector is not even consulted);
- ``"demand"``: the ``n_rf`` beams whose cells (UTs whose best beam of all it is) hold
  the most UTs (:func:`leolink.sim.beams.active.select_demand`), re-chosen every epoch;
- ``"hopping"``: a fixed illumination pattern cycled over the codebook, one row per dwell
  of ``dwell_epochs`` epochs (:func:`leolink.sim.beams.active.default_hopping_pattern` unless a
  ``pattern`` is given), the same on every satellite.

With a selector other than ``"all"`` the candidate search keeps every visible cell of a
UT, not only those within the policy's window of its best cell: a lit neighbour may be
further down than the window.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
"""

from __future__ import annotations

from typing import Literal, Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.errors import ConfigError
from leolink.registry import Params, Registry
from leolink.sim.beams import active as beams
from leolink.sim.candidates.table import Candidates

__all__ = ["BEAM_SELECTORS", "AllBeams", "BeamSelector", "DemandBeams", "HoppingBeams"]


@runtime_checkable
class BeamSelector(Protocol):
    """Which beams are lit each epoch (module docstring)."""

    #: ``"all"`` lights every beam: the run is today's (no selector consulted).
    lights_all: bool
    dark_fallback: str

    def lit(self, k: int, best_cell: np.ndarray, n_sat: int) -> np.ndarray:
        """Lit beams of every satellite at epoch ``k``, bool ``(n_sat, n_beam)``;
        ``best_cell (n_ut,)``: each UT's best cell of all beams (-1: none)."""
        ...


#: Beam selectors by config name (``satellite_array.active_beams``).
BEAM_SELECTORS: Registry[BeamSelector] = Registry("satellite_array.active_beams", BeamSelector)

_FALLBACK_DOC = (
    "a UT whose best beam is dark: 'neighbour' = served by its best lit beam, "
    "'wait' = outage until its beam is lit"
)


class AllBeams:
    """Every beam lit at every epoch (today's leolink; beams <= RF chains)."""

    lights_all = True
    dark_fallback = "neighbour"

    def __init__(self, n_beam, n_rf):
        beams.select_all(1, n_beam, n_rf)  # refuses more beams than chains
        self.n_beam = n_beam

    def lit(self, k, best_cell, n_sat):
        return np.ones((n_sat, self.n_beam), bool)


class DemandConfig(Params):
    dark_fallback: Literal["neighbour", "wait"] = Field("neighbour", description=_FALLBACK_DOC)


class DemandBeams:
    """The n_rf beams whose cells hold the most UTs, re-chosen every epoch."""

    lights_all = False

    def __init__(self, n_beam, n_rf, dark_fallback="neighbour"):
        self.n_beam, self.n_rf, self.dark_fallback = n_beam, n_rf, dark_fallback

    def lit(self, k, best_cell, n_sat):
        nb = self.n_beam
        ok = best_cell >= 0
        sat = np.where(ok, best_cell // nb, -1)
        counts = beams.cell_counts(sat, np.where(ok, best_cell % nb, -1), n_sat, nb)
        return beams.select_demand(counts, self.n_rf)


class HoppingConfig(Params):
    dwell_epochs: int = Field(
        1, ge=1, le=1_000_000, description="epochs each row of the pattern stays lit"
    )
    pattern: list[list[int]] = Field(
        [],
        description="beam ids lit in each dwell, one list per dwell, at most n_rf each "
        "(empty: ceil(n_beam / n_rf) dwells, dwell g lighting beams g, g + G, ...)",
    )
    dark_fallback: Literal["neighbour", "wait"] = Field("wait", description=_FALLBACK_DOC)


def _check_dwell(g, row, n_beam, n_rf):
    """Refuse dwell ``g`` of a hopping pattern unless it names at most ``n_rf`` distinct beam
    ids of the codebook (a repeated id would hide a row longer than the RF chains)."""
    said = f"satellite_array.hopping.pattern[{g}] = {row!r} is not allowed: "
    if any(not 0 <= b < n_beam for b in row):
        raise ConfigError(said + f"beam ids are 0 .. {n_beam - 1} ({n_beam} beams)")
    if len(set(row)) != len(row):
        raise ConfigError(said + "give each beam id once per dwell")
    if len(row) > n_rf:
        raise ConfigError(
            said + f"{len(row)} beams for n_rf = {n_rf} RF chains (one beam per chain)"
        )


class HoppingBeams:
    """A beam-hopping illumination pattern cycled over the codebook (DVB-S2X Annex E)."""

    lights_all = False

    def __init__(self, n_beam, n_rf, dwell_epochs=1, pattern=(), dark_fallback="wait"):
        self.dwell_epochs, self.dark_fallback = int(dwell_epochs), dark_fallback
        if len(pattern) == 0:
            table = beams.default_hopping_pattern(n_beam, n_rf)
        else:
            table = np.zeros((len(pattern), n_beam), bool)
            for g, row in enumerate(pattern):
                _check_dwell(g, row, n_beam, n_rf)
                table[g, row] = True
        try:
            self.pattern = beams.validate_pattern(table, n_rf)
        except ConfigError as exc:
            raise ConfigError(f"satellite_array.{exc}") from None

    def lit(self, k, best_cell, n_sat):
        row = self.pattern[(k // self.dwell_epochs) % self.pattern.shape[0]]
        return np.broadcast_to(row, (n_sat, row.size))


def _build(cls):
    def build(params, context):
        return cls(context.n_beam, context.n_rf, **dict(params))

    return build


BEAM_SELECTORS.add("all", _build(AllBeams), doc="every beam lit (beams <= RF chains)")
BEAM_SELECTORS.add(
    "demand",
    _build(DemandBeams),
    config=DemandConfig,
    doc="the n_rf beams whose cells hold the most UTs, each epoch",
)
BEAM_SELECTORS.add(
    "hopping",
    _build(HoppingBeams),
    config=HoppingConfig,
    doc="a beam-hopping pattern cycled over the codebook",
)


def restrict(table, lit, best_cell, fallback):
    """The candidate table the controller chooses from: dark cells NaN.

    Parameters
    ----------
    table : Candidates
        Cells (global ids ``sat * n_beam + beam``) and their SNR [dB].
    lit : ndarray of bool, shape (n_sat, n_beam)
    best_cell : ndarray of int, shape (n_ut,)
        Each UT's best cell over all beams, -1 for none.
    fallback : {"neighbour", "wait"}

    Returns
    -------
    Candidates
        ``snr_db`` NaN on dark cells, and on every cell of a UT whose best cell is dark
        under ``"wait"``.
    """
    flat = lit.reshape(-1)
    keep = (table.cell >= 0) & flat[np.maximum(table.cell, 0)]
    if fallback == "wait":
        dark = (best_cell >= 0) & ~flat[np.maximum(best_cell, 0)]
        keep &= ~dark[:, None]
    return Candidates(table.cell, np.where(keep, table.snr_db, np.nan))
