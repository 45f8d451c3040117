"""Trace and event tables: chunked CSV/Parquet writers, fixed schemas.

Tables are written chunk by chunk under temporary names (``trace.csv.<random>.partial``,
:mod:`leolink.io.atomic`) and renamed on :meth:`TableWriter.close`;
:meth:`TableWriter.abort` (or an exception inside ``with``) removes the partial files, so
a failed or interrupted run never leaves a file that looks complete. The bytes of
``trace.csv`` do not depend on ``chunk_rows``.

CSV: a plain header line, then pyarrow's ``CSVWriter`` (shortest round-trip float text,
``nan`` for NaN, strings unquoted). Parquet: one row group per chunk.
The trace ``service`` column holds the names ``served``, ``handover``, ``outage``
(``controller.SERVICE_NAMES``) and ``outage_reason`` the names ``none``, ``handover``,
``no_satellite``, ``below_threshold`` (``processes.OUTAGE_REASONS``) and ``modcod`` the
DVB-S2X MODCOD names (``leolink.link.modcod``, ``none`` for code -1); integer codes given
to ``append`` are mapped to them.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from leolink.engine import SERVE_COLUMNS, SERVE_GEOMETRY_COLUMNS
from leolink.errors import ConfigError, require_at_least
from leolink.io.atomic import PendingFiles
from leolink.link.acm import FIGURE_COLUMNS
from leolink.link.modcod import modcod_table
from leolink.sim.controller import EVENT_COLUMNS, SERVICE_NAMES
from leolink.sim.processes import OUTAGE_REASONS

__all__ = [
    "ENVIRONMENT_COLUMNS",
    "EVENT_SCHEMA",
    "FORMATS",
    "TRACE_COLUMNS",
    "TRACE_SCHEMA",
    "EventLog",
    "TableWriter",
    "TraceWriter",
    "schema_for",
    "trace_schema",
    "to_table",
]

TRACE_COLUMNS = (
    "time_s",
    "ut_id",
    "sat_id",
    "beam_id",
    "lat_deg",
    "lon_deg",
    *SERVE_COLUMNS,  # the serving link, as LinkEngine.serve computes it
    "service",
    # Diagnostics (DESIGN output contract): why a UT is not served, what it could see.
    "outage_reason",
    "n_visible",  # satellites above the minimum elevation
    "best_snr_db",  # the best candidate's SNR, also in outage [dB]
    *SERVE_GEOMETRY_COLUMNS,  # azimuth_deg
    "alt_m",  # UT height above the Earth model [m]
    "population",
    "interruption_s",  # part of the epoch without service: handover execution [s]
    *FIGURE_COLUMNS,  # eirp_dbw, cn0_dbhz, esn0_db, margin_db, modcod (leolink.link.acm)
)
#: Columns of a run that models UT environments (``RunInfo.environment``), after
#: ``TRACE_COLUMNS``: the serving path's LoS state (1 / 0, NaN without a link) and its
#: shadowing, clutter and scintillation losses [dB] (:mod:`leolink.sim.environment`).
ENVIRONMENT_COLUMNS = ("los", "shadow_db", "clutter_db", "scintillation_db")
_INT_COLUMNS = {
    "ut_id", "sat_id", "beam_id", "from_sat", "from_beam", "to_sat", "to_beam", "n_visible"
}  # fmt: skip
_STRING_COLUMNS = {"service", "kind", "outage_reason", "population", "modcod"}
#: Name of MODCOD code -1 (no MODCOD closes the link, or no link).
NO_MODCOD_NAME = "none"
#: Columns given as integer codes and written as names (code -1: the last name).
_CODED_COLUMNS = {
    "service": SERVICE_NAMES,
    "outage_reason": OUTAGE_REASONS,
    "modcod": (*modcod_table().names, NO_MODCOD_NAME),
}
FORMATS = ("csv", "parquet")


def _arrow_type(name):
    if name in _INT_COLUMNS:
        return pa.int32()
    if name in _STRING_COLUMNS:
        return pa.string()
    return pa.float64()


def schema_for(columns):
    """Fixed Arrow schema: ids int32, ``service``/``kind`` string, the rest float64."""
    return pa.schema([(name, _arrow_type(name)) for name in columns])


TRACE_SCHEMA = schema_for(TRACE_COLUMNS)
TRACE_ENVIRONMENT_SCHEMA = schema_for(TRACE_COLUMNS + ENVIRONMENT_COLUMNS)


def trace_schema(info):
    """The trace schema of a run (:class:`~leolink.sim.streams.RunInfo`): with the
    ``ENVIRONMENT_COLUMNS`` when it models environments."""
    return TRACE_ENVIRONMENT_SCHEMA if getattr(info, "environment", ()) else TRACE_SCHEMA


EVENT_SCHEMA = schema_for(EVENT_COLUMNS)


def _column_array(name, values, field):
    """One appended column -> Arrow array of the schema type (checks the dtype)."""
    values = np.asarray(values)
    if values.ndim != 1:
        raise ValueError(f"column {name!r} must be 1-D, got shape {values.shape}")
    if name in _CODED_COLUMNS and values.dtype.kind in "iu":
        # Decode the codes in Arrow (vectorized C++), not through a numpy string array.
        names = _CODED_COLUMNS[name]
        codes = pa.array(np.where(values < 0, values + len(names), values).astype(np.int8))
        return pa.DictionaryArray.from_arrays(codes, names).cast(pa.string())
    if pa.types.is_string(field.type):
        return pa.array(values if values.dtype == object else values.astype(str), pa.string())
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
        self._pending = PendingFiles()
        self._buffer, self._n_buffered, self._done = [], 0, False
        self._csv = self._parquet = None
        try:
            self._open()
        except BaseException:
            self.abort()
            raise

    def _open(self):
        if "csv" in self.paths:
            csv_file = self._pending.open(self.paths["csv"])
            csv_file.write((",".join(self.schema.names) + "\n").encode())
            options = pacsv.WriteOptions(include_header=False, quoting_style="none")
            self._csv = pacsv.CSVWriter(csv_file, self.schema, write_options=options)
        if "parquet" in self.paths:
            # Dictionary encoding only for the string columns: on float columns it costs
            # ~2 us a row and saves nothing (measured: 2.6 vs 0.36 us/row).
            strings = [n for n in self.schema.names if n in _STRING_COLUMNS]
            self._parquet = pq.ParquetWriter(
                self._pending.open(self.paths["parquet"]), self.schema, use_dictionary=strings
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
        ids_ok = all(arrays[n].dtype.kind in "iub" for n in names if n in _INT_COLUMNS)
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
            self._close_writers()
            self._pending.commit()
        except BaseException:
            self.abort()
            raise
        self._done = True
        return self.paths

    def _close_writers(self):
        for writer in (self._csv, self._parquet):
            if writer is not None:
                writer.close()
        self._csv = self._parquet = None

    def abort(self):
        """Drop everything: close the writers and remove the partial files."""
        self._done = True
        with contextlib.suppress(Exception):
            self._close_writers()
        self._pending.abort()

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
