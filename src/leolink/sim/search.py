"""The candidate table of an epoch: every cell a policy can need, evaluated exactly.

:class:`CandidateSearch` turns an epoch's geometry into the
:class:`~leolink.sim.candidates.Candidates` table the controller decides on, plus the
trace's per-UT diagnostics (satellites above the mask, the best cell and its SNR).

Pruned search (the default), per block of UTs (bounded memory):

1. :func:`leolink.engine.screening.screen` classifies every (UT, satellite) pair of the
   cone-selected satellites (visible, uncertain, below the mask) and bounds the SNR of
   every beam of the pair from above;
2. each UT's pair with the largest bound, and every uncertain pair, are evaluated
   exactly: their best beam gives ``L``, an SNR the UT certainly reaches;
3. every other pair above the mask whose bound is at least ``L`` minus the policy's
   ``neighbour_window_db`` (and the serving cell's pair) is evaluated exactly.

A pair left out has a bound below ``L - window``, so none of its cells can be within the
window of the best cell: the table holds exactly the cells within the window of the best
one, and the serving cell when above the mask, whether the search is pruned or not
(``prune=False`` evaluates every pair, the reference that the tests compare against).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.engine.screening import UNCERTAIN, VISIBLE, screen
from leolink.geometry import body_frame
from leolink.sim.candidates import Candidates

__all__ = ["CandidateSearch", "EpochCandidates"]

#: UT x satellite pairs screened at once (bounds the temporaries to a few MiB each).
SCREEN_PAIRS = 1 << 17


@dataclasses.dataclass
class EpochCandidates:
    """What :class:`CandidateSearch` found for one epoch.

    Attributes
    ----------
    table : Candidates
        Global cell ids (``sat_id * n_beam + beam_id``) and SNR [dB].
    n_visible : ndarray of int, shape (n_ut,)
        Satellites above the minimum elevation.
    best_cell : ndarray of int, shape (n_ut,)
        The best cell (any SNR), -1 without a satellite above the mask.
    best_snr_db : ndarray, shape (n_ut,)
        Its SNR [dB], NaN without one.
    """

    table: Candidates
    n_visible: np.ndarray
    best_cell: np.ndarray
    best_snr_db: np.ndarray


class CandidateSearch:
    """Candidate tables of the epochs of a run (module docstring).

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    window_db : float
        The policy's ``neighbour_window_db`` [dB] (``inf``: every cell above the mask).
    prune : bool
        Screen the pairs (default); False evaluates every pair (the reference).
    ut_id : ndarray of int, shape (n_ut,), optional
        The UT of each row (per-population terminals); default: row = UT.
    """

    def __init__(self, engine, window_db, prune=True, ut_id=None):
        self.engine, self.window_db, self.prune = engine, float(window_db), bool(prune)
        self.ut_id = ut_id

    def __call__(self, ut_pos_m, sat_pos_m, sat_vel_m_s, sat_ids, serving, ut_up=None):
        """The candidates of one epoch.

        Parameters
        ----------
        ut_pos_m : ndarray, shape (n_ut, 3)
        sat_pos_m, sat_vel_m_s : ndarray, shape (n_s, 3)
            The satellites that may be above the mask for some UT (and the serving ones).
        sat_ids : ndarray of int, shape (n_s,)
            Their global ids, ascending.
        serving : ndarray of int, shape (n_ut,)
            Serving cell of each UT (global), -1 for none.
        ut_up : ndarray, shape (n_ut, 3), optional
            Local up of each UT (WGS 84); None: the sphere's.

        Returns
        -------
        EpochCandidates
        """
        n_ut, nb = len(ut_pos_m), self.engine.n_beam
        ut_id = np.arange(n_ut) if self.ut_id is None else self.ut_id
        if not self.prune or len(sat_ids) == 0:
            return self._dense(ut_pos_m, sat_pos_m, sat_vel_m_s, sat_ids, ut_up)
        local_of = np.full(int(sat_ids.max()) + 1, -1)
        local_of[sat_ids] = np.arange(len(sat_ids))
        serv_sat = np.where(serving >= 0, serving // nb, 0)
        serv_local = np.where(serving >= 0, local_of[np.minimum(serv_sat, len(local_of) - 1)], -1)
        axes = body_frame(sat_pos_m, sat_vel_m_s)
        step = max(1, SCREEN_PAIRS // len(sat_ids))
        parts = [
            self._block(ut_pos_m, ut_up, ut_id, sat_pos_m, sat_vel_m_s, axes, serv_local, rows)
            for rows in (np.arange(lo, min(lo + step, n_ut)) for lo in range(0, n_ut, step))
        ]
        ut, sat, snr, n_visible = (np.concatenate(x) for x in zip(*parts, strict=True))
        return self._table(n_ut, ut, sat_ids[sat], snr, serving, n_visible)

    def _block(self, ut_pos_m, ut_up, ut_id, sat_pos_m, sat_vel_m_s, axes, serv_local, rows):
        """Exactly evaluated visible pairs of the UTs ``rows``: (ut, sat, snr_db (m, n_beam),
        n_visible (rows,))."""
        eng = self.engine
        up = None if ut_up is None else ut_up[rows]
        code, bound = screen(eng, ut_pos_m[rows], sat_pos_m, axes, up, ut_id[rows])
        maybe = code > 0
        n = len(rows)
        first = np.argmax(bound, axis=1)
        chosen = code == UNCERTAIN
        has = bound[np.arange(n), first] >= 0.0
        chosen[np.flatnonzero(has), first[has]] = True
        r1, s1 = np.nonzero(chosen)
        snr1, vis1 = self._exact(ut_pos_m, ut_up, sat_pos_m, sat_vel_m_s, rows[r1], s1)
        lin1 = np.where(vis1[:, None], 10.0 ** (snr1 / 10.0), 0.0).max(axis=1, initial=0.0)
        reach = np.zeros(n)
        np.maximum.at(reach, r1, lin1)
        # Pairs whose bound is within the window of what the UT reaches, and the serving one.
        with np.errstate(invalid="ignore"):
            more = maybe & (bound >= (reach * 10.0 ** (-self.window_db / 10.0))[:, None])
        sv = serv_local[rows]
        more[np.flatnonzero(sv >= 0), sv[sv >= 0]] = maybe[np.flatnonzero(sv >= 0), sv[sv >= 0]]
        more &= ~chosen
        r2, s2 = np.nonzero(more)
        snr2, vis2 = self._exact(ut_pos_m, ut_up, sat_pos_m, sat_vel_m_s, rows[r2], s2)
        ut, sat = np.concatenate([rows[r1], rows[r2]]), np.concatenate([s1, s2])
        vis = np.concatenate([vis1, vis2])
        snr = np.concatenate([snr1, snr2])
        evaluated = chosen | more
        n_visible = ((code == VISIBLE) & ~evaluated).sum(axis=1)
        n_visible += np.bincount(ut[vis] - rows[0], minlength=n)
        return ut[vis], sat[vis], snr[vis], n_visible

    def _exact(self, ut_pos_m, ut_up, sat_pos_m, sat_vel_m_s, ut, sat):
        """The engine's SNR of every beam of the pairs [dB], (m, n_beam), and visibility."""
        eng = self.engine
        links = eng.evaluate_pairs(
            ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up=ut_up, ut_id=self.ut_id
        )
        return links.snr_db_bm(eng.beam_ix, eng.beam_iy).T, links.visible

    def _dense(self, ut_pos_m, sat_pos_m, sat_vel_m_s, sat_ids, ut_up):
        """Every pair evaluated: the dense table over all the satellites' cells."""
        eng, nb, n_ut = self.engine, self.engine.n_beam, len(ut_pos_m)
        ut_rows = np.arange(n_ut)
        ut = np.tile(ut_rows, len(sat_ids))
        sat = np.repeat(np.arange(len(sat_ids)), n_ut)
        links = eng.evaluate_pairs(
            ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up=ut_up, ut_id=self.ut_id
        )
        snr = links.snr_db_bm(eng.beam_ix, eng.beam_iy)  # (n_beam, n_s n_ut)
        snr = snr.reshape(nb, len(sat_ids), n_ut).transpose(2, 1, 0).reshape(n_ut, -1)
        cells = (sat_ids[:, None] * nb + np.arange(nb)[None, :]).reshape(-1)
        table = Candidates.dense(snr, cells)
        best_cell, best_db = table.best()
        n_visible = links.visible.reshape(len(sat_ids), n_ut).sum(axis=0)
        # An all-NaN row has no best cell, but a -inf SNR (a kernel null) still has a value.
        return EpochCandidates(table, n_visible, best_cell, _fmax_rows(snr))

    def _table(self, n_ut, ut, sat_id, snr, serving, n_visible):
        """Entries within the window of each UT's best cell, and the serving cells."""
        nb = self.engine.n_beam
        cell = sat_id[:, None] * nb + np.arange(nb)[None, :]  # (m, n_beam)
        best_db = np.full(n_ut, -np.inf)
        with np.errstate(invalid="ignore"):
            np.fmax.at(best_db, ut, np.fmax.reduce(snr, axis=1, initial=-np.inf))
            keep = (snr >= (best_db - self.window_db)[ut][:, None]) | (cell == serving[ut][:, None])
        rows = np.broadcast_to(ut[:, None], cell.shape)
        table = Candidates.from_entries(n_ut, rows[keep], cell[keep], snr[keep])
        best_cell, _ = table.best()
        has = np.bincount(ut, minlength=n_ut) > 0
        return EpochCandidates(table, n_visible, best_cell, np.where(has, best_db, np.nan))


def _fmax_rows(snr):
    """``fmax`` over each row (NaN for an all-NaN row)."""
    if snr.shape[1] == 0:
        return np.full(snr.shape[0], np.nan)
    with np.errstate(invalid="ignore"):
        return np.fmax.reduce(snr, axis=1)
