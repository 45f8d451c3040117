"""Run statistics streamed in bounded memory: the summary of ``summary.json``.

:class:`SummaryAccumulator` is a sink (:class:`leolink.sim.streams.Sink`): fed every
recorded epoch, it keeps per-UT counts, sums and the samples the percentiles need.
"""

from __future__ import annotations

import numpy as np

from leolink.io.atomic import to_jsonable
from leolink.io.link_summary import LinkStats
from leolink.io.summary_environment import by_environment
from leolink.sim.controller import EVENT_KINDS, SERVICE_HANDOVER, SERVICE_NAMES, SERVICE_OUTAGE
from leolink.sim.processes import OUTAGE_REASONS

__all__ = ["SummaryAccumulator", "grouped_percentiles"]


class _Growable:
    """Append-only 1-D array with amortized doubling."""

    def __init__(self, dtype):
        self._data, self._n = np.empty(1024, dtype), 0

    def append(self, values):
        values = np.asarray(values, self._data.dtype)
        need = self._n + values.size
        if need > self._data.size:
            grown = np.empty(max(need, 2 * self._data.size), self._data.dtype)
            grown[: self._n] = self._data[: self._n]
            self._data = grown
        self._data[self._n : need] = values
        self._n = need

    def view(self):
        return self._data[: self._n]


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


def _codes(values, names):
    """Integer codes of a coded column given as codes or as names (-1: unknown)."""
    values = np.asarray(values)
    if values.dtype.kind in "iu":
        return values.astype(np.int64)
    codes = np.full(values.shape, -1, np.int64)
    for code, name in enumerate(names):
        codes[values == name] = code
    return codes


def _service_codes(service):
    return _codes(service, SERVICE_NAMES)


_NO_SATELLITE = OUTAGE_REASONS.index("no_satellite")
_BELOW_THRESHOLD = OUTAGE_REASONS.index("below_threshold")
_BLOCKED = OUTAGE_REASONS.index("blocked")


_PERCENTILES = (5.0, 50.0, 95.0)


class SummaryAccumulator:
    """Running per-UT statistics of a run in bounded memory.

    Feed it every epoch with :meth:`add_trace` (the trace columns), :meth:`add_events` and
    :meth:`add_dwells`. SNR and SINR samples are kept per UT as float32 (percentiles exact
    to float32 rounding, < 1e-5 dB at |x| < 100 dB); sums are float64.

    Definitions: outage fraction = epochs with ``service == outage`` / epochs; SNR/SINR
    mean and percentiles over the epochs where the value is finite (mean of dB values);
    mean throughput over all epochs, a NaN throughput counting as 0 b/s; max |Doppler| of
    ``doppler_hz``. Dwell mean/median over complete dwells only (not censored by the run
    start or end); censored dwells are listed separately.

    Fractions of UT-time: ``handover_interruption_fraction`` = the ``interruption_s`` of
    every row (the handover execution time inside each epoch) / (epochs x ``epoch_s``);
    ``outage_fraction_by_reason``: ``no_satellite`` and ``below_threshold`` = epochs in
    outage for that reason / epochs (an outage lasts whole epochs; the two add up to
    ``outage_fraction``), ``handover`` = ``handover_interruption_fraction``.
    The link figures (margin, MODCOD usage, ACM and Shannon throughput): ``link``,
    :class:`leolink.io.link_summary.LinkStats`.
    """

    def __init__(self, n_ut=0, epoch_s=1.0, environment=()):
        self.epoch_s = float(epoch_s)
        self._reset(n_ut)
        self.environment = tuple(environment)  # per UT; empty: open country, no env block

    # -- the Sink protocol -------------------------------------------------------------
    def start(self, info):
        """Start a run of ``info.n_ut`` UTs (statistics reset)."""
        self.epoch_s = float(info.epoch_s)
        self._reset(info.n_ut)
        self.environment = tuple(getattr(info, "environment", ()))

    def epoch(self, frame):
        """Add one recorded epoch: its trace columns, events and closed dwells."""
        self.add_trace(frame.columns)
        self.add_events(frame.events)
        self.add_dwells(frame.dwells)

    def finish(self, final):
        """Add the dwells still open at the end of the run; the summary is then fixed."""
        self.add_dwells(final.dwells)
        self._final = self.summary()

    def abort(self):
        """Nothing to clean up (no file)."""

    # -- statistics ----------------------------------------------------------------------
    def _reset(self, n_ut):
        self._final = None
        self.n_ut = int(n_ut)
        zeros = lambda dtype=np.int64: np.zeros(self.n_ut, dtype)  # noqa: E731
        self.n_epochs, self.n_outage = zeros(), zeros()
        self.interrupted_s = zeros(np.float64)
        self.n_no_satellite, self.n_below_threshold = zeros(), zeros()
        self.n_blocked, self.n_los, self.n_link = zeros(), zeros(), zeros()
        self.throughput_sum = zeros(np.float64)
        self.max_abs_doppler_hz = np.full(self.n_ut, np.nan)
        self.max_angular_speed_deg_s = np.full(self.n_ut, np.nan)
        self.event_counts = np.zeros((len(EVENT_KINDS), self.n_ut), np.int64)
        self._samples = {
            k: (_Growable(np.int32), _Growable(np.float32)) for k in ("snr_db", "sinr_db")
        }
        self._sums = {k: zeros(np.float64) for k in self._samples}
        self._dwells = []
        self._link = LinkStats(self.n_ut, _Growable)

    def add_trace(self, columns):
        """Add trace rows (dict of 1-D arrays; needs ``ut_id``, ``service``, ``snr_db``,
        ``sinr_db``, ``throughput_bps``, ``doppler_hz``, ``angular_speed_deg_s``)."""
        ut = np.asarray(columns["ut_id"], np.int64)
        n = self.n_ut
        self.n_epochs += np.bincount(ut, minlength=n)
        codes = _service_codes(columns["service"])
        self.n_outage += np.bincount(ut, codes == SERVICE_OUTAGE, minlength=n).astype(np.int64)
        handover = codes == SERVICE_HANDOVER
        # Rows without the interruption_s column (older traces): a whole epoch each.
        gap = columns.get("interruption_s")
        gap = np.where(handover, self.epoch_s, 0.0) if gap is None else np.asarray(gap, float)
        self.interrupted_s += np.bincount(ut, gap, minlength=n)
        self._link.add(columns, ut, codes)
        if "outage_reason" in columns:
            reason = _codes(columns["outage_reason"], OUTAGE_REASONS)
            for store, code in (
                (self.n_no_satellite, _NO_SATELLITE),
                (self.n_below_threshold, _BELOW_THRESHOLD),
                (self.n_blocked, _BLOCKED),
            ):
                store += np.bincount(ut, reason == code, minlength=n).astype(np.int64)
        if "los" in columns:
            los = np.asarray(columns["los"], float)
            self.n_los += np.bincount(ut, los == 1.0, minlength=n).astype(np.int64)
            self.n_link += np.bincount(ut, np.isfinite(los), minlength=n).astype(np.int64)
        tput = np.nan_to_num(np.asarray(columns["throughput_bps"], float), nan=0.0)
        self.throughput_sum += np.bincount(ut, tput, minlength=n)
        np.fmax.at(self.max_abs_doppler_hz, ut, np.abs(np.asarray(columns["doppler_hz"], float)))
        np.fmax.at(self.max_angular_speed_deg_s, ut, np.asarray(columns["angular_speed_deg_s"]))
        for key, (ut_store, val_store) in self._samples.items():
            values = np.asarray(columns[key], float)
            ok = np.isfinite(values)
            ut_store.append(ut[ok])
            val_store.append(values[ok])
            self._sums[key] += np.bincount(ut[ok], values[ok], minlength=n)

    def add_events(self, events):
        """Count events by kind and UT (dict with ``ut_id`` and ``kind``)."""
        kind = np.asarray(events["kind"]).astype(str)
        ut = np.asarray(events["ut_id"], np.int64)
        for i, name in enumerate(EVENT_KINDS):
            self.event_counts[i] += np.bincount(ut[kind == name], minlength=self.n_ut)

    def add_dwells(self, dwells):
        """Keep dwell records (dict of arrays, ``controller.DWELL_COLUMNS``)."""
        if len(dwells["ut_id"]):
            self._dwells.append({k: np.asarray(v) for k, v in dwells.items()})

    def _dwell_frame(self):
        keys = ("ut_id", "sat_id", "beam_id", "start_s", "end_s", "censored_start", "censored_end")
        if not self._dwells:
            return {k: np.zeros(0, bool if k.startswith("censored") else float) for k in keys}
        d = {k: np.concatenate([x[k] for x in self._dwells]) for k in keys}
        order = np.lexsort((d["start_s"], d["ut_id"]))
        return {k: v[order] for k, v in d.items()}

    def _stats(self, key):
        ut, values = (s.view() for s in self._samples[key])
        count = np.bincount(ut, minlength=self.n_ut)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self._sums[key] / count
        pct = grouped_percentiles(ut, values, self.n_ut, _PERCENTILES)
        pooled = (
            np.percentile(values.astype(np.float64), _PERCENTILES) if values.size else [None] * 3
        )
        overall_mean = self._sums[key].sum() / values.size if values.size else None
        per_ut = [
            dict(zip(("mean", "p5", "p50", "p95"), row, strict=True))
            for row in np.column_stack([mean, pct]).tolist()
        ]
        overall = dict(zip(("mean", "p5", "p50", "p95"), [overall_mean, *pooled], strict=True))
        return per_ut, overall

    def _dwell_summary(self):
        """Per-UT dwell dicts and the pooled one (complete dwells only in mean/median)."""
        d = self._dwell_frame()
        duration = d["end_s"] - d["start_s"]
        complete = ~(d["censored_start"] | d["censored_end"])
        ut_c = d["ut_id"][complete].astype(np.int64)
        n_complete = np.bincount(ut_c, minlength=self.n_ut)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.bincount(ut_c, duration[complete], minlength=self.n_ut) / n_complete
        median = grouped_percentiles(ut_c, duration[complete], self.n_ut, [50.0])[:, 0]
        complete_lists = np.split(duration[complete], np.cumsum(n_complete)[:-1])
        cens = ~complete
        records = _records(d, duration, cens)
        n_cens = np.bincount(d["ut_id"][cens].astype(np.int64), minlength=self.n_ut)
        bounds = np.concatenate(([0], np.cumsum(n_cens)))
        per_ut = [
            {
                "n_complete": n_complete[i],
                "mean_s": mean[i],
                "median_s": median[i],
                "complete_s": complete_lists[i],
                "censored": records[bounds[i] : bounds[i + 1]],
            }
            for i in range(self.n_ut)  # output formatting only; statistics are vectorized
        ]
        overall = {
            "n_complete": int(complete.sum()),
            "complete_s": duration[complete].tolist(),
            "n_censored": int(cens.sum()),
            "mean_s": duration[complete].mean() if complete.any() else None,
            "median_s": np.median(duration[complete]) if complete.any() else None,
        }
        return per_ut, overall

    def summary(self):
        """``{"overall": {...}, "per_ut": [{...}, ...]}``, JSON-ready (NaN -> None)."""
        if self._final is not None:
            return self._final
        dwell_ut, dwell_all = self._dwell_summary()
        with np.errstate(invalid="ignore", divide="ignore"):
            outage_fraction = self.n_outage / self.n_epochs
            interrupted_fraction = self.interrupted_s / (self.n_epochs * self.epoch_s)
            no_sat = self.n_no_satellite / self.n_epochs
            below = self.n_below_threshold / self.n_epochs
            tput_mean = self.throughput_sum / self.n_epochs
        snr_ut, snr_all = self._stats("snr_db")
        sinr_ut, sinr_all = self._stats("sinr_db")
        counts = {k: self.event_counts[i] for i, k in enumerate(EVENT_KINDS)}
        link_all, link_ut = self._link.summary(
            self.n_epochs, lambda g, v, n: grouped_percentiles(g, v, n, _PERCENTILES)
        )
        per_ut = []
        for i in range(self.n_ut):  # output formatting only; all statistics are vectorized
            per_ut.append(
                {
                    "ut_id": i,
                    "n_epochs": self.n_epochs[i],
                    "handovers": _handover_counts({k: c[i] for k, c in counts.items()}),
                    "dwell": dwell_ut[i],
                    "outage_fraction": outage_fraction[i],
                    "outage_fraction_by_reason": _by_reason(
                        no_sat[i], below[i], interrupted_fraction[i]
                    ),
                    "handover_interruption_fraction": interrupted_fraction[i],
                    "snr_db": snr_ut[i],
                    "sinr_db": sinr_ut[i],
                    "mean_throughput_bps": tput_mean[i],
                    "max_abs_doppler_hz": self.max_abs_doppler_hz[i],
                    "max_angular_speed_deg_s": self.max_angular_speed_deg_s[i],
                    "link": link_ut[i],
                }
            )
        n_all = self.n_epochs.sum()
        t_all = n_all * self.epoch_s
        interrupted_all = self.interrupted_s.sum() / t_all if n_all else None
        overall = {
            "n_ut": self.n_ut,
            "n_ut_epochs": n_all,
            "handovers": _handover_counts({k: c.sum() for k, c in counts.items()}),
            "dwell": dwell_all,
            "outage_fraction": self.n_outage.sum() / n_all if n_all else None,
            "outage_fraction_by_reason": _by_reason(
                self.n_no_satellite.sum() / n_all if n_all else None,
                self.n_below_threshold.sum() / n_all if n_all else None,
                interrupted_all,
            ),
            "handover_interruption_fraction": interrupted_all,
            "snr_db": snr_all,
            "sinr_db": sinr_all,
            "mean_throughput_bps": self.throughput_sum.sum() / n_all if n_all else None,
            "max_abs_doppler_hz": _nanmax(self.max_abs_doppler_hz),
            "max_angular_speed_deg_s": _nanmax(self.max_angular_speed_deg_s),
            "link": link_all,
        }
        return to_jsonable(self._with_environment({"overall": overall, "per_ut": per_ut}, counts))

    def _with_environment(self, out, counts):
        """``out`` with the ``blocked`` outage fractions and ``by_environment`` of a run with
        TR 38.811 environments (else as it was)."""
        if not self.environment:
            return out
        overall, per_ut = out["overall"], out["per_ut"]
        n_all = self.n_epochs.sum()
        reasons = overall["outage_fraction_by_reason"]
        reasons["blocked"] = self.n_blocked.sum() / n_all if n_all else None
        with np.errstate(invalid="ignore", divide="ignore"):
            blocked = self.n_blocked / self.n_epochs
        for i, row in enumerate(per_ut):
            row["outage_fraction_by_reason"]["blocked"] = blocked[i]
        overall["by_environment"] = by_environment(self.environment, self, counts)
        return out


def _by_reason(no_satellite, below_threshold, handover):
    return {
        "no_satellite": no_satellite,
        "below_threshold": below_threshold,
        "handover": handover,
    }


def _nanmax(x):
    return float(np.nanmax(x)) if np.isfinite(x).any() else None


def _handover_counts(by_kind):
    out = {k: int(v) for k, v in by_kind.items()}
    out["handovers_total"] = out["beam_handover"] + out["sat_handover"]
    return out


def _records(d, duration, mask):
    """Dwell records (list of dicts) of the rows in ``mask``."""
    cols = {k: d[k][mask].tolist() for k in ("sat_id", "beam_id", "start_s", "end_s")}
    cols["duration_s"] = duration[mask].tolist()
    cols["censored_start"] = d["censored_start"][mask].tolist()
    cols["censored_end"] = d["censored_end"][mask].tolist()
    return [dict(zip(cols, row, strict=True)) for row in zip(*cols.values(), strict=True)]
