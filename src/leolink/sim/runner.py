"""``leolink.run(config) -> Result``: build the scenario, run the SimPy processes, write outputs."""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import simpy

from leolink.rng import ut_keys
from leolink.scenario import build_scenario
from leolink.sim.controller import ControllerState, policy_from_config
from leolink.sim.mobility import concat_states
from leolink.sim.populations import populations_from_config
from leolink.sim.processes import (
    SimState,
    _Decider,
    _Monitor,
    beam_controller,
    final_dwells,
    link_monitor,
    satellite_motion,
    ut_motion,
)
from leolink.sim.recorder import (
    EVENT_SCHEMA,
    TRACE_SCHEMA,
    EventLog,
    SummaryAccumulator,
    TraceWriter,
    to_table,
)

__all__ = ["Result", "run"]


@dataclasses.dataclass
class Result:
    """What a run produced. ``trace`` and ``events`` are read back lazily when written."""

    summary: dict
    out_dir: Path | None
    _trace: object = None
    _events: object = None

    @property
    def trace(self) -> pd.DataFrame:
        if isinstance(self._trace, pd.DataFrame):
            return self._trace
        if self.out_dir is not None and (self.out_dir / "trace.parquet").exists():
            return pd.read_parquet(self.out_dir / "trace.parquet")
        return pd.read_csv(self.out_dir / "trace.csv")

    @property
    def events(self) -> pd.DataFrame:
        if isinstance(self._events, pd.DataFrame):
            return self._events
        return pd.read_csv(self.out_dir / "events.csv")


class _Recorder:
    """Trace and event writers (or in-memory tables) plus the summary accumulator."""

    def __init__(self, n_ut, out_dir, formats, chunk_rows):
        self.summary = SummaryAccumulator(n_ut)
        self.out_dir = out_dir
        if out_dir is None:
            self.trace_tables, self.event_tables = [], []
            self.trace = self.events = None
        else:
            self.trace = TraceWriter(out_dir, formats=tuple(formats), chunk_rows=chunk_rows)
            self.events = EventLog(out_dir, formats=("csv",), chunk_rows=chunk_rows)

    def add_epoch(self, cols, events, dwells, record_start_s):
        trace_cols = {k: cols[k] for k in TRACE_SCHEMA.names}
        if self.trace is None:
            self.trace_tables.append(to_table(trace_cols, TRACE_SCHEMA))
            if len(events["ut_id"]):
                self.event_tables.append(to_table(events, EVENT_SCHEMA))
        else:
            self.trace.append(trace_cols)
            if len(events["ut_id"]):
                self.events.append(events)
        self.summary.add_trace(trace_cols)
        self.summary.add_events(events)
        self.add_dwells(dwells, record_start_s)

    def add_dwells(self, dwells, record_start_s):
        dwells = dict(dwells)
        # A dwell that began before recording (warm-up) is cut by the start: censored.
        dwells["censored_start"] = dwells["censored_start"] | (dwells["start_s"] < record_start_s)
        self.summary.add_dwells(dwells)

    def close(self):
        if self.trace is not None:
            self.trace.close()
            self.events.close()
            return None, None
        empty_events = EVENT_SCHEMA.empty_table()
        trace = pa.concat_tables(self.trace_tables).to_pandas()
        events = pa.concat_tables([empty_events, *self.event_tables]).to_pandas()
        return trace, events

    def abort(self):
        if self.trace is not None:
            self.trace.abort()
            self.events.abort()


def _epoch_times(run_cfg):
    n_warm = int(round(run_cfg.warmup_s / run_cfg.epoch_s))
    n_rec = int(round(run_cfg.duration_s / run_cfg.epoch_s))
    k = np.arange(n_warm + n_rec)
    return run_cfg.start_s + k * run_cfg.epoch_s, n_warm


def _advance(env, times, epoch_s, progress):
    """Run the SimPy environment to the end; with ``progress``, in ~200 slices that feed a
    tqdm bar on stderr (simulated seconds done, epochs per wall-clock second)."""
    if not progress:
        env.run()
        return
    from tqdm import tqdm

    total_s = len(times) * epoch_s
    step = max(1, len(times) // 200)
    t_wall = time.perf_counter()
    fmt = (
        "{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} s simulated "
        "[{elapsed}<{remaining}{postfix}]"
    )
    with tqdm(total=total_s, desc="leolink run", bar_format=fmt, mininterval=0.5) as bar:
        for done in range(step, len(times) + step, step):
            # Stop half an epoch before the next slice so each slice ends on whole epochs.
            env.run(until=float(times[0]) + (min(done, len(times)) - 0.5) * epoch_s)
            bar.n = min(done, len(times)) * epoch_s
            rate = min(done, len(times)) / max(time.perf_counter() - t_wall, 1e-9)
            bar.set_postfix_str(f"{rate:,.0f} epochs/s", refresh=False)
            bar.refresh()
        env.run()


def _policy(ctrl):
    """The configured beam-selection policy."""
    params = {
        "max_snr": {},
        "hysteresis": {
            "margin_db": ctrl.hysteresis_db,
            "time_to_trigger_s": ctrl.time_to_trigger_s,
        },
        "predictive": {"lookahead_s": ctrl.lookahead_s, "margin_db": ctrl.hysteresis_db},
    }
    return policy_from_config(ctrl.policy, **params[ctrl.policy])


def run(cfg, out_dir=None, progress=False):
    """Run the simulation of ``cfg``.

    Parameters
    ----------
    cfg : leolink.config.Config
    out_dir : path or None
        Where to write ``trace.csv`` (and ``trace.parquet``), ``events.csv``,
        ``summary.json``, ``config.resolved.toml`` and plots. None keeps everything in
        memory (``Result.trace`` is then a DataFrame built at the end).
    progress : bool
        Show a progress bar (simulated time, epochs/s) on stderr.

    Returns
    -------
    Result
    """
    from leolink.config import dump_toml
    from leolink.io import write_json_atomic, write_text_atomic

    scen = build_scenario(cfg)
    rng = np.random.default_rng(np.random.SeedSequence(cfg.run.seed))
    pops = populations_from_config(cfg, scen.heading_rad, rng)
    times, n_warm = _epoch_times(cfg.run)
    epoch = cfg.run.epoch_s
    first = concat_states([p.state(float(times[0])) for _, p in pops])
    n_ut = first.n_ut

    state = SimState(
        times,
        n_warm,
        first.pos_m.copy(),
        first.vel_m_s.copy(),
        first.acc_m_s2.copy(),
        first.lat_rad.copy(),
        first.lon_rad.copy(),
        ControllerState.initial(n_ut, float(times[0])),
    )

    def future_state(t):
        ut = concat_states([p.state(t) for _, p in pops])
        pos, vel, _ = scen.ephemeris(t)
        return ut.pos_m, pos[0], vel[0]

    c = cfg.controller
    policy = _policy(c)
    decide = _Decider(
        scen.engine,
        policy,
        c,
        math.radians(cfg.constellation.min_elevation_deg),
        cfg.earth.radius_m,
        future_state,
    )

    if out_dir is not None:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
    recorder = _Recorder(n_ut, out_dir, cfg.run.trace_formats, cfg.run.chunk_rows)
    fading_k = cfg.link.rician_k if cfg.link.fading == "rician" else None
    keys = ut_keys(cfg.run.seed, n_ut) if fading_k is not None else None
    monitor = _Monitor(scen.engine, recorder, fading_k, keys)

    env = simpy.Environment(initial_time=float(times[0]))
    env.process(satellite_motion(env, state, scen.ephemeris, epoch))
    lo = 0
    for _, pop in pops:
        sl = slice(lo, lo + pop.n_ut)
        env.process(ut_motion(env, state, pop, sl, epoch))
        lo += pop.n_ut
    env.process(beam_controller(env, state, decide, epoch))
    env.process(link_monitor(env, state, monitor, epoch))

    t_wall = time.perf_counter()
    try:
        _advance(env, times, epoch, progress)
    except BaseException:
        recorder.abort()  # nothing half-written is left behind
        raise
    t_end = float(times[-1]) + epoch
    recorder.add_dwells(final_dwells(state, t_end, scen.engine.n_beam), float(times[n_warm]))
    trace, events = recorder.close()

    summary = recorder.summary.summary()
    summary["run"] = {
        "n_ut": n_ut,
        "n_epochs": len(times) - n_warm,
        "epoch_s": epoch,
        "start_s": float(times[n_warm]),
        "end_s": t_end,
        "n_beam": scen.engine.n_beam,
        "n_sat": scen.ephemeris.n_sat,
        "oversampling": float(scen.codebook.oversampling),
        "wall_time_s": time.perf_counter() - t_wall,
    }
    result = Result(summary, out_dir, trace, events)
    if out_dir is not None:
        write_json_atomic(out_dir / "summary.json", summary)
        write_text_atomic(out_dir / "config.resolved.toml", dump_toml(cfg))
        if cfg.run.plots:
            from leolink.plots import plot_run

            plot_run(result.trace, result.events, summary, out_dir, ut_ids=cfg.run.plot_uts)
    return result
