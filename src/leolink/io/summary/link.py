"""The link figures of a run in summary.json: margins, MODCOD usage, ACM beside Shannon.

:class:`LinkStats` is fed the same trace columns as
:class:`leolink.io.summary.accumulator.SummaryAccumulator` (which owns one) and gives the
``link`` block of the overall summary and per UT:

- ``margin_db``: mean and the 5th, 50th and 95th percentiles of ``margin_db`` over the rows
  where it is finite (rows with a link), and ``fraction_negative``, the part of those rows
  whose Es/N0 is below the required one;
- ``modcod_usage``: fraction of the served UT-epochs (``service`` not ``outage``) per
  MODCOD name, ``none`` where no MODCOD closes the link; names in the table's order;
- ``served_without_modcod``: the served time on which no MODCOD closes the link,
  ``ut_s`` [UT-s] (each served row counts ``epoch_s - interruption_s``) and ``fraction`` of
  all served time (None without served time); 0 with ``controller.service_metric =
  "modcod"``, which turns such rows into outage;
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

    def __init__(self, n_ut, db_stats, epoch_s=1.0):
        self.n_ut, self.epoch_s = int(n_ut), float(epoch_s)
        self.served_s = np.zeros(self.n_ut)  # served time, and that of it without a MODCOD
        self.no_modcod_s = np.zeros(self.n_ut)
        self.names = (*modcod_table().names, NO_MODCOD_NAME)
        self.modcod_counts = np.zeros((self.n_ut, len(self.names)), np.int64)
        self.margin = db_stats(self.n_ut)
        self.n_negative = np.zeros(self.n_ut, np.int64)
        self.tput_sum = {k: np.zeros(self.n_ut) for k in _MODELS}
        self.tput_seen = dict.fromkeys(_MODELS, False)

    def add(self, columns, ut, service_codes, gap_s=0.0):
        """Add trace rows (``ut``: their UT ids, ``service_codes``: their service codes,
        ``gap_s``: the unserved part of each row's epoch [s])."""
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
            self._add_served_time(ut, served, code == len(self.names) - 1, gap_s)
        for model, key in _MODELS.items():
            if key in columns:
                tput = np.nan_to_num(np.asarray(columns[key], float), nan=0.0)
                # row by row: the same sum whether the rows come an epoch or a block at a time
                self.tput_sum[model][:] = running_sum(self.tput_sum[model], ut, tput)
                self.tput_seen[model] = True

    def _add_served_time(self, ut, served, no_modcod, gap_s):
        served_s = np.where(served, self.epoch_s - np.nan_to_num(np.asarray(gap_s, float)), 0.0)
        self.served_s[:] = running_sum(self.served_s, ut, served_s)
        self.no_modcod_s[:] = running_sum(self.no_modcod_s, ut, np.where(no_modcod, served_s, 0.0))

    @staticmethod
    def _without_modcod(no_modcod_s, served_s):
        return {"fraction": no_modcod_s / served_s if served_s > 0 else None, "ut_s": no_modcod_s}

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

        def block(margin, f, usage, t, without):
            return {
                "margin_db": {**margin, "fraction_negative": f},
                "modcod_usage": usage,
                "served_without_modcod": without,
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
            self._without_modcod(float(self.no_modcod_s.sum()), float(self.served_s.sum())),
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
                self._without_modcod(float(self.no_modcod_s[i]), float(self.served_s[i])),
            )
            for i in range(self.n_ut)  # output formatting only
        ]
        return overall, per_ut_blocks
