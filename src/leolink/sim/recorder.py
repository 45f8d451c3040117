"""Output writers: chunked atomic trace/event tables, the run summary, atomic JSON/text.

Tables are written chunk by chunk under temporary names (``trace.csv.partial``) and
renamed on :meth:`TableWriter.close`; :meth:`TableWriter.abort` (or an exception inside
``with``) removes the partial files, so a failed or interrupted run never leaves a file
that looks complete. The bytes of ``trace.csv`` do not depend on ``chunk_rows``.

CSV: a plain header line, then pyarrow's ``CSVWriter`` (shortest round-trip float text,
``nan`` for NaN, strings unquoted). Parquet: one row group per chunk.
The trace ``service`` column holds the names ``served``, ``handover``, ``outage``
(``controller.SERVICE_NAMES``; integer codes given to ``append`` are mapped to them).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from leolink.engine import SERVE_COLUMNS
from leolink.errors import ConfigError, require_at_least
from leolink.io import to_jsonable
from leolink.sim.controller import (
    EVENT_COLUMNS,
    EVENT_KINDS,
    SERVICE_HANDOVER,
    SERVICE_NAMES,
    SERVICE_OUTAGE,
)

TRACE_COLUMNS = (
    "time_s",
    "ut_id",
    "sat_id",
    "beam_id",
    "lat_deg",
    "lon_deg",
    *SERVE_COLUMNS,  # the serving link, as LinkEngine.serve computes it
    "service",
)
_ID_COLUMNS = {"ut_id", "sat_id", "beam_id", "from_sat", "from_beam", "to_sat", "to_beam"}
_STRING_COLUMNS = {"service", "kind"}
FORMATS = ("csv", "parquet")


def _arrow_type(name):
    if name in _ID_COLUMNS:
        return pa.int32()
    if name in _STRING_COLUMNS:
        return pa.string()
    return pa.float64()


def schema_for(columns):
    """Fixed Arrow schema: ids int32, ``service``/``kind`` string, the rest float64."""
    return pa.schema([(name, _arrow_type(name)) for name in columns])


TRACE_SCHEMA = schema_for(TRACE_COLUMNS)
EVENT_SCHEMA = schema_for(EVENT_COLUMNS)


def _column_array(name, values, field):
    """One appended column -> Arrow array of the schema type (checks the dtype)."""
    values = np.asarray(values)
    if values.ndim != 1:
        raise ValueError(f"column {name!r} must be 1-D, got shape {values.shape}")
    if name == "service" and values.dtype.kind in "iu":
        # Decode the codes in Arrow (vectorized C++), not through a numpy string array.
        names = pa.DictionaryArray.from_arrays(pa.array(values.astype(np.int8)), SERVICE_NAMES)
        return names.cast(pa.string())
    if pa.types.is_string(field.type):
        return pa.array(values.astype(str), pa.string())
    if pa.types.is_integer(field.type):
        if values.dtype.kind not in "iub":
            raise ValueError(f"column {name!r} must be integer, got dtype {values.dtype}")
        return pa.array(values.astype(np.int32, copy=False), pa.int32())
    return pa.array(values.astype(np.float64, copy=False), pa.float64())


def to_table(columns, schema):
    """Dict of equal-length 1-D arrays -> ``pyarrow.Table`` in the schema's column order."""
    missing = [n for n in schema.names if n not in columns]
    extra = sorted(set(columns) - set(schema.names))
    if missing or extra:
        raise ValueError(f"columns missing: {missing}; unexpected: {extra}")
    arrays = [_column_array(f.name, columns[f.name], f) for f in schema]
    lengths = {len(a) for a in arrays}
    if len(lengths) > 1:
        raise ValueError(f"columns have different lengths: {sorted(lengths)}")
    return pa.Table.from_arrays(arrays, schema=schema)


class TableWriter:
    """Chunked, atomic writer of one table as ``<stem>.csv`` and/or ``<stem>.parquet``.

    Parameters
    ----------
    out_dir : path, created if needed.
    stem : str, file name without extension.
    schema : pyarrow.Schema, fixed column order and types.
    formats : tuple of ``"csv"``, ``"parquet"``.
    chunk_rows : int, rows per written chunk (Parquet row group); memory bound.
    """

    def __init__(self, out_dir, stem, schema, formats=("csv",), chunk_rows=200_000):
        bad = [f for f in formats if f not in FORMATS]
        if bad or not formats:
            raise ConfigError(f"output formats = {list(formats)!r}; use some of {list(FORMATS)}")
        require_at_least("output.chunk_rows", chunk_rows, 1, "rows per chunk")
        self.schema = schema
        self.chunk_rows = int(chunk_rows)
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        self.paths = {f: out_dir / f"{stem}.{f}" for f in formats}
        self.partial_paths = {f: p.with_name(p.name + ".partial") for f, p in self.paths.items()}
        self._buffer, self._n_buffered, self._done = [], 0, False
        self._csv_file = self._csv = self._parquet = None
        try:
            self._open()
        except BaseException:
            self.abort()
            raise

    def _open(self):
        if "csv" in self.paths:
            self._csv_file = open(self.partial_paths["csv"], "wb")  # noqa: SIM115
            self._csv_file.write((",".join(self.schema.names) + "\n").encode())
            options = pacsv.WriteOptions(include_header=False, quoting_style="none")
            self._csv = pacsv.CSVWriter(self._csv_file, self.schema, write_options=options)
        if "parquet" in self.paths:
            # Dictionary encoding only for the string columns: on float columns it costs
            # ~2 us a row and saves nothing (measured: 2.6 vs 0.36 us/row).
            strings = [n for n in self.schema.names if n in _STRING_COLUMNS]
            self._parquet = pq.ParquetWriter(
                self.partial_paths["parquet"], self.schema, use_dictionary=strings
            )

    def append(self, columns):
        """Buffer a dict of equal-length 1-D arrays; writes every full chunk.

        The arrays are kept as given until the chunk is written (one Arrow conversion
        per column per chunk, not per call): do not modify them after appending.
        """
        if self._done:
            raise ValueError("append() after close() or abort()")
        names = self.schema.names
        if len(columns) != len(names) or any(n not in columns for n in names):
            to_table(columns, self.schema)  # raises with the missing/unexpected columns
        arrays = {n: np.asarray(columns[n]) for n in names}
        lengths = {a.shape for a in arrays.values()}
        ids_ok = all(arrays[n].dtype.kind in "iub" for n in names if n in _ID_COLUMNS)
        if len(lengths) > 1 or len(next(iter(lengths))) != 1 or not ids_ok:
            to_table(columns, self.schema)  # raises naming the bad column
        self._buffer.append(arrays)
        self._n_buffered += len(arrays[names[0]])
        if self._n_buffered >= self.chunk_rows:
            self._flush(final=False)

    def _flush(self, final):
        names = self.schema.names
        merged = (
            {n: np.concatenate([b[n] for b in self._buffer]) for n in names} if self._buffer else {}
        )
        n_rows = self._n_buffered
        start = 0
        while n_rows - start >= self.chunk_rows or (final and start < n_rows):
            stop = min(start + self.chunk_rows, n_rows)
            chunk = to_table({n: merged[n][start:stop] for n in names}, self.schema)
            if self._csv is not None:
                self._csv.write_table(chunk)
            if self._parquet is not None:
                self._parquet.write_table(chunk, row_group_size=self.chunk_rows)
            start = stop
        self._buffer = [{n: merged[n][start:] for n in names}] if start < n_rows else []
        self._n_buffered = n_rows - start

    def close(self):
        """Write what is buffered and rename the partial files to their final names."""
        if self._done:
            return self.paths
        try:
            self._flush(final=True)
            self._close_handles()
            for fmt, path in self.paths.items():
                os.replace(self.partial_paths[fmt], path)
        except BaseException:
            self.abort()
            raise
        self._done = True
        return self.paths

    def _close_handles(self):
        for handle in (self._csv, self._csv_file, self._parquet):
            if handle is not None:
                handle.close()
        self._csv = self._csv_file = self._parquet = None

    def abort(self):
        """Drop everything: close handles and remove the partial files."""
        self._done = True
        with contextlib.suppress(Exception):
            self._close_handles()
        for path in self.partial_paths.values():
            with contextlib.suppress(FileNotFoundError):
                path.unlink()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


class TraceWriter(TableWriter):
    """``trace.csv`` / ``trace.parquet``: one row per UT per epoch, ``TRACE_COLUMNS``."""

    def __init__(self, out_dir, formats=("csv",), chunk_rows=200_000, columns=TRACE_COLUMNS):
        super().__init__(out_dir, "trace", schema_for(columns), formats, chunk_rows)


class EventLog(TableWriter):
    """``events.csv``: ``EVENT_COLUMNS``, written in the order appended (time, then ut_id
    as :func:`leolink.sim.controller.step` emits them)."""

    def __init__(self, out_dir, formats=("csv",), chunk_rows=200_000):
        super().__init__(out_dir, "events", EVENT_SCHEMA, formats, chunk_rows)


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


def _service_codes(service):
    service = np.asarray(service)
    if service.dtype.kind in "iu":
        return service.astype(np.int64)
    codes = np.full(service.shape, -1, np.int64)
    for code, name in enumerate(SERVICE_NAMES):
        codes[service == name] = code
    return codes


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
    """

    def __init__(self, n_ut):
        self.n_ut = int(n_ut)
        zeros = lambda dtype=np.int64: np.zeros(self.n_ut, dtype)  # noqa: E731
        self.n_epochs, self.n_outage, self.n_interrupted = zeros(), zeros(), zeros()
        self.throughput_sum = zeros(np.float64)
        self.max_abs_doppler_hz = np.full(self.n_ut, np.nan)
        self.max_angular_speed_deg_s = np.full(self.n_ut, np.nan)
        self.event_counts = np.zeros((len(EVENT_KINDS), self.n_ut), np.int64)
        self._samples = {
            k: (_Growable(np.int32), _Growable(np.float32)) for k in ("snr_db", "sinr_db")
        }
        self._sums = {k: zeros(np.float64) for k in self._samples}
        self._dwells = []

    def add_trace(self, columns):
        """Add trace rows (dict of 1-D arrays; needs ``ut_id``, ``service``, ``snr_db``,
        ``sinr_db``, ``throughput_bps``, ``doppler_hz``, ``angular_speed_deg_s``)."""
        ut = np.asarray(columns["ut_id"], np.int64)
        n = self.n_ut
        self.n_epochs += np.bincount(ut, minlength=n)
        codes = _service_codes(columns["service"])
        self.n_outage += np.bincount(ut, codes == SERVICE_OUTAGE, minlength=n).astype(np.int64)
        self.n_interrupted += np.bincount(ut, codes == SERVICE_HANDOVER, minlength=n).astype(
            np.int64
        )
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
        dwell_ut, dwell_all = self._dwell_summary()
        with np.errstate(invalid="ignore", divide="ignore"):
            outage_fraction = self.n_outage / self.n_epochs
            interrupted_fraction = self.n_interrupted / self.n_epochs
            tput_mean = self.throughput_sum / self.n_epochs
        snr_ut, snr_all = self._stats("snr_db")
        sinr_ut, sinr_all = self._stats("sinr_db")
        counts = {k: self.event_counts[i] for i, k in enumerate(EVENT_KINDS)}
        per_ut = []
        for i in range(self.n_ut):  # output formatting only; all statistics are vectorized
            per_ut.append(
                {
                    "ut_id": i,
                    "n_epochs": self.n_epochs[i],
                    "handovers": _handover_counts({k: c[i] for k, c in counts.items()}),
                    "dwell": dwell_ut[i],
                    "outage_fraction": outage_fraction[i],
                    "handover_interruption_fraction": interrupted_fraction[i],
                    "snr_db": snr_ut[i],
                    "sinr_db": sinr_ut[i],
                    "mean_throughput_bps": tput_mean[i],
                    "max_abs_doppler_hz": self.max_abs_doppler_hz[i],
                    "max_angular_speed_deg_s": self.max_angular_speed_deg_s[i],
                }
            )
        n_all = self.n_epochs.sum()
        overall = {
            "n_ut": self.n_ut,
            "n_ut_epochs": n_all,
            "handovers": _handover_counts({k: c.sum() for k, c in counts.items()}),
            "dwell": dwell_all,
            "outage_fraction": self.n_outage.sum() / n_all if n_all else None,
            "handover_interruption_fraction": self.n_interrupted.sum() / n_all if n_all else None,
            "snr_db": snr_all,
            "sinr_db": sinr_all,
            "mean_throughput_bps": self.throughput_sum.sum() / n_all if n_all else None,
            "max_abs_doppler_hz": _nanmax(self.max_abs_doppler_hz),
            "max_angular_speed_deg_s": _nanmax(self.max_angular_speed_deg_s),
        }
        return to_jsonable({"overall": overall, "per_ut": per_ut})


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
