"""The paper's SNR / SINR trade-off in the oversampling factor O, extended past O = 1.28.

Sec. 3.2 of the paper: a larger O shrinks the beams (less straddling loss, higher SNR)
and packs them closer (more inter-beam interference, lower SINR); with 15 RF chains the
paper stops where the codebook holds 15 beams. With active beams (issue 14) a codebook
may hold more beams than chains: each epoch the 15 beams whose cells hold the most UTs
are lit (``satellite_array.active_beams = "demand"``, a UT whose best beam is dark is
served by its best lit beam), and the digital precoder can remove what the beams' overlap
adds.

For each O: the paper's pass (``configs/paper.toml``) with 60 static UTs dropped in the
ROI (the seeded drop of ``beams_pass.py``), ``allow_holes`` on (O < 1.1 leaves holes);
``active_beams = "all"`` while the codebook fits the chains, ``"demand"`` beyond. Curves:
mean served SNR and SINR without precoder (every UT at its beam's full rate, the paper's
model), and the SINR with round-robin sharing and ZF / normalized ZF / MMSE across the
lit beams.

Run: ``python analysis/oversampling_active.py [--fast] [--out DIR]``; writes
``oversampling_active.png`` (copied to ``docs/img/`` for the docs) and its JSON.
"""

from __future__ import annotations

import sys
import tempfile

import numpy as np
from _common import figure, parse_args, report, save
from beams_pass import drop_config

from leolink.app.codebook import codebook_from_config
from leolink.app.scenario import build_scenario
from leolink.io.sinks import MemorySink
from leolink.sim.runner import run_simulation

O_VALUES = (1.0, 1.1, 1.2, 1.28, 1.4, 1.6, 1.8, 2.0, 2.4)
O_FAST = (1.2, 1.6, 2.0)
N_RF = 15


def _run(folder, sets):
    scen = build_scenario(drop_config(folder, 60, sets))
    mem = MemorySink()
    run_simulation(scen, [mem])
    trace = mem.trace()
    on = trace[trace.service != "outage"]
    return float(on.snr_db.mean()), float(on.sinr_db.mean()), float(len(on) / len(trace))


def study(folder, o_values, fast):
    rows = []
    span = ["run.duration_s=20", "run.start_s=50"] if fast else []
    for o in o_values:
        base = [*span, f"satellite_array.oversampling={o}", "satellite_array.allow_holes=true"]
        probe = drop_config(folder, 1, [*base, "satellite_array.active_beams=demand"])
        n_beam = codebook_from_config(probe).n_beam
        sel = "all" if n_beam <= N_RF else "demand"
        base.append(f"satellite_array.active_beams={sel}")
        snr, sinr, served = _run(folder, base)
        rr = [*base, "scheduler.kind=round_robin"]
        _, zf, _ = _run(folder, [*rr, "link.precoder=zf"])
        _, zfn, _ = _run(folder, [*rr, "link.precoder=zf_normalized"])
        _, mmse, _ = _run(folder, [*rr, "link.precoder=mmse"])
        rows.append(dict(o=o, n_beam=n_beam, selector=sel, snr_db=snr, sinr_db=sinr,
                         sinr_zf_db=zf, sinr_zfn_db=zfn, sinr_mmse_db=mmse,
                         served=served))  # fmt: skip
        print(f"O = {o:5.2f}: {n_beam:3d} beams ({sel}), SNR {snr:6.2f}, SINR {sinr:6.2f}, "
              f"ZF {zf:6.2f}, ZF-n {zfn:6.2f}, MMSE {mmse:6.2f} dB, "
              f"served {served:.3f}")  # fmt: skip
    return rows


def main(argv=None):
    args = parse_args(argv, __doc__)
    with tempfile.TemporaryDirectory() as tmp:
        rows = study(tmp, O_FAST if args.fast else O_VALUES, args.fast)
    o = np.array([r["o"] for r in rows])
    fig, axes = figure(1, 1, figsize=(7.5, 4.8))
    ax = axes[0, 0]
    for key, label in (("snr_db", "SNR"), ("sinr_db", "SINR, no precoder"),
                       ("sinr_zf_db", "SINR, ZF"), ("sinr_zfn_db", "SINR, ZF normalized"),
                       ("sinr_mmse_db", "SINR, MMSE")):  # fmt: skip
        ax.plot(o, [r[key] for r in rows], "o-", label=label)
    limit = max((r["o"] for r in rows if r["n_beam"] <= N_RF), default=o[0])
    ax.axvline(limit, color="k", ls="--", lw=0.8)
    ax.text(limit, ax.get_ylim()[0], f"  {N_RF} beams = chains", va="bottom", fontsize=8)
    for r in rows:
        ax.annotate(str(r["n_beam"]), (r["o"], r["snr_db"]), textcoords="offset points",
                    xytext=(0, 6), ha="center", fontsize=7)  # fmt: skip
    ax.set_xlabel("oversampling factor O (labels: beams in the codebook)")
    ax.set_ylabel("mean over served UTs [dB]")
    ax.set_title("60 static UTs, paper pass; demand-lit 15 of the beams beyond")
    ax.legend(fontsize=8)
    png = save(fig, args.out, "oversampling_active.png")
    numbers = {f"O={r['o']}: {k}": (round(v, 3) if isinstance(v, float) else v)
               for r in rows for k, v in r.items() if k != "o"}  # fmt: skip
    report(args.out, "oversampling_active", numbers, [png])


if __name__ == "__main__":
    main(sys.argv[1:])
