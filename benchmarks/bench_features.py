"""Every feature at the speed of the core: each variant of ``configs/constellation.toml`` side
by side with the max-SNR baseline, in one run (issue 44).

Variants: the 3GPP trigger policies ``a3``, ``cho``, ``t1``, ``time_to_exit``; ``a3_measured``
(a3 behind ``[controller.measurement]``: error, period, SMTC, RSRP); ``predictive``
with a 60 s look-ahead; every population in the TR 38.811 ``urban`` environment; the report
on; UTs spread over -60..60 deg of latitude (``global``, floor 1.5). Each is a
``leolink run`` process (plots off; the report off but in the ``report``
variant), preceded by its own baseline process (max_snr, report off): the runs are
interleaved, so a change of the machine's load reaches a variant and its baseline alike.
CPU time is the child's (user + system, its own children included, as ``os.wait4`` gives
it), peak RSS its maximum resident set. One baseline run comes first and is not counted (it
fills numba's cache after an edit: ~10 s of compilation). With ``--repeat N`` each variant
runs in N such pairs and its figures are the medians of the pairs' (a ratio moves by +-0.4
between single pairs on a loaded machine). Figures: ``<variant>_cpu_ratio`` (variant over
its baseline's CPU time), ``<variant>_rss_ratio`` and the absolute ``<variant>_cpu_s``,
``<variant>_peak_rss_mib``, ``baseline_cpu_s`` (the smallest), ``baseline_peak_rss_mib``.

Run: ``python benchmarks/bench_features.py [--quick] [--duration-s S] [--uts N] [--only
a3,urban] [--repeat N]`` (default 1,000 UTs x 120 s; quick: 200 UTs x 30 s). The issue's
floors: every CPU ratio <= 2.0 (predictive <= 3.0), every RSS ratio <= 1.5. On a shared
machine compare CPU, not wall time; the load average is printed with the table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
from pathlib import Path

from _common import ROOT, run_cli

CONFIG = ROOT / "configs" / "constellation.toml"
#: UTs of the config's four populations (static, car, train, aircraft): scaled together.
COUNTS = (400, 300, 200, 100)
#: The baseline: the config's max-SNR run, without pictures.
BASE = ["output.plots.enabled=false", "output.report.enabled=false"]
#: name -> settings added to the baseline's (the last one wins).
VARIANTS = {
    "a3": ['controller.policy="a3"'],
    # a3 behind the measurement model (issue 46): error, period, SMTC, RSRP
    "a3_measured": [
        'controller.policy="a3"',
        "controller.measurement.error_db=3.0",
        "controller.measurement.period_s=1.0",
        "controller.measurement.smtc_period_s=0.5",
        "controller.measurement.smtc_duration_s=0.25",
        'controller.measurement.quantity="rsrp"',
    ],
    "cho": ['controller.policy="cho"'],
    "t1": ['controller.policy="t1"'],
    "time_to_exit": ['controller.policy="time_to_exit"'],
    "predictive": ['controller.policy="predictive"', "controller.predictive.lookahead_s=60.0"],
    "urban": [f'population.{i}.environment="urban"' for i in range(len(COUNTS))],
    "report": ["output.report.enabled=true"],
    # issue 46: satellites reassigned on the 15 s grid; the NTN timing columns
    "slotted": ['controller.policy="slotted"'],
    "timing": ["timing.enabled=true"],
    # UTs spread over -60..60 deg of latitude (uniform on the sphere) instead of the ROI:
    # the same UT-epochs, so the CPU ratio is the ratio per UT-epoch (floor 1.5).
    "global": [
        s
        for i in range(len(COUNTS))
        for s in (
            f"population.{i}.placement='random_region'",
            f"population.{i}.lat_band_deg=[-60.0, 60.0]",
        )
    ],
}
#: The issue's floors on the CPU ratio (the RSS ratio's is 1.5 for every variant).
CPU_FLOOR = {"predictive": 3.0, "global": 1.5}


def _counts(n_ut):
    """The four populations' counts for ``n_ut`` UTs in the config's proportions."""
    counts = [n_ut * c // sum(COUNTS) for c in COUNTS]
    counts[0] += n_ut - sum(counts)
    return counts


def _run(sets, duration_s, n_ut):
    """(CPU [s], peak RSS [MiB], wall [s]) of one ``leolink run`` process."""
    args = ["--set", f"run.duration_s={duration_s!r}"]
    for i, c in enumerate(_counts(n_ut)):
        args += ["--set", f"population.{i}.count={c}"]
    for s in sets:
        args += ["--set", s]
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "run")
        wall, rss, cpu = run_cli(["run", str(CONFIG), "--out", out, "--quiet", *args])
    return cpu, rss, wall


def main(quick=False, argv=None):
    """Figures by name (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration-s", type=float, default=30.0 if quick else 120.0)
    ap.add_argument("--uts", type=int, default=200 if quick else 1000)
    ap.add_argument("--only", default="", help="comma-separated variants (default: all)")
    ap.add_argument("--repeat", type=int, default=1, help="pairs per variant (medians)")
    args = ap.parse_args([] if argv is None else argv)
    names = [n for n in args.only.split(",") if n] or list(VARIANTS)
    print(f"features: {CONFIG.name}, {args.uts:,} UTs x {args.duration_s:g} s, "
          f"load average {os.getloadavg()[0]:.1f}")  # fmt: skip
    _run(BASE, args.duration_s, args.uts)  # warm-up: numba's cache (not counted)
    figures, base_cpu, base_rss, rows = {}, [], [], []
    for name in names:
        pairs = [_pair(name, args) for _ in range(max(1, args.repeat))]
        b_cpu, cpu, b_rss, rss = (statistics.median(p[i] for p in pairs) for i in range(4))
        base_cpu.append(b_cpu)
        base_rss.append(b_rss)
        figures[f"{name}_cpu_s"], figures[f"{name}_peak_rss_mib"] = cpu, rss
        figures[f"{name}_cpu_ratio"] = statistics.median(p[1] / p[0] for p in pairs)
        figures[f"{name}_rss_ratio"] = statistics.median(p[3] / p[2] for p in pairs)
        rows.append((name, b_cpu, cpu, b_rss, rss, figures[f"{name}_cpu_ratio"],
                     figures[f"{name}_rss_ratio"]))  # fmt: skip
    figures["baseline_cpu_s"] = min(base_cpu)
    figures["baseline_peak_rss_mib"] = max(base_rss)
    _table(rows)
    print(f"  (load average after: {os.getloadavg()[0]:.1f})")
    return figures


def _pair(name, args):
    """(baseline CPU [s], variant CPU [s], baseline RSS [MiB], variant RSS [MiB]) of one
    baseline process and then one of the variant."""
    b_cpu, b_rss, _ = _run(BASE, args.duration_s, args.uts)
    cpu, rss, _ = _run(BASE + VARIANTS[name], args.duration_s, args.uts)
    return b_cpu, cpu, b_rss, rss


def _table(rows):
    head = ("variant", "base CPU s", "CPU s", "CPU ratio", "floor", "base MiB", "MiB", "RSS ratio")
    print("  " + " ".join(f"{h:>12}" for h in head))
    for name, b_cpu, cpu, b_rss, rss, cpu_ratio, rss_ratio in rows:
        floor = CPU_FLOOR.get(name, 2.0)
        flag = "" if cpu_ratio <= floor and rss_ratio <= 1.5 else "  NOT met"
        cells = (name, f"{b_cpu:.2f}", f"{cpu:.2f}", f"{cpu_ratio:.2f}x", f"<= {floor:g}x",
                 f"{b_rss:.0f}", f"{rss:.0f}", f"{rss_ratio:.2f}x")  # fmt: skip
        print("  " + " ".join(f"{c:>12}" for c in cells) + flag)


if __name__ == "__main__":
    import sys

    main(quick="--quick" in sys.argv, argv=[a for a in sys.argv[1:] if a != "--quick"])
