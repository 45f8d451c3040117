"""Sinks of a run's stream (:mod:`leolink.sim.streams`): files, tables in memory, plots.

Output sinks are a pluggable kind: :data:`SINKS` holds one entry per ``[output.<name>]``
table of the config, each with an ``enabled`` switch and its own keys. A sink is built
with the context ``out_dir`` (a folder, or None for a run kept in memory) and
``summary`` (the run's :class:`~leolink.io.summary.accumulator.SummaryAccumulator`, fed first),
``ephemeris`` and ``codebook`` (the scenario's) and ``epoch_utc`` (UTC of time 0, or None).
A sink that writes files lists them, once finished, in its ``files`` attribute (the run's
manifest, ``run.json``, is made of these lists; pictures are drawn in the run's own
process, at ``finish``). ``abort`` after ``finish`` drops what the sink still holds. A
sink may also have
``after_run(summary, config_text) -> list of paths``, called once ``summary.json`` is
written, for outputs drawn from the final summary (the report page).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
import pyarrow as pa
from pydantic import AfterValidator, Field

from leolink.io.arrow import UTC_TIMESTAMP, numeric_array
from leolink.io.tables import (
    EVENT_SCHEMA,
    TRACE_SCHEMA,
    EventLog,
    TraceWriter,
    schema_for,
    to_table,
    trace_schema,
)
from leolink.registry import Params, Registry
from leolink.sim.streams import Sink

if TYPE_CHECKING:  # pandas is imported where a DataFrame is made (~0.5 s of start-up)
    import pandas as pd

__all__ = [
    "SINKS",
    "EventSink",
    "MemorySink",
    "PlotSink",
    "ReportParams",
    "SinkParams",
    "TraceSink",
    "utc_us",
]

#: Output sinks by config name (``[output.<name>]``).
SINKS: Registry[Sink] = Registry("output", protocol=Sink)


class SinkParams(Params):
    """Keys every sink has."""

    enabled: bool = Field(False, description="write this output")


def _trace_columns(columns, schema=TRACE_SCHEMA):
    return {name: columns[name] for name in schema.names}


class TraceSink:
    """``trace.csv`` and/or ``trace.parquet``, chunk by chunk (:class:`TraceWriter`).

    With ``time_zero_utc`` (an aware ``datetime``: the UTC instant of simulation time 0)
    the trace ends with ``time_utc``: ISO 8601 text in CSV, a timestamp in Parquet
    (microseconds, UTC), ``time_zero_utc + time_s`` (:func:`utc_us`).
    """

    def __init__(self, out_dir, formats=("csv",), chunk_rows=200_000, time_zero_utc=None):
        self.out_dir, self.formats, self.chunk_rows = Path(out_dir), tuple(formats), chunk_rows
        self.writer, self.files, self.digests = None, [], {}
        self.time_zero_utc = time_zero_utc

    def start(self, info):
        self.schema = trace_schema(info)
        if self.time_zero_utc is not None:
            self.schema = schema_for((*self.schema.names, "time_utc"))
        self.writer = TraceWriter(self.out_dir, formats=self.formats, chunk_rows=self.chunk_rows,
                                  columns=tuple(self.schema.names))  # fmt: skip

    def epoch(self, frame):
        columns = frame.columns
        if self.time_zero_utc is not None:
            columns = {**columns, "time_utc": utc_us(self.time_zero_utc, columns["time_s"])}
        self.writer.append(_trace_columns(columns, self.schema))

    block = epoch  # the writer cuts chunks of ``chunk_rows`` whatever it is given

    def flush_pending(self):
        self.writer.flush()

    def finish(self, final):
        self.files = list(self.writer.close().values())
        self.digests = self.writer.digests

    def abort(self):
        if self.writer is not None:
            self.writer.abort()


def utc_us(time_zero_utc, time_s):
    """The trace's ``time_utc``: microseconds since 1970-01-01T00:00:00Z (UTC, int64) of
    simulation times ``time_s`` (n,) [s] after the aware ``datetime`` ``time_zero_utc``,
    rounded to the microsecond."""
    delta = time_zero_utc - datetime(1970, 1, 1, tzinfo=UTC)
    t0_us = (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds
    return t0_us + np.round(np.asarray(time_s, float) * 1e6).astype(np.int64)


class EventSink:
    """``events.csv`` (and ``events.parquet``: the same rows), in the order the controller
    emits events (time, then UT)."""

    def __init__(self, out_dir, formats=("csv",), chunk_rows=200_000):
        self.out_dir, self.formats, self.chunk_rows = Path(out_dir), tuple(formats), chunk_rows
        self.writer, self.files, self.digests = None, [], {}

    def start(self, info):
        self.writer = EventLog(self.out_dir, formats=self.formats, chunk_rows=self.chunk_rows)

    def epoch(self, frame):
        if len(frame.events["ut_id"]):
            self.writer.append(frame.events)

    block = epoch

    def flush_pending(self):
        self.writer.flush()

    def finish(self, final):
        self.files = list(self.writer.close().values())
        self.digests = self.writer.digests

    def abort(self):
        if self.writer is not None:
            self.writer.abort()


class MemorySink:
    """Trace and events kept in memory as Arrow tables (a run without an output folder);
    with ``time_zero_utc`` the trace gains ``time_utc`` as :class:`TraceSink`'s."""

    def __init__(self, time_zero_utc=None):
        self._trace, self._events = [], []
        self.schema, self.time_zero_utc = TRACE_SCHEMA, time_zero_utc

    def start(self, info):
        self._trace, self._events = [], []
        self.schema = trace_schema(info)

    def epoch(self, frame):
        self._trace.append(to_table(_trace_columns(frame.columns, self.schema), self.schema))
        if len(frame.events["ut_id"]):
            self._events.append(to_table(frame.events, EVENT_SCHEMA))

    block = epoch  # the tables are joined at the end

    def finish(self, final):
        pass

    def abort(self):
        self._trace, self._events = [], []

    def trace(self) -> pd.DataFrame:
        if not self._trace:
            return self.schema.empty_table().to_pandas()
        table = pa.concat_tables(self._trace)
        if self.time_zero_utc is not None:
            t_us = utc_us(self.time_zero_utc, table.column("time_s").to_numpy())
            table = table.append_column("time_utc", numeric_array(t_us, UTC_TIMESTAMP))
        return table.to_pandas()

    def events(self) -> pd.DataFrame:
        return pa.concat_tables([EVENT_SCHEMA.empty_table(), *self._events]).to_pandas()


#: Small per-epoch tables merged into one every this many (an Arrow table of a few rows
#: costs ~10 kB: 1,800 epochs of them were ~40 MB that grew with the run length).
COMPACT_TABLES = 256


def _compacted(tables, table):
    """``tables + [table]``, merged into one contiguous table every COMPACT_TABLES."""
    tables.append(table)
    if len(tables) >= COMPACT_TABLES:
        tables = [pa.concat_tables(tables).combine_chunks()]
    return tables


class PlotSink:
    """The run's PNG plots, drawn at the end from the streamed statistics and the rows of
    the chosen UTs only (bounded memory: never the whole trace)."""

    def __init__(self, out_dir, summary, ut_ids=(0,)):
        self.out_dir, self.summary, self.ut_ids = Path(out_dir), summary, list(ut_ids)
        self._rows, self._events, self.files = [], [], []

    def start(self, info):
        self._rows, self._events = [], []
        self._span = [None, None]

    def epoch(self, frame):
        self._add(frame.columns, frame.events, frame.t_s, frame.t_s)

    def block(self, frame):
        """The block's rows of the chosen UTs at once (the same rows as epoch by epoch)."""
        self._add(frame.columns, frame.events, frame.t_s[0], frame.t_s[-1])

    def _add(self, cols, ev, first_s, last_s):
        keep = np.isin(cols["ut_id"], self.ut_ids)
        if keep.any():
            rows = {n: np.asarray(v)[keep] for n, v in _trace_columns(cols).items()}
            self._rows = _compacted(self._rows, to_table(rows, TRACE_SCHEMA))
        keep = np.isin(ev["ut_id"], self.ut_ids)
        if keep.any():
            table = to_table({k: np.asarray(v)[keep] for k, v in ev.items()}, EVENT_SCHEMA)
            self._events = _compacted(self._events, table)
        self._span = [first_s if self._span[0] is None else self._span[0], last_s]

    def finish(self, final):
        """Draw the PNGs (:attr:`files`), in this process."""
        self.files = self._draw()

    def _draw(self):
        from leolink.io.plots import plot_run

        rows = pa.concat_tables([TRACE_SCHEMA.empty_table(), *self._rows]).to_pandas()
        events = pa.concat_tables([EVENT_SCHEMA.empty_table(), *self._events]).to_pandas()
        span = 0.0 if self._span[0] is None else self._span[1] - self._span[0]
        stats = self.summary
        return plot_run(
            rows, events, stats.summary(), self.out_dir, self.ut_ids, duration_s=span,
            per_ut=stats.per_ut_table(), dwells=stats.dwell_table(),
        )  # fmt: skip

    def abort(self):
        """Drop the kept rows."""
        self._rows, self._events = [], []


def _each_once(formats):
    if len(set(formats)) != len(formats):
        raise ValueError("give each format once")
    return formats


#: The file formats of a table sink, each once (a repeated one would write its file twice).
Formats = Annotated[list[Literal["csv", "parquet"]], AfterValidator(_each_once)]


class TraceParams(SinkParams):
    enabled: bool = Field(True, description="write trace.csv / trace.parquet")
    formats: Formats = Field(
        default_factory=lambda: ["csv"],  # type: ignore[arg-type]  # mypy infers list[str]
        min_length=1,
        description="trace files to write",
    )
    chunk_rows: int = Field(200_000, ge=1, le=100_000_000, description="rows per written chunk")


class EventsParams(SinkParams):
    enabled: bool = Field(True, description="write events.csv / events.parquet")
    formats: Formats = Field(
        default_factory=lambda: ["csv", "parquet"],  # type: ignore[arg-type]  # list[str]
        min_length=1,
        description="event files",
    )


class PlotsParams(SinkParams):
    enabled: bool = Field(True, description="write PNG plots next to the traces")
    uts: list[Annotated[int, Field(ge=0, le=10_000_000)]] = Field(
        default_factory=lambda: [0], description="UTs shown in the time plots (ids >= 0)"
    )


class ReportParams(SinkParams):
    enabled: bool = Field(True, description="write report.html and what it is drawn from")
    uts: list[Annotated[int, Field(ge=0, le=10_000_000)]] = Field(
        default_factory=list,
        description="UTs of the time plots; empty: the first UT of each population (at most 6)",
    )
    sample_uts: int = Field(
        500, ge=1, le=1_000_000, description="UTs drawn on the map and in the animation"
    )
    max_frames: int = Field(
        60, ge=2, le=5000, description="most epochs kept for the map and the animation"
    )
    animation: bool = Field(True, description="write footprint.gif (shown in the page)")
    exports: bool = Field(
        False, description="write run.geojson and run.czml (also: leolink report DIR --exports)"
    )


def _report_sink(p, ctx):
    from leolink.io.report.sink import ReportSink

    return ReportSink(
        ctx.out_dir,
        p,
        getattr(ctx, "ephemeris", None),
        getattr(ctx, "codebook", None),
        getattr(ctx, "epoch_utc", None),
    )


SINKS.add(
    "trace",
    lambda p, ctx: TraceSink(
        ctx.out_dir, p.formats, p.chunk_rows, getattr(ctx, "time_zero_utc", None)
    ),
    config=TraceParams,
    doc="one row per UT per epoch (CSV and/or Parquet)",
)
SINKS.add(
    "events",
    lambda p, ctx: EventSink(ctx.out_dir, p.formats),
    config=EventsParams,
    doc="handovers and outages, one row each",
)
SINKS.add(
    "plots",
    lambda p, ctx: PlotSink(ctx.out_dir, ctx.summary, p.uts),
    config=PlotsParams,
    doc="SNR/SINR and Doppler vs time, dwell and handover plots (PNG)",
)


class UtMapParams(SinkParams):
    enabled: bool = Field(
        False, description="write ut_map.csv / .geojson / .png: per-UT values on the globe"
    )


def _ut_map_sink(p, ctx):
    from leolink.io.ut_map import UtMapSink

    return UtMapSink(ctx.out_dir, ctx.summary)


SINKS.add(
    "ut_map",
    _ut_map_sink,
    config=UtMapParams,
    doc="per-UT handover rate, outage and mean SINR on a world map, CSV and GeoJSON",
)
SINKS.add(
    "report",
    _report_sink,
    config=ReportParams,
    doc="report.html (tables, figures, map, animation), report_stats.npz, GeoJSON and CZML",
)
