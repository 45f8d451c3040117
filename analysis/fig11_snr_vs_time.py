"""Fig. 11: SNR of a static UT at the ROI centre during the paper's 120 s pass.

(a) satellite positions at several times and the beam each selects for the UT, in the
ROI plane of the overhead instant; (b) SNR vs time with max-SNR beam selection (the
simulator, ``leolink.sim.runner.run`` on ``configs/paper.toml``), with the SNR of every
beam underneath. Paper (Sec. 5): the UT stays in one beam for "around 30 seconds".

Closed-form dwell: the UT is on the ground track, so its Earth-central angle from the
sub-satellite point changes at the orbital rate ``w = v / (R + h)``; it leaves a
central-row beam where two neighbouring beams have equal gain, at ``u_x = (2k+1) / (O N)``,
the central angle of that ray is ``gamma(u) = asin((R+h) u / R) - asin(u)``, so the dwell
in beam k is ``(gamma(u_{k+1/2}) - gamma(u_{k-1/2})) / w``.

Run: ``python analysis/fig11_snr_vs_time.py [--fast] [--out DIR]``.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from _common import figure, paper_config, parse_args, report, roi_outline, save

from leolink.app.run import run
from leolink.app.scenario import build_scenario
from leolink.geometry import geodetic_to_ecef, ground_to_roi, ray_to_ground
from leolink.orbit import orbital_speed_m_s

SNAPSHOT_TIMES_S = (0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0)
PAPER_DWELL_S = 30.0


def closed_form_dwells_s(cfg, codebook):
    """Dwell [s] of a ground-track UT in each central-row beam, k = -2..2 (closed form)."""
    radius, h = cfg.earth.radius_m, cfg.constellation.altitude_m
    w = orbital_speed_m_s(h, radius, cfg.earth.gm_m3_s2) / (radius + h)
    ux = np.unique(np.round(codebook.u_xy[:, 0], 12))
    step = 2.0 / (codebook.oversampling * codebook.n_sub_x)
    inner = np.concatenate([ux[:-1] + 0.5 * step, [ux[-1] + 0.5 * step]])[:-1]  # crossovers
    gamma = np.arcsin((radius + h) / radius * inner) - np.arcsin(inner)
    return np.diff(gamma) / w  # beams between two crossovers (the outer ones are open)


def all_beam_snr_db(scen, cfg, times_s):
    """SNR [dB] of every beam at the ROI centre, (n_time, n_beam), satellites as a time axis."""
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    ut = geodetic_to_ecef(lat, lon, 0.0, cfg.earth.radius_m)[None, :]
    pos, vel, _ = scen.ephemeris(times_s)
    snap = scen.engine.evaluate(ut, pos[:, 0], vel[:, 0])
    return snap.snr_db[0], pos[:, 0], vel[:, 0]


def snapshot_panel(ax, scen, cfg, trace0):
    """Sub-satellite points and selected-beam boresights in the overhead ROI frame."""
    t_pass = cfg.constellation.pass_time_s
    p0, v0, _ = scen.ephemeris(t_pass)
    radius = cfg.earth.radius_m
    t_trace = trace0["time_s"].to_numpy()
    nearest = np.argmin(np.abs(t_trace[:, None] - np.array(SNAPSHOT_TIMES_S)[None, :]), axis=0)
    times = t_trace[nearest]
    pos, vel, _ = scen.ephemeris(times)
    beams = trace0["beam_id"].to_numpy().astype(int)[nearest]
    boresight = ray_to_ground(pos[:, 0], vel[:, 0], scen.engine.codebook.u_xy[beams], radius)
    bx, by = ground_to_roi(boresight, p0[0, 0], v0[0, 0], radius)
    sx, sy = ground_to_roi(pos[:, 0], p0[0, 0], v0[0, 0], radius)
    rx, ry = cfg.roi_semi_axes_m()
    roi_outline(ax, rx, ry, label="ROI at t = 60 s")
    colours = [f"C{i}" for i in range(len(times))]
    for i, t in enumerate(times):
        ax.plot([sx[i] * 1e-3, bx[i] * 1e-3], [sy[i] * 1e-3, by[i] * 1e-3], color=colours[i], lw=1)
        ax.plot(sx[i] * 1e-3, sy[i] * 1e-3, "^", color=colours[i], ms=8,
                label=f"t = {t:.0f} s, beam {beams[i]}")  # fmt: skip
        ax.plot(bx[i] * 1e-3, by[i] * 1e-3, "o", color=colours[i], ms=5)
    ax.plot(0, 0, "k*", ms=12, label="UT")
    ax.set_aspect("equal")
    ax.set_xlabel("x, along-track [km] (triangle: sub-satellite point)")
    ax.set_ylabel("y [km]")
    ax.set_title("(a) satellite positions and selected beams (dot: boresight)", fontsize=10)
    ax.legend(fontsize=7, ncol=2, loc="lower right")


def main(argv=None):
    args = parse_args(argv, __doc__)
    epoch_s = 1.0 if args.fast else 0.1
    cfg = paper_config(["output.plots.enabled=false", f"run.epoch_s={epoch_s}"])
    scen = build_scenario(cfg)
    result = run(cfg)
    trace0 = result.trace[result.trace["ut_id"] == 0].sort_values("time_s")
    events0 = result.events[result.events["ut_id"] == 0]
    dwell = result.summary["per_ut"][0]["dwell"]
    snr_all, _, _ = all_beam_snr_db(scen, cfg, trace0["time_s"].to_numpy())

    fig, axes = figure(2, 1, figsize=(8.0, 8.0))
    snapshot_panel(axes[0, 0], scen, cfg, trace0)
    ax = axes[1, 0]
    ax.plot(trace0["time_s"], snr_all, color="lightgrey", lw=0.8)
    ax.plot(trace0["time_s"], trace0["snr_db"], color="tab:blue", lw=2, label="max-SNR beam")
    for t in events0["time_s"]:
        ax.axvline(t, color="tab:purple", ls=":", lw=1)
    ax.set_ylim(np.nanmin(trace0["snr_db"]) - 6, np.nanmax(trace0["snr_db"]) + 1)
    ax.set_xlabel("time [s] (satellite overhead at 60 s; dotted: beam handovers)")
    ax.set_ylabel("SNR [dB]")
    ax.set_title("(b) SNR of the UT at the ROI centre (grey: every beam)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    pngs = [save(fig, args.out, "fig11_snr_vs_time.png")]

    gap_db = np.nanmax(snr_all, axis=-1) - trace0["snr_db"].to_numpy()
    numbers = {
        "epoch_s": epoch_s,
        "n_beam_handovers": int(len(events0)),
        "handover_times_s": events0["time_s"].to_numpy(),
        "dwell_complete_s": dwell["complete_s"],
        "dwell_mean_s": dwell["mean_s"],
        "paper_dwell_s": PAPER_DWELL_S,
        "dwell_closed_form_s": closed_form_dwells_s(cfg, scen.engine.codebook),
        "snr_db_max": float(trace0["snr_db"].max()),
        "snr_db_min": float(trace0["snr_db"].min()),
        "snr_db_swing": float(trace0["snr_db"].max() - trace0["snr_db"].min()),
        "max_gap_served_vs_best_beam_db": float(np.nanmax(np.abs(gap_db))),
    }
    report(args.out, "fig11_snr_vs_time", numbers, pngs)
    return numbers


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
