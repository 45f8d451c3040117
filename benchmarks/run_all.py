"""Run every benchmark and print its figures: ``python benchmarks/run_all.py [--quick]``.

``--quick`` shrinks the work (100k points, 600 epochs) for a fast look; the figures
quoted in the issues and the README come from the default sizes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_engine  # noqa: E402
import bench_sim  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    bench_engine.main(["--points", "100000"] if args.quick else [])
    print()
    bench_sim.main(["--epochs", "600"] if args.quick else [])


if __name__ == "__main__":
    main()
