"""numba kernels of the candidate table (imported by :mod:`leolink.sim.candidates` only
when compiled kernels run; numba required).

Each is the loop over the rows of a :class:`~leolink.sim.candidates.Candidates` method
that numpy computes through several ``(n_ut, n_slot)`` temporaries: the same results
(integer comparisons and a maximum: nothing is rounded), without them. A 1,000-UT table
of 6 slots: ``best`` 81 -> 6 us, here.
"""

from __future__ import annotations

import numba
import numpy as np

_NO_CELL = np.iinfo(np.int64).max


@numba.njit(cache=True, nogil=True)
def best(cell, snr_db, out_cell, out_db):
    """:meth:`Candidates.best` into ``out_cell``, ``out_db`` (n_ut,): each row's highest
    SNR ignoring NaN, ties to the lowest cell id; -1 and NaN where none exceeds -inf.
    (A tie of -0.0 and +0.0 gives the first zero; numpy's maximum may give the other:
    the same cell, a zero of the other sign. No SNR of the simulator is a signed zero.)"""
    for i in range(cell.shape[0]):
        top_db, top_cell = -np.inf, _NO_CELL
        for j in range(cell.shape[1]):
            v = snr_db[i, j]
            if v > top_db:  # (False for NaN)
                top_db, top_cell = v, cell[i, j]
            elif v == top_db and v > -np.inf and cell[i, j] < top_cell:
                top_cell = cell[i, j]
        if top_db > -np.inf:
            out_cell[i], out_db[i] = top_cell, top_db
        else:
            out_cell[i], out_db[i] = -1, np.nan


@numba.njit(cache=True, nogil=True)
def slots(cell, wanted, out):
    """:meth:`Candidates.slot_of` into ``out`` (n_query, n_ut): the first slot of row
    ``i`` holding ``wanted[q, i]``, -1 where none does or ``wanted[q, i] < 0``."""
    for q in range(wanted.shape[0]):
        for i in range(wanted.shape[1]):
            c, found = wanted[q, i], -1
            if c >= 0:
                for j in range(cell.shape[1]):
                    if cell[i, j] == c:
                        found = j
                        break
            out[q, i] = found


@numba.njit(cache=True, nogil=True)
def values_at(snr_db, slot, out):
    """:meth:`Candidates.at` into ``out`` (n_ut,): row ``i``'s SNR in slot ``slot[i]``,
    NaN where ``slot[i] < 0``."""
    for i in range(slot.shape[0]):
        out[i] = snr_db[i, slot[i]] if slot[i] >= 0 else np.nan


@numba.njit(cache=True, nogil=True)
def window_entries(snr_bm, rows, sat, n_beam, window_db, best_db):
    """The window entries of :meth:`CandidateSearch._tables` for a search without a floor:
    writes ``best_db`` of ``rows`` (the largest SNR of their pairs' beams, NaN ignored as
    ``np.fmax``) and returns ``(row, cell, snr_db)`` of every beam within ``window_db`` of
    its row's best, in (pair, beam) order.

    ``snr_bm`` (n_beam, m): the pairs' SNR [dB]; ``rows`` (m,) sorted (a row's pairs
    consecutive), ``sat`` (m,) their satellites' global ids."""
    m = rows.shape[0]
    p = 0
    while p < m:  # the rows' best
        q, top = p, np.nan
        while q < m and rows[q] == rows[p]:
            for b in range(n_beam):
                v = snr_bm[b, q]
                if top != top or v > top:  # np.fmax: a NaN loses (NaN for NaN is the same)
                    top = v
            q += 1
        best_db[rows[p]] = top
        p = q
    n = 0
    for p in range(m):  # how many entries (a comparison with NaN is False)
        low = best_db[rows[p]] - window_db
        for b in range(n_beam):
            n += snr_bm[b, p] >= low
    out_row, out_cell = np.empty(n, np.int64), np.empty(n, np.int64)
    out_db = np.empty(n)
    k = 0
    for p in range(m):
        low = best_db[rows[p]] - window_db
        for b in range(n_beam):
            v = snr_bm[b, p]
            if v >= low:
                out_row[k], out_cell[k], out_db[k] = rows[p], sat[p] * n_beam + b, v
                k += 1
    return out_row, out_cell, out_db
