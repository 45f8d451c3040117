"""Digital precoder study on the paper's geometry: SINR with no precoder, ZF and MMSE.

Run: ``python analysis/precoding_pass.py [--drops N] [--seed S]``.

The satellite is 1300 km overhead the ROI centre (canonical geometry: body axes = ECI
axes, velocity +x); 15 beams at O = 1.2 (``build_codebook(12, 24, 1.2, 534.1 km,
170.5 km, 1300 km)``) on the 60 x 72 array of 5 x 3 subarrays, beam m on chain m; each
drop places 60 static UTs uniformly in the 534.1 x 170.5 km ROI (ROI plane). Every beam
whose cell holds a UT is lit and serves the best UT of its cell in the slot (one UT per
beam); beams with an empty cell are dark. Link budget of the paper's Table: 15 dBW per
chain, 11.45 GHz, 250 MHz, 24.1 dBK, 0.017 dB atmosphere, 24 x 24 UPA with K = 10
(27.60 dB). The ephemeris-error rows compute the precoder from the directions the
satellite derives from a position off by the given distance (random horizontal
direction), and the SINR from the true directions.
"""

import argparse

import numpy as np

from leolink.antenna.array import HybridArray
from leolink.antenna.codebook import build_codebook
from leolink.antenna.response import chain_response
from leolink.constants import EARTH_RADIUS_M
from leolink.geometry import direction_cosines, roi_to_ground
from leolink.link.budget import fspl_db, noise_power_dbw
from leolink.link.precoder import (
    mmse_regularization,
    precode,
    precoder_matrix,
    sinr_after_precoding,
)

ALTITUDE_M, RX_M, RY_M = 1300e3, 534.1e3, 170.5e3
ARRAY = HybridArray(60, 72, 5, 3)
CODEBOOK = build_codebook(12, 24, 1.2, RX_M, RY_M, ALTITUDE_M)
SAT = np.array([0.0, 0.0, EARTH_RADIUS_M + ALTITUDE_M])
VEL = np.array([7.2e3, 0.0, 0.0])  # only its direction matters (body frame)
RX_DB = 10.0 * np.log10(24 * 24 + 1 / 10.0)
K_DB = 15.0 - 0.017 + RX_DB - float(noise_power_dbw(24.1, 250e6))


def _drops(rng, n_drop, n_ut=60):
    """Ground positions (n_drop, n_ut, 3) uniform in the ROI ellipse (ROI plane)."""
    r, t = np.sqrt(rng.uniform(0, 1, (n_drop, n_ut))), rng.uniform(0, 2 * np.pi, (n_drop, n_ut))
    return roi_to_ground(RX_M * r * np.cos(t), RY_M * r * np.sin(t), SAT, VEL)


def _channel(ground, sat_m):
    """Noise-normalized H (n_drop, n_ut, n_beam) as the satellite at sat_m computes it."""
    u = direction_cosines(sat_m, VEL, ground)
    rho_m = np.linalg.norm(ground - sat_m, axis=-1)
    path = 10.0 ** ((K_DB - fspl_db(rho_m, 11.45e9)) / 10.0)
    chain = np.arange(CODEBOOK.n_beam)
    return np.sqrt(path)[..., None] * chain_response(u, CODEBOOK.u_xy, chain, ARRAY)


def _schedule(h):
    """Row b = the best UT of beam b's cell -> (n_drop, n_beam) UT index, lit mask."""
    g = np.abs(h) ** 2
    best = np.argmax(g, axis=-1)
    n_beam = h.shape[-1]
    in_cell = best[:, :, None] == np.arange(n_beam)  # (n_drop, n_ut, n_beam)
    score = np.where(in_cell, g, -1.0)
    return np.argmax(score, axis=1), np.max(score, axis=1) > 0.0


def _take(h, ut):
    return np.take_along_axis(h, ut[..., None], axis=1)


def _stats(sinr, lit):
    s = sinr[lit]
    se = np.log2(1 + s)
    per_sat = np.nansum(np.where(lit, np.log2(1 + sinr), 0.0), axis=1)
    return 10 * np.log10(s).mean(), np.percentile(10 * np.log10(s), 5), se.mean(), per_sat.mean()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--drops", type=int, default=500)
    p.add_argument("--seed", type=int, default=20201)
    args = p.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    ground = _drops(rng, args.drops)
    ut, lit = _schedule(_channel(ground, SAT))
    h_true = _take(_channel(ground, SAT), ut)
    serving = np.broadcast_to(np.arange(CODEBOOK.n_beam), lit.shape)
    print(
        f"{args.drops} drops x 60 UTs, {CODEBOOK.n_beam} beams, lit per drop "
        f"{lit.sum(1).mean():.2f}; per scheduled UT: mean SINR, 5th pct [dB], mean SE; "
        "sum SE per satellite [bit/s/Hz]"
    )
    hdr = f"{'error':>8} {'precoder':>8} {'SINR dB':>8} {'p5 dB':>7} {'SE':>6} {'sum SE':>7}"
    print(hdr)
    for err_m in (0.0, 100.0, 1000.0, 5000.0):
        az = rng.uniform(0, 2 * np.pi, args.drops)
        offset = err_m * np.stack([np.cos(az), np.sin(az), np.zeros_like(az)], -1)
        h_est = _take(_channel(ground, SAT + offset[:, None, :]), ut)
        for kind in ("none", "zf", "mmse"):
            _, sinr = precode(h_est, kind, h_true, serving_beam=serving, ut_mask=lit, beam_mask=lit)
            m, p5, se, tot = _stats(sinr, lit)
            print(f"{err_m:8.0f} {kind:>8} {m:8.2f} {p5:7.2f} {se:6.3f} {tot:7.2f}")
    # MMSE regularization: the noise-optimal alpha of Peel et al. against a sweep.
    alpha0 = mmse_regularization(lit.sum(1), lit.sum(1))  # one UT per lit beam: 1
    print("alpha / alpha_Peel   sum SE per satellite (MMSE, known channel)")
    for scale in (0.1, 0.3, 1.0, 2.0, 3.0, 5.0, 10.0):
        f = precoder_matrix(h_true, "mmse", ut_mask=lit, beam_mask=lit, alpha=scale * alpha0)
        tot = _stats(sinr_after_precoding(h_true, f, ut_mask=lit), lit)[3]
        print(f"{scale:18.1f}   {tot:7.2f}")


if __name__ == "__main__":
    main()
