"""Streamed statistics of the summary: dB histograms, running sums, grouped percentiles.

The building blocks of :class:`leolink.io.summary.accumulator.SummaryAccumulator`, each in
memory that does not grow with the number of epochs (:class:`DbStats`) or used once at the end on a
table that is small beside the trace (:func:`grouped_percentiles`, the dwells).
"""

from __future__ import annotations

import numpy as np

from leolink.io.summary.records import STAT_KEYS
from leolink.sim.histograms import GroupedPercentileHistogram, PercentileHistogram

__all__ = [
    "DB_RANGE",
    "OVERALL_RESOLUTION_DB",
    "PERCENTILES",
    "PER_UT_RESOLUTION_DB",
    "DbStats",
    "grouped_percentiles",
    "running_sum",
]

#: SNR/SINR histogram range [dB]: values outside are counted as below / above it.
DB_RANGE = (-200.0, 200.0)
#: Bin of the pooled SNR/SINR percentiles [dB] (within half a bin of numpy.percentile).
OVERALL_RESOLUTION_DB = 0.01
#: Bin of the per-UT SNR/SINR percentiles [dB]: coarser, so that the per-UT histograms of
#: a long run stay small (a UT's SNR spans a few hundred 0.1 dB bins).
PER_UT_RESOLUTION_DB = 0.1
#: The percentiles of an SNR / SINR / margin block [%] (``p5``, ``p50``, ``p95``).
PERCENTILES = (5.0, 50.0, 95.0)


def grouped_percentiles(group, values, n_group, q_percent):
    """Per-group percentiles, linear interpolation (numpy's default method).

    Parameters
    ----------
    group : int array (n,), group index in ``[0, n_group)``.
    values : float array (n,), finite.
    q_percent : sequence of percentiles in [0, 100].

    Returns
    -------
    ndarray (n_group, len(q_percent)), NaN for empty groups.
    """
    q = np.asarray(q_percent, float) / 100.0
    out = np.full((n_group, q.size), np.nan)
    if len(values) == 0:
        return out
    group = np.asarray(group, np.int64)
    # Sort by value, then stably by group: the group sort is a radix sort on small ints,
    # ~3x faster than np.lexsort on millions of samples.
    by_value = np.argsort(values)
    small = np.int16 if n_group < 2**15 else np.int64
    order = by_value[np.argsort(group[by_value].astype(small), kind="stable")]
    v = np.asarray(values, np.float64)[order]
    counts = np.bincount(group, minlength=n_group)
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    pos = q[None, :] * np.maximum(counts - 1, 0)[:, None]
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, np.maximum(counts - 1, 0)[:, None])
    idx_lo = np.minimum(starts[:, None] + lo, v.size - 1)
    idx_hi = np.minimum(starts[:, None] + hi, v.size - 1)
    interp = v[idx_lo] + (pos - lo) * (v[idx_hi] - v[idx_lo])
    out[counts > 0] = interp[counts > 0]
    return out


def running_sum(total, group, values):
    """``total`` plus the ``values`` of each group, added one by one in their order (the
    same float rounding as adding them one call at a time)."""
    n = total.size
    # (np.concatenate: np.r_ costs ~0.1 ms a call in Python, ~10 calls a block)
    index = np.concatenate((np.arange(n), np.asarray(group, np.int64)))
    return np.bincount(index, np.concatenate((total, np.asarray(values, float))), minlength=n)


class DbStats:
    """Streamed statistics of one dB column: per-UT count, sum and histogram, pooled
    histogram (finite values only)."""

    def __init__(self, n_ut):
        self.count, self.sum = np.zeros(n_ut, np.int64), np.zeros(n_ut)
        self.pooled = PercentileHistogram(*DB_RANGE, OVERALL_RESOLUTION_DB)
        self.per_ut = GroupedPercentileHistogram(n_ut, *DB_RANGE, PER_UT_RESOLUTION_DB)

    def add(self, ut, values):
        """Add the finite ``values`` (1-D float) of UTs ``ut`` (1-D int)."""
        ok = np.isfinite(values)
        if not ok.all():
            ut, values = ut[ok], values[ok]
        self.count += np.bincount(ut, minlength=self.count.size)
        self.sum[:] = running_sum(self.sum, ut, values)
        self.per_ut.add(ut, values)
        self.pooled.add(values)

    def per_ut_stats(self):
        """(n_ut, 4): mean, p5, p50, p95 [dB]."""
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self.sum / self.count
        return np.column_stack([mean, self.per_ut.percentiles(PERCENTILES)])

    def overall(self):
        n = int(self.count.sum())
        pooled = self.pooled.percentiles(PERCENTILES) if n else [None] * 3
        return dict(zip(STAT_KEYS, [self.sum.sum() / n if n else None, *pooled], strict=True))
