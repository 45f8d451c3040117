"""Coverage: the best beam and its link for ground points under one satellite (Sec. 5).

Pure engine use (no config, no files); ``leolink coverage`` builds the grid and writes the
maps in :mod:`leolink.app.coverage`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["evaluate_points"]


def evaluate_points(engine, ut_pos_m, sat_pos_m, sat_vel_m_s, sat_acc_m_s2, chunk=250_000):
    """Best beam and its link for static ground points under one satellite.

    Parameters
    ----------
    engine : LinkEngine
    ut_pos_m : ndarray, shape (n, 3)
    sat_pos_m, sat_vel_m_s, sat_acc_m_s2 : ndarray, shape (1, 3)
    chunk : int
        Points per engine call (bounds peak memory).

    Returns
    -------
    dict of ndarray, shape (n,)
        ``best_beam`` (-1 where the satellite is below the minimum elevation) and the
        trace columns of :meth:`LinkEngine.serve`.
    """
    parts = []
    for lo in range(0, len(ut_pos_m), chunk):
        pos = ut_pos_m[lo : lo + chunk]
        snap = engine.evaluate(pos, sat_pos_m, sat_vel_m_s)
        best = np.argmax(snap.gain_tx_lin[:, 0, :], axis=-1)
        sat = np.where(snap.visible[:, 0], 0, -1)
        best = np.where(sat >= 0, best, -1)
        zero = np.zeros_like(pos)
        cols = engine.serve(snap, sat, best, zero, zero, sat_vel_m_s, sat_acc_m_s2)
        cols["best_beam"] = best
        parts.append(cols)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
