"""Body-fixed vs Earth-fixed beams along the paper's 120 s pass (issue 15).

The simulator (``leolink.app.run.run``) on ``configs/paper.toml`` (7 static UTs, max-SNR
beam selection) with ``satellite_array.steering = "body_fixed"`` (the paper: the beams
move with the satellite) and ``"earth_fixed"`` (each beam re-steered every epoch to the
ground point its boresight hit at the overhead instant, t = 60 s), ideal and with 3-bit
phase shifters. Writes ``steering_pass.png`` (UT 0's SNR and SINR vs time) and
``steering_pass.json`` (handover counts and SNR statistics).

Run: ``python analysis/steering_pass.py [--fast] [--out DIR]`` (``--fast``: 1 s epochs;
otherwise 0.1 s).
"""

from __future__ import annotations

import sys

import numpy as np
from _common import figure, paper_config, parse_args, report, save

from leolink.app.run import run

VARIANTS = {
    "body-fixed (paper)": [],
    "Earth-fixed": ["satellite_array.steering=earth_fixed"],
    "Earth-fixed, 3-bit phases": [
        "satellite_array.steering=earth_fixed",
        "satellite_array.phase_bits=3",
    ],
}


def _stats(trace, events):
    ut0 = trace[trace.ut_id == 0]
    beam_ho = events[events.kind == "beam_handover"]
    return {
        "ut0_beam_handovers": int((beam_ho.ut_id == 0).sum()),
        "beam_handovers_all_uts": int(len(beam_ho)),
        "ut0_snr_db_min": float(ut0.snr_db.min()),
        "ut0_snr_db_mean": float(ut0.snr_db.mean()),
        "ut0_snr_db_max": float(ut0.snr_db.max()),
        "ut0_sinr_db_mean": float(ut0.sinr_db.mean()),
        "all_uts_snr_db_mean": float(trace.snr_db.mean()),
        "all_uts_snr_db_p5": float(np.percentile(trace.snr_db, 5)),
        "all_uts_sinr_db_mean": float(trace.sinr_db.mean()),
    }


def main(argv=None):
    args = parse_args(argv, __doc__)
    epoch = "1.0" if args.fast else "0.1"
    fig, ax = figure(2, 1, figsize=(7.5, 6.0), sharex=True)
    numbers = {}
    for i, (name, over) in enumerate(VARIANTS.items()):
        res = run(paper_config([f"run.epoch_s={epoch}", *over]))
        trace, events = res.trace, res.events
        numbers[name] = _stats(trace, events)
        ut0 = trace[trace.ut_id == 0]
        style = dict(color=f"C{i}", lw=1.2, label=name)
        ax[0, 0].plot(ut0.time_s, ut0.snr_db, **style)
        ax[1, 0].plot(ut0.time_s, ut0.sinr_db, **style)
        for t in events[(events.ut_id == 0) & (events.kind == "beam_handover")].time_s:
            ax[0, 0].axvline(t, color=f"C{i}", ls=":", lw=0.8)
    ax[0, 0].set_ylabel("SNR [dB]")
    ax[1, 0].set_ylabel("SINR [dB]")
    ax[1, 0].set_xlabel("time [s] (overhead at 60 s; dotted: beam handovers)")
    ax[0, 0].set_title("UT 0 (ROI centre), paper's pass: beams moving vs re-steered", fontsize=10)
    ax[0, 0].legend(fontsize=8)
    png = save(fig, args.out, "steering_pass.png")
    return report(args.out, "steering_pass", numbers, [png.name])


if __name__ == "__main__":
    main(sys.argv[1:])
