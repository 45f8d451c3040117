"""Real run outputs for the report tests: ``leolink run`` through its CLI, plus the
geometry files that ``stats_from_dir`` reads when a folder has no ``report_stats.npz``
(``satellites.csv``, ``codebook.json``).

The run's report sink keeps the satellite states itself (``report_stats.npz``); here they
are recomputed from the resolved config with the stable ``leolink.orbit`` functions (pass
and Walker constellations), and ``tests/test_report_sink.py`` checks that both agree; the
codebook comes from ``leolink codebook CONFIG --json``.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from leolink.orbit import CentralBody, Ephemeris, pass_over, walker_delta

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "configs" / "paper.toml"
WALKER = REPO / "configs" / "examples" / "walker.toml"


def cli(*args):
    """Run ``python -m leolink.cli ARGS``; return its stdout (raises on failure)."""
    done = subprocess.run(
        [sys.executable, "-m", "leolink.cli", *map(str, args)],
        check=True,
        capture_output=True,
        text=True,
        cwd=REPO,
    )
    return done.stdout


def ephemeris(cfg):
    """The run's ephemeris from a resolved config dict (pass or Walker constellations)."""
    c, e = cfg["constellation"], cfg["earth"]
    inc = math.radians(c["inclination_deg"])
    if c["kind"] == "walker":
        el = walker_delta(
            c["n_planes"] * c["sats_per_plane"], c["n_planes"], c["phasing"], inc, c["altitude_m"]
        )
    elif c["kind"] == "pass":
        el = pass_over(
            math.radians(cfg["roi"]["center_lat_deg"]),
            math.radians(cfg["roi"]["center_lon_deg"]),
            c["pass_time_s"],
            c["altitude_m"],
            inc,
            ascending=c["ascending"],
            earth=CentralBody(e["radius_m"], e["gm_m3_s2"], e["rotation"]),
        )
    else:
        raise NotImplementedError(c["kind"])
    return Ephemeris.from_elements(
        el, earth_rotation=e["rotation"], radius_m=e["radius_m"], gm_m3_s2=e["gm_m3_s2"]
    )


def write_geometry(out_dir, config):
    """Write ``satellites.csv`` (every epoch) and ``codebook.json`` into a run folder."""
    out_dir = Path(out_dir)
    cfg = tomllib.loads((out_dir / "config.resolved.toml").read_text())
    run = json.loads((out_dir / "summary.json").read_text())["run"]
    t = run["start_s"] + run["epoch_s"] * np.arange(run["n_epochs"])
    pos, vel, _ = ephemeris(cfg)(t)  # (n_t, n_sat, 3)
    n_t, n_sat, _ = pos.shape
    table = {"time_s": np.repeat(t, n_sat), "sat_id": np.tile(np.arange(n_sat), n_t)}
    for i, axis in enumerate("xyz"):
        table[f"{axis}_m"] = pos[..., i].ravel()
        table[f"v{axis}_m_s"] = vel[..., i].ravel()
    pd.DataFrame(table).to_csv(out_dir / "satellites.csv", index=False)
    (out_dir / "codebook.json").write_text(cli("codebook", config, "--json"))


def make_run(out_dir, config=PAPER, *extra):
    """``leolink run CONFIG --out DIR`` plus the geometry files; returns the folder.

    The run's own report is off here (these tests build it from the folder's files;
    tests/test_report_sink.py checks the one a run writes)."""
    cli("run", config, "--out", out_dir, "--quiet", "--set", "output.report.enabled=false", *extra)
    write_geometry(out_dir, config)
    return Path(out_dir)
