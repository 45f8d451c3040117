"""The link figures of a run in summary.json: margins, MODCOD usage, ACM beside Shannon.

:class:`LinkStats` is fed the same trace columns as :class:`leolink.io.summary.SummaryAccumulator`
(which owns one) and gives the ``link`` block of the overall summary and per UT:

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

from leolink.io.tables import NO_MODCOD_NAME
from leolink.link.acm import THROUGHPUT_COLUMNS
from leolink.link.modcod import modcod_table
from leolink.sim.controller import SERVICE_OUTAGE

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
    """Streamed link-figure statistics of ``n_ut`` UTs (bounded memory but the margins)."""

    def __init__(self, n_ut, growable):
        self.n_ut = int(n_ut)
        self.names = (*modcod_table().names, NO_MODCOD_NAME)
        self.modcod_counts = np.zeros((self.n_ut, len(self.names)), np.int64)
        self.margin = (growable(np.int32), growable(np.float32))
        self.margin_sum = np.zeros(self.n_ut)
        self.n_negative = np.zeros(self.n_ut, np.int64)
        self.tput_sum = {k: np.zeros(self.n_ut) for k in _MODELS}
        self.tput_seen = dict.fromkeys(_MODELS, False)

    def add(self, columns, ut, service_codes):
        """Add trace rows (``ut``: their UT ids, ``service_codes``: their service codes)."""
        n = self.n_ut
        if "margin_db" in columns:
            m = np.asarray(columns["margin_db"], float)
            ok = np.isfinite(m)
            self.margin[0].append(ut[ok])
            self.margin[1].append(m[ok])
            self.margin_sum += np.bincount(ut[ok], m[ok], minlength=n)
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
                self.tput_sum[model] += np.bincount(ut, tput, minlength=n)
                self.tput_seen[model] = True

    def _usage(self, counts):
        total = counts.sum()
        if not total:
            return {}
        return {self.names[i]: counts[i] / total for i in np.flatnonzero(counts)}

    def summary(self, n_epochs, percentiles):
        """``(overall, per_ut)`` link blocks; ``percentiles(ut, values, n) -> (n, 3)``."""
        ut, values = (s.view() for s in self.margin)
        count = np.bincount(ut, minlength=self.n_ut)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self.margin_sum / count
            neg = self.n_negative / count
            tput = {
                k: v / n_epochs if self.tput_seen[k] else None for k, v in self.tput_sum.items()
            }
        pct = percentiles(ut, values, self.n_ut)
        pooled = percentiles(np.zeros(values.size, np.int64), values, 1)[0]
        n_all = int(n_epochs.sum())

        def block(m, p, f, usage, t):
            margin = dict(zip(("mean", "p5", "p50", "p95"), [m, *p], strict=True))
            return {
                "margin_db": {**margin, "fraction_negative": f},
                "modcod_usage": usage,
                "mean_throughput_bps": t,
            }

        overall = block(
            self.margin_sum.sum() / values.size if values.size else None,
            pooled.tolist(),
            self.n_negative.sum() / values.size if values.size else None,
            self._usage(self.modcod_counts.sum(axis=0)),
            {
                k: (v.sum() / n_all if n_all else None) if self.tput_seen[k] else None
                for k, v in self.tput_sum.items()
            },
        )
        per_ut = [
            block(
                mean[i],
                pct[i].tolist(),
                neg[i],
                self._usage(self.modcod_counts[i]),
                {k: (None if v is None else v[i]) for k, v in tput.items()},
            )
            for i in range(self.n_ut)  # output formatting only
        ]
        return overall, per_ut
