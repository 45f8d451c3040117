"""What the report adds to a run, ``python benchmarks/bench_report_cost.py [--quick]``.

Runs ``configs/constellation.toml`` (1,000 UTs, ``--duration-s`` 120 s) with the report
off (``output.report.enabled = false``) and on (the default: statistics streamed during
the run, ``report_stats.npz``, ``footprint.gif``, the page's figures, ``report.html``),
interleaved ``--repeat`` times (the machine is shared: each pair sees the same load), and
prints the CPU time of each (the run's process and the picture jobs it forks, from
``wait4``), the CPU the report adds and its budget, issue 44's floor: 1 s plus 10 % of the
run without the report. Plots (``output.plots``) are on in both.
"""

from __future__ import annotations

import argparse
import statistics

from _common import ROOT, row, run_cli

CONFIG = ROOT / "configs" / "constellation.toml"
FIXED_S, SHARE = 1.0, 0.10  # the floor: report CPU <= 1 s + 10 % of the run's CPU


def _cpu_s(out, duration_s, report):
    sets = ["--set", f"run.duration_s={duration_s}"]
    if not report:
        sets += ["--set", "output.report.enabled=false"]
    args = ["run", str(CONFIG), "--out", str(out), "--overwrite", "--quiet", *sets]
    return run_cli(args)[2]


def main(quick=False, argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=30.0 if quick else 120.0)
    ap.add_argument("--repeat", type=int, default=1 if quick else 3)
    ap.add_argument("--out", default="/tmp/leolink_bench_report_cost")
    args = ap.parse_args(argv)
    off, on = [], []
    for _ in range(args.repeat):  # interleaved: off, on, off, on, ...
        off.append(_cpu_s(f"{args.out}/off", args.duration_s, False))
        on.append(_cpu_s(f"{args.out}/on", args.duration_s, True))
    base, with_report = statistics.median(off), statistics.median(on)
    added, budget = with_report - base, FIXED_S + SHARE * base
    print(f"report cost, constellation.toml 1,000 UTs x {args.duration_s:g} s (median of "
          f"{args.repeat}, interleaved)")  # fmt: skip
    row("CPU, report off", base, "s")
    row("CPU, report on", with_report, "s")
    row("CPU ratio on / off", with_report / base, "x")
    row("CPU the report adds", added, "s", aim=budget, better="lower")
    return {
        "off_cpu_s": base,
        "on_cpu_s": with_report,
        "ratio": with_report / base,
        "added_cpu_s": added,
        "added_per_budget": added / budget,
    }


if __name__ == "__main__":
    main()
