"""Run every figure script of the paper's evaluation and write ``index.json``.

Run: ``python analysis/run_all.py [--fast] [--out DIR]`` (``--fast`` is passed through).
``DIR/index.json`` maps each script to its numbers, PNGs and wall time.
"""

from __future__ import annotations

import importlib
import json
import sys
import time
from pathlib import Path

from _common import _jsonable, parse_args

SCRIPTS = (
    "fig5_mesh_vs_oversampling",
    "fig6_terminal_gains",
    "fig7_9_coverage",
    "fig10_doppler_angular_speed",
    "fig11_snr_vs_time",
)


def main(argv=None):
    args = parse_args(argv, __doc__)
    passed = ["--out", str(args.out)] + (["--fast"] if args.fast else [])
    index = {"fast": args.fast, "scripts": {}}
    for name in SCRIPTS:
        t0 = time.perf_counter()
        numbers = importlib.import_module(name).main(passed)
        data = json.loads((Path(args.out) / f"{name}.json").read_text(encoding="utf-8"))
        index["scripts"][name] = {
            "numbers": numbers,
            "pngs": data["pngs"],
            "wall_time_s": time.perf_counter() - t0,
        }
    path = Path(args.out) / "index.json"
    path.write_text(json.dumps(_jsonable(index), indent=2) + "\n", encoding="utf-8")
    print(f"wrote {path}")
    return index


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
