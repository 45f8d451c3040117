"""Writing benchmark: the trace writer and the summary, fed as a run feeds them.

1,000 UTs x ``--epochs`` epochs of the trace's columns (dtypes as the simulator hands
them: ids int64, ``service``/``outage_reason`` int8 codes, ``population`` strings, the
rest float64), appended one epoch at a time:

- :class:`leolink.io.tables.TraceWriter` to ``trace.parquet`` (float32 columns but times
  and positions, background thread), to ``trace.csv``, and to both: rows/s, the floor of
  the simulator's end-to-end rate (aim >= 4.5 M rows/s with Parquet);
- :class:`leolink.io.summary.accumulator.SummaryAccumulator` (the summary sink): rows/s, and the
  per-epoch fixed cost of both at 10 UTs.

Run: ``python benchmarks/bench_writer.py [--epochs N]``. Prints figures only;
``main(argv)`` returns them by name.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time

import numpy as np
from _common import row

from leolink.io.summary.accumulator import SummaryAccumulator
from leolink.io.tables import _INT_COLUMNS, TRACE_COLUMNS, TraceWriter
from leolink.sim.handover.controller import DWELL_COLUMNS, EVENT_COLUMNS
from leolink.sim.streams import EpochFrame, RunInfo

FLOOR_ROWS_S = 4.5e6


def epoch_columns(n_ut, rng):
    """One epoch's trace columns, dtypes as the simulator's frames."""
    cols = {}
    for name in TRACE_COLUMNS:
        if name in _INT_COLUMNS:
            cols[name] = rng.integers(0, 15, n_ut).astype(np.int64)
        else:
            cols[name] = rng.normal(10.0, 5.0, n_ut)
    cols["ut_id"] = np.arange(n_ut, dtype=np.int64)
    cols["service"] = (rng.random(n_ut) < 0.02).astype(np.int8) * 2
    cols["outage_reason"] = np.zeros(n_ut, np.int8)
    cols["population"] = np.array(["static"] * n_ut)
    return cols


def _frames(n_ut, n_epoch, n_distinct=16):
    rng = np.random.default_rng(3)
    distinct = [epoch_columns(n_ut, rng) for _ in range(n_distinct)]
    for k in range(n_epoch):
        cols = dict(distinct[k % n_distinct])
        cols["time_s"] = np.full(n_ut, float(k))
        yield k, cols


def writer_rate(n_ut, n_epoch, formats):
    """Rows/s of TraceWriter.append + close for ``formats``."""
    with tempfile.TemporaryDirectory() as tmp:
        frames = list(_frames(n_ut, n_epoch))
        t0 = time.perf_counter()
        w = TraceWriter(tmp, formats=formats)
        for _, cols in frames:
            w.append(cols)
        w.close()
        return n_ut * n_epoch / (time.perf_counter() - t0)


def summary_rate(n_ut, n_epoch):
    """Rows/s of the summary sink (epoch + summary at the end)."""
    events = {k: np.zeros(0) for k in EVENT_COLUMNS}
    dwells = {k: np.zeros(0) for k in DWELL_COLUMNS}
    frames = list(_frames(n_ut, n_epoch))
    acc = SummaryAccumulator()
    acc.start(RunInfo(n_ut, 1, 15, 1.0, 0.0, n_epoch, ("static",) * n_ut))
    t0 = time.perf_counter()
    for k, cols in frames:
        acc.epoch(EpochFrame(k, float(k), cols, events, dwells))
    acc.summary()
    return n_ut * n_epoch / (time.perf_counter() - t0)


def main(argv=None):
    """Figures: ``writer_parquet_rows_per_s``, ``writer_csv_rows_per_s``,
    ``writer_both_rows_per_s``, ``summary_rows_per_s``, ``writer_epoch_cost_10ut_ms``,
    ``summary_epoch_cost_10ut_ms``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uts", type=int, default=1000)
    ap.add_argument("--epochs", type=int, default=3600)
    ap.add_argument("--quick", action="store_true", help="600 epochs")
    args = ap.parse_args([] if argv is None else argv)
    n_epoch = 600 if args.quick else args.epochs
    n = args.uts
    print(f"writing: {n} UTs x {n_epoch} epochs = {n * n_epoch / 1e6:.1f} M rows, "
          f"{len(TRACE_COLUMNS)} columns")  # fmt: skip
    f = {}
    for key, formats in (
        ("parquet", ("parquet",)),
        ("csv", ("csv",)),
        ("both", ("csv", "parquet")),
    ):
        f[f"writer_{key}_rows_per_s"] = max(writer_rate(n, n_epoch, formats) for _ in range(2))
        aim = FLOOR_ROWS_S if key == "parquet" else None
        row(f"TraceWriter {'+'.join(formats)}", f[f"writer_{key}_rows_per_s"], "rows/s", aim=aim)
    f["summary_rows_per_s"] = max(summary_rate(n, n_epoch) for _ in range(2))
    row("SummaryAccumulator", f["summary_rows_per_s"], "rows/s")
    small = 10 * 600
    f["writer_epoch_cost_10ut_ms"] = 1e3 * small / writer_rate(10, 600, ("csv",)) / 600
    f["summary_epoch_cost_10ut_ms"] = 1e3 * small / summary_rate(10, 600) / 600
    row("10 UTs: TraceWriter csv per epoch", f["writer_epoch_cost_10ut_ms"], "ms")
    row("10 UTs: summary per epoch", f["summary_epoch_cost_10ut_ms"], "ms")
    return f


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1:]), indent=1))
