"""Issue 14 on the paper's pass: precoder none / ZF / MMSE vs reuse 3 and 4, and 4-beam corners.

Part 1, the simulator: ``configs/paper.toml`` (one satellite over Vigo, 120 s) with 60
static UTs dropped uniformly in the ROI (seeded), each variant a run of the same drop:
today's (no sharing: every UT at its beam's full rate), and round-robin sharing with
``link.precoder`` none / zf / zf_normalized / mmse at full reuse, and none at reuse 3
and 4 (and ZF on the colours). Numbers: mean served SINR [dB] (rows with service), mean per-UT
throughput [Mbit/s], and the mean number of UTs sharing a beam.

Part 2, the 4-beam corners at the overhead instant (t = 60 s): a UT at each point where
four beams of the 5 x 3 lattice meet (direction cosines at the mean of the four
boresights, 8 interior corners), served by the first of the four; the other 14 beams
each serve a UT at their footprint centre (the boresight's ground point); the SINR of
the corner UTs under none / zf / zf_normalized / mmse. The paper (Sec. 5): "a SINR not larger than
-4.77 dB" at these points without precoder (1 / 3 of equal beams, at high SNR).

Run: ``python analysis/beams_pass.py [--fast] [--out DIR]``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from _common import PAPER_CONFIG, figure, parse_args, report, save

from leolink.antenna.array import HybridArray
from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.engine import precoded
from leolink.geometry import direction_cosines, ray_to_ground
from leolink.io.sinks import MemorySink
from leolink.link.precoder import PRECODERS
from leolink.sim.runner import run_simulation

RR = ["scheduler.kind=round_robin"]
VARIANTS = {
    "today (no sharing)": [],
    "none, reuse 1": RR,
    "zf, reuse 1": RR + ["link.precoder=zf"],
    "zf_normalized, reuse 1": RR + ["link.precoder=zf_normalized"],
    "mmse, reuse 1": RR + ["link.precoder=mmse"],
    "none, reuse 3": RR + ["link.reuse_colors=3"],
    "none, reuse 4": RR + ["link.reuse_colors=4"],
    "zf, reuse 3": RR + ["link.precoder=zf", "link.reuse_colors=3"],
}


def drop_config(folder, n_ut=60, sets=()):
    """The paper's config with ``n_ut`` random static UTs instead of its populations."""
    text = PAPER_CONFIG.read_text()
    text = text[: text.index("[[population]]")].replace("uts = [0, 5, 6]", "uts = [0]")
    text += (
        f'[[population]]\nname = "random"\nkind = "static"\nplacement = "random"\ncount = {n_ut}\n'
    )
    path = Path(folder) / "drop.toml"
    path.write_text(text)
    return load_config(path, list(sets))


def run_variant(folder, sets, fast):
    extra = ["run.duration_s=20", "run.start_s=50"] if fast else []
    scen = build_scenario(drop_config(folder, 60, [*extra, *sets]))
    mem = MemorySink()
    run_simulation(scen, [mem])
    trace = mem.trace()
    on = trace[trace.service != "outage"]
    return {
        "mean_sinr_db": float(on.sinr_db.mean()),
        "p5_sinr_db": float(np.percentile(on.sinr_db, 5)),
        "mean_throughput_mbps": float(trace.throughput_bps.fillna(0.0).mean() / 1e6),
        "mean_n_sharing": float(on.n_sharing.mean()) if "n_sharing" in on else 1.0,
    }


def corner_sinr(folder):
    """SINR [dB] of UTs at the 8 interior 4-beam corners, per precoder (module docstring)."""
    scen = build_scenario(drop_config(folder, 1))
    eng = scen.engine
    pos, vel, _ = scen.ephemeris(np.array([60.0]))
    sat, v = pos[0, 0], vel[0, 0]
    u_b = np.asarray(eng.codebook.u_xy, float)
    ix, iy = eng.beam_ix, eng.beam_iy
    beam_at = {(int(a), int(b)): m for m, (a, b) in enumerate(zip(ix, iy, strict=True))}
    corners = [(i, j) for i in range(ix.max()) for j in range(iy.max())]
    centres = ray_to_ground(sat, v, u_b, scen.radius_m)
    out = {k: [] for k in ("none", "zf", "zf_normalized", "mmse")}
    array = HybridArray(60, 72, 5, 3)
    for i, j in corners:
        four = [beam_at[(i + a, j + b)] for a in (0, 1) for b in (0, 1)]
        u_c = u_b[four].mean(axis=0)
        ground = centres.copy()
        ground[four[0]] = ray_to_ground(sat, v, u_c[None], scen.radius_m)[0]
        snap = eng.evaluate(ground, pos[0], vel[0])
        path = snap.path_snr_lin[:, 0]
        u = direction_cosines(sat, v, ground)
        member = np.ones((1, len(ground)), bool)
        h = precoded.channel(u[None], path[None], u_b[None], np.arange(len(ground))[None],
                             eng.colors[None], member, array)  # fmt: skip
        for kind in out:
            sinr = precoded.precoded_sinr(PRECODERS.build(kind), h, member, 0.0)
            out[kind].append(float(10 * np.log10(sinr[0, four[0]])))
    return out


def main(argv=None):
    args = parse_args(argv, __doc__)
    numbers = {}
    with tempfile.TemporaryDirectory() as tmp:
        runs = {name: run_variant(tmp, sets, args.fast) for name, sets in VARIANTS.items()}
        corners = corner_sinr(tmp)
    for name, r in runs.items():
        for key, value in r.items():
            numbers[f"{name}: {key}"] = round(value, 3)
    for kind, values in corners.items():
        numbers[f"4-beam corners, {kind}: mean SINR dB"] = round(float(np.mean(values)), 3)
        numbers[f"4-beam corners, {kind}: max SINR dB"] = round(float(np.max(values)), 3)
    fig, axes = figure(1, 2, figsize=(11.0, 4.2))
    names = list(runs)
    axes[0, 0].barh(names, [runs[n]["mean_sinr_db"] for n in names], color="tab:blue")
    axes[0, 0].set_xlabel("mean served SINR [dB] (60 static UTs, paper pass)")
    axes[0, 0].invert_yaxis()
    for k, kind in enumerate(corners):
        axes[0, 1].plot(np.arange(len(corners[kind])) + 0.1 * k, corners[kind], "o", label=kind)
    axes[0, 1].axhline(-4.77, color="k", ls="--", lw=0.8, label="paper: -4.77 dB")
    axes[0, 1].set_xlabel("interior 4-beam corner")
    axes[0, 1].set_ylabel("SINR [dB]")
    axes[0, 1].legend()
    png = save(fig, args.out, "beams_pass.png")
    report(args.out, "beams_pass", numbers, [png])


if __name__ == "__main__":
    main(sys.argv[1:])
