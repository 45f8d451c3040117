"""Simulator benchmark (issue: the simulator).

1,000 UTs (half static, half moving at car to aircraft speeds, spread over the ROI) x
3,600 epochs (the paper's 120 s pass at 1/30 s), one satellite, 15 beams:
UT-epochs/s of the engine alone, end to end with the Parquet trace, and peak memory.

Run: ``python benchmarks/bench_sim.py [--uts N] [--epochs N]``. Prints figures only.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import PAPER, peak_rss_mib, row

from leolink.app.run import run
from leolink.config import load_config


def scenario(n_ut, n_epoch):
    half = n_ut // 2
    over = [
        "output.plots.enabled=false",
        'output.trace.formats=["parquet"]',
        f"run.epoch_s={120.0 / n_epoch!r}",
        "run.duration_s=120.0",
        "population.0.count=1",
        f"population.1.count={half - 1}",
        'population.1.placement="random"',
        f"population.2.count={n_ut - half - 1}",
        'population.2.placement="random"',
        'population.2.heading_deg="random"',
        "population.2.speed_m_s=100.0",
        "population.3.count=1",
    ]
    cfg = load_config(PAPER, over)
    pops = list(cfg.population)
    pops[1] = pops[1].model_copy(update={"x_m": [], "y_m": []})
    pops[2] = pops[2].model_copy(update={"x_m": [], "y_m": []})
    return cfg.model_copy(update={"population": pops})


def engine_alone(cfg):
    """The engine calls of the run, without SimPy, controller or recorder."""
    from leolink.app.scenario import build_scenario
    from leolink.sim.mobility import concat_states

    scen = build_scenario(cfg)
    pops = scen.populations
    n_epoch = int(round(cfg.run.duration_s / cfg.run.epoch_s))
    times = cfg.run.start_s + np.arange(n_epoch) * cfg.run.epoch_s
    pos, vel, acc = scen.ephemeris(times)
    ut = concat_states([p.state(0.0) for _, p in pops])
    n_ut = ut.n_ut
    sat0 = np.zeros(n_ut, dtype=int)
    eng = scen.engine
    t0 = time.perf_counter()
    for k in range(n_epoch):
        snap = eng.evaluate(ut.pos_m, pos[k], vel[k])
        beam = np.argmax(snap.snr_lin_bm[:, 0, :], axis=0)
        eng.serve(snap, sat0, beam, ut.vel_m_s, ut.acc_m_s2, vel[k], acc[k])
    return n_ut * n_epoch / (time.perf_counter() - t0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--uts", type=int, default=1000)
    ap.add_argument("--epochs", type=int, default=3600)
    args = ap.parse_args(argv)
    cfg = scenario(args.uts, args.epochs)
    n = args.uts * args.epochs
    print(
        f"simulator: {args.uts} UTs x {args.epochs} epochs = {n / 1e6:.2f} M UT-epochs, "
        "1 satellite, 15 beams"
    )
    row("engine alone", engine_alone(cfg), "UT-ep/s", aim=1e6)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        result = run(cfg, out_dir=Path(tmp))
        dt = time.perf_counter() - t0
        size = (Path(tmp) / "trace.parquet").stat().st_size / 2**20
    row("end to end with trace.parquet", n / dt, "UT-ep/s", aim=2e5)
    row("wall time end to end", dt, "s")
    row("trace.parquet size", size, "MiB")
    row("peak resident memory (process)", peak_rss_mib(), "MiB", aim=1024, better="lower")
    o = result.summary["overall"]
    print(
        f"  served: outage fraction {o['outage_fraction']:.4f}, "
        f"{o['handovers']['beam_handover']} beam handovers"
    )


if __name__ == "__main__":
    main()
