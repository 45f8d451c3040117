"""Memory benchmark: peak RSS flat in run length, 100,000 UTs, summary.json size.

Every run is a fresh child process (``python -m leolink.cli run``-like: ``leolink.run``
into a temporary folder, started through a small spawner), so that its peak resident
memory (``ru_maxrss``) is its own, whatever this process holds.

- Run length: the Walker example (``configs/examples/walker.toml``, 120 satellites,
  1300 km) with ``--uts`` static UTs spread over the ROI, 5 minutes and 30 minutes at 1 s
  epochs, plots on and off (the report always on, as by default). Aim: the 30-minute peak
  within 15 % of the 5-minute peak.
- Many UTs: the paper's pass (``configs/paper.toml``) with 100,000 UTs spread over the
  ROI for 60 s at 1 s epochs, every default output on (trace CSV, events, plots, report).
  Aim: under 1.5 GiB; ``summary.json`` small (the per-UT statistics in
  ``per_ut.parquet``).
- :meth:`SummaryAccumulator.summary` for 50,000 UTs (in this process: real frames of the
  paper run would take minutes; the accumulator is fed synthetic columns of the trace's
  dtypes and 600 epochs), and ``per_ut_table``.

Run: ``python benchmarks/bench_memory.py [--quick] [--uts N]``. Prints figures only;
``main(argv)`` returns them by name.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from _common import _SPAWNER, PAPER, ROOT, row

WALKER = ROOT / "configs" / "examples" / "walker.toml"
GIB = 2**30

CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from pathlib import Path
from leolink.app.run import run
from leolink.config import load_config
spec = json.loads(sys.argv[1])
res = run(load_config(spec["config"], spec["set"]), spec["out"])
out = Path(spec["out"])
print(json.dumps({
    "wall_s": time.perf_counter() - t0,
    "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
    "summary_json_bytes": (out / "summary.json").stat().st_size,
    "files": sorted(p.name for p in res.files),
    "n_ut_epochs": res.summary["overall"]["n_ut_epochs"],
}))
"""


def child_run(config, overrides, tmp, name):
    """One run in a fresh process: its figures (peak RSS, wall time, summary size)."""
    spec = {"config": str(config), "set": list(overrides), "out": os.path.join(tmp, name)}
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    # Through the small spawner: a child forked from this process would report at least
    # this process's resident size as its peak (Linux carries it across fork and exec).
    done = subprocess.run(
        [sys.executable, "-c", _SPAWNER, sys.executable, "-c", CHILD, json.dumps(spec)],
        env=env, cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    lines = done.stdout.strip().splitlines()
    code, maxrss_kib = lines[-1].split()[:2] if lines else ("1", "0")
    if done.returncode != 0 or int(code) != 0:
        raise RuntimeError(f"{name}: the run failed:\n{done.stderr[-2000:]}")
    return json.loads(lines[-2]) | {"peak_rss_bytes": int(maxrss_kib) * 1024}


def walker_overrides(n_ut, duration_s, plots):
    return [
        f"run.duration_s={duration_s!r}",
        "population.1.count=" + str(n_ut - 1),
        'population.1.placement="random"',
        f"output.plots.enabled={'true' if plots else 'false'}",
    ]


def paper_overrides(n_ut, duration_s):
    return [
        f"run.duration_s={duration_s!r}",
        "run.epoch_s=1.0",
        "population.0.count=1",
        f"population.1.count={n_ut - 3}",
        'population.1.placement="random"',
        "population.1.x_m=[]",
        "population.1.y_m=[]",
        "population.2.count=1",
        "population.3.count=1",
    ]


def run_length(n_ut, short_s, long_s, tmp, variants=("plots", "no_plots")):
    """Peak RSS of a short and a long run, plots on and off."""
    figures = {}
    for plots in [v == "plots" for v in variants]:
        tag = "plots" if plots else "no_plots"
        got = {}
        for label, dur in (("short", short_s), ("long", long_s)):
            got[label] = child_run(WALKER, walker_overrides(n_ut, dur, plots), tmp, tag + label)
            figures[f"memory_{tag}_{label}_peak_mib"] = got[label]["peak_rss_bytes"] / 2**20
            figures[f"memory_{tag}_{label}_wall_s"] = got[label]["wall_s"]
        ratio = got["long"]["peak_rss_bytes"] / got["short"]["peak_rss_bytes"]
        figures[f"memory_{tag}_long_over_short"] = ratio
        row(f"{n_ut} UTs, {tag}: {short_s / 60:g} min peak", got["short"]["peak_rss_bytes"] / 2**20,
            "MiB")  # fmt: skip
        row(f"{n_ut} UTs, {tag}: {long_s / 60:g} min peak", got["long"]["peak_rss_bytes"] / 2**20,
            "MiB")  # fmt: skip
        row(f"  long / short ({tag})", ratio, "x", aim=1.15, better="lower")
    return figures


def many_uts(n_ut, duration_s, tmp):
    got = child_run(PAPER, paper_overrides(n_ut, duration_s), tmp, "many")
    peak = got["peak_rss_bytes"] / GIB
    row(f"{n_ut:,} UTs x {duration_s:g} s: peak RSS", peak, "GiB", aim=1.5, better="lower")
    row(f"{n_ut:,} UTs x {duration_s:g} s: wall time (process)", got["wall_s"], "s")
    kib = got["summary_json_bytes"] / 1024
    row(f"{n_ut:,} UTs: summary.json", kib, "KiB", aim=64.0, better="lower")
    return {
        "many_uts_n_ut": n_ut,
        "many_uts_peak_gib": peak,
        "many_uts_wall_s": got["wall_s"],
        "many_uts_summary_json_kib": kib,
        "many_uts_per_ut_parquet": "per_ut.parquet" in got["files"],
    }


def summary_speed(n_ut, n_epoch, repeat=3):
    """Seconds of ``summary()`` and ``per_ut_table()`` for ``n_ut`` UTs fed ``n_epoch``
    epochs (SNR of each UT a slow ramp plus noise, as a pass; a few outages)."""
    from leolink.io.summary.accumulator import SummaryAccumulator
    from leolink.sim.streams import EpochFrame, RunInfo

    rng = np.random.default_rng(1)
    ut = np.arange(n_ut)
    base = rng.uniform(0.0, 20.0, n_ut)
    events = {"ut_id": np.zeros(0, int), "kind": np.zeros(0, int)}
    dwells = {k: np.zeros(0) for k in ("ut_id", "sat_id", "beam_id", "start_s", "end_s")}
    dwells.update(censored_start=np.zeros(0, bool), censored_end=np.zeros(0, bool))
    best = float("inf")
    for _ in range(repeat):
        acc = SummaryAccumulator()
        acc.start(RunInfo(n_ut, 1, 15, 1.0, 0.0, n_epoch, ("p",) * n_ut))
        for k in range(n_epoch):
            snr = base + 5.0 * np.sin(k / n_epoch * np.pi) + rng.normal(0.0, 0.5, n_ut)
            cols = {
                "ut_id": ut, "service": (rng.random(n_ut) < 0.01).astype(np.int8),
                "snr_db": snr, "sinr_db": snr - 1.0, "throughput_bps": snr * 1e7,
                "doppler_hz": rng.normal(0, 1e5, n_ut), "angular_speed_deg_s": snr * 0.01,
                "interruption_s": np.zeros(n_ut),
            }  # fmt: skip
            acc.epoch(EpochFrame(k, float(k), cols, events, dwells))
        t0 = time.perf_counter()
        acc.summary()
        acc.per_ut_table()
        best = min(best, time.perf_counter() - t0)
    row(f"summary() + per_ut_table(), {n_ut:,} UTs x {n_epoch}", best, "s")
    return {"summary_n_ut": n_ut, "summary_s": best}


def main(argv=None):
    """Figures by name (see the module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs, fewer UTs")
    ap.add_argument("--uts", type=int, default=None, help="UTs of the run-length runs")
    ap.add_argument("--many-uts", type=int, default=None)
    ap.add_argument("--skip", nargs="*", default=[], choices=["length", "many", "summary"])
    ap.add_argument(
        "--variants", nargs="*", default=["plots", "no_plots"], choices=["plots", "no_plots"]
    )
    args = ap.parse_args([] if argv is None else argv)
    n_ut = args.uts or (200 if args.quick else 1000)
    short_s, long_s = (60.0, 360.0) if args.quick else (300.0, 1800.0)
    many = args.many_uts or (10_000 if args.quick else 100_000)
    figures = {}
    with tempfile.TemporaryDirectory() as tmp:
        if "summary" not in args.skip:
            figures.update(summary_speed(5_000 if args.quick else 50_000, 600))
        if "many" not in args.skip:
            figures.update(many_uts(many, 60.0, tmp))
        if "length" not in args.skip:
            figures.update(run_length(n_ut, short_s, long_s, tmp, args.variants))
    return figures


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1:]), indent=1))
