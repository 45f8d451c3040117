"""Planned end of service from the ephemeris look-ahead: the input of T1 and time-to-exit.

A candidate *serves* a UT while its SNR is at or above the service threshold
(``controller.min_snr_db``) and its satellite is above the minimum elevation. Its end of
service is the first epoch ``t_s + j * epoch_s`` (``j >= 1``) at which it no longer
serves, found by evaluating the engine at the future positions of the UT (its mobility
model) and of the satellite (the ephemeris); ``inf`` when it still serves at
``t_s + horizon_s``. The resolution is the epoch: the true end lies in
``(end - epoch_s, end]``.

Per cell (``end_cell``) and per satellite (``end_sat``: the first epoch at which none of
its beams serves). Both are computed once per (UT, satellite) pair when the pair starts
serving and kept on the UT's :class:`~leolink.sim.local_axis.LocalAxis` while they lie in
the future: positions are deterministic, so the answer does not change. A cell that
starts serving later (the UT moved into another beam) or again (a second pass) is
looked ahead afresh.
"""

from __future__ import annotations

import math

import numpy as np

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
        self.axis, self.end_cell, self.end_sat = None, None, None
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

    def update(self, t_s, axis, serving_now, ut_up=None):
        """End of service on ``axis`` at epoch ``t_s``.

        Parameters
        ----------
        t_s : float [s]
        axis : LocalAxis
        serving_now : bool (n_ut, axis.n_cand), the cells that serve now.
        ut_up : (n_ut, 3) or None, the UTs' local up (WGS 84), kept over the look-ahead.

        Returns
        -------
        end_cell (n_ut, n_cand), end_sat (n_ut, n_local) [s]: absolute times; NaN where
        the cell (satellite) does not serve now.
        """
        nb = axis.n_beam
        if self.axis is None:
            end_cell = np.full((axis.n_ut, axis.n_cand), np.nan)
            end_sat = np.full((axis.n_ut, axis.n_local), np.nan)
        else:
            end_cell = self.axis.remap(axis, self.end_cell, np.nan)
            end_sat = self.axis.remap(axis, self.end_sat, np.nan)
        sat_now = serving_now.reshape(axis.n_ut, axis.n_local, nb).any(axis=2)
        with np.errstate(invalid="ignore"):
            stale_cell = serving_now & ~(end_cell > t_s + TIME_TOL_S)
            stale_sat = sat_now & ~(end_sat > t_s + TIME_TOL_S)
        todo = stale_sat | stale_cell.reshape(sat_now.shape + (nb,)).any(axis=2)
        rows, slots = np.nonzero(todo)
        if rows.size:
            cells, sats = self._scan(t_s, rows, axis.sats[rows, slots], serving_now, axis, ut_up)
            block = end_cell.reshape(axis.n_ut, axis.n_local, nb)
            block[rows, slots] = cells
            end_sat[rows, slots] = sats
        self._forget_before(t_s)
        self.axis, self.end_cell, self.end_sat = axis, end_cell, end_sat
        now = serving_now.reshape(axis.n_ut, axis.n_local, nb)
        cell_out = np.where(now, end_cell.reshape(now.shape), np.nan).reshape(end_cell.shape)
        return cell_out, np.where(sat_now, end_sat, np.nan)

    def _scan(self, t_s, rows, sats, serving_now, axis, ut_up):
        """Ends of the pairs ``(rows[k], sats[k])`` that serve now: ``(cells (m, n_beam),
        sats (m,))``; a cell that does not serve now gets NaN."""
        eng, nb, m = self.engine, axis.n_beam, rows.size
        slot = axis._slot(rows, sats)
        now = serving_now.reshape(axis.n_ut, axis.n_local, nb)[rows, slot]  # (m, n_beam)
        end_cell = np.where(now, np.inf, np.nan)
        end_sat = np.full(m, np.inf)
        alive = np.ones(m, bool)
        for j in range(1, self.n_step + 1):  # a loop over look-ahead steps, not over UTs
            idx = np.flatnonzero(alive)
            if idx.size == 0:
                break
            t_j = t_s + j * self.epoch_s
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
            gone = ~serves.any(axis=1)
            end_sat[idx[gone]] = t_j
            alive[idx[gone]] = False
        return end_cell, end_sat
