"""What a 20 km (1 sigma per axis) ephemeris error costs along the paper's pass (issue 15).

``configs/paper.toml`` (7 static UTs, 1 s epochs) with ``[ephemeris_error] model = "rtn"``,
20 km 1-sigma along-track, cross-track and radial, over 10 seeds (one draw per satellite
and run), body-fixed and Earth-fixed beams. Prints the beam handovers per seed and the
:func:`leolink.io.ephemeris_sink.ephemeris_summary` of all rows (wrong-beam rate, UT
pointing error and loss, SNR loss, position error).

Run: ``python analysis/ephemeris_pass.py [--seeds N] [--sigma-m S]``.
"""

from __future__ import annotations

import argparse
import json

import pandas as pd

from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.io.ephemeris_sink import EphemerisErrorSink, ephemeris_summary
from leolink.io.sinks import MemorySink
from leolink.sim.runner import run_simulation


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--sigma-m", type=float, default=20e3)
    args = p.parse_args(argv)
    out = {}
    for steer in ("body_fixed", "earth_fixed"):
        rows, handovers = [], []
        for seed in range(1, args.seeds + 1):
            over = [f"run.seed={seed}", "ephemeris_error.model=rtn",
                    f"satellite_array.steering={steer}"]  # fmt: skip
            over += [f"ephemeris_error.rtn.{a}_m={args.sigma_m}"
                     for a in ("along_track", "cross_track", "radial")]  # fmt: skip
            scen = build_scenario(load_config("configs/paper.toml", over))
            mem, eph = MemorySink(), EphemerisErrorSink(None)
            run_simulation(scen, [mem, eph])
            rows.append(eph.table())
            handovers.append(int((mem.events().kind == "beam_handover").sum()))
        out[steer] = {"beam_handovers": handovers, **ephemeris_summary(pd.concat(rows))}
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
