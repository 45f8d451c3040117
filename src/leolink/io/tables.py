"""Trace and event tables: chunked CSV/Parquet writers (their schemas:
:mod:`leolink.io.table_schemas`).

Tables are written chunk by chunk under temporary names (``trace.csv.<random>.partial``,
:mod:`leolink.io.atomic`) and renamed on :meth:`TableWriter.close`;
:meth:`TableWriter.abort` (or an exception inside ``with``) removes the partial files, so
a failed or interrupted run never leaves a file that looks complete. The bytes of
``trace.csv`` do not depend on the chunking.

Memory: a writer copies what it is given, once and cast to the written types, into a
chunk preallocated for ``min(chunk_rows, CHUNK_BYTES / bytes of a buffered row)`` rows (at
most 8 MiB: ~30,000 trace rows of float64 with a CSV, ~50,000 of float32 in Parquet
alone) and writes each full chunk, on a background thread
(pyarrow releases the GIL while it encodes; at most one more chunk waits), so its memory
does not grow with the run.

CSV: a plain header line, then pyarrow's ``CSVWriter`` (shortest round-trip float text of
the float64 values, ``nan`` for NaN, strings unquoted). Parquet: one row group per chunk;
in ``trace.parquet`` the float columns are float32 (relative precision 6e-8: 1e-6 dB on
an SNR, 0.03 Hz on a 300 kHz Doppler, 0.25 m on a 4,000 km range) except
:data:`TRACE_FLOAT64_COLUMNS` (times and positions), which keep float64.
Integer codes given to ``append`` for a string column are written as its names.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np
import pyarrow as pa  # core only (~0.1 s); pyarrow.csv / .parquet when a format needs them

from leolink.background import BackgroundWorker, cancelled
from leolink.errors import ConfigError, require_at_least
from leolink.io.arrow import (
    NUMPY_TYPES,
    Vocabulary,
    decoded_array,
    dictionary_array,
    iso_utc_text,
    numeric_array,
)
from leolink.io.atomic import PendingFiles
from leolink.io.run_dir import GrowingDigest
from leolink.io.table_schemas import (  # noqa: F401  (the schemas' names, re-exported)
    _CODED_COLUMNS,
    _INT_COLUMNS,
    _STRING_COLUMNS,
    ENVIRONMENT_COLUMNS,
    EVENT_SCHEMA,
    FORMATS,
    NO_MODCOD_NAME,
    TIMESTAMP_COLUMNS,
    TRACE_COLUMNS,
    TRACE_FLOAT64_COLUMNS,
    TRACE_SCHEMA,
    _check,
    _coded,
    csv_schema,
    float32_schema,
    schema_for,
    to_table,
    trace_schema,
)

__all__ = [
    "CHUNK_BYTES",
    "ENVIRONMENT_COLUMNS",
    "EVENT_SCHEMA",
    "FORMATS",
    "TRACE_COLUMNS",
    "TRACE_FLOAT64_COLUMNS",
    "TRACE_SCHEMA",
    "EventLog",
    "TableWriter",
    "TraceWriter",
    "float32_schema",
    "parquet_options",
    "schema_for",
    "trace_schema",
    "to_table",
]

#: Buffered input per written chunk [bytes] (the values in their buffered types).
CHUNK_BYTES = 8 * 2**20
#: Rows a writer has written after which its string columns are gathered by Arrow's take
#: (:func:`~leolink.io.arrow.decoded_array`): 4x faster, once ``pyarrow.compute`` is
#: imported (~50 ms, more than a small run's strings cost). ``bench_sim.py`` (1,000 UTs
#: x 3,600 epochs, four string columns in chunks of ~30,000 rows): 0.43-0.46 -> 0.24-0.25
#: s, the import and the first million rows included.
TAKE_AFTER_ROWS = 1_000_000
#: Rows of a chunk's CSV written at once (the same bytes as the whole chunk at once): a stop
#: waits for one slice's text, not a chunk's (:func:`leolink.background.cancelled`).
CSV_SLICE_ROWS = 8_192


#: Columns whose Parquet min/max statistics are written (those a reader filters on: a
#: time window, some UTs or beams); the others' cost ~0.1 us a row and serve nobody.
PARQUET_STATISTICS_COLUMNS = ("time_s", "ut_id", "sat_id", "beam_id")
#: Values Arrow hands the Parquet encoder at once (its default, 1,024, pays a fixed cost
#: per column every 1,024 rows).
PARQUET_WRITE_BATCH = 1 << 16


def parquet_options(schema):
    """The Parquet writer's codec and encodings for a table of ``schema``.

    Snappy of byte-stream-split floats: a float's bytes are stored by significance
    (exponent bytes together), which snappy then compresses; of plain floats it compressed
    nothing but the constant columns. With :data:`PARQUET_STATISTICS_COLUMNS` and
    :data:`PARQUET_WRITE_BATCH`, ``bench_sim``'s trace (1.16 M rows, the encoder alone):
    ~290 -> ~170 ns a row of CPU, 111 -> 87 MiB (the hash of the smaller file costs less
    too). LZ4 (raw) made it 66 MiB at the same CPU, but older readers (Spark before 3.5)
    cannot read it: snappy is every reader's. The values read back are the same: only the
    encoding differs.
    """
    floats = [f.name for f in schema if pa.types.is_floating(f.type)]
    stats = [n for n in PARQUET_STATISTICS_COLUMNS if n in schema.names]
    return {
        "compression": "snappy",
        "use_byte_stream_split": floats or False,
        "write_statistics": stats or False,
        "write_batch_size": PARQUET_WRITE_BATCH,
    }


class TableWriter:
    """Chunked, atomic writer of one table as ``<stem>.csv`` and/or ``<stem>.parquet``.

    Parameters
    ----------
    out_dir : path, created if needed.
    stem : str, file name without extension.
    schema : pyarrow.Schema, fixed column order and types (the CSV's).
    formats : tuple of ``"csv"``, ``"parquet"``.
    chunk_rows : int, most rows per written chunk (Parquet row group); the chunk is also
        bounded by :data:`CHUNK_BYTES`.
    parquet_schema : pyarrow.Schema, optional: the Parquet file's types (default
        ``schema``), e.g. :func:`float32_schema`.
    background : bool, write on a background thread.

    Once closed, ``digests`` holds ``{path: (size [bytes], SHA-256 hex)}`` of the files,
    hashed as they grew (the manifest's, :func:`~leolink.io.run_dir.write_manifest`).
    """

    def __init__(
        self, out_dir, stem, schema, formats=("csv",), chunk_rows=200_000,
        parquet_schema=None, background=False,
    ):  # fmt: skip
        bad = [f for f in formats if f not in FORMATS]
        if bad or not formats:
            raise ConfigError(f"output formats = {list(formats)!r}; use some of {list(FORMATS)}")
        require_at_least("output.chunk_rows", chunk_rows, 1, "rows per chunk")
        self.schema, self._csv_schema = schema, csv_schema(schema)
        self.parquet_schema = schema if parquet_schema is None else parquet_schema
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        self.paths = {f: out_dir / f"{stem}.{f}" for f in formats}
        self._pending = PendingFiles()
        self._n_written, self._done = 0, False
        self._vocab = {
            n: Vocabulary(_CODED_COLUMNS.get(n, ())) for n in schema.names if n in _STRING_COLUMNS
        }
        self._dtypes = self._chunk_dtypes(formats)
        # bounded by the bytes of a row as it is buffered (float32 in Parquet alone): the
        # larger row groups of a Parquet-only trace cost less to write, in the same memory
        row_bytes = sum(np.dtype(d).itemsize for d in self._dtypes.values())
        self.chunk_rows = max(1, min(int(chunk_rows), CHUNK_BYTES // row_bytes))
        self._chunk, self._n_filled = self._new_chunk(), 0
        self._csv = self._parquet = self._thread = None
        self._growing, self.digests = {}, {}
        try:
            self._open()
            self._thread = BackgroundWorker(self._write, "leolink-writer") if background else None
        except BaseException:
            self.abort()
            raise

    def _open(self):
        if "csv" in self.paths:
            import pyarrow.csv as pacsv

            csv_file = self._pending.open_native(self.paths["csv"])
            csv_file.write((",".join(self.schema.names) + "\n").encode())
            options = pacsv.WriteOptions(include_header=False, quoting_style="none")
            self._csv = pacsv.CSVWriter(csv_file, self._csv_schema, write_options=options)
            self._growing["csv"] = GrowingDigest(self._pending.partial_path(self.paths["csv"]))
        if "parquet" in self.paths:
            import pyarrow.parquet as pq

            # Dictionary encoding only for the string columns: on float columns it costs
            # ~2 us a row and saves nothing (measured: 2.6 vs 0.36 us/row). The string
            # columns are handed over as their codes and names (Arrow dictionary arrays),
            # which the encoding writes as they are; without the Arrow schema in the file
            # (store_schema) a reader sees them as the strings they are, as before:
            # bench_sim's 3.6 M rows of four such columns 0.67 -> 0.30 s.
            strings = [n for n in self.schema.names if n in _STRING_COLUMNS]
            self._coded_schema = _coded(self.parquet_schema)
            self._parquet = pq.ParquetWriter(
                self._pending.open_native(self.paths["parquet"]),
                self._coded_schema,
                use_dictionary=strings,
                store_schema=False,
                **parquet_options(self.parquet_schema),
            )
            parquet_tmp = self._pending.partial_path(self.paths["parquet"])
            self._growing["parquet"] = GrowingDigest(parquet_tmp)

    def _chunk_dtypes(self, formats):
        """numpy dtype of each column's chunk: the written type (int32 codes for strings),
        the CSV's when there is a CSV (Parquet's float32 is then cast from it per chunk)."""
        written = self.schema if "csv" in formats else self.parquet_schema
        return {f.name: np.int32 if f.name in self._vocab else NUMPY_TYPES[f.type] for f in written}

    def _new_chunk(self):
        return {n: np.empty(self.chunk_rows, dtype) for n, dtype in self._dtypes.items()}

    def append(self, columns):
        """Copy a dict of equal-length 1-D arrays into the chunk; writes every full chunk.

        Each value is copied once, cast to the written type, into a chunk preallocated
        for ``chunk_rows`` rows, which Arrow then wraps without a copy: the arrays may be
        reused as soon as ``append`` returns.
        """
        if self._done:
            raise ValueError("append() after close() or abort()")
        names = self.schema.names
        if len(columns) != len(names) or any(n not in columns for n in names):
            to_table(columns, self.schema)  # raises with the missing/unexpected columns
        arrays = {}
        for n in names:
            values = np.asarray(columns[n])
            _check(n, values)
            arrays[n] = self._vocab[n].codes(values) if n in self._vocab else values
        if len({a.shape for a in arrays.values()}) > 1:
            to_table(columns, self.schema)  # raises naming the lengths
        n_rows, start = len(arrays[names[0]]), 0
        while start < n_rows:
            if cancelled():  # a stop: the rows are dropped, abort follows
                return
            take = min(n_rows - start, self.chunk_rows - self._n_filled)
            for n in names:
                self._chunk[n][self._n_filled : self._n_filled + take] = arrays[n][
                    start : start + take
                ]
            start, self._n_filled = start + take, self._n_filled + take
            if self._n_filled == self.chunk_rows:
                self._flush()

    def _arrow(self, cols, schema, coded=False):
        """The chunk as an Arrow table of ``schema``: the string columns as strings, or
        ``coded`` as dictionary arrays (:func:`_coded`, the Parquet writer's)."""
        # Past TAKE_AFTER_ROWS rows the run is large: Arrow's take repays its import.
        by_take = self._n_written >= TAKE_AFTER_ROWS

        def strings(name):
            codes, names = cols[name], self._vocab[name].names
            return (
                dictionary_array(codes, names)
                if coded
                else decoded_array(codes, names, by_take=by_take)
            )

        def values(f):
            if f.name in TIMESTAMP_COLUMNS and pa.types.is_string(f.type):  # the CSV's text
                return iso_utc_text(cols[f.name])
            return numeric_array(cols[f.name], f.type)

        arrays = [strings(f.name) if f.name in self._vocab else values(f) for f in schema]
        return pa.Table.from_arrays(arrays, schema=self._coded_schema if coded else schema)

    def _flush(self):
        """Hand the filled part of the chunk to the writer and start a new chunk (the
        tables hold the old one's memory until they are written)."""
        cols = {n: column[: self._n_filled] for n, column in self._chunk.items()}
        csv = self._arrow(cols, self._csv_schema) if self._csv is not None else None
        parquet = None if self._parquet is None else self._arrow(cols, self.parquet_schema, True)
        if self._thread is None:
            self._write((csv, parquet))
        else:
            self._thread.put((csv, parquet))
        self._n_written += self._n_filled
        self._chunk, self._n_filled = self._new_chunk(), 0

    def _write(self, tables):
        csv, parquet = tables
        if csv is not None:
            for start in range(0, csv.num_rows, CSV_SLICE_ROWS):
                if cancelled():  # a stop: the file is removed next
                    return
                self._csv.write_table(csv.slice(start, CSV_SLICE_ROWS))
        if parquet is not None:
            self._parquet.write_table(parquet, row_group_size=self.chunk_rows)
        for growing in self._growing.values():  # (on the writer's thread when it has one)
            growing.update()

    def flush(self):
        """Hand the rows buffered so far to the writer: with a writer thread, they are
        written while the caller goes on (the chunk it would write at :meth:`close`: the
        same files)."""
        if self._n_filled and not self._done:
            self._flush()

    def close(self):
        """Write what is buffered and rename the partial files to their final names."""
        if self._done:
            return self.paths
        try:
            if self._n_filled:
                self._flush()
            if self._thread is not None:
                self._thread.close()
            self._close_writers()
            self._pending.flush()  # (the Python file of a system without /proc/self/fd)
            digests = {self.paths[f]: g.finish() for f, g in self._growing.items()}
            self._pending.commit()
        except BaseException:
            self.abort()
            raise
        self._done, self.digests = True, digests
        return self.paths

    def _close_writers(self):
        for writer in (self._csv, self._parquet):
            if writer is not None:
                writer.close()
        self._csv = self._parquet = None

    def abort(self):
        """Drop everything: stop the writer thread, close the files and remove them."""
        self._done = True
        if self._thread is not None:
            with contextlib.suppress(BaseException):
                self._thread.cancel()  # the chunks still waiting are not written
        with contextlib.suppress(Exception):
            self._close_writers()
        for growing in self._growing.values():
            growing.close()
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
    """``trace.csv`` / ``trace.parquet``: one row per UT per epoch, ``TRACE_COLUMNS``
    (float32 in Parquet but for :data:`TRACE_FLOAT64_COLUMNS`), on a background thread."""

    def __init__(
        self, out_dir, formats=("csv",), chunk_rows=200_000, columns=TRACE_COLUMNS,
        background=True,
    ):  # fmt: skip
        schema = schema_for(columns)
        super().__init__(
            out_dir, "trace", schema, formats, chunk_rows, float32_schema(schema), background
        )


class EventLog(TableWriter):
    """``events.csv``: ``EVENT_COLUMNS``, written in the order appended (time, then ut_id
    as :func:`leolink.sim.handover.controller.step` emits them)."""

    def __init__(self, out_dir, formats=("csv",), chunk_rows=200_000):
        super().__init__(out_dir, "events", EVENT_SCHEMA, formats, chunk_rows)
