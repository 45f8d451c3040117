"""One run of a trigger policy: the epoch inputs, the per-cell state across epochs, the target.

The policies of :mod:`leolink.sim.handover.decisions` are pure and dense: ``decide(epoch, state,
n_beam)`` on a candidate axis ``cand = sat * n_beam + beam``. :class:`TriggerRun` drives
one of them through a run whose candidates come as sparse per-UT tables
(:class:`~leolink.sim.candidates.table.Candidates`, global cell ids), every epoch:

1. the UT's :class:`~leolink.sim.handover.local_axis.LocalAxis` (the satellites of this table and
   those of the last axis that still have live state) and the policy and filter state
   carried onto it by global satellite id; for a cell-level policy that reads only the
   measurements (A3, A4, A5, a2a4, CHO of those) the axis holds cells instead: the
   table's and those with live state;
2. the measurements: the table's SNR [dB] of the cells the UT detects, those at or above
   the service threshold (``controller.min_snr_db``), NaN elsewhere, layer-3 filtered
   (:func:`~leolink.sim.handover.measurements.l3_update`, ``[controller.filter]``). A cell below
   the threshold is not detected (TS 38.133 detects a cell only above a side condition,
   its SS-SINR / Es/Iot): its filter restarts when it is detected again, it never enters
   and is never a target (docs/errata.md). So nothing here depends on cells below the
   threshold, and the policy declares ``usable_cells_only``: the candidate search leaves
   them out (:mod:`leolink.sim.candidates.search`), which changes no decision;
3. the other :class:`~leolink.sim.handover.triggers.Epoch` fields the policy ``needs``, NaN
   wherever the candidate is not usable now (so it never enters either): ``ut_pos_m``;
   ``ref_pos_m``, the cells' ground centres now (D1: each beam's boresight on the
   sphere; beams are fixed in the satellite body, so these move with the satellite:
   leolink has earth-moving cells only); ``moving_ref_pos_m``, the satellites' nadir
   points now (D2); ``elevation_rad``; ``service_end_s`` from the ephemeris look-ahead
   (:mod:`leolink.sim.handover.service_time`), of the serving satellite alone (NaN
   elsewhere) when every trigger reading it reads the serving's only (T1's Thresh1);
4. ``decide``; the target is turned back into a global cell. A UT without a usable
   serving cell (first assignment, serving cell lost) gets its best usable cell, as
   under every policy (the controller switches such a UT at once).

The controller (:func:`leolink.sim.handover.controller.step`) then executes the target with its
own time-to-trigger at 0: the policy owns its time-to-trigger.
"""

from __future__ import annotations

import numpy as np

from leolink.arrays import KeyTable, any_per_group, nonzero_2d
from leolink.geometry import ray_to_ground
from leolink.sim.handover.decisions import PolicyState
from leolink.sim.handover.local_axis import LocalAxis
from leolink.sim.handover.measurements import L3State, l3_update
from leolink.sim.handover.service_time import ServiceTimes
from leolink.sim.handover.triggers import Epoch, TriggerState

__all__ = ["TriggerRun"]


class TriggerRun:
    """The state of one trigger policy over one run (module docstring).

    Parameters
    ----------
    policy : TriggerPolicy or ConditionalHandover (``leolink.sim.handover.decisions``)
    l3 : L3Filter, layer-3 filter parameters.
    engine : LinkEngine (beam directions ``codebook.u_xy``, ``n_beam``).
    min_snr_db : float [dB], service threshold.
    radius_m : float [m], Earth radius (ground points).
    future_state : callable, the run's future (see ServiceTimes); used only if the
        policy needs ``service_end_s``.
    epoch_s, horizon_s : float [s], epoch and look-ahead horizon.
    """

    def __init__(self, policy, l3, engine, min_snr_db, radius_m, future_state, epoch_s, horizon_s):
        self.policy, self.l3 = policy, l3
        self.engine, self.n_beam = engine, engine.n_beam
        self.min_snr_db, self.radius_m = float(min_snr_db), float(radius_m)
        self.u_xy = np.asarray(engine.codebook.u_xy, float)
        needs = policy.needs
        self.service = (
            ServiceTimes(engine, future_state, min_snr_db, epoch_s, horizon_s)
            if "service_end_s" in needs
            else None
        )
        self.serving_end_only = _serving_only(policy, "service_end_s")
        # The units of the local axis: cells for a cell-level policy that reads only the
        # measurements (and the UT positions), so its state is kept for the detected cells
        # alone; satellites (each with all its beams) for the others.
        self.axis_beams = 1 if _on_cells(policy) else self.n_beam
        self.axis, self.pstate, self.filt = None, None, None
        self.cell_offsets = ()  # (sat_id, beam_id or None, Ocn [dB]): the entry sets them
        # D1's configured reference locations: (sat_id, beam_id or None, (x, y, z) [m]).
        self.reference_points = ()
        self._points = None  # their KeyTable, built at the first epoch
        self._ocn = None  # KeyTable of Ocn by global cell, built at the first epoch
        # The measurement stage (measurement_model.MeasurementRun); None: every detected
        # cell every epoch, without error, in SNR (the entry sets it).
        self.measurement = None

    # -- state across epochs ---------------------------------------------------------------
    def _live_sats(self):
        """(ut, sat) of the last axis's satellites that still hold state."""
        axis = self.axis
        if axis.n_local == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        arrays = [~np.isnan(self.filt.value)]
        arrays += [
            ~np.isnan(a) for t in self.pstate.triggers for a in (t.since_s, t.triggered_at_s)
        ]
        if self.pstate.prepared is not None:
            arrays.append(self.pstate.prepared)
        live, per_cell = np.zeros(axis.sats.shape, bool), None
        for mask in arrays:  # per satellite, or per cell: those reduced once, joined
            if mask.shape == live.shape:
                live |= mask
            else:
                per_cell = mask if per_cell is None else per_cell | mask
        if per_cell is not None:
            live |= any_per_group(per_cell, axis.n_beam)
        rows, slots = nonzero_2d(live & (axis.sats >= 0))
        return rows, axis.sats[rows, slots]

    def _axis(self, table, serving):
        nb = self.axis_beams
        rows, slots = nonzero_2d(table.cell >= 0)
        ut = [rows, np.arange(table.n_ut)]
        sat = [table.cell[rows, slots] // nb, np.where(serving >= 0, serving // nb, -1)]
        if self.axis is not None:
            r, s = self._live_sats()
            ut.append(r)
            sat.append(s)
        return LocalAxis.union(table.n_ut, nb, np.concatenate(ut), np.concatenate(sat))

    def _carry(self, axis):
        """Policy state and filter on ``axis`` (initial at the first epoch)."""
        n_ut = axis.n_ut
        # (an empty last axis, every UT out of coverage, carries nothing; its zero-width
        # state could not tell a satellite axis from a cell axis)
        if self.axis is None or self.axis.n_local == 0:
            return self.policy.initial_state(n_ut, axis.n_cand, axis.n_beam), L3State.initial(
                n_ut, axis.n_cand
            )
        old, ps = self.axis, self.pstate
        trig = tuple(
            TriggerState(
                old.remap(axis, t.since_s, np.nan), old.remap(axis, t.triggered_at_s, np.nan)
            )
            for t in ps.triggers
        )
        prepared = None if ps.prepared is None else old.remap(axis, ps.prepared, False)
        serving = axis.local_cell(old.global_cell(ps.serving))
        filt = L3State(old.remap(axis, self.filt.value, np.nan), self.filt.t_s)
        # (a per-UT gate has no cell axis: it is carried as it is)
        return PolicyState(serving, trig, prepared, ps.gate), filt

    # -- the epoch's inputs ----------------------------------------------------------------
    def _offsets(self, axis):
        """Ocn of every local cell ``(n_ut, n_local * n_beam)`` [dB], 0 where none is set
        (a later entry for a cell wins)."""
        nb = self.n_beam
        if self._ocn is None:
            cells, values = [], []
            for sat, beam, db in self.cell_offsets:
                beams = np.arange(nb) if beam is None else np.array([beam])
                cells.append(sat * nb + beams)
                values.append(np.full(beams.size, float(db)))
            self._ocn = KeyTable(np.concatenate(cells), np.concatenate(values))
        local = self._cells(axis)
        return np.where(local >= 0, self._ocn.get(local, 0.0), 0.0)

    @staticmethod
    def _cells(axis):
        """The global cell id of every local cell, ``(n_ut, n_cand)``, -1 in unused slots."""
        ab = axis.n_beam  # the local units' beams: 1 on a cell axis
        local = (axis.sats[:, :, None] * ab + np.arange(ab)).reshape(axis.n_ut, -1)
        return np.where(np.repeat(axis.sats, ab, axis=1) >= 0, local, -1)

    def _fields(self, t_s, axis, usable, ut_pos_m, sat_pos_m, sat_vel_m_s, ut_up, serving=None):
        """The Epoch fields of ``policy.needs`` besides ``meas``, NaN where not usable
        (``serving``: the local serving cells, -1 for none; None: every usable satellite's
        end of service is looked ahead)."""
        needs, nb = self.policy.needs, self.n_beam
        fields = {}
        if "ut_pos_m" in needs:
            fields["ut_pos_m"] = ut_pos_m
        if set(needs) <= CELL_AXIS_NEEDS:  # (no satellite geometry: any axis)
            return fields
        n_ut, n_loc = axis.n_ut, axis.n_local
        sat_ok = any_per_group(usable, nb)
        satellite = self.policy.level == "satellite"
        if "ref_pos_m" in needs or "moving_ref_pos_m" in needs:
            uniq = np.unique(axis.sats[axis.sats >= 0])
            nadir = sat_pos_m[uniq] * (
                self.radius_m / np.linalg.norm(sat_pos_m[uniq], axis=1, keepdims=True)
            )
            nadir_loc = self._gather(axis, uniq, nadir)  # (n_ut, n_loc, 3)
            nadir_loc = np.where(sat_ok[..., None], nadir_loc, np.nan)
            if satellite:
                per_cell = nadir_loc
            else:
                per_cell = np.repeat(nadir_loc, nb, axis=1)
            if "moving_ref_pos_m" in needs:
                fields["moving_ref_pos_m"] = per_cell
            if "ref_pos_m" in needs:
                if satellite:  # one reference per satellite: its nadir (leolink decision)
                    fields["ref_pos_m"] = nadir_loc
                else:
                    ground = ray_to_ground(
                        sat_pos_m[uniq][:, None, :],
                        sat_vel_m_s[uniq][:, None, :],
                        self.u_xy[None, :, :],
                        self.radius_m,
                    )  # (n_uniq, n_beam, 3)
                    cells = self._gather(axis, uniq, ground).reshape(n_ut, n_loc * nb, 3)
                    fields["ref_pos_m"] = np.where(usable[..., None], cells, np.nan)
        if "cell_ref_pos_m" in needs or "point_ref_pos_m" in needs:
            fields.update(self._fixed_references(axis, usable, sat_ok))
        if "elevation_rad" in needs:
            el = self._elevation(axis, ut_pos_m, sat_pos_m, ut_up)
            el = np.where(sat_ok, el, np.nan)
            # per satellite for a satellite-level policy (decisions.to_satellites keeps it)
            fields["elevation_rad"] = el if satellite else np.repeat(el, nb, axis=1)
        if "service_end_s" in needs:
            ahead = usable
            if self.serving_end_only and serving is not None:  # only the serving's is read (T1)
                slot = np.where(serving >= 0, serving // nb, -1)
                ahead = usable & np.repeat(np.arange(n_loc)[None, :] == slot[:, None], nb, axis=1)
            end_cell, end_sat = self.service.update(t_s, axis, ahead, ut_up, not satellite)
            fields["service_end_s"] = end_sat if satellite else end_cell
        return fields

    def _fixed_references(self, axis, usable, sat_ok):
        """D1's Earth-fixed reference locations (``cell_ref_pos_m``, ``point_ref_pos_m``)
        of the local candidates, NaN where not usable or without one."""
        needs, nb, out = self.policy.needs, self.n_beam, {}
        cells = self._cells(axis)  # (n_ut, n_local * n_beam): the satellite axis's cells
        if "cell_ref_pos_m" in needs:
            fixed = self.engine.steering.cells_m  # (n_sat or 1, n_beam, 3)
            rows = 0 if len(fixed) == 1 else np.maximum(cells, 0) // nb
            got = fixed[rows, np.maximum(cells, 0) % nb]
            out["cell_ref_pos_m"] = np.where((usable & (cells >= 0))[..., None], got, np.nan)
        if "point_ref_pos_m" in needs:
            satellite = self.policy.level == "satellite"
            if self._points is None:
                self._points = self._point_table(satellite)
            units, ok = (axis.sats, sat_ok) if satellite else (cells, usable)
            got = self._points.get(np.where(units >= 0, units, -1), np.nan)
            out["point_ref_pos_m"] = np.where(ok[..., None], got, np.nan)
        return out

    def _point_table(self, satellite):
        """The configured reference points (a :class:`~leolink.arrays.KeyTable` of
        ``(x, y, z)``) by global cell, or by satellite from the entries without a beam."""
        nb, keys, xyz = self.n_beam, [np.zeros(0, np.int64)], [np.zeros((0, 3))]
        for sat, beam, pos in self.reference_points:
            if satellite:
                units = np.array([sat] if beam is None else [], np.int64)
            else:
                units = sat * nb + (np.arange(nb) if beam is None else np.array([beam]))
            keys.append(units)
            xyz.append(np.tile(np.asarray(pos, float), (units.size, 1)))
        return KeyTable(np.concatenate(keys), np.concatenate(xyz))

    @staticmethod
    def _gather(axis, uniq, values):
        """``values[k]`` of satellite ``uniq[k]`` at every local satellite, (n_ut, n_loc, ...)."""
        idx = np.searchsorted(uniq, np.maximum(axis.sats, 0))
        idx = np.minimum(idx, max(len(uniq) - 1, 0))
        if len(uniq) == 0:
            return np.full(axis.sats.shape + values.shape[1:], np.nan)
        got = values[idx]
        mask = (axis.sats < 0).reshape(axis.sats.shape + (1,) * (got.ndim - 2))
        return np.where(mask, np.nan, got)

    @staticmethod
    def _elevation(axis, ut_pos_m, sat_pos_m, ut_up):
        """Elevation of each local satellite seen by its UT [rad], (n_ut, n_loc)."""
        sat = sat_pos_m[np.maximum(axis.sats, 0)]  # (n_ut, n_loc, 3)
        rel = sat - ut_pos_m[:, None, :]
        up = ut_pos_m / np.linalg.norm(ut_pos_m, axis=1, keepdims=True) if ut_up is None else ut_up
        sin_el = np.einsum("usk,uk->us", rel, up) / np.linalg.norm(rel, axis=2)
        return np.where(axis.sats >= 0, np.arcsin(np.clip(sin_el, -1.0, 1.0)), np.nan)

    # -- one epoch -------------------------------------------------------------------------
    def target(self, t_s, table, serving, ut_pos_m, sat_pos_m, sat_vel_m_s, ut_up=None):
        """The global cell every UT should be served by at ``t_s``.

        Parameters
        ----------
        t_s : float [s]
        table : Candidates, the epoch's candidate table (SNR [dB], not masked).
        serving : int64 (n_ut,), the serving cell (global), -1 for none.
        ut_pos_m : (n_ut, 3) [m]; sat_pos_m, sat_vel_m_s : (n_sat, 3), every satellite.
        ut_up : (n_ut, 3) or None, the UTs' local up (WGS 84).

        Returns
        -------
        int64 (n_ut,): a usable cell wherever the UT has one, else the serving cell.
        """
        serving = np.asarray(serving, np.int64)
        axis = self._axis(table, serving)
        pstate, filt = self._carry(axis)
        masked = table.masked(self.min_snr_db)  # NaN below it, and for -inf (a beam's null)
        if self.measurement is None:
            # (the threshold applied once, on the table: ~4x narrower than the axis)
            sample = axis.values(masked)
            usable = ~np.isnan(sample)
            filt, meas = l3_update(filt, t_s, sample, self.l3)
        else:
            raw = axis.values(table)
            with np.errstate(invalid="ignore"):
                usable = raw >= self.min_snr_db  # False for NaN and -inf
            cells = self._cells(axis)
            filt, meas = self.measurement.step(t_s, filt, raw, usable, cells, self.l3)
        local_serving = axis.local_cell(serving)
        extra = self._fields(
            t_s, axis, usable, ut_pos_m, sat_pos_m, sat_vel_m_s, ut_up, local_serving
        )
        if self.cell_offsets:
            extra["offset_db"] = self._offsets(axis)
        epoch = Epoch(t_s=float(t_s), serving=local_serving, meas=meas, **extra)
        decision, pstate = self.policy.decide(epoch, pstate, axis.n_beam)
        self.axis, self.pstate, self.filt = axis, pstate, filt
        chosen = np.where(decision.target >= 0, axis.global_cell(decision.target), serving)
        best, _ = masked.best()
        serving_ok = np.isfinite(masked.value_at(serving))
        return np.where(serving_ok, chosen, best)


#: The Epoch fields a policy on a cell axis may read (none needs a satellite's geometry).
CELL_AXIS_NEEDS = frozenset({"meas", "ut_pos_m"})


def _serving_only(policy, field):
    """Whether every trigger of ``policy`` that reads ``field`` reads it at the serving
    index alone (its ``serving_only``): then the run computes it for the serving satellite
    only, NaN elsewhere, which changes no condition and no ranking. False when no trigger
    of a known kind reads it (the safe answer: every candidate's value)."""
    found = [getattr(policy, "trigger", None), getattr(policy, "gate", None),
             getattr(policy, "prepare", None), *getattr(policy, "execute", ())]  # fmt: skip
    users = [t for t in found if t is not None and field in t.needs]
    return bool(users) and all(field in getattr(t, "serving_only", ()) for t in users)


def _on_cells(policy):
    """A cell-level policy reading only :data:`CELL_AXIS_NEEDS`: its local units are cells.

    Exact: a cell off the axis has no measurement and no state, as it would have on the
    satellite axis (a NaN measurement never enters; a cell without state leaves nothing),
    and the local cells keep ascending global order, so ties resolve alike."""
    return policy.level == "cell" and set(policy.needs) <= CELL_AXIS_NEEDS
