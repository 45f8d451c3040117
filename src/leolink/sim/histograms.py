"""Percentiles of streams of samples in bounded memory: fixed-bin histograms.

:class:`PercentileHistogram` of one stream, :class:`GroupedPercentileHistogram` of one
stream per group (per UT); both are within half a bin of ``numpy.percentile`` (linear) on
the same samples.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PERCENTILES", "GroupedPercentileHistogram", "PercentileHistogram"]
__all__ += ["interpolated_percentiles"]

#: The percentiles reported for SINR and throughput.
PERCENTILES = (1, 5, 10, 50, 90, 95, 99)


class PercentileHistogram:
    """Percentiles of a stream of samples from a fixed-bin histogram.

    Bins of width ``resolution`` cover ``[lo, hi)``; a value there is known to within half
    a bin, so a percentile is within ``resolution / 2`` of ``numpy.percentile`` (linear
    interpolation) on the same samples. Values below ``lo`` (unserved UT-epochs: NaN is
    read as ``unserved_value``, -inf by default) and above ``hi`` are counted, not
    placed: a percentile that falls among them is -inf or +inf.

    Parameters
    ----------
    lo, hi, resolution : float, same unit as the samples (e.g. dB: -60, 80, 0.01).
    unserved_value : float, the value an unserved (NaN) sample stands for (0 for
        throughput, -inf for SINR).
    """

    def __init__(self, lo, hi, resolution, unserved_value=-math.inf):
        if not (hi > lo and resolution > 0):
            raise ValueError(f"need hi > lo and resolution > 0 (got {lo}, {hi}, {resolution})")
        if math.isnan(unserved_value):  # NaN stands for it: it must have a slot
            raise ValueError("unserved_value must be a number or +-inf, not NaN")
        self.lo, self.resolution = float(lo), float(resolution)
        self.n_bins = int(math.ceil((hi - lo) / resolution))
        self.hi = self.lo + self.n_bins * self.resolution
        self.unserved_value = float(unserved_value)
        self.counts = np.zeros(self.n_bins + 2, np.int64)  # [underflow, bins..., overflow]

    @property
    def n(self):
        return int(self.counts.sum())

    def slots(self, values):
        """Slot of every value: 0 below ``lo``, ``1 .. n_bins`` the bins, ``n_bins + 1``
        at or above ``hi`` (NaN read as ``unserved_value``)."""
        x = np.asarray(values, float).reshape(-1)
        # in place, one temporary: the summary's sink folds ~10 columns of every row here
        idx = np.subtract(x, self.lo)
        with np.errstate(invalid="ignore"):
            np.floor(np.divide(idx, self.resolution, out=idx), out=idx)
            idx[x < self.lo] = -1  # (a tiny x - lo could round to -0.0 here)
            idx[x >= self.hi] = self.n_bins
        np.clip(idx, -1, self.n_bins, out=idx)
        nan = np.isnan(x)
        if nan.any():
            idx[nan] = self.slots(np.array([self.unserved_value]))[0] - 1
        out = idx.astype(np.int64)
        out += 1
        return out

    def slot_values(self, slot):
        """The value a slot stands for: its bin's middle, -inf / +inf outside the bins."""
        mid = self.lo + (np.asarray(slot) - 0.5) * self.resolution  # slot 1 is the first bin
        return np.where(slot == 0, -np.inf, np.where(slot > self.n_bins, np.inf, mid))

    def add(self, values):
        self.add_slots(self.slots(values))

    def add_slots(self, slots):
        """Add samples by their slots (:meth:`slots`, of this histogram's bins)."""
        self.counts += np.bincount(slots, minlength=self.counts.size)

    def merge(self, other):
        if (other.lo, other.resolution, other.n_bins) != (self.lo, self.resolution, self.n_bins):
            raise ValueError("cannot merge histograms with different bins")
        self.counts += other.counts

    def _value_at_rank(self, rank):
        return self.slot_values(np.searchsorted(np.cumsum(self.counts), rank, side="right"))

    def percentiles(self, q=PERCENTILES):
        """Percentiles ``q`` [%] as numpy.percentile (linear) would give; NaN when empty."""
        q = np.asarray(q, float)
        if self.n == 0:
            return np.full(q.shape, np.nan)
        return interpolated_percentiles(self._value_at_rank, np.asarray(self.n), q)

    def summary(self, prefix=""):
        """``{"p1": ..., "p5": ..., ...}`` for :data:`PERCENTILES`."""
        got = self.percentiles(PERCENTILES)
        return {f"{prefix}p{q}": float(v) for q, v in zip(PERCENTILES, got, strict=True)}


def interpolated_percentiles(value_at_rank, n, q):
    """numpy.percentile's linear method from a rank -> value function.

    ``value_at_rank(rank)`` gives the sorted sample of (0-based) ``rank``, rank an array of
    shape ``n.shape + q.shape``; ``n`` (>= 1) is the number of samples (broadcast with
    ``q[None]`` over groups). An infinite neighbour makes the result infinite.
    """
    n = np.asarray(n)[..., None]
    h = (n - 1) * np.asarray(q, float) / 100.0
    lo_r = np.floor(h)
    frac = h - lo_r
    a, b = value_at_rank(lo_r), value_at_rank(np.minimum(lo_r + 1, n - 1))
    with np.errstate(invalid="ignore"):
        mixed = a + frac * (b - a)
    mixed = np.where(np.isneginf(a), -np.inf, np.where(np.isposinf(b), np.inf, mixed))
    return np.where(frac == 0, a, mixed)


class GroupedPercentileHistogram:
    """Per-group percentiles (e.g. per UT) of a stream, in bounded memory.

    The bins are those of a :class:`PercentileHistogram` ``(lo, hi, resolution)`` (same
    error bound: within ``resolution / 2`` of ``numpy.percentile`` on each group's
    samples), stored sparsely: one ``(group, bin)`` count per occupied bin. Memory is
    ``12 B x`` occupied bins (at most ``n_group x`` the bins a group's values span,
    whatever the number of samples) plus a pending buffer of new samples' keys no larger
    than the table (compacted by sorting when it fills).

    Parameters
    ----------
    n_group : int, groups ``0 .. n_group - 1``.
    lo, hi, resolution : float, as :class:`PercentileHistogram`.
    """

    MIN_PENDING = 1 << 16

    def __init__(self, n_group, lo, hi, resolution):
        self.grid = PercentileHistogram(lo, hi, resolution)
        self.n_group = int(n_group)
        self._n_slot = self.grid.n_bins + 2
        fits = self.n_group * self._n_slot < np.iinfo(np.int32).max
        self._key_dtype = np.int32 if fits else np.int64
        self._keys = np.zeros(0, self._key_dtype)  # sorted group * n_slot + slot
        self._counts = np.zeros(0, np.int64)
        self._pending, self._n_pending = [], 0

    def add(self, group, values):
        """Add samples ``values`` (1-D) of groups ``group`` (1-D int, same length)."""
        self.add_keys(np.asarray(group, np.int64) * self._n_slot + self.grid.slots(values))

    def add_keys(self, key):
        """Add samples by their keys ``group * (n_bins + 2) + slot`` (``grid.slots``)."""
        self._pending.append(key.astype(self._key_dtype))
        self._n_pending += key.size
        if self._n_pending > max(self._keys.size, self.MIN_PENDING):
            self._compact()

    def _compact(self):
        """Merge the pending keys into the sorted table: the new keys alone are sorted and
        counted, then added to the entries they match and inserted where they are new
        (half the time of sorting the table with them: 1.0-1.2 -> 0.6 s for 8 M samples
        over 1,000 groups, here)."""
        new = np.concatenate(self._pending) if self._pending else self._keys[:0]
        self._pending, self._n_pending = [], 0
        if not new.size:
            return
        new = np.sort(new)
        first = np.flatnonzero(np.r_[True, new[1:] != new[:-1]])
        keys, counts = new[first], np.diff(np.r_[first, new.size])
        pos = np.searchsorted(self._keys, keys)  # (keys are unique: so are their matches)
        hit = pos < self._keys.size
        hit[hit] = self._keys[pos[hit]] == keys[hit]
        merged = self._counts.copy()
        merged[pos[hit]] += counts[hit]
        self._keys = np.insert(self._keys, pos[~hit], keys[~hit])
        self._counts = np.insert(merged, pos[~hit], counts[~hit])

    def counts(self):
        """Samples per group, (n_group,)."""
        self._compact()
        group = self._keys.astype(np.int64) // self._n_slot
        return np.bincount(group, self._counts, minlength=self.n_group).astype(np.int64)

    def percentiles(self, q=PERCENTILES):
        """(n_group, len(q)) percentiles [%] as numpy.percentile (linear); NaN for empty
        groups."""
        q = np.asarray(q, float).reshape(-1)
        n = self.counts()
        out = np.full((self.n_group, q.size), np.nan)
        if not n.any():
            return out
        cum = np.cumsum(self._counts)
        start = np.concatenate(([0], np.cumsum(n)[:-1]))[n > 0]

        def value_at_rank(rank):
            entry = np.searchsorted(cum, start[:, None] + rank, side="right")
            return self.grid.slot_values(self._keys[entry].astype(np.int64) % self._n_slot)

        out[n > 0] = interpolated_percentiles(value_at_rank, n[n > 0], q)
        return out
