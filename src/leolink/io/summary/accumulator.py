"""Run statistics streamed in bounded memory: the summary of ``summary.json``.

:class:`SummaryAccumulator` is a sink (:class:`leolink.sim.streams.Sink`): fed every
recorded epoch, it keeps per-UT counts, sums and histograms, in memory that does not grow
with the number of epochs (dwell records and the handover KPIs' serving-change events
aside: one per serving change).

Per-UT statistics of a run with more than :data:`PER_UT_IN_JSON_MAX` UTs stay out of
``summary.json``: :meth:`SummaryAccumulator.per_ut_table` gives them as columns (written
as ``per_ut.parquet`` by :mod:`leolink.app.run`).
"""

from __future__ import annotations

import numpy as np

from leolink.io.atomic import to_jsonable
from leolink.io.summary.bands import LatitudeBands
from leolink.io.summary.environment import with_environment
from leolink.io.summary.kpi import KpiAccumulator
from leolink.io.summary.link import LinkStats
from leolink.io.summary.records import (
    STAT_KEYS,
    by_reason,
    handover_counts,
    nanmax,
    per_ut_records,
)
from leolink.io.summary.stats import (
    DB_RANGE,
    OVERALL_RESOLUTION_DB,
    PER_UT_RESOLUTION_DB,
    DbStats,
    grouped_percentiles,
    running_sum,
)
from leolink.sim.handover.controller import (
    EVENT_KINDS,
    SERVICE_HANDOVER,
    SERVICE_NAMES,
    SERVICE_OUTAGE,
)
from leolink.sim.processes import OUTAGE_REASONS

__all__ = [
    "DB_RANGE",
    "KPI_COLUMNS",
    "OVERALL_RESOLUTION_DB",
    "PER_UT_IN_JSON_MAX",
    "PER_UT_RESOLUTION_DB",
    "SummaryAccumulator",
    "grouped_percentiles",
]

#: Runs with more UTs keep per-UT statistics out of summary.json (``per_ut.parquet``).
PER_UT_IN_JSON_MAX = 1000
#: The per-UT handover KPIs (each UT's ``kpi`` block), also columns of ``per_ut.parquet``.
KPI_COLUMNS = ("handover_rate_per_ut_min", "ping_pong_count", "rlf_count",
               "handover_failure_count", "too_early_count", "too_late_count",
               "wrong_cell_count")  # fmt: skip
# Trace rows buffered before they are folded into the statistics (~4 MiB): one set of
# numpy calls per 64 Ki rows, not per epoch (the fixed cost of a small run's epoch).
_POOL_BUFFER = 1 << 16


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


#: Per-UT epoch counters of the outage reasons they count.
_REASON_COUNTERS = {
    "n_no_satellite": OUTAGE_REASONS.index("no_satellite"),
    "n_below_threshold": OUTAGE_REASONS.index("below_threshold"),
    "n_blocked": OUTAGE_REASONS.index("blocked"),
    "n_rlf": OUTAGE_REASONS.index("rlf"),
}
_DB_COLUMNS = ("snr_db", "sinr_db")
_BUFFERED = ("throughput_bps", "doppler_hz", "angular_speed_deg_s", *_DB_COLUMNS)
_DWELL_KEYS = ("ut_id", "sat_id", "beam_id", "start_s", "end_s", "censored_start", "censored_end")


class SummaryAccumulator:
    """Running per-UT statistics of a run in bounded memory.

    Feed it every epoch with :meth:`add_trace` (the trace columns), :meth:`add_events` and
    :meth:`add_dwells`. Means and sums are exact (float64). SNR and SINR percentiles come
    from fixed-bin histograms over :data:`DB_RANGE`: the pooled ones (``overall``) with
    bins of :data:`OVERALL_RESOLUTION_DB` (0.01 dB), the per-UT ones with bins of
    :data:`PER_UT_RESOLUTION_DB` (0.1 dB); each is within half its bin of
    ``numpy.percentile`` (linear) on the same samples. Memory: ~0.6 MB + ``n_ut x`` the
    0.1 dB bins each UT's values visit (12 B each), whatever the run length.

    Definitions: outage fraction = epochs with ``service == outage`` / epochs; SNR/SINR
    mean and percentiles over the epochs where the value is finite (mean of dB values);
    mean throughput over all epochs, a NaN throughput counting as 0 b/s; max |Doppler| of
    ``doppler_hz``. Dwell mean/median over complete dwells only (not censored by the run
    start or end); censored dwells are listed separately.

    Fractions of UT-time: ``handover_interruption_fraction`` = the ``interruption_s`` of
    every row (the handover execution time inside each epoch) / (epochs x ``epoch_s``);
    ``outage_fraction_by_reason``: ``no_satellite`` and ``below_threshold`` = epochs in
    outage for that reason / epochs (an outage lasts whole epochs; the two add up to
    ``outage_fraction``), ``handover`` = ``handover_interruption_fraction``, ``rlf`` =
    epochs re-establishing after a radio link failure / epochs; ``blocked`` and
    ``by_environment`` for a run with UT environments
    (:mod:`leolink.io.summary.environment`).

    Handover KPIs (``overall.kpi``, each UT's ``kpi``): :mod:`leolink.io.summary.kpi`,
    with ``ping_pong_s`` and ``mro_window_s`` [s] (``[kpi]``), the MRO cells at
    ``mro_level`` (``"cell"``, or ``"satellite"`` when cells are satellites: then the
    beam switches of ``beam_switch_s`` each are counted apart). The link
    figures (margin, MODCOD usage, ACM and Shannon throughput): ``link``,
    :class:`leolink.io.summary.link.LinkStats`.
    """

    def __init__(self, n_ut=0, epoch_s=1.0, ping_pong_s=1.0, environment=(), mro_window_s=1.0,
                 mro_level="cell", beam_switch_s=None):  # fmt: skip
        self.epoch_s, self.ping_pong_s = float(epoch_s), float(ping_pong_s)
        self.mro = (float(mro_window_s), mro_level, beam_switch_s)
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

    block = epoch  # epochs in order: the same statistics as epoch by epoch (add_trace)

    def finish(self, final):
        """Add the dwells still open at the end of the run; the summary is then fixed."""
        self.add_dwells(final.dwells)
        self._final = self.summary()

    def abort(self):
        """Nothing to clean up (no file)."""

    # -- statistics ----------------------------------------------------------------------
    def _reset(self, n_ut):
        self._final = self._kpi_result = None
        self.n_ut = int(n_ut)
        zeros = lambda dtype=np.int64: np.zeros(self.n_ut, dtype)  # noqa: E731
        self.n_epochs, self.n_outage = zeros(), zeros()
        self.interrupted_s = zeros(np.float64)
        for name in _REASON_COUNTERS:
            setattr(self, name, zeros())
        self.n_los, self.n_link = zeros(), zeros()  # LoS epochs / epochs with a link
        self.kpi = KpiAccumulator(self.n_ut, self.ping_pong_s, *self.mro)
        self.throughput_sum = zeros(np.float64)
        self.max_abs_doppler_hz = np.full(self.n_ut, np.nan)
        self.max_angular_speed_deg_s = np.full(self.n_ut, np.nan)
        self.event_counts = np.zeros((len(EVENT_KINDS), self.n_ut), np.int64)
        self._db = {k: DbStats(self.n_ut) for k in _DB_COLUMNS}
        self._dwells = []
        self._rows, self._n_rows = [], 0
        self._link = LinkStats(self.n_ut, DbStats, self.epoch_s)  # margins in histograms too
        self.bands = LatitudeBands(self.n_ut, self.epoch_s)
        self.lat_deg, self.lon_deg = np.full(self.n_ut, np.nan), np.full(self.n_ut, np.nan)

    def add_trace(self, columns):
        """Add trace rows (dict of 1-D arrays; needs ``ut_id``, ``service``, ``snr_db``,
        ``sinr_db``, ``throughput_bps``, ``doppler_hz``, ``angular_speed_deg_s``; uses
        ``interruption_s``, ``outage_reason``, ``los`` and the link figures if given).

        Rows are buffered and folded into the statistics every :data:`_POOL_BUFFER` rows
        (a run's small epochs cost one append each, not ~20 numpy calls); a per-UT sum
        still adds the rows in their order, so it is the same number either way.
        """
        self._kpi_result = None
        ut = np.asarray(columns["ut_id"], np.int64)
        codes = _service_codes(columns["service"])
        # Rows without the interruption_s column (older traces): a whole epoch each.
        gap = columns.get("interruption_s")
        if gap is None:
            gap = np.where(codes == SERVICE_HANDOVER, self.epoch_s, 0.0)
        reason = columns.get("outage_reason")
        reason = np.full(ut.shape, -1) if reason is None else _codes(reason, OUTAGE_REASONS)
        los = columns.get("los")  # a run with environments only: NaN counts nowhere
        los = np.full(ut.shape, np.nan) if los is None else los
        self._link.add(columns, ut, codes, gap)  # per call: it needs the frame-only columns
        piece = {"ut": ut, "service": codes, "gap": gap, "reason": reason, "los": los}
        piece["band"] = self._place(columns, ut)
        for key in _BUFFERED:
            piece[key] = columns[key]
        self._rows.append(piece)
        self._n_rows += ut.size
        if self._n_rows >= _POOL_BUFFER:
            self._fold()

    def _place(self, columns, ut):
        """Each row's latitude band (-1 without ``lat_deg``); each UT's first position."""
        if "lat_deg" not in columns:
            return np.full(ut.shape, -1, np.int64)
        lat, lon = np.asarray(columns["lat_deg"], float), np.asarray(columns["lon_deg"], float)
        new = np.flatnonzero(np.isnan(self.lat_deg[ut]))
        if new.size:  # the first row of each UT not placed yet
            first_ut, at = np.unique(ut[new], return_index=True)
            self.lat_deg[first_ut], self.lon_deg[first_ut] = lat[new[at]], lon[new[at]]
        return self.bands.note_rows(columns["time_s"], ut, lat)

    def _fold(self):
        """Add the buffered rows to the statistics."""
        if not self._rows:
            return
        c = {k: np.concatenate([np.asarray(r[k]) for r in self._rows]) for k in self._rows[0]}
        self._rows, self._n_rows = [], 0
        ut, n = c["ut"], self.n_ut
        self.n_epochs += np.bincount(ut, minlength=n)
        self.n_outage += np.bincount(ut[c["service"] == SERVICE_OUTAGE], minlength=n)
        self.interrupted_s[:] = running_sum(self.interrupted_s, ut, c["gap"])
        for name, code in _REASON_COUNTERS.items():
            counter = getattr(self, name)
            counter += np.bincount(ut[c["reason"] == code], minlength=n)
        los = np.asarray(c["los"], float)
        self.n_los += np.bincount(ut[los == 1.0], minlength=n)
        self.n_link += np.bincount(ut[np.isfinite(los)], minlength=n)
        self.kpi.add_trace(c)  # histograms of sinr_db and throughput_bps: order-free
        tput = np.nan_to_num(np.asarray(c["throughput_bps"], float), nan=0.0)
        self.throughput_sum[:] = running_sum(self.throughput_sum, ut, tput)
        np.fmax.at(self.max_abs_doppler_hz, ut, np.abs(np.asarray(c["doppler_hz"], float)))
        np.fmax.at(self.max_angular_speed_deg_s, ut, np.asarray(c["angular_speed_deg_s"], float))
        for key, stats in self._db.items():
            stats.add(ut, np.asarray(c[key], float))
        placed = c["band"] >= 0
        self.bands.fold(c["band"][placed], c["service"][placed] == SERVICE_OUTAGE,
                        np.asarray(c["sinr_db"], float)[placed])  # fmt: skip

    def add_events(self, events):
        """Count events by kind and UT (dict with ``ut_id`` and ``kind``)."""
        if not len(events["ut_id"]):
            return
        self._kpi_result = None
        kind = np.asarray(events["kind"]).astype(str)
        ut = np.asarray(events["ut_id"], np.int64)
        for i, name in enumerate(EVENT_KINDS):
            self.event_counts[i] += np.bincount(ut[kind == name], minlength=self.n_ut)
        self.kpi.add_events(events)
        self.bands.add_events(events["time_s"], ut, kind)

    def add_dwells(self, dwells):
        """Keep dwell records (dict of arrays, ``controller.DWELL_COLUMNS``)."""
        if len(dwells["ut_id"]):
            self._kpi_result = None
            self._dwells.append({k: np.asarray(dwells[k]) for k in _DWELL_KEYS})

    def dwell_table(self):
        """Every dwell, sorted by UT then start: ``DWELL_COLUMNS`` + ``duration_s``."""
        if not self._dwells:
            d = {k: np.zeros(0, bool if k.startswith("censored") else float) for k in _DWELL_KEYS}
        else:
            d = {k: np.concatenate([x[k] for x in self._dwells]) for k in _DWELL_KEYS}
            self._dwells = [d]  # one block from now on
            order = np.lexsort((d["start_s"], d["ut_id"]))
            d = {k: v[order] for k, v in d.items()}
        d["duration_s"] = d["end_s"] - d["start_s"]
        return d

    def _dwell_stats(self, d):
        """Per-UT columns of complete/censored dwells, and the complete mask."""
        complete = ~(d["censored_start"].astype(bool) | d["censored_end"].astype(bool))
        ut = d["ut_id"].astype(np.int64)
        n_complete = np.bincount(ut[complete], minlength=self.n_ut)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.bincount(ut[complete], d["duration_s"][complete], minlength=self.n_ut)
            mean = mean / n_complete
        median = grouped_percentiles(ut[complete], d["duration_s"][complete], self.n_ut, [50.0])
        cols = {
            "n_dwell_complete": n_complete,
            "dwell_mean_s": mean,
            "dwell_median_s": median[:, 0],
            "n_dwell_censored": np.bincount(ut[~complete], minlength=self.n_ut),
        }
        return cols, complete

    def _kpi(self, d):
        """``overall.kpi`` and the per-UT KPI dicts (:mod:`leolink.io.summary.kpi`), kept
        until rows, events or dwells are added."""
        if self._kpi_result is None:
            n_rlf = int(self.n_rlf.sum())
            interruption = {
                "handover": float(self.interrupted_s.sum()),
                "rlf": n_rlf * self.epoch_s,
                "outage": (int(self.n_outage.sum()) - n_rlf) * self.epoch_s,
            }
            observed = self.n_epochs * self.epoch_s
            self._kpi_result = self.kpi.summary(d, observed, interruption)
        return self._kpi_result

    def per_ut_table(self, dwells=None):
        """Per-UT statistics as columns, one row per UT (``per_ut.parquet``).

        Columns: ``ut_id, n_epochs``, ``lat_deg, lon_deg`` (where the UT was at its first
        recorded epoch; NaN for rows without them), ``n_<event kind>`` and ``n_handovers_total``,
        ``n_dwell_complete, dwell_mean_s, dwell_median_s, n_dwell_censored``,
        ``outage_fraction``, ``outage_fraction_<reason>`` for ``no_satellite``,
        ``below_threshold``, ``rlf`` (and ``blocked`` in a run with UT environments),
        ``handover_interruption_fraction``, ``snr_mean_db, snr_p5_db, snr_p50_db,
        snr_p95_db`` and the same for ``sinr``, ``mean_throughput_bps,
        max_abs_doppler_hz, max_angular_speed_deg_s`` and the KPIs :data:`KPI_COLUMNS`
        (when every UT was recorded: the ``kpi`` blocks are empty otherwise).
        """
        self._fold()
        d = self.dwell_table() if dwells is None else dwells
        with np.errstate(invalid="ignore", divide="ignore"):
            epochs = self.n_epochs.astype(float)
            table = {"ut_id": np.arange(self.n_ut), "n_epochs": self.n_epochs}
            table["lat_deg"], table["lon_deg"] = self.lat_deg, self.lon_deg
            for i, kind in enumerate(EVENT_KINDS):
                table[f"n_{kind}"] = self.event_counts[i]
            table["n_handovers_total"] = self.event_counts[0] + self.event_counts[1]
            table.update(self._dwell_stats(d)[0])
            table["outage_fraction"] = self.n_outage / epochs
            for name in _REASON_COUNTERS:
                if name != "n_blocked" or self.environment:
                    table[f"outage_fraction_{name[2:]}"] = getattr(self, name) / epochs
            table["handover_interruption_fraction"] = self.interrupted_s / (epochs * self.epoch_s)
            for key, stats in self._db.items():
                name = key.removesuffix("_db")
                for stat, col in zip(STAT_KEYS, stats.per_ut_stats().T, strict=True):
                    table[f"{name}_{stat}_db"] = col
            table["mean_throughput_bps"] = self.throughput_sum / epochs
        table["max_abs_doppler_hz"] = self.max_abs_doppler_hz
        table["max_angular_speed_deg_s"] = self.max_angular_speed_deg_s
        kpi_ut = self._kpi(d)[1]
        if self.n_ut and kpi_ut[0]:
            for key in KPI_COLUMNS:
                table[key] = np.array([k[key] for k in kpi_ut])
        return table

    def _overall(self, d, complete, per_ut_in_json, link_all):
        n_all = int(self.n_epochs.sum())
        frac = (lambda x: x / n_all) if n_all else (lambda x: None)  # noqa: E731
        interrupted_all = self.interrupted_s.sum() / (n_all * self.epoch_s) if n_all else None
        done = d["duration_s"][complete]
        dwell = {"n_complete": int(complete.sum())}
        if per_ut_in_json:
            dwell["complete_s"] = done.tolist()
        dwell["n_censored"] = int((~complete).sum())
        dwell["mean_s"] = done.mean() if done.size else None
        dwell["median_s"] = float(np.median(done)) if done.size else None
        counts = {k: self.event_counts[i].sum() for i, k in enumerate(EVENT_KINDS)}
        return {
            "n_ut": self.n_ut,
            "n_ut_epochs": n_all,
            "handovers": handover_counts(counts),
            "dwell": dwell,
            "outage_fraction": frac(self.n_outage.sum()),
            "outage_fraction_by_reason": by_reason(
                frac(self.n_no_satellite.sum()),
                frac(self.n_below_threshold.sum()),
                interrupted_all,
                frac(self.n_rlf.sum()),
            ),  # fmt: skip
            "handover_interruption_fraction": interrupted_all,
            "snr_db": self._db["snr_db"].overall(),
            "sinr_db": self._db["sinr_db"].overall(),
            "mean_throughput_bps": frac(self.throughput_sum.sum()),
            "max_abs_doppler_hz": nanmax(self.max_abs_doppler_hz),
            "max_angular_speed_deg_s": nanmax(self.max_angular_speed_deg_s),
            "link": link_all,
            "kpi": self._kpi(d)[0],
            "by_latitude": self.bands.summary(),
        }

    def summary(self):
        """``{"overall": {...}, "per_ut": [{...}, ...]}``, JSON-ready (NaN -> None).

        With more than :data:`PER_UT_IN_JSON_MAX` UTs, ``per_ut`` and the overall list of
        dwell durations are left out (see :meth:`per_ut_table`, :meth:`dwell_table`).
        """
        if self._final is not None:
            return self._final
        self._fold()
        d = self.dwell_table()
        in_json = self.n_ut <= PER_UT_IN_JSON_MAX
        _, complete = self._dwell_stats(d)
        link_all, link_ut = self._link.summary(self.n_epochs, per_ut=in_json)
        out = {"overall": self._overall(d, complete, in_json, link_all)}
        if in_json:
            kpi_ut = self._kpi(d)[1]
            out["per_ut"] = per_ut_records(self.per_ut_table(d), d, complete, link_ut, kpi_ut)
        counts = {k: self.event_counts[i] for i, k in enumerate(EVENT_KINDS)}
        return to_jsonable(with_environment(self, out, counts))
