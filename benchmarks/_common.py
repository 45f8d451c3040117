"""Shared helpers of the benchmarks: timing, peak memory, the paper's scenario."""

from __future__ import annotations

import resource
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
