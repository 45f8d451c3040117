"""Small runs against a peer: leolink vs opensatcom 0.7's mission loop, 10 UTs x 600 s.

The workload: one LEO satellite pass (the ISS TLE of ``configs/examples/tle.toml``,
centred in the run), 10 static UTs, 600 s at 1 s epochs: 6,000 UT-epochs.

- leolink: ``python -m leolink.cli run`` on that config, process start included, the
  default outputs without plots and report (``trace.csv``, ``events.csv``/``.parquet``,
  ``summary.json``, ``run.json``): the peer's loop draws no figure either.
- opensatcom (if installed in another environment, never this project's: set
  ``LEOLINK_PEER_PYTHON`` to its interpreter, default ``/tmp/peer-venv/bin/python``): its
  mission loop per UT as ``opensatcom mission`` runs it (``SGP4TrajectoryProvider
  .compute_pass`` then ``SimpleWorldSim.run``, DVB-S2 ACM modem) for the same TLE, start
  time and UT positions; the loop alone is timed in-process, and the whole process.

``leolink_warm_s``: ``leolink.run`` of the same config in a warm process (imports and
compiled loops loaded by a first run), and ``ratio_peer_loop_over_leolink_warm`` (aim >= 1).
Two more figures have an aim (>= 1): ``ratio_peer_loop_over_leolink_process`` (leolink's whole
process faster than the peer's loop alone, the issue's words; the interpreter with numpy
imported alone takes about as long as that loop), and
``ratio_peer_process_over_leolink_process`` (whole process against whole process; the
issue's "~15 k UT-epochs/s" of the peer is its whole process's rate here). Run both from
a virtual environment (as the peer's), not an interpreter whose site-packages load more
at start. Skips cleanly, with a message, when the peer is not installed. The driver below
is ours; none of the peer's code is copied.

Run: ``python benchmarks/bench_peer.py [--repeat N] [--quick]`` (quick: 1 repeat).
Prints figures only.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import ROOT, row

PEER_PYTHON = os.environ.get("LEOLINK_PEER_PYTHON", "/tmp/peer-venv/bin/python")
TLE_CONFIG = ROOT / "configs" / "examples" / "tle.toml"
N_UT, DURATION_S, EPOCH_S = 10, 600.0, 1.0
# UT offsets in the ROI frame [m]: the centre UT of tle.toml, then these nine.
X_M = [0.0, 100e3, -100e3, 200e3, -200e3, 0.0, 0.0, 50e3, -50e3]
Y_M = [100e3, 0.0, 0.0, 50e3, -50e3, 150e3, -150e3, -20e3, 20e3]

PEER_DRIVER = r"""
import dataclasses, json, sys, time
t_start = time.perf_counter()
from datetime import datetime
from opensatcom.cli.builders import build_link_inputs_from_config
from opensatcom.core.models import OpsPolicy, PropagationConditions
from opensatcom.geometry.sgp4_provider import SGP4TrajectoryProvider
from opensatcom.io.config_loader import ProjectConfig
from opensatcom.world.providers import StaticEnvironmentProvider
from opensatcom.world.sim import SimpleWorldSim
spec = json.loads(sys.argv[1])
t_imported = time.perf_counter()
link = build_link_inputs_from_config(ProjectConfig.model_validate(spec["config"]))
ops = OpsPolicy(min_elevation_deg=spec["min_elevation_deg"], max_scan_deg=60.0)
env = StaticEnvironmentProvider(PropagationConditions())
sim = SimpleWorldSim()
epoch = datetime.fromisoformat(spec["start_utc"])
t0, c0 = time.perf_counter(), time.process_time()
served = 0
for lat, lon, alt in spec["sites"]:
    ut = dataclasses.replace(link.rx_terminal, lat_deg=lat, lon_deg=lon, alt_m=alt)
    traj, doppler = SGP4TrajectoryProvider(*spec["tle"], ut, epoch=epoch).compute_pass(
        0.0, spec["duration_s"], spec["epoch_s"], f_hz=spec["freq_hz"])
    out = sim.run(dataclasses.replace(link, rx_terminal=ut), traj, ops, env, doppler_hz=doppler)
    served += int((~out.outages_mask).sum())
loop_s, loop_cpu_s = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps({"loop_s": loop_s, "loop_cpu_s": loop_cpu_s, "import_s": t_imported - t_start,
                  "n_steps": len(traj.pass_data.times_s), "served": served}))
"""


def leolink_config(tmp):
    """The workload as a leolink config file (absolute TLE path), and the UT sites."""
    from leolink.app.scenario import build_scenario
    from leolink.config import dump_toml, load_config

    half = DURATION_S / 2.0
    cfg = load_config(
        TLE_CONFIG,
        [
            f"run.start_s={60.0 - half!r}",  # the pass is overhead at t = 60 s
            f"run.duration_s={DURATION_S!r}",
            f"run.epoch_s={EPOCH_S!r}",
            f"population.1.x_m={X_M!r}",
            f"population.1.y_m={Y_M!r}",
            "output.plots.enabled=false",
            "output.report.enabled=false",
            f'constellation.tle_file="{(TLE_CONFIG.parent / "tles" / "iss.tle").as_posix()}"',
        ],
    )
    path = Path(tmp) / "ut10.toml"
    path.write_text(dump_toml(cfg))
    scen = build_scenario(cfg)
    states = [p.state(float(scen.times_s[0])) for _, p in scen.populations]
    lat = np.degrees(np.concatenate([s.lat_rad for s in states]))
    lon = np.degrees(np.concatenate([s.lon_rad for s in states]))
    alt = np.concatenate([s.alt_m for s in states])
    assert lat.size == N_UT
    return cfg, path, list(zip(lat.tolist(), lon.tolist(), alt.tolist(), strict=True))


def peer_spec(cfg, sites):
    """The peer's config: the same carrier, bandwidth, power, noise, gains and mask."""
    from datetime import datetime, timedelta

    from leolink.io.tle import read_tle_file

    start = datetime.fromisoformat(cfg.run.start_utc) + timedelta(seconds=cfg.run.start_s)
    (_, l1, l2), *_ = read_tle_file(cfg.constellation.tle_file)
    project = {
        "project": {"name": "leolink_peer", "output_dir": tempfile.gettempdir()},
        "scenario": {
            "name": "ku_downlink", "direction": "downlink", "freq_hz": cfg.link.freq_hz,
            "bandwidth_hz": cfg.link.bandwidth_hz, "polarization": "RHCP",
            "required_metric": "ebn0_db", "required_value": 0.0,
        },
        "terminals": {
            "tx": {"name": "sat", "lat_deg": 0.0, "lon_deg": 0.0, "alt_m": 416e3},
            "rx": {"name": "ut", "lat_deg": sites[0][0], "lon_deg": sites[0][1],
                   "alt_m": 0.0, "system_noise_temp_k": 10 ** (cfg.link.noise_temp_dbk / 10)},
        },
        "antenna": {  # the paper's peak gains: 60 x 72 UPA / 12 x 10 subarray, 24 x 24 UPA
            "tx": {"model": "parametric", "parametric": {"gain_dbi": 15.6}},
            "rx": {"model": "parametric", "parametric": {"gain_dbi": 27.6}},
        },
        "rf_chain": {"tx_power_w": 10 ** (cfg.link.ptx_dbw / 10), "tx_losses_db": 0.0,
                     "rx_noise_temp_k": 10 ** (cfg.link.noise_temp_dbk / 10)},
        "propagation": {"model": "composite", "components": [{"type": "fspl"}]},
        "modem": {"enabled": True},
    }  # fmt: skip
    return {
        "config": project,
        "tle": [l1, l2],
        "start_utc": start.isoformat(),
        "sites": sites,
        "duration_s": DURATION_S,
        "epoch_s": EPOCH_S,
        "freq_hz": cfg.link.freq_hz,
        "min_elevation_deg": cfg.constellation.min_elevation_deg,
    }


#: ``leolink.run`` of a config in process, once to warm up (imports, compiled loops, caches),
#: then timed ``repeat`` times: prints the shortest wall time and the shortest CPU time [s]
#: (the process's, every thread's: on a shared machine the CPU figures compare).
WARM_DRIVER = """
import sys, time
import leolink
from leolink.config import load_config
cfg = load_config(sys.argv[1])
leolink.run(cfg, sys.argv[2], overwrite=True)
best = best_cpu = float("inf")
for _ in range(int(sys.argv[3])):
    t0, c0 = time.perf_counter(), time.process_time()
    leolink.run(cfg, sys.argv[2], overwrite=True)
    best = min(best, time.perf_counter() - t0)
    best_cpu = min(best_cpu, time.process_time() - c0)
print(best, best_cpu)
"""


def _timed(cmd, env=None):
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, done.stdout


def peer_available():
    """The peer's version, or None (with the reason printed)."""
    try:
        done = subprocess.run(
            [PEER_PYTHON, "-c", "import importlib.metadata as m; print(m.version('opensatcom'))"],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
    except (OSError, subprocess.SubprocessError) as exc:
        print(f"  peer: skipped ({PEER_PYTHON}: {exc})")
        return None
    if done.returncode != 0:
        print(f"  peer: skipped (opensatcom is not installed for {PEER_PYTHON})")
        return None
    return done.stdout.strip()


def main(argv=None):
    """Figures: ``leolink_process_s`` (min), ``leolink_ut_epochs_per_s``, and with the peer
    ``peer_loop_s``, ``peer_process_s``, ``peer_ut_epochs_per_s`` (loop), the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="one run of each")
    args = ap.parse_args([] if argv is None else argv)
    if args.quick:
        args.repeat = 1
    n = N_UT * int(round(DURATION_S / EPOCH_S))
    print(f"small run: {N_UT} UTs x {DURATION_S:.0f} s at {EPOCH_S:g} s = {n:,} UT-epochs, "
          "one LEO pass (ISS TLE)")  # fmt: skip
    figures = {}
    with tempfile.TemporaryDirectory() as tmp:
        cfg, path, sites = leolink_config(tmp)
        env = dict(os.environ)  # a caller's PYTHONPATH (run_all --compare REF) chooses the tree
        env.setdefault("PYTHONPATH", str(ROOT / "src"))
        env.pop("PYTHONDONTWRITEBYTECODE", None)  # as _common.run_cli: the bytecode cache on
        cmd = [sys.executable, "-m", "leolink.cli", "run", str(path), "--out", f"{tmp}/o",
               "--overwrite"]  # fmt: skip
        times = [_timed([*cmd, "--quiet"], env)[0] for _ in range(args.repeat)]
        figures["leolink_process_s"] = min(times)
        figures["leolink_process_median_s"] = float(np.median(times))
        figures["leolink_ut_epochs_per_s"] = n / min(times)
        row("leolink run, whole process (min)", min(times), "s")
        row("leolink run, whole process (median)", float(np.median(times)), "s")
        warm = _timed([sys.executable, "-c", WARM_DRIVER, str(path), f"{tmp}/w",
                       str(args.repeat)], env)[1]  # fmt: skip
        figures["leolink_warm_s"], figures["leolink_warm_cpu_s"] = map(float, warm.split()[-2:])
        row("leolink.run in process, warm (min)", figures["leolink_warm_s"], "s")
        row("leolink.run in process, warm, CPU (min)", figures["leolink_warm_cpu_s"], "s")
        version = peer_available()
        if version is None:
            return figures
        spec = json.dumps(peer_spec(cfg, sites))
        script = Path(tmp) / "peer_driver.py"
        script.write_text(PEER_DRIVER)
        runs = [_timed([PEER_PYTHON, str(script), spec]) for _ in range(args.repeat)]
    loops = [json.loads(out.splitlines()[-1])["loop_s"] for _, out in runs]
    figures["peer_version"] = version
    figures["peer_loop_s"] = min(loops)
    figures["peer_process_s"] = min(t for t, _ in runs)
    figures["peer_ut_epochs_per_s"] = n / min(loops)
    figures["ratio_peer_loop_over_leolink_process"] = min(loops) / figures["leolink_process_s"]
    figures["ratio_peer_process_over_leolink_process"] = (
        figures["peer_process_s"] / figures["leolink_process_s"]
    )
    figures["ratio_peer_loop_over_leolink_warm"] = min(loops) / figures["leolink_warm_s"]
    figures["peer_loop_cpu_s"] = min(
        json.loads(out.splitlines()[-1])["loop_cpu_s"] for _, out in runs
    )
    figures["ratio_peer_loop_over_leolink_warm_cpu"] = (
        figures["peer_loop_cpu_s"] / figures["leolink_warm_cpu_s"]
    )
    row(f"opensatcom {version} mission loop alone (min)", min(loops), "s")
    row("opensatcom loop rate", figures["peer_ut_epochs_per_s"], "UT-ep/s")
    row("opensatcom whole process (min)", figures["peer_process_s"], "s")
    row("peer loop / leolink process", figures["ratio_peer_loop_over_leolink_process"], "x",
        aim=1.0)  # fmt: skip
    row("peer process / leolink process", figures["ratio_peer_process_over_leolink_process"],
        "x", aim=1.0)  # fmt: skip
    row("peer loop / leolink.run warm", figures["ratio_peer_loop_over_leolink_warm"], "x",
        aim=1.0)  # fmt: skip
    row(f"opensatcom {version} mission loop alone, CPU (min)", figures["peer_loop_cpu_s"], "s")
    row("peer loop / leolink.run warm, CPU", figures["ratio_peer_loop_over_leolink_warm_cpu"],
        "x", aim=1.0)  # fmt: skip
    return figures


if __name__ == "__main__":
    main(argv=sys.argv[1:])
