"""``leolink validate`` with ``atmosphere.model = "itu_p676"`` (issue 49 item 7).

The process as a user starts it (wall, CPU, peak RSS; the paper's config otherwise
unchanged) beside the same with the fixed atmosphere, and, in process, the P.676 table's
ray trace (``link.atmosphere.p676_ray_trace_db``, every elevation at once) beside itur's
own exact path (one elevation at a time: what the table cost before) on the table's grid.

Run: ``python benchmarks/bench_atmosphere.py [--quick]``.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
from _common import PAPER, best_of, row, run_cli

#: The grid the itu_p676 table is built on (link.atmosphere._TABLE_STEP_DEG).
GRID_DEG = np.arange(0.0, 90.0 + 1e-9, 2.0)


def _processes(repeat):
    """Best of ``repeat`` validate processes: {model: (wall s, peak MiB, CPU s)}."""
    out = {}
    for model in ("fixed", "itu_p676"):
        args = ["validate", str(PAPER), "--set", f"atmosphere.model={model!r}"]
        out[model] = min((run_cli(args) for _ in range(repeat)), key=lambda r: r[2])
    return out


def main(quick=False, argv=None):
    """Figures: ``p676_validate_cpu_s``, ``p676_validate_wall_s``, ``p676_validate_rss_mib``,
    ``fixed_validate_cpu_s``, ``ray_trace_s``, ``itur_exact_s``, ``speedup_x``."""
    from itur.models import itu676

    from leolink.link.atmosphere import p676_ray_trace_db

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1 if quick else 3)
    args = ap.parse_args([] if argv is None else argv)
    procs = _processes(args.repeat)
    ours_s, _ = best_of(lambda: p676_ray_trace_db(GRID_DEG, 20e9, 7.5), args.repeat)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        itur_s, _ = best_of(
            lambda: itu676.gaseous_attenuation_slant_path(
                20.0, GRID_DEG, 7.5, 1013.25, 288.15, mode="exact"
            ),
            1,
        )
    figures = {
        "p676_validate_cpu_s": procs["itu_p676"][2],
        "p676_validate_wall_s": procs["itu_p676"][0],
        "p676_validate_rss_mib": procs["itu_p676"][1],
        "fixed_validate_cpu_s": procs["fixed"][2],
        "ray_trace_s": ours_s,
        "itur_exact_s": itur_s,
        "speedup_x": itur_s / ours_s,
    }
    print("validate with atmosphere.model = 'itu_p676' (the paper's config)")
    row("p676_validate_cpu_s", figures["p676_validate_cpu_s"], "s", 5.0, better="lower")
    row("p676_validate_wall_s", figures["p676_validate_wall_s"], "s")
    row("p676_validate_rss_mib", figures["p676_validate_rss_mib"], "MiB")
    row("fixed_validate_cpu_s", figures["fixed_validate_cpu_s"], "s")
    row("ray_trace_s (46 elevations at once)", ours_s, "s")
    row("itur_exact_s (one elevation at a time)", itur_s, "s")
    row("speedup_x", figures["speedup_x"], "x", 10.0)
    return figures


if __name__ == "__main__":
    main()
