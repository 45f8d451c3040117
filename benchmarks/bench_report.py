"""Report at scale: 100,000 UTs over the paper's ROI, ``python benchmarks/bench_report.py``.

Runs the paper scenario with ``--uts`` random static UTs for ``--epochs`` epochs (Parquet
trace) twice, with the report sink off and on (``[output.report]``: statistics kept epoch by
epoch, ``report_stats.npz``, ``footprint.gif``, ``report.html``), then times, separately:

1. streaming the trace file into :class:`leolink.io.report.stats.ReportStats` (what
   ``leolink report DIR`` does for a folder without ``report_stats.npz``);
2. building ``report.html`` from the statistics and ``summary.json`` (the page);
3. writing ``footprint.gif``;
4. rebuilding the page from the saved ``report_stats.npz`` (``leolink report DIR``).

It prints the figures and the statistics' size in memory; nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import tomli_w

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from leolink.io.report.animation import frames_from_stats, write_footprint_gif  # noqa: E402
from leolink.io.report.page import build_run_report  # noqa: E402
from leolink.io.report.rebuild import build_report_from_dir, stats_from_dir  # noqa: E402
from leolink.io.report.stats import ReportStats  # noqa: E402


def _config(path, n_ut, n_epoch):
    cfg = tomllib.loads((REPO / "configs" / "paper.toml").read_text())
    cfg["run"].update(duration_s=float(n_epoch))
    cfg["output"] = {"trace": {"formats": ["parquet"]}, "plots": {"enabled": False}}
    cfg["population"] = [{"name": "crowd", "kind": "static", "count": n_ut, "placement": "random"}]
    path.write_text(tomli_w.dumps(cfg))
    return path


def _run(config, run_dir, *sets):
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "leolink.cli", "run", str(config), "--out", str(run_dir)]
    subprocess.run([*cmd, "--quiet", "--overwrite", *sets], check=True, cwd=REPO)
    return time.perf_counter() - t0


def _nbytes(stats):
    return sum(v.nbytes for v in vars(stats).values() if hasattr(v, "nbytes"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uts", type=int, default=100_000)
    ap.add_argument("--epochs", type=int, default=60)
    ap.add_argument("--out", type=Path, default=Path("/tmp/leolink_bench_report"))
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    config = _config(args.out / "crowd.toml", args.uts, args.epochs)
    run_dir = args.out / "run"
    t_bare = _run(config, run_dir, "--set", "output.report.enabled=false")
    t_run = _run(config, run_dir)
    n_rows = args.uts * args.epochs
    t0 = time.perf_counter()
    stats = stats_from_dir(run_dir, series_ut=[0, 1, 2, 3])
    t_stream = time.perf_counter() - t0
    summary = json.loads((run_dir / "summary.json").read_text())
    t0 = time.perf_counter()
    saved = ReportStats.load(run_dir / "report_stats.npz")  # the run's, with the satellites
    build_run_report(run_dir / "report.html", summary, saved, config.read_text())
    t_page = time.perf_counter() - t0
    t0 = time.perf_counter()
    gif = write_footprint_gif(run_dir / "footprint.gif", frames_from_stats(saved))
    t_gif = time.perf_counter() - t0
    t0 = time.perf_counter()
    build_report_from_dir(run_dir, animate=False)
    t_rebuild = time.perf_counter() - t0
    print(f"report at scale: {args.uts:,} UTs x {args.epochs} epochs = {n_rows:,} trace rows")
    print(f"  leolink run, report off              {t_bare:7.1f} s")
    print(f"  leolink run, report on (default)     {t_run:7.1f} s (+{t_run - t_bare:.1f} s)")
    print(
        f"  stream trace into ReportStats        {t_stream:7.1f} s "
        f"({n_rows / t_stream / 1e6:.2f} M rows/s)"
    )
    print(f"  statistics in memory                 {_nbytes(stats) / 2**20:7.1f} MiB")
    print(f"  report.html from the statistics      {t_page:7.1f} s "
          f"({(run_dir / 'report.html').stat().st_size / 2**20:.1f} MiB)")  # fmt: skip
    print(f"  footprint.gif ({gif['n_frames']} frames)            {t_gif:7.1f} s "
          f"({gif['n_bytes'] / 2**20:.1f} MiB)")  # fmt: skip
    print(f"  leolink report DIR (saved statistics) {t_rebuild:6.1f} s")


if __name__ == "__main__":
    main()
