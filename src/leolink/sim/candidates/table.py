"""The per-UT candidate table: the cells a UT may be served by this epoch, and their SNR.

A cell is a (satellite, beam) pair, numbered ``cell = sat_id * n_beam + beam_id`` with the
run's global satellite ids: a cell keeps its id from epoch to epoch, so whatever follows a
cell over time (the controller's pending target, a policy's time-to-trigger timer or
layer-3 filter) is keyed by the id. The table is padded: row ``i`` lists UT ``i``'s cells
in slots ``0 .. n_slot - 1`` (``cell = -1``, ``snr_db = NaN`` in unused slots); slots are
in no particular order and are not stable across epochs, cell ids are.

Which cells a row holds (:mod:`leolink.sim.candidates.search`): every cell whose SNR is within the
policy's ``neighbour_window_db`` of the UT's best cell, and the serving cell when its
satellite is above the minimum elevation. A cell missing from the table is treated as
NaN (no link), exactly as a NaN entry is.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink import compiled

__all__ = ["Candidates"]

_NO_CELL = np.iinfo(np.int64).max


@dataclasses.dataclass
class Candidates:
    """Candidate cells and their SNR, per UT.

    Attributes
    ----------
    cell : ndarray of int64, shape (n_ut, n_slot)
        Global cell ids, -1 in unused slots.
    snr_db : ndarray, shape (n_ut, n_slot)
        SNR [dB], NaN in unused slots (and where a cell has no usable link).
    """

    cell: np.ndarray
    snr_db: np.ndarray

    @classmethod
    def dense(cls, snr_db, cells=None):
        """The table of a dense matrix ``snr_db (n_ut, n_cand)`` whose column ``j`` is
        cell ``cells[j]`` (default ``j``) for every UT."""
        snr_db = np.asarray(snr_db, float)
        cells = np.arange(snr_db.shape[1]) if cells is None else np.asarray(cells, np.int64)
        return cls(np.broadcast_to(cells, snr_db.shape), snr_db)

    @classmethod
    def from_entries(cls, n_ut, ut, cell, snr_db):
        """Table of the entries ``(ut[k], cell[k], snr_db[k])`` (at most one per UT and cell)."""
        counts = np.bincount(ut, minlength=n_ut)
        n_slot = int(counts.max(initial=0))
        if ut.size > 1 and (ut[1:] < ut[:-1]).any():  # (the search's entries are sorted)
            order = np.argsort(ut, kind="stable")
            ut, cell, snr_db = ut[order], cell[order], snr_db[order]
        start = np.cumsum(counts) - counts
        slot = np.arange(ut.size) - start[ut]
        table = cls(np.full((n_ut, n_slot), -1, np.int64), np.full((n_ut, n_slot), np.nan))
        at = ut * n_slot + slot  # (flat: 1-D puts, not 2-D ones)
        table.cell.reshape(-1)[at] = cell
        table.snr_db.reshape(-1)[at] = snr_db
        return table

    @property
    def n_ut(self) -> int:
        return self.cell.shape[0]

    @property
    def shape(self) -> tuple[int, int]:
        """``(n_ut, n_slot)``."""
        return self.cell.shape

    @property
    def n_slot(self) -> int:
        return self.cell.shape[1]

    def like(self, snr_db):
        """The same cells with other values (e.g. masked, or at a later time)."""
        return Candidates(self.cell, np.asarray(snr_db, float))

    def masked(self, min_snr_db):
        """NaN wherever the SNR is below ``min_snr_db`` (or NaN)."""
        with np.errstate(invalid="ignore"):
            return self.like(np.where(self.snr_db >= min_snr_db, self.snr_db, np.nan))

    def rows(self, idx):
        """The table of the UTs ``idx``."""
        return Candidates(self.cell[idx], self.snr_db[idx])

    def slot_of(self, cells, *more):
        """Slot of ``cells[i]`` in row ``i``, -1 where absent (or ``cells[i] < 0``); given
        ``more`` arrays of cells, a tuple of the slots of each (found in one search)."""
        if self.n_slot == 1:  # the best cell only (max-SNR's window): one comparison each
            column = self.cell[:, 0]
            found = [np.where((column == c) & (c >= 0), 0, -1) for c in (cells, *more)]
            return tuple(found) if more else found[0]
        arrays = np.array((cells, *more), np.int64) if more else np.asarray(cells, np.int64)[None]
        if self.n_slot and compiled.use(self.n_ut):  # the same first hits, row by row
            arrays = np.broadcast_to(arrays, (arrays.shape[0], self.n_ut))  # (a 1-cell query)
            slots = np.empty(arrays.shape, np.int64)
            _slot_rows(self.cell, arrays, slots)
        elif self.n_slot == 0:
            slots = np.full(arrays.shape, -1, np.int64)
        else:
            hit = self.cell == arrays[..., None]  # (n_arrays, n_ut, n_slot)
            first = hit.argmax(axis=2)  # the first hit, or slot 0 where there is none
            found = hit.reshape(-1, self.n_slot)[np.arange(first.size), first.ravel()]
            # (a cell < 0 may meet an unused slot's -1: not a hit)
            slots = np.where(found.reshape(first.shape) & (arrays >= 0), first, -1)
        return tuple(slots) if more else slots[0]

    def value_at(self, cells):
        """``snr_db`` of ``cells[i]`` in row ``i``, NaN where absent or ``cells[i] < 0``."""
        return self.at(self.slot_of(cells))

    def at(self, slot):
        """``snr_db`` of slot ``slot[i]`` in row ``i``, NaN where ``slot[i] < 0`` (the
        slots of :meth:`slot_of`, for a table of the same cells)."""
        if self.n_slot == 0:
            return np.full(slot.shape, np.nan)
        if self.n_slot == 1:
            return np.where(slot >= 0, self.snr_db[:, 0], np.nan)
        val = self.snr_db[np.arange(slot.size), np.maximum(slot, 0)]
        return np.where(slot >= 0, val, np.nan)

    def best(self):
        """Per-UT best cell ignoring NaN: ``(cell (n_ut,) int64, value (n_ut,))``.

        -1 and NaN where a row has no finite value; ties go to the lowest cell id (as
        ``numpy.argmax`` over cells in id order).
        """
        if self.n_slot == 1:  # (NaN > -inf is False: a row of NaN or -inf has none)
            val = self.snr_db[:, 0]
            ok = val > -np.inf
            return np.where(ok, self.cell[:, 0], -1).astype(np.int64), np.where(ok, val, np.nan)
        if compiled.use(self.n_ut):  # the same rule, row by row
            cell, val = np.empty(self.n_ut, np.int64), np.empty(self.n_ut)
            _best_rows(self.cell, self.snr_db, cell, val)
            return cell, val
        filled = np.where(np.isnan(self.snr_db), -np.inf, self.snr_db)
        val = filled.max(axis=1, initial=-np.inf)
        ok = val > -np.inf
        tied = (filled == val[:, None]) & ok[:, None]
        cell = np.where(tied, self.cell, _NO_CELL).min(axis=1, initial=_NO_CELL)
        return np.where(ok, cell, -1).astype(np.int64), np.where(ok, val, np.nan)


@compiled.jit
def _slot_rows(cell, arrays, slots):
    """:meth:`Candidates.slot_of` of each row of ``arrays`` (n_arrays, n_ut) into ``slots``:
    the first slot holding the cell, -1 where none does or the cell is < 0."""
    for a in range(arrays.shape[0]):
        for i in range(arrays.shape[1]):
            c, slots[a, i] = arrays[a, i], -1
            if c >= 0:
                for s in range(cell.shape[1]):
                    if cell[i, s] == c:
                        slots[a, i] = s
                        break


@compiled.jit
def _best_rows(cell, snr_db, best_cell, best_db):
    """:meth:`Candidates.best` row by row: the largest value (NaN skipped), ties to the
    lowest cell id; -1 and NaN where no value is above -inf."""
    for i in range(cell.shape[0]):
        val, c = -np.inf, _NO_CELL
        for s in range(cell.shape[1]):
            v = snr_db[i, s]
            if v > val or (v == val and cell[i, s] < c):
                val, c = v, cell[i, s]
        ok = val > -np.inf
        best_cell[i], best_db[i] = (c, val) if ok else (-1, np.nan)
