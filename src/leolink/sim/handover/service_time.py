"""Planned end of service from the ephemeris look-ahead: the input of T1 and time-to-exit.

A candidate *serves* a UT while its SNR is at or above the service threshold
(``controller.min_snr_db``) and its satellite is above the minimum elevation. Its end of
service is the first epoch ``t_s + j * epoch_s`` (``j >= 1``) at which it no longer
serves, found by evaluating the engine at the future positions of the UT (its mobility
model) and of the satellite (the ephemeris); ``inf`` when it still serves at
``t_s + horizon_s``. The resolution is the epoch: the true end lies in
``(end - epoch_s, end]``.

Per cell (``end_cell``) and per satellite (``end_sat``: the first epoch at which none of
its beams serves). Both are looked ahead once per (UT, satellite) pair when the pair
starts serving and kept on the UT's :class:`~leolink.sim.handover.local_axis.LocalAxis` while they
lie in the future: positions are deterministic, so the answer does not change. An end
not found within the horizon (``inf``) is looked ahead further every epoch, one epoch at
a time, so ``inf`` always means "beyond ``t_s + horizon_s``". A cell that starts serving
later (the UT moved into another beam) or again (a second pass) is looked ahead afresh.

Cost: a pair's pass is looked ahead in chunks of steps (8, 16, 32, ...), every open
pair's steps of a chunk in one engine call, and the future states are evaluated once per
(time, satellite) and kept in a ring of one horizon: a few calls per epoch, not one per
step, and only the satellites looked ahead (~90 of 4,399 on configs/constellation.toml).
"""

from __future__ import annotations

import math

import numpy as np

from leolink import compiled
from leolink.arrays import any_per_group, nonzero_2d

# Epoch times accumulate float rounding; 1 ns is far below any epoch length.
TIME_TOL_S = 1e-9

__all__ = ["ServiceTimes"]

#: Look-ahead steps of the first chunk (:meth:`ServiceTimes._scan`); each next one doubles.
FIRST_CHUNK = 8
#: (Pair, step) evaluations of one look-ahead engine call, at most (but one step a chunk).
SCAN_PAIRS = 1 << 16
#: Future times evaluated in one call of ``future_state``, at most (bounded temporaries).
STATE_BATCH = 32


class ServiceTimes:
    """End of service of every serving candidate, per run (module docstring).

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    future_state : callable ``(t_s (n_t,), sats (n_s,), uts=True) -> (ut_pos_m (n_t, n_ut,
        3), sat_pos_m (n_t, n_s, 3), sat_vel_m_s (n_t, n_s, 3))``, the run's known future at
        the times ``t_s`` [s], of the satellites ``sats`` (global ids); ``uts=False``: no UT
        positions (None). Its attribute ``n_sat_whole``, if not None: the run's satellites,
        when some cost as much as all (every one is then a column from the start).
    min_snr_db : float [dB], service threshold.
    epoch_s, horizon_s : float [s], look-ahead step and horizon.
    """

    def __init__(self, engine, future_state, min_snr_db, epoch_s, horizon_s):
        self.engine, self.future_state = engine, future_state
        self.min_snr_db, self.epoch_s = float(min_snr_db), float(epoch_s)
        self.n_step = max(1, math.ceil(horizon_s / epoch_s - 1e-9))
        self.axis, self.end_cell, self.end_sat, self.until = None, None, None, None
        # The future states by time index (slot ``key % (n_step + 2)``): each slot's key
        # and time [s], the UTs' positions, and the satellites' states in columns, one per
        # satellite asked for so far (``_ids``; ``_column``: each global id's, -1 if none).
        n = self.n_step + 2
        self._keys, self._times = np.full(n, -1, np.int64), np.full(n, np.nan)
        self._ut, self._pos, self._vel = None, np.empty((n, 0, 3)), np.empty((n, 0, 3))
        self._ids, self._column = np.zeros(0, np.int64), np.zeros(0, np.int64)

    def _slots(self, t_j, sats):
        """Ring slots of the future states at the distinct times ``t_j`` [s] and ring
        columns of the distinct satellites ``sats`` (global ids). The ring holds every step
        of one look-ahead, each with every satellite asked for so far: a new time is
        evaluated with all of them (:data:`STATE_BATCH` times a call), a new satellite at
        every time held (one call, without the UTs): each (time, satellite) once, and
        only the satellites looked ahead (not every satellite of the run)."""
        t_j = np.asarray(t_j, float)
        keys = np.round(t_j / self.epoch_s).astype(np.int64)
        slots = keys % self._keys.size
        whole = getattr(self.future_state, "n_sat_whole", None)
        if whole is not None and self._ids.size == 0:  # every satellite at each new time
            self._add(np.arange(whole))
        known, inside = np.zeros(sats.size, bool), sats < self._column.size
        known[inside] = self._column[sats[inside]] >= 0
        if not known.all():
            self._add(sats[~known])
        stale = np.flatnonzero(self._keys[slots] != keys)
        for lo in range(0, stale.size, STATE_BATCH):
            at = stale[lo : lo + STATE_BATCH]
            ut, pos, vel = self.future_state(t_j[at], self._ids)  # leading time axes
            if self._ut is None:
                self._ut = np.empty((self._keys.size, *ut.shape[1:]))
            got = slots[at]
            self._ut[got], self._pos[got, : self._ids.size], self._vel[got, : self._ids.size] = (
                ut, pos, vel)  # fmt: skip
            self._keys[got], self._times[got] = keys[at], t_j[at]
        return slots, self._column[sats]

    def _add(self, sats):
        """New columns for the satellites ``sats`` (global ids, new), evaluated at every
        time the ring holds; the ring grows by doubling."""
        n_col = self._ids.size
        if sats.max() >= self._column.size:
            grow = np.full(sats.max() + 1 - self._column.size, -1, np.int64)
            self._column = np.concatenate([self._column, grow])
        self._column[sats] = n_col + np.arange(sats.size)
        self._ids = np.concatenate([self._ids, sats])
        if self._ids.size > self._pos.shape[1]:
            wider = max(16, 2 * self._pos.shape[1], self._ids.size)
            for name in ("_pos", "_vel"):
                old, grown = getattr(self, name), np.empty((self._keys.size, wider, 3))
                grown[:, :n_col] = old[:, :n_col]
                setattr(self, name, grown)
        held = np.flatnonzero(self._keys >= 0)
        if held.size:  # (the same times as the other columns: the first asked for each)
            _, pos, vel = self.future_state(self._times[held], sats, uts=False)
            cols = slice(n_col, self._ids.size)
            self._pos[held, cols], self._vel[held, cols] = pos, vel

    def update(self, t_s, axis, serving_now, ut_up=None, per_cell=True):
        """End of service on ``axis`` at epoch ``t_s``.

        Parameters
        ----------
        t_s : float [s]
        axis : LocalAxis
        serving_now : bool (n_ut, axis.n_cand), the cells that serve now.
        ut_up : (n_ut, 3) or None, the UTs' local up (WGS 84), kept over the look-ahead.
        per_cell : bool, keep ``end_cell`` exact (a cell that starts serving is looked
            ahead); False looks ahead only the satellites (when one starts serving, until
            none of its beams serves: each step's best beam alone) and keeps no cell's
            end: for satellite-level policies.

        Returns
        -------
        end_cell (n_ut, n_cand), end_sat (n_ut, n_local) [s]: absolute times; NaN where
        the cell (satellite) does not serve now; ``end_cell`` None without ``per_cell``.
        """
        nb, shape = axis.n_beam, (axis.n_ut, axis.n_local)
        cell_shape = (axis.n_ut, axis.n_cand)
        if self.axis is None:
            end_sat, until = np.full(shape, np.nan), np.full(shape, np.nan)
        else:
            end_sat = self.axis.remap(axis, self.end_sat, np.nan)
            until = self.axis.remap(axis, self.until, np.nan)
        cells = None  # (n_ut, n_local, n_beam): kept only per cell
        if per_cell:
            kept = self.axis is not None and self.end_cell is not None
            cells = (
                self.axis.remap(axis, self.end_cell, np.nan)
                if kept
                else np.full(cell_shape, np.nan)
            )
            cells = cells.reshape(shape + (nb,))
        now = serving_now.reshape(shape + (nb,))
        sat_now = any_per_group(serving_now, nb).reshape(shape)
        with np.errstate(invalid="ignore"):
            fresh = sat_now & ~(end_sat > t_s + TIME_TOL_S)
            if per_cell:
                fresh |= (now & ~(cells > t_s + TIME_TOL_S)).any(axis=2)
                # fresh look-ahead from now: every cell that serves now, until it stops
                cells[fresh] = np.where(now[fresh], np.inf, np.nan)
            end_sat[fresh], until[fresh] = np.inf, t_s
            # an open end (beyond the last horizon) is looked ahead further
            open_end = np.isposinf(end_sat)
            if per_cell:
                open_end |= np.isposinf(cells).any(axis=2)
            extend = sat_now & open_end & (until < t_s + self.n_step * self.epoch_s - TIME_TOL_S)
        rows, slots = nonzero_2d(extend)
        if rows.size:
            got_cells, got_sat = self._scan(
                t_s, rows, axis.sats[rows, slots], until[rows, slots],
                None if cells is None else cells[rows, slots], end_sat[rows, slots], ut_up,
            )  # fmt: skip
            end_sat[rows, slots] = got_sat
            if per_cell:
                cells[rows, slots] = got_cells
            until[rows, slots] = t_s + self.n_step * self.epoch_s
        self.axis, self.end_sat, self.until = axis, end_sat, until
        self.end_cell = None if cells is None else cells.reshape(cell_shape)
        cell_out = None if cells is None else np.where(now, cells, np.nan).reshape(cell_shape)
        return cell_out, np.where(sat_now, end_sat, np.nan)

    def _scan(self, t_s, rows, sats, start_s, end_cell, end_sat, ut_up):
        """Look ahead the pairs ``(rows[k], sats[k])`` over ``(start_s[k], t_s + horizon]``;
        ``end_cell (m, n_beam)``, ``end_sat (m,)``: the ends found so far (inf: open);
        ``end_cell`` None: ``end_sat`` alone (satellite-level policies).

        The steps go in chunks of doubling length (:data:`FIRST_CHUNK` steps first), every
        open pair's steps of a chunk in one engine call: a pass is looked ahead in a few
        calls, whatever its length, and a pair costs at most twice the steps it needs; a
        chunk holds at most :data:`SCAN_PAIRS` evaluations (or one step)."""
        end_cell = None if end_cell is None else end_cell.copy()
        end_sat = end_sat.copy()
        j0, size = 1, FIRST_CHUNK
        while j0 <= self.n_step and np.isposinf(end_sat).any():
            # (at most SCAN_PAIRS evaluations a call: bounded temporaries at a run's start)
            n = min(size, max(1, SCAN_PAIRS // int(np.isposinf(end_sat).sum())))
            steps = np.arange(j0, min(j0 + n, self.n_step + 1))
            self._chunk(t_s, steps, rows, sats, start_s, end_cell, end_sat, ut_up)
            j0, size = steps[-1] + 1, 2 * size
        return end_cell, end_sat

    def _chunk(self, t_s, steps, rows, sats, start_s, end_cell, end_sat, ut_up):
        """The look-ahead steps ``steps`` of the open pairs, in place: each pair's first
        step at which a beam (all its beams) no longer serves is that beam's (its) end.

        ``end_cell`` None: the satellite's end alone, from each step's best beam
        (:meth:`~leolink.engine.links.Links.best_beam`'s SNR, the largest of
        ``snr_db_bm``): no beam serves exactly when that one does not, so
        :func:`_first_failures` of that one row is the satellite's first failure, without
        the SNR of every beam."""
        eng, per_cell = self.engine, end_cell is not None
        t_j = t_s + steps * self.epoch_s
        open_ = np.flatnonzero(np.isposinf(end_sat))
        # (pair, step) combinations, pair-major: each pair's steps ascending
        todo = t_j[None, :] > start_s[open_, None] + TIME_TOL_S
        pair, step = np.nonzero(todo)
        if pair.size == 0:
            return
        step_slot = np.full(steps.size, -1, np.int64)
        used = np.flatnonzero(todo.any(axis=0))  # the steps some pair takes
        u_sat, u_ix = np.unique(sats[open_], return_inverse=True)
        step_slot[used], u_col = self._slots(t_j[used], u_sat)
        ut_ring, pos_ring, vel_ring = self._ut, self._pos, self._vel
        ut = rows[open_[pair]]
        m = np.arange(pair.size)  # every combination its own UT row
        # one satellite row per (step, satellite): its body frame is formed once, not per
        # UT (dense keys over the chunk's steps and satellites: no sort of the combinations)
        key = step * u_sat.size + u_ix.reshape(-1)[pair]
        taken = np.zeros(steps.size * u_sat.size, bool)
        taken[key] = True
        at_step, at_u = np.divmod(np.flatnonzero(taken), u_sat.size)
        at_slot, at_sat, at_col = step_slot[at_step], u_sat[at_u], u_col[at_u]
        links = eng.evaluate_pairs(
            ut_ring[step_slot[step], ut], pos_ring[at_slot, at_col], vel_ring[at_slot, at_col],
            m, (np.cumsum(taken) - 1)[key], ut_up=None if ut_up is None else ut_up[ut],
            ut_id=ut, sat_id=at_sat,
        )  # fmt: skip
        if per_cell:
            snr_bm = links.snr_db_bm(eng.beam_ix, eng.beam_iy)  # (n_beam, combinations)
        else:
            snr_bm = links.best_beam(eng.beam_ix, eng.beam_iy, with_snr_db=True)[1][None, :]
        first_sat, first_beam = _first_failures(
            snr_bm, links.visible, pair, step, self.min_snr_db, open_.size, steps.size
        )
        ended = first_sat < steps.size
        end_sat[open_[ended]] = t_j[first_sat[ended]]
        if not per_cell:
            return
        cells = end_cell[open_]
        hit = np.isposinf(cells) & (first_beam < steps.size)
        cells[hit] = t_j[first_beam[hit]]
        end_cell[open_] = cells


def _first_failures(snr_bm, visible, pair, step, min_snr_db, n_pair, n_step):
    """Each pair's first step at which none of its beams serves, and each (pair, beam)'s
    first step up to it at which the beam does not serve (``n_step``: none), from the
    combinations' SNRs ``snr_bm (n_beam, m)`` [dB], pair-major with ascending steps.

    By the compiled :func:`_first_failures_loop` where it runs, else numpy (the same
    steps)."""
    nb = snr_bm.shape[0]
    first_sat = np.full(n_pair, n_step, np.int64)
    first_beam = np.full((n_pair, nb), n_step, np.int64)
    if compiled.use(pair.size):
        _first_failures_loop(snr_bm, visible, pair, step, float(min_snr_db), first_sat, first_beam)
        return first_sat, first_beam
    serves = visible[:, None] & (snr_bm.T >= min_snr_db)
    fail = np.flatnonzero(~serves.any(axis=1))
    got, at = np.unique(pair[fail], return_index=True)
    first_sat[got] = step[fail[at]]
    combo, beam = np.divmod(np.flatnonzero(~serves), nb)
    keep = step[combo] <= first_sat[pair[combo]]
    got, at = np.unique(pair[combo[keep]] * nb + beam[keep], return_index=True)
    first_beam.reshape(-1)[got] = step[combo[keep][at]]
    return first_sat, first_beam


@compiled.jit
def _first_failures_loop(snr_bm, visible, pair, step, min_snr_db, first_sat, first_beam):
    """:func:`_first_failures` combination by combination, in place (``first_sat``,
    ``first_beam`` filled with the no-failure step): a pair's steps after its end are
    skipped."""
    nb = snr_bm.shape[0]
    for c in range(pair.size):
        p, s = pair[c], step[c]
        if s > first_sat[p]:
            continue
        serves_any = False
        for b in range(nb):
            if visible[c] and snr_bm[b, c] >= min_snr_db:
                serves_any = True
            elif first_beam[p, b] > s:
                first_beam[p, b] = s
        if not serves_any:
            first_sat[p] = s
