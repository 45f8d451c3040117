"""Compiled loops of the candidate table (``leolink._kernels``, C; imported by
:mod:`leolink.sim.candidates.table` and :mod:`leolink.sim.candidates.search` only when the
extension is built).

Each is the loop over the rows of a :class:`~leolink.sim.candidates.table.Candidates` method
that numpy computes through several ``(n_ut, n_slot)`` temporaries: the same results
(integer comparisons and a maximum: nothing is rounded), without them. A 1,000-UT table
of 6 slots: ``best`` 81 -> 6 us, here.
"""

from __future__ import annotations

import numpy as np

from leolink import _kernels

__all__ = ["best", "slots", "values_at", "window_entries"]

#: :meth:`Candidates.best` into ``out_cell``, ``out_db`` (n_ut,): each row's highest SNR
#: ignoring NaN, ties to the lowest cell id; -1 and NaN where none exceeds -inf. (A tie of
#: -0.0 and +0.0 gives the first zero; numpy's maximum may give the other: the same cell,
#: a zero of the other sign. No SNR of the simulator is a signed zero.)
best = _kernels.table_best
#: :meth:`Candidates.slot_of` into ``out`` (n_query, n_ut): the first slot of row ``i``
#: holding ``wanted[q, i]``, -1 where none does or ``wanted[q, i] < 0``.
slots = _kernels.table_slots
#: :meth:`Candidates.at` into ``out`` (n_ut,): row ``i``'s SNR in slot ``slot[i]``, NaN
#: where ``slot[i] < 0``.
values_at = _kernels.table_values_at


def window_entries(snr_bm, rows, sat, n_beam, window_db, best_db):
    """The window entries of :meth:`CandidateSearch._tables` for a search without a floor:
    writes ``best_db`` of ``rows`` (the largest SNR of their pairs' beams, NaN ignored as
    ``np.fmax``) and returns ``(row, cell, snr_db)`` of every beam within ``window_db`` of
    its row's best, in (pair, beam) order.

    ``snr_bm`` (n_beam, m): the pairs' SNR [dB]; ``rows`` (m,) sorted (a row's pairs
    consecutive), ``sat`` (m,) their satellites' global ids."""
    n = _kernels.window_best(snr_bm, rows, best_db, float(window_db))
    out_row, out_cell, out_db = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n)
    _kernels.window_fill(snr_bm, rows, sat, int(n_beam), float(window_db), best_db, out_row,
                         out_cell, out_db)  # fmt: skip
    return out_row, out_cell, out_db
