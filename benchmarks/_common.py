"""Shared helpers of the benchmarks: timing, peak memory, the paper's scenario."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"


def best_of(fn, repeat=3):
    """Smallest wall time of ``repeat`` calls of ``fn()`` [s] and the last result."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def peak_rss_mib():
    """Peak resident memory of this process so far [MiB] (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def row(name, value, unit, aim=None, better="higher"):
    """One printed figure, with the aim and whether it is met."""
    verdict = ""
    if aim is not None:
        ok = value >= aim if better == "higher" else value <= aim
        verdict = (
            f"  (aim {'>=' if better == 'higher' else '<='} {aim:,.3g} {unit}: "
            f"{'met' if ok else 'NOT met'})"
        )
    text = f"{value:>14.3e}" if 0 < abs(value) < 1e-3 else f"{value:>14,.3f}"
    print(f"  {name:<48} {text} {unit}{verdict}")


#: A small parent for the measured child: Linux carries a process's peak RSS across fork
#: and exec, so a child forked from this (large) process would report at least its size.
#: It prints the child's exit code, peak RSS [KiB], CPU time [s] and wall time [s], from
#: its start to its end (the spawner's own start, ~15-20 ms, is not the child's).
_SPAWNER = (
    "import os, subprocess, sys, time; t = time.perf_counter(); "
    "p = subprocess.Popen(sys.argv[1:]); _, st, ru = os.wait4(p.pid, 0); "
    "t = time.perf_counter() - t; "
    "print(os.waitstatus_to_exitcode(st), ru.ru_maxrss, ru.ru_utime + ru.ru_stime, t)"
)


def run_cli(args, env=None):
    """``python -m leolink.cli ARGS`` in a child process, process start included, with
    bytecode caching on: (wall time [s], peak RSS [MiB], CPU time [s]) of the child alone."""
    env = dict(os.environ, **(env or {}))
    # Python's default: compiled modules cached in __pycache__. `pip install .` compiles
    # them at install whatever the shell says; this machine's shell sets
    # PYTHONDONTWRITEBYTECODE=1, which makes an editable checkout recompile leolink's ~110
    # source files at every start (+0.2-0.3 s measured) where an installed copy does not.
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    cmd = [sys.executable, "-c", _SPAWNER, sys.executable, "-m", "leolink.cli", *args]
    out = subprocess.run(cmd, cwd=ROOT, env=env, check=True, capture_output=True, text=True)
    code, maxrss_kib, cpu_s, wall_s = out.stdout.split()[-4:]
    if int(code) != 0:
        raise RuntimeError(f"leolink {' '.join(args)} exited with {code}: {out.stderr[-400:]}")
    return float(wall_s), int(maxrss_kib) / 1024.0, float(cpu_s)


def cpu_s():
    """CPU time of this process so far [s] (user + system): on a shared machine, the
    ratio of wall to CPU time says how much the other processes took."""
    t = os.times()
    return t.user + t.system
