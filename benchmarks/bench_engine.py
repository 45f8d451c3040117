"""Engine benchmarks (issue: arrays/engine).

(a) closed-form beam gains vs the explicit steering-vector product on the same work;
(b) SNR and SINR for 1,000,000 ground points x 15 beams of one satellite (time, memory);
(c) engine throughput in UT-epochs/s: SNR over 15 beams, SINR, Doppler, angular speed.

Run: ``python benchmarks/bench_engine.py [--points N]``. Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse

import numpy as np
from _common import PAPER, best_of, peak_rss_mib, row

from leolink.antenna.array import explicit_gain
from leolink.app.scenario import build_engine, overhead_satellite
from leolink.config import load_config
from leolink.coverage import evaluate_points
from leolink.geometry import roi_to_ground


def closed_vs_explicit(engine, n_dir=2000):
    cb = engine.codebook
    rng = np.random.default_rng(1)
    u = rng.uniform(-0.4, 0.4, (n_dir, 2))
    # Explicit: a 12 x 24 subarray's steering vectors against the 15 DFT beam weights.
    from leolink.antenna.array import steering_vector

    weights = steering_vector(cb.u_xy, cb.n_sub_x, cb.n_sub_y).T  # (n_el, n_beam)
    t_exp, g_exp = best_of(lambda: explicit_gain(u, weights, cb.n_sub_x, cb.n_sub_y))
    t_cf, g_cf = best_of(lambda: cb.gain_lin(u))
    err = np.max(np.abs(g_cf - g_exp) / np.max(g_exp))
    print(
        f"(a) beam gains, {n_dir} directions x {cb.n_beam} beams ({cb.n_sub_x}x{cb.n_sub_y} "
        "subarrays)"
    )
    row("explicit steering-vector product", n_dir / t_exp, "dir/s")
    row("closed form (Dirichlet kernels)", n_dir / t_cf, "dir/s")
    row("speed ratio closed/explicit", t_exp / t_cf, "x", aim=20)
    row("max |difference| / peak", err, "", aim=1e-9, better="lower")


def million_points(cfg, engine, n_points):
    rx, ry = cfg.roi_semi_axes_m()
    rng = np.random.default_rng(2)
    x = rng.uniform(-1.1 * rx, 1.1 * rx, n_points)
    y = rng.uniform(-1.1 * ry, 1.1 * ry, n_points)
    sp, sv, sa = overhead_satellite(cfg)
    ground = roi_to_ground(x, y, sp[0], sv[0], cfg.earth.radius_m)
    t, cols = best_of(lambda: evaluate_points(engine, ground, sp, sv, sa), repeat=2)
    print(
        f"(b) coverage: {n_points:,} ground points x {engine.n_beam} beams, one satellite "
        "(best beam, SNR, SINR, SE, Doppler, angular speed)"
    )
    row("wall time", t, "s", aim=1.0, better="lower")
    row("points x beams per second", n_points * engine.n_beam / t / 1e6, "M/s")
    row("peak resident memory (process)", peak_rss_mib(), "MiB", aim=2048, better="lower")
    return cols


def engine_throughput(cfg, engine, n_ut=1000, n_epoch=300):
    """evaluate + serve per epoch on one satellite moving over n_ut static UTs."""
    from leolink.app.scenario import ephemeris_from_config

    rx, ry = cfg.roi_semi_axes_m()
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.6 * rx, 0.6 * rx, n_ut)
    y = rng.uniform(-0.6 * ry, 0.6 * ry, n_ut)
    eph = ephemeris_from_config(cfg)
    times = np.linspace(0.0, 120.0, n_epoch)
    pos, vel, acc = eph(times)
    sp, sv, _ = overhead_satellite(cfg)
    ut = roi_to_ground(x, y, sp[0], sv[0], cfg.earth.radius_m)
    zero = np.zeros_like(ut)
    sat0 = np.zeros(n_ut, dtype=int)

    def work():
        for k in range(n_epoch):
            snap = engine.evaluate(ut, pos[k], vel[k])
            beam = np.argmax(snap.snr_lin_bm[:, 0, :], axis=0)  # SNR of all 15 beams
            engine.serve(snap, sat0, beam, zero, zero, vel[k], acc[k])

    t, _ = best_of(work, repeat=2)
    print(
        f"(c) engine per epoch: {n_ut} UTs x {engine.n_beam} beams x {n_epoch} epochs "
        "(SNR all beams, best beam, SINR, SE, Doppler + rate, angular speed)"
    )
    row("UT-epochs per second", n_ut * n_epoch / t, "UT-ep/s", aim=3e6)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1_000_000)
    args = ap.parse_args(argv)
    cfg = load_config(PAPER)
    engine = build_engine(cfg)
    closed_vs_explicit(engine)
    million_points(cfg, engine, args.points)
    engine_throughput(cfg, engine)


if __name__ == "__main__":
    main()
