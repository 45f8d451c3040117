"""Engine benchmarks (issue: arrays/engine).

(a) closed-form beam gains vs the explicit steering-vector product on the same work;
(b) SNR and SINR for 1,000,000 ground points x 15 beams of one satellite (time, memory);
(c) engine throughput in UT-epochs/s, 1,000 UTs, one satellite, blocks of 64 epochs (the
calls the simulator makes), with the compiled kernels (the default) and numpy only. Per
UT-epoch: the pair's geometry and beam kernels, the SNR of all 15 beams and the best of
them (``Links.best_beam``, the paper's max-SNR selection: ``numpy.argmax`` of the dB SNRs;
compiled, every beam's linear SNR, the dB value of the largest only), then the serving
link's columns (gains, SNR, SINR, SE, throughput, Doppler + rate, angular speed, azimuth).

Run: ``python benchmarks/bench_engine.py [--quick] [--points N]``. Prints figures.
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
    return t_exp / t_cf


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
    return t


def _static_uts(cfg, n_ut, n_epoch):
    """``n_ut`` static UTs over the ROI and one satellite's states at ``n_epoch`` epochs."""
    from leolink.app.scenario import ephemeris_from_config

    rx, ry = cfg.roi_semi_axes_m()
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.6 * rx, 0.6 * rx, n_ut)
    y = rng.uniform(-0.6 * ry, 0.6 * ry, n_ut)
    pos, vel, acc = ephemeris_from_config(cfg)(np.linspace(0.0, 120.0, n_epoch))
    sp, sv, _ = overhead_satellite(cfg)
    return roi_to_ground(x, y, sp[0], sv[0], cfg.earth.radius_m), pos[:, 0], vel[:, 0], acc[:, 0]


def _snapshot_work(engine, ut, pos, vel, acc):
    """One ``evaluate`` + ``serve`` call per epoch (the API of the main branch)."""
    n_ut, zero, sat0 = len(ut), np.zeros_like(ut), np.zeros(len(ut), dtype=int)
    for k in range(len(pos)):
        snap = engine.evaluate(ut, pos[k : k + 1], vel[k : k + 1])
        beam = np.argmax(snap.snr_db[:, 0, :], axis=1)  # SNR of all 15 beams
        engine.serve(snap, sat0, beam, zero, zero, vel[k : k + 1], acc[k : k + 1])
    return n_ut


def _block_work(engine, ut, pos, vel, acc, block):
    """The simulator's calls: the pairs of ``block`` epochs at once (``evaluate_pairs``),
    each pair's best beam (``Links.best_beam``: the SNR of all 15 beams, the largest
    kept, the paper's max-SNR selection; on an older tree ``argmax`` of ``snr_db_bm``),
    then every serving link (``serve_pairs``). The rows' states are laid out as the
    simulator has them (UT-major within an epoch: ``np.repeat`` of the epoch's states;
    the index arrays and the static UTs' rows once per block length, as the simulator
    keeps a block's UT positions)."""
    n_ut = len(ut)
    zero = np.zeros((n_ut * block, 3))
    u, s = np.tile(np.arange(n_ut), block), np.repeat(np.arange(block), n_ut)
    pair, ut_rows = np.arange(u.size), np.tile(ut, (block, 1))
    for k0 in range(0, len(pos), block):
        n_k = min(block, len(pos) - k0)
        m = n_k * n_ut
        links = engine.evaluate_pairs(ut, pos[k0 : k0 + n_k], vel[k0 : k0 + n_k], u[:m], s[:m])
        if hasattr(links, "best_beam"):
            beam, _ = links.best_beam(engine.beam_ix, engine.beam_iy)  # no dB values
        else:
            beam = np.argmax(links.snr_db_bm(engine.beam_ix, engine.beam_iy), axis=0)
        sat_vel = np.repeat(vel[k0 : k0 + n_k], n_ut, axis=0)
        sat_acc = np.repeat(acc[k0 : k0 + n_k], n_ut, axis=0)
        engine.serve_pairs(links, pair[:m], beam, zero[:m], zero[:m], sat_vel, sat_acc,
                           ut_pos_m=ut_rows[:m])  # fmt: skip


def engine_throughput(cfg, engine, n_ut=1000, n_epoch=640, block=64):
    """UT-epochs/s of the engine on one satellite moving over ``n_ut`` static UTs:
    (the simulator's block calls, or on an older tree one call per epoch)."""
    ut, pos, vel, acc = _static_uts(cfg, n_ut, n_epoch)
    if hasattr(engine, "serve_pairs"):
        t, _ = best_of(lambda: _block_work(engine, ut, pos, vel, acc, block), repeat=3)
        how = f"blocks of {block} epochs"
    else:
        t, _ = best_of(lambda: _snapshot_work(engine, ut, pos, vel, acc), repeat=3)
        how = "one call per epoch"
    print(
        f"(c) engine: {n_ut} UTs x {engine.n_beam} beams x {n_epoch} epochs, {how} (SNR of "
        "every beam, best beam, SINR, SE, Doppler + rate, angular speed, azimuth)"
    )
    rate = n_ut * n_epoch / t
    row("UT-epochs per second", rate, "UT-ep/s", aim=3e6)
    return rate


def main(quick=False, argv=None):
    """Figures: ``closed_vs_explicit_x``, ``coverage_wall_s``, ``ut_epochs_per_s`` (the
    default path: the compiled kernels, leolink._kernels), ``numpy_ut_epochs_per_s``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=100_000 if quick else 1_000_000)
    args = ap.parse_args([] if argv is None else argv)
    cfg = load_config(PAPER)
    engine = build_engine(cfg)
    figures = {"closed_vs_explicit_x": closed_vs_explicit(engine)}
    figures["coverage_wall_s"] = million_points(cfg, engine, args.points)
    figures["ut_epochs_per_s"] = engine_throughput(cfg, engine)
    import leolink.compiled as switch

    if not hasattr(switch, "use"):  # a tree before 2026-12-05: the switch was the engine's
        try:
            from leolink.engine import jit as switch
        except ImportError:
            return figures
    use = switch.use
    switch.use = lambda n: False
    try:
        print("    numpy only (LEOLINK_JIT=0):")
        figures["numpy_ut_epochs_per_s"] = engine_throughput(cfg, engine)
    finally:
        switch.use = use
    return figures


if __name__ == "__main__":
    import sys

    main(quick="--quick" in sys.argv, argv=[a for a in sys.argv[1:] if a != "--quick"])
