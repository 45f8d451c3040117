"""The paper's constellation end to end: ``configs/constellation.toml`` (4,399 satellites,
1,000 UTs, 600 epochs, Parquet trace), wall time and peak memory, process start included.

Twice: as configured (plots on) and with ``output.plots.enabled=false``.
Run: ``python benchmarks/bench_constellation.py [--quick]`` (quick: 60 epochs).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from _common import ROOT, row, run_cli

CONFIG = ROOT / "configs" / "constellation.toml"


def main(quick=False, argv=None):
    """Figures: ``wall_s``, ``cpu_s``, ``peak_rss_mib`` and the same with ``noplots_``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=60.0 if quick else 600.0)
    args = ap.parse_args([] if argv is None else argv)
    figures = {}
    print(f"constellation: {CONFIG.name}, {args.duration_s:g} s, 1,000 UTs, 4,399 satellites")
    for tag, extra in (("", []), ("noplots_", ["--set", "output.plots.enabled=false"])):
        with tempfile.TemporaryDirectory() as tmp:
            out = str(Path(tmp) / "run")
            cmd = ["run", str(CONFIG), "--out", out, "--quiet",
                   "--set", f"run.duration_s={args.duration_s!r}", *extra]  # fmt: skip
            wall, rss, cpu = run_cli(cmd)
            figures.update({f"{tag}wall_s": wall, f"{tag}peak_rss_mib": rss, f"{tag}cpu_s": cpu})
        what = "plots on" if not tag else "plots off"
        row(f"wall time ({what})", figures[f"{tag}wall_s"], "s", aim=20.0, better="lower")
        row(f"CPU time ({what})", cpu, "s")
        row(f"peak resident memory ({what})", figures[f"{tag}peak_rss_mib"], "MiB", aim=1024,
            better="lower")  # fmt: skip
    return figures


if __name__ == "__main__":
    import sys

    main(quick="--quick" in sys.argv, argv=[a for a in sys.argv[1:] if a != "--quick"])
