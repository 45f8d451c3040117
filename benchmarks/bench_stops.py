"""Issue 49: how long a stop takes. A 1,500-UT run of the paper's pass (1,000 static UTs
and 500 cars at random in the ROI, every output on: CSV trace, events, plots, report) is
stopped by each signal (SIGINT, SIGTERM, SIGHUP, SIGXCPU, and a second SIGINT 0.2 s after
the first) at five observable points:

``locked``     the output folder is locked (the scenario built, the sinks starting);
``streaming``  the trace and event files are open (the first blocks streaming);
``large``      the trace's temporary CSV holds ``--large-mib`` MiB (a large trace, mid-run);
``finishing``  ``trace.csv`` has its final name (the sinks finishing: the plots drawn);
``report``     ``report_stats.npz`` is written (the report's animation and figures drawn).

Each cell is the wall time from the signal to the process's exit [s], and whether the
stop was clean: exit code 128 + the signal's number, one line on stderr and no
traceback, no ``*.partial`` file and no lock left. Nothing is asserted (issue 49's aim:
< 3 s); ``stop_s_max`` is the worst cell. Run alone:
``python benchmarks/bench_stops.py [--points P,...] [--signals S,...] [--large-mib M]``
(``PYTHONPATH=<another checkout>/src`` measures that checkout's code).
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import PAPER, ROOT, row

N_UT = 1_500
POPULATIONS = (
    'population=[{name="ground", kind="static", placement="random", count=1000}, '
    '{name="cars", kind="constant_velocity", placement="random", count=500, speed="car", '
    'heading_deg="random"}]'
)
OVERRIDES = [POPULATIONS, "run.duration_s=240", "output.report.max_frames=30"]
SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP", "SIGXCPU", "SIGINT x2")
POLL_S = 0.02
TIMEOUT_S = 600.0


def _points(large_mib):
    """``{name: predicate(out_dir)}``, in the order a run reaches them."""

    def size_mib(out, pattern):
        try:
            return sum(p.stat().st_size for p in out.glob(pattern)) / 2**20
        except OSError:
            return 0.0

    return {
        "locked": lambda out: (out / ".leolink.lock").exists(),
        "streaming": lambda out: len(list(out.glob("*.partial"))) >= 2,
        "large": lambda out: size_mib(out, "trace.csv.*.partial") >= large_mib,
        "finishing": lambda out: (out / "trace.csv").exists(),
        "report": lambda out: (out / "report_stats.npz").exists(),
    }


def _start(out):
    env = {**os.environ, "PYTHONPATH": os.environ.get("PYTHONPATH", str(ROOT / "src"))}
    sets = [a for o in OVERRIDES for a in ("--set", o)]
    cmd = [sys.executable, "-m", "leolink.cli", "run", str(PAPER), *sets, "--out", str(out),
           "--quiet"]  # fmt: skip
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)  # fmt: skip


def _left(out):
    return [p.name for p in out.rglob("*") if ".partial" in p.name or p.name == ".leolink.lock"]


def stop_once(point, name, tmp, large_mib):
    """(seconds from the signal to the exit, clean?, what was wrong) of one stop."""
    out = Path(tmp) / f"{point}-{name.replace(' ', '')}"
    proc, reached = _start(out), _points(large_mib)[point]
    deadline = time.monotonic() + TIMEOUT_S
    while not reached(out):
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            return float("nan"), False, f"the run ended before {point}"
        time.sleep(POLL_S)
    sig = getattr(signal, name.split()[0])
    t0 = time.perf_counter()
    proc.send_signal(sig)
    if name.endswith("x2"):
        time.sleep(0.2)
        if proc.poll() is None:
            proc.send_signal(sig)
    _, err = proc.communicate(timeout=TIMEOUT_S)
    seconds = time.perf_counter() - t0
    lines = err.strip().splitlines()
    wrong = []
    if proc.returncode != 128 + sig:
        wrong.append(f"exit {proc.returncode}")
    if len(lines) != 1 or "Traceback" in err:
        wrong.append(f"{len(lines)} lines")
    if _left(out):
        wrong.append(f"left {_left(out)}")
    return seconds, not wrong, "; ".join(wrong)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", default=",".join(_points(0)))
    ap.add_argument("--signals", default=",".join(SIGNALS))
    ap.add_argument("--large-mib", type=float, default=60.0)
    args = ap.parse_args(argv)
    points, signals = args.points.split(","), args.signals.split(",")
    load = os.getloadavg()[0]
    print(f"stops: {N_UT:,} UTs of the paper's pass, every output; load average {load:.1f}")
    figures, worst = {}, 0.0
    print(f"  {'point':<10}" + "".join(f"{s:>14}" for s in signals))
    with tempfile.TemporaryDirectory() as tmp:
        for point in points:
            cells = []
            for name in signals:
                seconds, clean, wrong = stop_once(point, name, tmp, args.large_mib)
                figures[f"{point}_{name.replace(' ', '_')}_s"] = seconds
                worst = max(worst, seconds) if seconds == seconds else worst
                cells.append(f"{seconds:.2f}" + ("" if clean else "!"))
                if not clean:
                    print(f"    {point} / {name}: not clean: {wrong}")
            print(f"  {point:<10}" + "".join(f"{c:>14}" for c in cells), flush=True)
    figures["stop_s_max"] = worst
    row("stop_s_max (issue 49: < 3 s)", worst, "s", aim=3.0, better="lower")
    print(f"  load average at the end: {os.getloadavg()[0]:.1f} ('!': not clean)")
    return figures


if __name__ == "__main__":
    main()
