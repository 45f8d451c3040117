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
    SNR ignoring NaN, ties to the lowest cell id; -1 and NaN where none exceeds -inf."""
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
