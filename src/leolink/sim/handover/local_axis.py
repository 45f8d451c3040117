"""Per-UT local candidate axes: what lets dense trigger state follow sparse candidate tables.

The trigger policies of :mod:`leolink.sim.handover.decisions` keep one time-to-trigger run, one
triggered flag and one layer-3 filter per (UT, candidate), on a dense candidate axis
``cand = sat * n_beam + beam`` shared by all UTs. A run's candidate tables
(:class:`~leolink.sim.candidates.table.Candidates`) are sparse: a UT sees a few of thousands of
satellites. A :class:`LocalAxis` gives every UT its own dense axis over *its*
satellites: row ``i`` lists global satellite ids ``sats[i, 0 .. n_local - 1]`` in
ascending order (-1 in unused slots), and local cell ``s * n_beam + b`` is beam ``b`` of
satellite ``sats[i, s]``. So the pure trigger code runs unchanged (``serving // n_beam``
is the local satellite, a reshape to ``(n_local, n_beam)`` reduces cells to satellites),
and ties resolve as the global table's (lowest local index = lowest global cell id).

From one epoch to the next, :meth:`LocalAxis.remap` carries every per-candidate array
to the new axis by global satellite id: a cell keeps its timers and filter while it is on
the UT's axis. The next axis holds the satellites of the new table plus every satellite
of the old axis that still has live state (a running timer, a triggered cell, a filter
value, the serving cell): a satellite that left the table is kept, with NaN
measurements, until its state has run out, exactly as a dense axis over all satellites
would behave (a NaN measurement resets the filter and lets a triggered cell leave after
its time-to-trigger; :mod:`leolink.sim.handover.triggers`). A satellite without live state is
dropped: on a dense axis it would hold nothing either.

With ``n_beam = 1`` and global *cell* ids in place of satellite ids, the same class is a
per-UT axis of cells: what a cell-level policy that reads only the measurements uses
(:mod:`leolink.sim.handover.trigger_run`), its state then held for the detected cells alone
(~51 per UT on configs/constellation.toml, against 15 beams of each of ~30 satellites).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from leolink import compiled
from leolink.arrays import nonzero_2d

__all__ = ["LocalAxis"]

#: :meth:`LocalAxis.remap` carries an array value by value where fewer than this share of
#: the carried slots' values differ from the fill, else slot by slot.
SPARSE_SHARE = 0.25


@dataclasses.dataclass(frozen=True)
class LocalAxis:
    """Per-UT local satellites (module docstring).

    Attributes
    ----------
    sats : ndarray of int64, shape (n_ut, n_local)
        Global satellite ids, ascending per row, -1 in unused slots (at the end).
    n_beam : int
    """

    sats: np.ndarray
    n_beam: int
    #: The last map of :meth:`_sources`, ``[(new axis, (dst, src, to))]``: a mutable
    #: holder of this frozen axis (every array of an epoch is carried by the same map).
    _last_sources: list = dataclasses.field(
        default_factory=list, init=False, repr=False, compare=False
    )

    @classmethod
    def empty(cls, n_ut, n_beam):
        return cls(np.full((n_ut, 0), -1, np.int64), int(n_beam))

    @classmethod
    def union(cls, n_ut, n_beam, ut, sat):
        """The axis holding every satellite ``sat[k]`` of UT ``ut[k]`` (repeats allowed)."""
        ut, sat = np.asarray(ut, np.int64), np.asarray(sat, np.int64)
        keep = sat >= 0
        if not keep.all():
            ut, sat = ut[keep], sat[keep]
        span = int(sat.max(initial=0)) + 1
        # By UT, then satellite: a sort (np.unique's hash is slow on these wide keys), the
        # stable one (a merge of the sorted runs the callers give: 5x faster than the
        # default's on a table's ~50,000 keys, both sorted alike)
        key = np.sort(ut * span + sat, kind="stable")
        if key.size:  # (no satellite at all: an empty axis)
            key = key[np.r_[True, key[1:] != key[:-1]]]
        row, s = np.divmod(key, span)
        counts = np.bincount(row, minlength=n_ut)
        start = np.cumsum(counts) - counts
        width = int(counts.max(initial=0))
        sats = np.full(n_ut * width, -1, np.int64)
        sats[row * width + np.arange(key.size) - np.repeat(start, counts)] = s  # (flat: a 1-D put)
        return cls(sats.reshape(n_ut, width), int(n_beam))

    @property
    def n_ut(self) -> int:
        return self.sats.shape[0]

    @property
    def n_local(self) -> int:
        return self.sats.shape[1]

    @property
    def n_cand(self) -> int:
        """Local cells per UT, ``n_local * n_beam``."""
        return self.n_local * self.n_beam

    @functools.cached_property
    def _index(self):
        """``(span, keys, slots)``: sorted keys ``row * span + sat`` of the occupied slots."""
        rows, slots = nonzero_2d(self.sats >= 0)  # row-major: by row, then ascending sat
        span = int(self.sats.max(initial=0)) + 1
        return span, rows * span + self.sats[rows, slots], slots

    def _slot(self, rows, sat):
        """Local slot of global satellite ``sat[k]`` in row ``rows[k]``, -1 where absent."""
        rows, sat = np.asarray(rows, np.int64), np.asarray(sat, np.int64)
        if compiled.use(rows.size) and self.n_local:  # a search in each short row
            out = np.empty(rows.size, np.int64)
            _slot_rows(self.sats, rows.reshape(-1), sat.reshape(-1), out)
            return out.reshape(rows.shape)
        span, keys, slots = self._index
        if keys.size == 0:
            return np.full(rows.shape, -1, np.int64)
        query = rows * span + sat
        pos = np.minimum(np.searchsorted(keys, query), keys.size - 1)
        hit = (keys[pos] == query) & (sat >= 0) & (sat < span)
        return np.where(hit, slots[pos], -1)

    def local_cell(self, cell):
        """Global cell ``cell[i]`` of UT ``i`` -> its local cell, -1 if absent or < 0."""
        cell = np.asarray(cell, np.int64)
        sat, beam = np.divmod(np.maximum(cell, 0), self.n_beam)
        slot = self._slot(np.arange(cell.size), np.where(cell >= 0, sat, -1))
        return np.where(slot >= 0, slot * self.n_beam + beam, -1)

    def global_cell(self, local):
        """Local cell ``local[i]`` of UT ``i`` -> its global cell id, -1 for -1."""
        local = np.asarray(local, np.int64)
        slot, beam = np.divmod(np.maximum(local, 0), self.n_beam)
        if self.n_local == 0:
            return np.full(local.shape, -1, np.int64)
        sat = self.sats[np.arange(local.size), np.minimum(slot, self.n_local - 1)]
        return np.where((local >= 0) & (sat >= 0), sat * self.n_beam + beam, -1)

    def values(self, table, fill=np.nan):
        """A :class:`~leolink.sim.candidates.table.Candidates` table on this axis, ``(n_ut,
        n_cand)``: its values at their local cells, ``fill`` where the table has none."""
        out = np.full(self.n_ut * self.n_cand, fill, float)
        cells = table.cell.reshape(-1)  # flat indices: 1-D takes and puts, not 2-D ones
        at = np.flatnonzero(cells >= 0)
        rows = at // max(table.n_slot, 1)
        sat, beam = np.divmod(cells[at], self.n_beam)
        local = self._slot(rows, sat)
        ok = local >= 0
        if not ok.all():  # (the table's cells off this axis are left out)
            at, rows, beam, local = at[ok], rows[ok], beam[ok], local[ok]
        out[rows * self.n_cand + local * self.n_beam + beam] = table.snr_db.reshape(-1)[at]
        return out.reshape(self.n_ut, self.n_cand)

    def _sources(self, new):
        """``(dst, src, to)``: flat slot ``src[k]`` (``row * n_local + slot``) of this axis
        holds the satellite of flat slot ``dst[k]`` of ``new`` (those on both axes), and
        ``to``, the same map by this axis's flat slots (``to[src[k]] = dst[k]``, -1 for a
        satellite not on ``new``); kept for the last ``new`` (every array of an epoch is
        carried by the same map). Flat indices: one 1-D take and put per array, a third of
        a 2-D fancy index's time."""
        if self._last_sources and self._last_sources[0][0] is new:
            return self._last_sources[0][1]
        rows, slots = nonzero_2d(new.sats >= 0)
        src = self._slot(rows, new.sats[rows, slots])
        ok = src >= 0
        rows = rows[ok]
        dst, src = rows * new.n_local + slots[ok], rows * self.n_local + src[ok]
        to = np.full(self.n_ut * self.n_local, -1, np.int64)
        to[src] = dst
        self._last_sources[:] = [(new, (dst, src, to))]
        return dst, src, to

    def remap(self, new, values, fill):
        """Carry ``values`` from this axis to axis ``new`` by global satellite id.

        ``values``: shape ``(n_ut, n_local * n_beam, ...)`` (per cell) or ``(n_ut,
        n_local, ...)`` (per satellite); returns the same on ``new``, ``fill`` for
        satellites that were not on this axis.
        """
        values = np.asarray(values)
        if values.shape[1] not in (self.n_cand, self.n_local):
            raise ValueError(f"remap: axis 1 has {values.shape[1]}, not a cell or satellite axis")
        per_cell = values.shape[1] == self.n_cand  # n_beam = 1: both readings agree
        inner = (self.n_beam,) if per_cell else ()
        old = values.reshape((self.n_ut * self.n_local,) + inner + values.shape[2:])
        out = np.full((new.n_ut * new.n_local,) + inner + values.shape[2:], fill, values.dtype)
        dst, src, to = self._sources(new)
        unit = int(np.prod(old.shape[1:], dtype=np.int64))  # values per slot
        blank = _blank(old, fill)
        # Mostly the fill (a timer, a triggered or prepared cell: a few per UT): only the
        # other values are carried, each by its slot's map (the same array).
        if blank is None or blank.size - np.count_nonzero(blank) >= SPARSE_SHARE * dst.size * unit:
            out[dst] = old[src]
        else:
            at = np.flatnonzero(~blank)
            slot = to[at // unit]
            kept = slot >= 0
            out.reshape(-1)[slot[kept] * unit + at[kept] % unit] = old.reshape(-1)[at[kept]]
        width = new.n_cand if per_cell else new.n_local
        return out.reshape((new.n_ut, width) + values.shape[2:])


def _blank(values, fill):
    """bool, where ``values`` hold ``fill`` itself (a NaN fill: NaN; a boolean array: the
    flag), or None where that is not told apart exactly (a float fill: -0.0 equals 0.0)."""
    if values.dtype == bool:
        return values == bool(fill)
    if values.dtype.kind == "f" and isinstance(fill, float) and np.isnan(fill):
        return np.isnan(values)
    return None


@compiled.jit
def _slot_rows(sats, rows, sat, out):
    """:meth:`LocalAxis._slot` query by query, into ``out``: a binary search in row
    ``rows[k]`` of ``sats`` (ascending, -1 only in its unused slots at the end), the same
    answer as the numpy search over every row's keys at once (-1 where absent or < 0)."""
    n_local = sats.shape[1]
    for k in range(rows.size):
        r, s = rows[k], sat[k]
        lo, hi = 0, n_local
        while lo < hi:  # the first slot holding s or more (an unused slot: more)
            mid = (lo + hi) // 2
            v = sats[r, mid]
            if 0 <= v < s:
                lo = mid + 1
            else:
                hi = mid
        out[k] = lo if s >= 0 and lo < n_local and sats[r, lo] == s else -1
