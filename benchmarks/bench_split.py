"""One global run split over parts of its UTs (``leolink run --workers N``): 10,000 static
UTs drawn uniformly over land between 56 deg S and 56 deg N, the paper's 4,399-satellite
constellation, Parquet trace (no plots, no report), as three ``leolink run`` processes:
in one process, split into parts run one after the other in that process (``--workers 1
--parts P``), and split over two local worker processes (``--workers 2 --parts P``).

Figures: ``{single,serial,two}_wall_s``, ``..._cpu_s`` (the process and its workers),
``..._peak_rss_mib`` (the largest process), ``two_worker_peak_rss_mib`` (each worker's
peak, the largest), ``part_cpu_s_per_ut_epoch`` (the parts' wall time in the serial run
over their UT-epochs: the cost a part pays per UT and epoch, its own start included),
``merge_s`` (the serial run's wall time beyond its parts: the parent's scenario, the
merge into the outputs), ``speedup_two_over_single`` and ``speedup_two_over_serial``,
and for 1,000,000 UTs x 600 s: ``parts_core_hours_1m`` (the parts' cost per UT-epoch x
6e8: spread over a cluster's cores) and ``merge_hours_1m`` (the merge scaled by its rows:
one parent), so a cluster of C cores needs about ``parts / C + merge`` hours.
Run alone: ``python benchmarks/bench_split.py [--uts N] [--duration-s S] [--parts P]``,
or on another config as it is: ``... --config configs/global.toml``.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

from _common import ROOT, row, run_cli

#: The split runs' config, shared with tests/test_split.py.
CONFIG = ROOT / "tests" / "data" / "global_split.toml"


def _run(config, out, extra):
    wall, rss, cpu = run_cli(["run", str(config), "--out", str(out), "--quiet", *extra])
    run = json.loads((out / "summary.json").read_text("utf-8"))["run"]
    return wall, rss, cpu, run


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uts", type=int, default=10_000)
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--parts", type=int, default=8)
    ap.add_argument("--config", type=Path, help="another config, as it is (no --uts, --duration-s)")
    args = ap.parse_args(argv)
    figures, config = {}, (args.config or CONFIG).resolve()
    sets = [] if args.config else ["--set", f"run.duration_s={args.duration_s!r}", "--set",
                                   f"population.0.count={args.uts}"]  # fmt: skip
    what = args.config or f"{args.uts:,} UTs over land, 4,399 satellites, {args.duration_s:g} s"
    print(f"split: {what}, {args.parts} parts; load average {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        parts = ["--parts", str(args.parts)]
        for tag, extra in (("single", []), ("serial", parts), ("two", ["--workers", "2", *parts])):
            wall, rss, cpu, run = _run(config, Path(tmp) / tag, [*sets, *extra])
            split, n_ut_epochs = run.get("split"), run["n_ut"] * run["n_epochs"]
            figures.update({f"{tag}_wall_s": wall, f"{tag}_cpu_s": cpu, f"{tag}_peak_rss_mib": rss})
            row(f"{tag}: wall time", wall, "s")
            row(f"{tag}: CPU time (process and workers)", cpu, "s")
            row(f"{tag}: peak resident memory (largest process)", rss, "MiB")
            if tag == "serial":
                figures["part_cpu_s_per_ut_epoch"] = sum(split["part_wall_s"]) / n_ut_epochs
                figures["merge_s"] = wall - sum(split["part_wall_s"])
                figures["part_wall_s_max"] = max(split["part_wall_s"])
            if tag == "two":
                figures["two_worker_peak_rss_mib"] = max(split["peak_rss_mib_by_worker"].values())
    figures["speedup_two_over_single"] = figures["single_wall_s"] / figures["two_wall_s"]
    figures["speedup_two_over_serial"] = figures["serial_wall_s"] / figures["two_wall_s"]
    # 1,000,000 UTs x 600 s: the parts' cost spreads over the cluster's cores, the merge
    # (one parent) grows with the rows
    big = 1_000_000 * 600
    figures["parts_core_hours_1m"] = figures["part_cpu_s_per_ut_epoch"] * big / 3600.0
    figures["merge_hours_1m"] = figures["merge_s"] * big / n_ut_epochs / 3600.0
    print(f"  ({n_ut_epochs:,} UT-epochs; load average at the end {os.getloadavg()[0]:.1f})")
    for name in ("part_cpu_s_per_ut_epoch", "merge_s", "two_worker_peak_rss_mib",
                 "speedup_two_over_single", "speedup_two_over_serial",
                 "parts_core_hours_1m", "merge_hours_1m"):  # fmt: skip
        row(name, figures[name], "")
    return figures


if __name__ == "__main__":
    main()
