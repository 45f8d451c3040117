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
"""

from __future__ import annotations

import math

import numpy as np

from leolink.arrays import nonzero_2d

# Epoch times accumulate float rounding; 1 ns is far below any epoch length.
TIME_TOL_S = 1e-9

__all__ = ["ServiceTimes"]


class ServiceTimes:
    """End of service of every serving candidate, per run (module docstring).

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    future_state : callable ``t_s -> (ut_pos_m (n_ut, 3), sat_pos_m (n_sat, 3),
        sat_vel_m_s (n_sat, 3))``, the run's known future.
    min_snr_db : float [dB], service threshold.
    epoch_s, horizon_s : float [s], look-ahead step and horizon.
    """

    def __init__(self, engine, future_state, min_snr_db, epoch_s, horizon_s):
        self.engine, self.future_state = engine, future_state
        self.min_snr_db, self.epoch_s = float(min_snr_db), float(epoch_s)
        self.n_step = max(1, math.ceil(horizon_s / epoch_s - 1e-9))
        self.axis, self.end_cell, self.end_sat, self.until = None, None, None, None
        self._future = {}  # step time index -> future state, a sliding window

    def _at(self, t_s):
        key = round(t_s / self.epoch_s)
        if key not in self._future:
            self._future[key] = self.future_state(t_s)
        return self._future[key]

    def _forget_before(self, t_s):
        first = round(t_s / self.epoch_s)
        for key in [k for k in self._future if k <= first]:
            del self._future[key]

    def update(self, t_s, axis, serving_now, ut_up=None, per_cell=True):
        """End of service on ``axis`` at epoch ``t_s``.

        Parameters
        ----------
        t_s : float [s]
        axis : LocalAxis
        serving_now : bool (n_ut, axis.n_cand), the cells that serve now.
        ut_up : (n_ut, 3) or None, the UTs' local up (WGS 84), kept over the look-ahead.
        per_cell : bool, keep ``end_cell`` exact (a cell that starts serving is looked
            ahead); False looks ahead only when a satellite starts serving (its
            ``end_cell`` entries may then be stale: for satellite-level policies).

        Returns
        -------
        end_cell (n_ut, n_cand), end_sat (n_ut, n_local) [s]: absolute times; NaN where
        the cell (satellite) does not serve now.
        """
        nb, shape = axis.n_beam, (axis.n_ut, axis.n_local)
        if self.axis is None:
            end_cell = np.full((axis.n_ut, axis.n_cand), np.nan)
            end_sat, until = np.full(shape, np.nan), np.full(shape, np.nan)
        else:
            end_cell = self.axis.remap(axis, self.end_cell, np.nan)
            end_sat = self.axis.remap(axis, self.end_sat, np.nan)
            until = self.axis.remap(axis, self.until, np.nan)
        now = serving_now.reshape(shape + (nb,))
        cells = end_cell.reshape(shape + (nb,)).copy()
        sat_now = now.any(axis=2)
        with np.errstate(invalid="ignore"):
            fresh = sat_now & ~(end_sat > t_s + TIME_TOL_S)
            if per_cell:
                fresh |= (now & ~(cells > t_s + TIME_TOL_S)).any(axis=2)
            # fresh look-ahead from now: every cell that serves now, until it stops
            cells[fresh] = np.where(now[fresh], np.inf, np.nan)
            end_sat[fresh], until[fresh] = np.inf, t_s
            # an open end (beyond the last horizon) is looked ahead further
            open_end = np.isposinf(end_sat) | (per_cell & np.isposinf(cells).any(axis=2))
            extend = sat_now & open_end & (until < t_s + self.n_step * self.epoch_s - TIME_TOL_S)
        rows, slots = nonzero_2d(extend)
        if rows.size:
            got_cells, got_sat = self._scan(
                t_s, rows, axis.sats[rows, slots], until[rows, slots],
                cells[rows, slots], end_sat[rows, slots], ut_up,
            )  # fmt: skip
            cells[rows, slots], end_sat[rows, slots] = got_cells, got_sat
            until[rows, slots] = t_s + self.n_step * self.epoch_s
        self._forget_before(t_s)
        end_cell = cells.reshape(end_cell.shape)
        self.axis, self.end_cell, self.end_sat, self.until = axis, end_cell, end_sat, until
        cell_out = np.where(now, cells, np.nan).reshape(end_cell.shape)
        return cell_out, np.where(sat_now, end_sat, np.nan)

    def _scan(self, t_s, rows, sats, start_s, end_cell, end_sat, ut_up):
        """Look ahead the pairs ``(rows[k], sats[k])`` over ``(start_s[k], t_s + horizon]``;
        ``end_cell (m, n_beam)``, ``end_sat (m,)``: the ends found so far (inf: open)."""
        eng = self.engine
        end_cell, end_sat = end_cell.copy(), end_sat.copy()
        for j in range(1, self.n_step + 1):  # a loop over look-ahead steps, not over UTs
            t_j = t_s + j * self.epoch_s
            idx = np.flatnonzero(np.isposinf(end_sat) & (t_j > start_s + TIME_TOL_S))
            if idx.size == 0:
                continue
            ut_pos, sat_pos, sat_vel = self._at(t_j)
            uniq, local = np.unique(sats[idx], return_inverse=True)
            links = eng.evaluate_pairs(
                ut_pos, sat_pos[uniq], sat_vel[uniq], rows[idx], local.reshape(-1), ut_up=ut_up
            )
            snr = links.snr_db_bm(eng.beam_ix, eng.beam_iy).T  # (k, n_beam)
            serves = links.visible[:, None] & (snr >= self.min_snr_db)
            sub = end_cell[idx]
            sub[np.isposinf(sub) & ~serves] = t_j
            end_cell[idx] = sub
            end_sat[idx[~serves.any(axis=1)]] = t_j
        return end_cell, end_sat
