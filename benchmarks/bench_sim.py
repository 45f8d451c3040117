"""Simulator benchmark (issue: the simulator).

1,000 UTs (half static, half moving at car to aircraft speeds, spread over the ROI) x
3,600 epochs (the paper's 120 s pass at 1/30 s), one satellite, 15 beams:
UT-epochs/s end to end with the Parquet trace (in this process: no start-up), peak memory.
The outputs: trace.parquet, events, summary.json; no pictures (plots and report off: the
report's cost is ``bench_report``).
The engine alone on this workload is ``bench_engine`` (c).

Run: ``python benchmarks/bench_sim.py [--quick] [--uts N] [--epochs N]``. Prints figures.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from _common import PAPER, cpu_s, peak_rss_mib, row

from leolink.app.run import run
from leolink.config import load_config


def scenario(n_ut, n_epoch):
    half = n_ut // 2
    over = [
        "output.plots.enabled=false",
        "output.report.enabled=false",
        'output.trace.formats=["parquet"]',
        f"run.epoch_s={120.0 / n_epoch!r}",
        "run.duration_s=120.0",
        "population.0.count=1",
        f"population.1.count={half - 1}",
        'population.1.placement="random"',
        f"population.2.count={n_ut - half - 1}",
        'population.2.placement="random"',
        'population.2.heading_deg="random"',
        "population.2.speed_m_s=100.0",
        "population.3.count=1",
    ]
    cfg = load_config(PAPER, over)
    pops = list(cfg.population)
    pops[1] = pops[1].model_copy(update={"x_m": [], "y_m": []})
    pops[2] = pops[2].model_copy(update={"x_m": [], "y_m": []})
    return cfg.model_copy(update={"population": pops})


def main(quick=False, argv=None):
    """Figures: ``end_to_end_ut_epochs_per_s``, ``wall_s``, ``trace_mib``, ``peak_rss_mib``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uts", type=int, default=1000)
    ap.add_argument("--epochs", type=int, default=600 if quick else 3600)
    args = ap.parse_args([] if argv is None else argv)
    cfg = scenario(args.uts, args.epochs)
    n = args.uts * args.epochs
    print(
        f"simulator: {args.uts} UTs x {args.epochs} epochs = {n / 1e6:.2f} M UT-epochs, "
        "1 satellite, 15 beams"
    )
    with tempfile.TemporaryDirectory() as tmp:
        t0, c0 = time.perf_counter(), cpu_s()
        result = run(cfg, out_dir=Path(tmp))
        dt, cpu = time.perf_counter() - t0, cpu_s() - c0
        size = (Path(tmp) / "trace.parquet").stat().st_size / 2**20
    figures = {"end_to_end_ut_epochs_per_s": n / dt, "wall_s": dt, "cpu_s": cpu, "trace_mib": size,
               "peak_rss_mib": peak_rss_mib()}  # fmt: skip
    row("end to end with trace.parquet", n / dt, "UT-ep/s", aim=1e6)
    row("wall time end to end", dt, "s")
    row("CPU time (wall / CPU: the share others took)", cpu, "s")
    row("trace.parquet size", size, "MiB")
    row("peak resident memory (process)", peak_rss_mib(), "MiB", aim=1024, better="lower")
    o = result.summary["overall"]
    print(
        f"  served: outage fraction {o['outage_fraction']:.4f}, "
        f"{o['handovers']['beam_handover']} beam handovers"
    )
    return figures


if __name__ == "__main__":
    import sys

    main(quick="--quick" in sys.argv, argv=[a for a in sys.argv[1:] if a != "--quick"])
