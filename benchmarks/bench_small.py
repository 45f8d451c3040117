"""Small runs: the fixed cost of an epoch, process start included.

10 UTs (the paper's 7 with 7 random static UTs for its 4 points: 1 + 7 + 1 + 1) under the
paper's pass, 600 epochs of 1 s centred on the overhead instant, default outputs but the
pictures (trace.csv, events.csv and .parquet, summary.json: no plots, no report, as the
peer's loop draws none; the report's cost is ``bench_report``), each run a fresh
``leolink run`` process.
The fixed cost per epoch is the slope, between a 600-epoch and a 60-epoch run, of the
simulation loop's own wall time (``run.wall_time_s`` of ``summary.json``: the sinks, the
epochs and their end; no pictures);
start-up is the 60-epoch run's wall time minus 60 of those epochs.

Run: ``python benchmarks/bench_small.py [--quick]``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from _common import PAPER, row, run_cli

N_UT = 10
SETS = [
    "output.plots.enabled=false",
    "output.report.enabled=false",
    'population.1.placement="random"',
    "population.1.count=7",
    "population.1.x_m=[]",
    "population.1.y_m=[]",
]


def _run(n_epoch, repeat):
    """Best of ``repeat``: (wall time of the process, the simulation loop's own wall time
    ``run.wall_time_s`` of summary.json) [s]."""
    best = (float("inf"), float("inf"))
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            sets = [*SETS, f"run.start_s={60.0 - n_epoch / 2!r}", f"run.duration_s={n_epoch!r}"]
            args = ["run", str(PAPER), "--out", str(Path(tmp) / "run"), "--quiet"]
            for s in sets:
                args += ["--set", s]
            wall = run_cli(args)[0]  # wall time: the start-up is the user's wait
            summary = json.loads((Path(tmp) / "run" / "summary.json").read_text())
            best = min(best, (wall, summary["run"]["wall_time_s"]))
    return best


def main(quick=False, argv=None):
    """Figures: ``wall_s`` (10 UTs x 600 s), ``ut_epochs_per_s``, ``fixed_ms_per_epoch``,
    ``startup_s``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1 if quick else 3)
    args = ap.parse_args([] if argv is None else argv)
    (long, long_loop), (short, short_loop) = _run(600, args.repeat), _run(60, args.repeat)
    # The loop's own time: the process's start and its writing after the loop are not
    # per-epoch costs.
    per_epoch = (long_loop - short_loop) / 540.0
    figures = {
        "wall_s": long,
        "ut_epochs_per_s": N_UT * 600 / long,
        "fixed_ms_per_epoch": 1e3 * per_epoch,
        "startup_s": short - 60 * per_epoch,
    }
    print(f"small run: {N_UT} UTs x 600 epochs, process start included (best of {args.repeat})")
    row("wall time end to end", long, "s")
    row("UT-epochs per second end to end", figures["ut_epochs_per_s"], "UT-ep/s", aim=15e3)
    row("fixed cost per epoch", figures["fixed_ms_per_epoch"], "ms", aim=0.2, better="lower")
    row("start-up (imports, config, scenario, outputs)", figures["startup_s"], "s")
    return figures


if __name__ == "__main__":
    import sys

    main(quick="--quick" in sys.argv, argv=[a for a in sys.argv[1:] if a != "--quick"])
