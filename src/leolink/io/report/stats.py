"""Streamed statistics for the report: what a sink keeps so the page never needs the trace.

:class:`ReportStats` is fed chunk by chunk (any chunking: one epoch, many epochs, a file
batch) and keeps, in memory bounded independently of the number of UTs x epochs:

- fixed-bin histograms of ``snr_db``, ``sinr_db`` (0.05 dB bins over [-60, 60] dB plus
  under/overflow) and ``throughput_bps`` (0.01-decade bins over [1e3, 1e12] b/s plus a
  bin for 0 b/s, where a NaN throughput counts as 0 b/s as in ``summary.json``); the CDFs
  read from them are exact to one bin;
- UT-epoch counts by ``service`` and by ``outage_reason`` (``"unspecified"`` when the
  trace has no such column);
- every row of a few chosen UTs (``series_ut``) and their events: the time plots;
- the positions and serving (satellite, beam) of a fixed sample of UTs at a subsampled
  set of epochs (``keep_times_s``, at most ``max_frames``): the map and the animation;
- satellite positions and velocities at those epochs and the codebook: ground tracks and
  beam cells;
- histograms of dwell durations, complete and censored apart (bins of one epoch).

Memory: ``n_series x n_epoch`` rows + ``max_frames x (n_sample_ut + 2 n_sat x 3)`` numbers
+ ~3,000 bins, whatever ``n_ut``. :meth:`save` / :meth:`load` keep it as ``report_stats.npz``
beside the run, so ``leolink report DIR`` rebuilds the page in seconds.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SERIES_COLUMNS", "ReportStats"]

SERIES_COLUMNS = (
    "time_s",
    "ut_id",
    "sat_id",
    "beam_id",
    "lat_deg",
    "lon_deg",
    "snr_db",
    "sinr_db",
    "throughput_bps",
    "doppler_hz",
    "doppler_rate_hz_s",
    "angular_speed_deg_s",
    "service",
)
_OPTIONAL_SERIES = ("outage_reason", "alt_m")
EVENT_COLUMNS = ("time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat", "to_beam")
DB_EDGES = np.round(np.arange(-60.0, 60.0 + 1e-9, 0.05), 10)  # [dB]
LOG_TPUT_EDGES = np.round(np.arange(3.0, 12.0 + 1e-9, 0.01), 10)  # log10 [b/s]
_TIME_TOL = 1e-6  # fraction of an epoch within which a time matches a kept epoch


def _hist(values, edges):
    """Counts of finite ``values`` in ``[-inf, e0), [e0, e1), ..., [e_last, inf)``.

    The edges are uniform, so the bin is computed arithmetically and then corrected by one
    where rounding put a value next to an edge on the wrong side (same result as
    ``searchsorted(edges, v, side="right")``, ~5x faster)."""
    v = values[np.isfinite(values)]
    step = (edges[-1] - edges[0]) / (edges.size - 1)
    idx = np.clip(np.floor((v - edges[0]) / step).astype(np.int64) + 1, 0, edges.size)
    lower = edges[np.clip(idx - 1, 0, edges.size - 1)]
    idx -= (idx > 0) & (v < lower)
    upper = edges[np.clip(idx, 0, edges.size - 1)]
    idx += (idx < edges.size) & (v >= upper)
    return np.bincount(idx, minlength=edges.size + 1)


def _count_into(store, values):
    """Add the counts of each distinct value (strings) to the dict ``store``; a missing
    value (None, NaN: a CSV column read back) is not counted."""
    values = np.asarray(values)
    if values.dtype.kind not in "US":  # object or float columns read from files
        from pandas import notna  # only there: a run's columns are names already

        values = values[notna(values)].astype(str)
    names, counts = np.unique(values, return_counts=True)
    for name, c in zip(names.tolist(), counts.tolist(), strict=True):
        store[str(name)] = store.get(str(name), 0) + int(c)


def _plain(values):
    """A column as a non-object numpy array (strings as unicode)."""
    values = np.asarray(values)
    return values.astype(str) if values.dtype == object else values


def _columns(parts, names, order):
    """The chunks ``parts`` (dicts of arrays) joined, rows in the order ``order(columns)``
    gives; empty columns ``names`` when there is none."""
    if not parts:
        return {k: np.empty(0) for k in names}
    cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    rows = order(cols)
    return {k: v[rows] for k, v in cols.items()}


class ReportStats:
    """Bounded-memory statistics of a run for :mod:`leolink.io.report.page` (see module doc).

    Parameters
    ----------
    n_ut : int
        UTs of the run (ids ``0 .. n_ut - 1``).
    start_s, end_s, epoch_s : float
        Run start, end and epoch [s]; epochs at ``start_s + k epoch_s < end_s``.
    series_ut : sequence of int
        UTs whose every row is kept (time plots).
    n_sample_ut : int
        UTs kept at the subsampled epochs (map, animation), spread evenly over the ids;
        the ``series_ut`` are always among them.
    max_frames : int
        Most subsampled epochs (every ``ceil(n_epoch / max_frames)``-th epoch is kept).
    """

    def __init__(
        self, n_ut, start_s, end_s, epoch_s, series_ut=(0,), n_sample_ut=500, max_frames=120
    ):
        self.n_ut, self.epoch_s = int(n_ut), float(epoch_s)
        self.start_s, self.end_s = float(start_s), float(end_s)
        n_epoch = max(int(np.ceil((self.end_s - self.start_s) / self.epoch_s - 1e-9)), 1)
        self.stride = max(int(np.ceil(n_epoch / max(int(max_frames), 1))), 1)
        self.keep_times_s = self.start_s + self.epoch_s * np.arange(0, n_epoch, self.stride)
        self.series_ut = np.unique(np.asarray([u for u in series_ut if 0 <= u < n_ut], int))
        spread = np.round(np.linspace(0, self.n_ut - 1, min(int(n_sample_ut), self.n_ut)))
        self.sample_ut = np.union1d(spread.astype(int), self.series_ut)
        shape = (self.keep_times_s.size, self.sample_ut.size)
        self.ut_lat_deg, self.ut_lon_deg = np.full(shape, np.nan), np.full(shape, np.nan)
        self.ut_sat, self.ut_beam = np.full(shape, -2, np.int64), np.full(shape, -2, np.int64)
        self.hist = {
            "snr_db": np.zeros(DB_EDGES.size + 1, np.int64),
            "sinr_db": np.zeros(DB_EDGES.size + 1, np.int64),
            "log10_throughput_bps": np.zeros(LOG_TPUT_EDGES.size + 1, np.int64),
        }
        self.n_zero_throughput = 0
        self.service_counts, self.outage_reason_counts = {}, {}
        self._series, self._events = [], []
        n_dwell_bins = min(max(int(np.ceil((self.end_s - self.start_s) / self.epoch_s)), 1), 4000)
        self.dwell_edges_s = np.linspace(
            0.0, max(self.end_s - self.start_s, self.epoch_s), n_dwell_bins + 1
        )
        self.dwell_complete = np.zeros(n_dwell_bins, np.int64)
        self.dwell_censored = np.zeros(n_dwell_bins, np.int64)
        self.dwell_complete_sum_s = np.zeros(())  # exact: the mean is summary.json's
        self.sat_ids = self.sat_pos_m = self.sat_vel_m_s = None
        self.beam_u_xy, self.n_sub_xy = None, None

    # ------------------------------------------------------------------ feeding
    def _keep_index(self, t_s):
        """Index into ``keep_times_s`` of each time, -1 where the time is not kept."""
        k = np.round((np.asarray(t_s, float) - self.start_s) / (self.epoch_s * self.stride))
        k = k.astype(np.int64)
        ok = (k >= 0) & (k < self.keep_times_s.size)
        kk = np.where(ok, k, 0)
        ok &= np.abs(self.keep_times_s[kk] - t_s) <= _TIME_TOL * self.epoch_s
        return np.where(ok, kk, -1)

    def add_trace(self, columns):
        """Add trace rows: dict of 1-D arrays with the trace columns (see module doc)."""
        ut = np.asarray(columns["ut_id"], np.int64)
        for key in ("snr_db", "sinr_db"):
            self.hist[key] += _hist(np.asarray(columns[key], float), DB_EDGES)
        tput = np.nan_to_num(np.asarray(columns["throughput_bps"], float), nan=0.0)
        positive = tput > 0.0
        self.n_zero_throughput += int(tput.size - positive.sum())
        self.hist["log10_throughput_bps"] += _hist(np.log10(tput[positive]), LOG_TPUT_EDGES)
        service = np.asarray(columns["service"])
        _count_into(self.service_counts, service)
        out = service == "outage"
        if "outage_reason" in columns:
            _count_into(self.outage_reason_counts, np.asarray(columns["outage_reason"])[out])
        elif out.any():
            _count_into(self.outage_reason_counts, np.full(int(out.sum()), "unspecified"))
        self._add_series(columns, ut)
        self._add_samples(columns, ut)

    def _add_series(self, columns, ut):
        rows = np.flatnonzero(np.isin(ut, self.series_ut))
        if rows.size:
            keys = [*SERIES_COLUMNS, *(c for c in _OPTIONAL_SERIES if c in columns)]
            self._series.append({k: np.asarray(columns[k])[rows] for k in keys})

    def _add_samples(self, columns, ut):
        k = self._keep_index(np.asarray(columns["time_s"], float))
        j = np.searchsorted(self.sample_ut, ut)
        ok = (k >= 0) & (j < self.sample_ut.size)
        ok[ok] &= self.sample_ut[j[ok]] == ut[ok]
        k, j = k[ok], j[ok]
        self.ut_lat_deg[k, j] = np.asarray(columns["lat_deg"], float)[ok]
        self.ut_lon_deg[k, j] = np.asarray(columns["lon_deg"], float)[ok]
        self.ut_sat[k, j] = np.asarray(columns["sat_id"], np.int64)[ok]
        self.ut_beam[k, j] = np.asarray(columns["beam_id"], np.int64)[ok]

    def add_events(self, events):
        """Keep the events (dict of arrays or DataFrame, trace event columns) of ``series_ut``."""
        ut = np.asarray(events["ut_id"], np.int64)
        rows = np.flatnonzero(np.isin(ut, self.series_ut))
        if rows.size:
            self._events.append({k: np.asarray(events[k])[rows] for k in EVENT_COLUMNS})

    def add_dwells(self, duration_s, censored):
        """Histogram dwell durations [s] (1-D), ``censored`` (bool, 1-D) kept apart."""
        d = np.asarray(duration_s, float)
        c = np.asarray(censored, bool)
        n = self.dwell_complete.size
        idx = np.clip(np.searchsorted(self.dwell_edges_s, d, side="right") - 1, 0, n - 1)
        self.dwell_complete += np.bincount(idx[~c], minlength=n)
        self.dwell_censored += np.bincount(idx[c], minlength=n)
        self.dwell_complete_sum_s += d[~c].sum()

    @property
    def dwell_mean_s(self):
        """Mean of the complete dwells [s] (``summary.json``'s ``dwell.mean_s``, the one
        definition), None when there is none or the statistics predate the exact sum."""
        n = int(self.dwell_complete.sum())
        total = getattr(self, "dwell_complete_sum_s", None)
        return float(total) / n if n and total is not None else None

    def add_dwells_from_summary(self, summary):
        """Dwells of ``summary.json``: ``overall.dwell.complete_s`` and the per-UT censored."""
        complete = np.asarray(summary["overall"]["dwell"].get("complete_s", []), float)
        censored = np.asarray(
            [
                c["duration_s"]
                for u in summary.get("per_ut", [])
                for c in u.get("dwell", {}).get("censored", [])
            ],
            float,
        )
        self.add_dwells(
            np.concatenate([complete, censored]),
            np.r_[np.zeros(complete.size, bool), np.ones(censored.size, bool)],
        )

    def add_satellites(self, t_s, sat_pos_m, sat_vel_m_s, sat_ids=None):
        """Satellite states at one epoch ``t_s`` [s]: ``(n_sat, 3)`` [m] and [m/s]; kept
        only at the subsampled epochs. ``sat_ids`` default ``0 .. n_sat - 1``."""
        pos = np.asarray(sat_pos_m, float).reshape(-1, 3)
        if self.sat_pos_m is None:
            shape = (self.keep_times_s.size, pos.shape[0], 3)
            self.sat_pos_m, self.sat_vel_m_s = np.full(shape, np.nan), np.full(shape, np.nan)
            self.sat_ids = np.arange(pos.shape[0]) if sat_ids is None else np.asarray(sat_ids)
        k = int(self._keep_index(np.asarray([t_s], float))[0])
        if k >= 0:
            self.sat_pos_m[k] = pos
            self.sat_vel_m_s[k] = np.asarray(sat_vel_m_s, float).reshape(-1, 3)

    def set_codebook(self, beam_u_xy, n_sub_x, n_sub_y):
        """Beam boresights ``(n_beam, 2)`` [-] (row = beam_id) and the subarray size."""
        self.beam_u_xy = np.asarray(beam_u_xy, float).reshape(-1, 2)
        self.n_sub_xy = (int(n_sub_x), int(n_sub_y))

    # ------------------------------------------------------------------ reading
    def series_columns(self):
        """Rows of the chosen UTs sorted by (ut_id, time_s): dict of 1-D arrays (the
        figures read these; no pandas in a run)."""
        return _columns(
            self._series, SERIES_COLUMNS, lambda c: np.lexsort((c["time_s"], c["ut_id"]))
        )

    def events_columns(self):
        """Events of the chosen UTs sorted by time: dict of 1-D arrays."""
        return _columns(
            self._events, EVENT_COLUMNS, lambda c: np.argsort(c["time_s"], kind="stable")
        )

    def series(self):
        """Rows of the chosen UTs, a DataFrame sorted by (ut_id, time_s)."""
        import pandas as pd

        return pd.DataFrame(self.series_columns())

    def events(self):
        """Events of the chosen UTs, a DataFrame sorted by time."""
        import pandas as pd

        return pd.DataFrame(self.events_columns())

    def cdf(self, key):
        """``(x, F)``: the empirical CDF at the upper bin edges (``F`` in [0, 1]).

        ``key`` in ``snr_db``, ``sinr_db`` [dB] or ``throughput_bps`` [b/s]; for the
        throughput the first point is ``(0, fraction of UT-epochs at 0 b/s)``.
        """
        if key == "throughput_bps":
            counts = self.hist["log10_throughput_bps"]
            x = np.r_[0.0, 10.0**LOG_TPUT_EDGES, np.inf]
            counts = np.r_[self.n_zero_throughput, counts]
        else:
            counts, x = self.hist[key], np.r_[DB_EDGES, np.inf]
        total = counts.sum()
        return x, (np.cumsum(counts) / total if total else np.zeros(x.size))

    # ------------------------------------------------------------------ persistence
    def save(self, path):
        """Write everything to an ``.npz`` (no pickle); see :meth:`load`."""
        from leolink.io.atomic import atomic_file

        arrays = {k: v for k, v in vars(self).items() if isinstance(v, np.ndarray)}
        arrays.update({f"hist__{k}": v for k, v in self.hist.items()})
        for name, parts in (("series", self.series_columns()), ("events", self.events_columns())):
            arrays.update({f"{name}__{c}": _plain(v) for c, v in parts.items()})
        for name, d in (("service", self.service_counts), ("reason", self.outage_reason_counts)):
            arrays[f"{name}__names"] = np.asarray(list(d), str)
            arrays[f"{name}__counts"] = np.asarray(list(d.values()), np.int64)
        scalars = [
            self.n_ut,
            self.start_s,
            self.end_s,
            self.epoch_s,
            self.stride,
            self.n_zero_throughput,
            *(self.n_sub_xy or (0, 0)),
        ]
        arrays["scalars"] = np.asarray(scalars, float)
        with atomic_file(path) as fh:
            np.savez_compressed(
                fh,
                **{
                    k: np.asarray(v)
                    for k, v in arrays.items()
                    if v is not None and np.asarray(v).dtype != object
                },
            )
        return path

    @classmethod
    def load(cls, path):
        """Read a file written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
        n_ut, start, end, epoch, stride, n_zero, nsx, nsy = data.pop("scalars").tolist()
        self = cls.__new__(cls)
        self.n_ut, self.start_s, self.end_s, self.epoch_s = int(n_ut), start, end, epoch
        self.stride, self.n_zero_throughput = int(stride), int(n_zero)
        self.n_sub_xy = (int(nsx), int(nsy)) if nsx else None
        self.sat_ids = self.sat_pos_m = self.sat_vel_m_s = self.beam_u_xy = None
        self.hist = {k[6:]: data.pop(k) for k in list(data) if k.startswith("hist__")}
        self.service_counts = dict(
            zip(
                data.pop("service__names").tolist(),
                data.pop("service__counts").tolist(),
                strict=True,
            )
        )
        self.outage_reason_counts = dict(
            zip(
                data.pop("reason__names").tolist(), data.pop("reason__counts").tolist(), strict=True
            )
        )
        for name, store in (("series", "_series"), ("events", "_events")):
            cols = {
                k.split("__", 1)[1]: data.pop(k) for k in list(data) if k.startswith(f"{name}__")
            }
            setattr(self, store, [cols] if cols and len(next(iter(cols.values()))) else [])
        for key, value in data.items():
            setattr(self, key, value)
        return self
