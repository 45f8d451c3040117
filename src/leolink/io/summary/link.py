"""The link figures of a run in summary.json: margins, MODCOD usage, ACM beside Shannon.

:class:`LinkStats` is fed the same trace columns as
:class:`leolink.io.summary.accumulator.SummaryAccumulator` (which owns one) and gives the
``link`` block of the overall summary and per UT:

- ``margin_db``: mean and the 5th, 50th and 95th percentiles of ``margin_db`` over the rows
  where it is finite (rows with a link), and ``fraction_negative``, the part of those rows
  whose Es/N0 is below the required one;
- ``modcod_usage``: fraction of the served UT-epochs (``service`` not ``outage``) per
  MODCOD name, ``none`` where no MODCOD closes the link; names in the table's order;
- ``mean_throughput_bps``: ``shannon`` and ``dvbs2x`` (ACM), over all UT-epochs (NaN
  counts as 0, as the overall ``mean_throughput_bps``), when the columns
  ``throughput_shannon_bps`` and ``throughput_dvbs2x_bps`` of the run's frames are given
  (not written to the trace; None when fed a trace read back from a file).
"""

from __future__ import annotations

import numpy as np

from leolink.io.summary.stats import running_sum
from leolink.io.tables import NO_MODCOD_NAME
from leolink.link.acm import THROUGHPUT_COLUMNS
from leolink.link.modcod import modcod_table
from leolink.sim.handover.controller import SERVICE_OUTAGE

__all__ = ["LinkStats"]

_MODELS = {"shannon": THROUGHPUT_COLUMNS[0], "dvbs2x": THROUGHPUT_COLUMNS[1]}


def _modcod_codes(values, names):
    """Row codes of a ``modcod`` column given as codes (-1: none) or as names."""
    values = np.asarray(values)
    if values.dtype.kind in "iu":
        return np.where(values < 0, len(names) - 1, values).astype(np.int64)
    lookup = {name: code for code, name in enumerate(names)}
    return np.array([lookup.get(v, len(names) - 1) for v in values.tolist()], np.int64)


class LinkStats:
    """Streamed link-figure statistics of ``n_ut`` UTs, in bounded memory.

    ``db_stats(n_ut)`` keeps the margins (finite values only): per-UT count, sum and
    histogram, and a pooled histogram (``leolink.io.summary.stats.DbStats``: the margin
    percentiles have the SNR percentiles' resolution, 0.01 dB pooled, 0.1 dB per UT).
    """

    def __init__(self, n_ut, db_stats):
        self.n_ut = int(n_ut)
        self.names = (*modcod_table().names, NO_MODCOD_NAME)
        self.modcod_counts = np.zeros((self.n_ut, len(self.names)), np.int64)
        self.margin = db_stats(self.n_ut)
        self.n_negative = np.zeros(self.n_ut, np.int64)
        self.tput_sum = {k: np.zeros(self.n_ut) for k in _MODELS}
        self.tput_seen = dict.fromkeys(_MODELS, False)

    def add(self, columns, ut, service_codes):
        """Add trace rows (``ut``: their UT ids, ``service_codes``: their service codes)."""
        n = self.n_ut
        if "margin_db" in columns:
            m = np.asarray(columns["margin_db"], float)
            ok = np.isfinite(m)
            self.margin.add(ut, m)
            self.n_negative += np.bincount(ut[ok], m[ok] < 0.0, minlength=n).astype(np.int64)
        if "modcod" in columns:
            code = _modcod_codes(columns["modcod"], self.names)
            served = service_codes != SERVICE_OUTAGE
            flat = ut[served] * len(self.names) + code[served]
            self.modcod_counts += np.bincount(flat, minlength=self.modcod_counts.size).reshape(
                self.modcod_counts.shape
            )
        for model, key in _MODELS.items():
            if key in columns:
                tput = np.nan_to_num(np.asarray(columns[key], float), nan=0.0)
                # row by row: the same sum whether the rows come an epoch or a block at a time
                self.tput_sum[model][:] = running_sum(self.tput_sum[model], ut, tput)
                self.tput_seen[model] = True

    def _usage(self, counts):
        total = counts.sum()
        if not total:
            return {}
        return {self.names[i]: counts[i] / total for i in np.flatnonzero(counts)}

    def summary(self, n_epochs, per_ut=True):
        """``(overall, per_ut)`` link blocks (``per_ut`` None unless asked for)."""
        count = self.margin.count
        n_margin = int(count.sum())
        with np.errstate(invalid="ignore", divide="ignore"):
            neg = self.n_negative / count
            tput = {
                k: v / n_epochs if self.tput_seen[k] else None for k, v in self.tput_sum.items()
            }
        n_all = int(n_epochs.sum())

        def block(margin, f, usage, t):
            return {
                "margin_db": {**margin, "fraction_negative": f},
                "modcod_usage": usage,
                "mean_throughput_bps": t,
            }

        overall = block(
            self.margin.overall(),
            self.n_negative.sum() / n_margin if n_margin else None,
            self._usage(self.modcod_counts.sum(axis=0)),
            {
                k: (v.sum() / n_all if n_all else None) if self.tput_seen[k] else None
                for k, v in self.tput_sum.items()
            },
        )
        if not per_ut:
            return overall, None
        stats = self.margin.per_ut_stats().tolist()  # (n_ut, 4): mean, p5, p50, p95
        keys = ("mean", "p5", "p50", "p95")
        per_ut_blocks = [
            block(
                dict(zip(keys, stats[i], strict=True)),
                neg[i],
                self._usage(self.modcod_counts[i]),
                {k: (None if v is None else v[i]) for k, v in tput.items()},
            )
            for i in range(self.n_ut)  # output formatting only
        ]
        return overall, per_ut_blocks
