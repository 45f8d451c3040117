"""Every benchmark, one command: ``python benchmarks/run_all.py [--quick] [--json FILE]
[--compare BEFORE.json | --compare REF_CHECKOUT] [--only MODULE ...]``.

Runs each ``bench_*`` module of :data:`MODULES` that exists (a missing one is skipped with
a note), prints its figures, then one table of every figure by name with its aim and the
ratio to the aim (> 1 is better than the aim either way) and, with ``--compare``, the
ratio to the same figure of another run (``head / ref``: > 1 is faster for a rate, slower
for a time). ``--compare`` takes the figures of an earlier ``--json`` run, or another
checkout's folder (e.g. ``/work/main``): then each module runs twice, side by side, in
fresh processes, first with that checkout's ``src`` first on ``PYTHONPATH`` (its compiled
extension as built there), then with this tree's, so that both see the same load.
``--quick`` shrinks the work for a fast look; the README's figures come from the default.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

#: The benchmark modules, in the order they run (each ``main(quick, argv) -> dict``).
MODULES = ("bench_engine", "bench_sim", "bench_constellation", "bench_features",
           "bench_small", "bench_memory", "bench_visibility", "bench_peer",
           "bench_atmosphere")  # fmt: skip
#: Benchmarks run on their own, not by this command (minutes each, or a part's floor).
RUN_ALONE = ("bench_report", "bench_report_cost", "bench_split", "bench_stops", "bench_writer")
#: The variants of bench_features (its VARIANTS).
FEATURES = ("a3", "cho", "t1", "time_to_exit", "predictive", "urban", "report", "global")
#: Aims of the issue (speed at constellation scale): name -> (unit, "<=" or ">=", aim).
AIMS = {
    "engine.ut_epochs_per_s": ("UT-ep/s", ">=", 3e6),
    "sim.end_to_end_ut_epochs_per_s": ("UT-ep/s", ">=", 1e6),
    "constellation.wall_s": ("s", "<=", 20.0),
    "constellation.peak_rss_mib": ("MiB", "<=", 1024.0),
    "constellation.noplots_wall_s": ("s", "<=", 20.0),
    "constellation.noplots_peak_rss_mib": ("MiB", "<=", 1024.0),
    # Every feature at the speed of the core (issue 44): each variant over its baseline.
    **{
        f"features.{v}_cpu_ratio": ("x", "<=", {"predictive": 3.0, "global": 1.5}.get(v, 2.0))
        for v in FEATURES
    },
    **{f"features.{v}_rss_ratio": ("x", "<=", 1.5) for v in FEATURES},
    "small.fixed_ms_per_epoch": ("ms", "<=", 0.2),
    "small.ut_epochs_per_s": ("UT-ep/s", ">=", 15e3),
    "visibility.speedup_vs_skyfield": ("x", ">=", 100.0),
    # leolink's whole process against the peer's mission loop alone, and against its whole
    # process (bench_peer: the issue's ~15 k UT-epochs/s of the peer is the latter's rate).
    "peer.ratio_peer_loop_over_leolink_process": ("x", ">=", 1.0),
    "peer.ratio_peer_process_over_leolink_process": ("x", ">=", 1.0),
    "peer.ratio_peer_loop_over_leolink_warm": ("x", ">=", 1.0),
}


def run_modules(quick, names=MODULES):
    """``{module short name: figures}`` of every module present."""
    out = {}
    for name in names:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            print(f"[{name}: not in this tree, skipped]\n")
            continue
        t0 = time.perf_counter()
        if "quick" in inspect.signature(mod.main).parameters:
            figures = mod.main(quick=quick, argv=[]) or {}
        else:  # main(argv) modules (bench_memory, bench_visibility) take --quick
            figures = mod.main(["--quick"] if quick else []) or {}
        print(f"  ({name}: {time.perf_counter() - t0:.1f} s)\n")
        out[name.removeprefix("bench_")] = figures
    return out


def flatten(results):
    return {f"{m}.{k}": v for m, figs in results.items() for k, v in figs.items()}


def print_table(flat, before=None):
    print(f"{'figure':<40} {'value':>14} {'aim':>14} {'vs aim':>8}" + (" vs before" * bool(before)))
    for name, value in flat.items():
        if not isinstance(value, int | float):  # e.g. the peer's version
            print(f"{name:<40} {value!s:>14}")
            continue
        unit, op, aim = AIMS.get(name, ("", None, None))
        ratio = "" if aim is None else f"{(value / aim if op == '>=' else aim / value):7.2f}x"
        target = "" if aim is None else f"{op} {aim:,.4g}"
        line = f"{name:<40} {value:>14,.4g} {target:>14} {ratio:>8}"
        if before and isinstance(before.get(name), (int, float)) and before[name]:
            line += f" {value / before[name]:9.2f}x"
        print(f"{line} {unit}")
    if before:
        print(
            "(vs before: this tree's figure / the other's; > 1 is faster for a rate, slower"
            " for a time)"
        )


def _module_in_process(tree, name, quick):
    """The figures of module ``name`` run in a fresh process with ``tree/src`` first on
    ``PYTHONPATH``."""
    with tempfile.TemporaryDirectory(prefix="bench_") as tmp:
        out = Path(tmp) / "figures.json"
        cmd = [sys.executable, __file__, "--only", name, "--json", str(out)]
        env = dict(os.environ, PYTHONPATH=str(Path(tree).resolve() / "src"))
        subprocess.run(cmd + ["--quick"] * quick, env=env, check=True, cwd=ROOT)
        return json.loads(out.read_text())["figures"]


def side_by_side(ref, quick, names=MODULES):
    """``(figures of this tree, figures of the checkout ref)``, module by module."""
    head, before = {}, {}
    for name in names:
        print(f"=== {name}: {ref}")
        before.update(_module_in_process(ref, name, quick))
        print(f"=== {name}: this tree")
        head.update(_module_in_process(ROOT, name, quick))
    return head, before


ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--json", type=Path, help="write the figures by name to this file")
    ap.add_argument("--compare", type=Path, help="an earlier --json run, or a checkout's folder")
    ap.add_argument("--only", nargs="+", choices=MODULES, help="these modules only")
    args = ap.parse_args(argv)
    names = tuple(args.only or MODULES)
    before = None
    if args.compare and args.compare.is_dir():
        flat, before = side_by_side(args.compare, args.quick, names)
    else:
        flat = flatten(run_modules(args.quick, names))
        before = json.loads(args.compare.read_text())["figures"] if args.compare else None
    if args.json:  # first: a figures table that fails to print loses no run
        meta = {"quick": args.quick, "python": platform.python_version(),
                "load_average_1_5_15": os.getloadavg(),
                "machine": platform.machine(), "time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                time.gmtime())}  # fmt: skip
        args.json.write_text(json.dumps({"meta": meta, "figures": flat}, indent=1) + "\n")
    print_table(flat, before)


if __name__ == "__main__":
    main()
