"""SimPy processes: one per population, sharing state through arrays.

Every epoch, in this order (SimPy runs same-time events first in, first out, and all
processes start together and wait one epoch each, so the order holds):

1. :func:`satellite_motion` moves all satellites (ephemeris evaluated in blocks of epochs);
2. :func:`ut_motion`, one per mobility population, moves that population's UTs;
3. :func:`beam_controller` evaluates the engine for every (UT, satellite, beam) and
   re-picks the serving beam of every UT with the configured policy;
4. :func:`link_monitor` computes the serving links and streams the epoch to the sinks.

SimPy owns time only; all decisions are pure functions (``controller.step``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.geometry import enu_basis
from leolink.link.fading import mean_rician_gain_lin, rician_gain_from_draws_lin
from leolink.rng import complex_normal
from leolink.sim.controller import (
    SERVICE_HANDOVER,
    SERVICE_OUTAGE,
    ControllerState,
    StepResult,
    close_dwells,
    concat_events,
    interruption_s,
    resumed_events,
    step,
)
from leolink.sim.policies import neighbour_window_db
from leolink.sim.search import CandidateSearch
from leolink.sim.streams import EpochFrame

#: Trace ``outage_reason`` code -> name (index = code): served; handover execution;
#: no satellite above the minimum elevation; satellites above it but no beam above the
#: service threshold.
#: re-establishing after a radio link failure (appended: leolink.sim.rlf_run).
OUTAGE_REASONS = ("none", "handover", "no_satellite", "below_threshold", "rlf")

__all__ = [
    "OUTAGE_REASONS",
    "SimState",
    "beam_controller",
    "candidate_satellites",
    "link_monitor",
    "satellite_motion",
    "ut_motion",
]

#: Epochs of ephemeris computed in one vectorized call.
EPHEMERIS_BLOCK = 512


@dataclasses.dataclass
class SimState:
    """Arrays shared by the processes (the only coupling between them)."""

    times_s: np.ndarray  # (n_epoch,) epoch times
    n_warmup: int  # epochs before recording starts
    ut_pos_m: np.ndarray  # (n_ut, 3)
    ut_vel_m_s: np.ndarray
    ut_acc_m_s2: np.ndarray
    ut_lat_rad: np.ndarray  # (n_ut,)
    ut_lon_rad: np.ndarray
    ut_alt_m: np.ndarray
    controller: ControllerState
    k: int = 0  # current epoch index
    sat_pos_m: np.ndarray | None = None  # (n_sat, 3)
    sat_vel_m_s: np.ndarray | None = None
    sat_acc_m_s2: np.ndarray | None = None
    cand_sats: np.ndarray | None = None  # global ids of the cone-selected satellites
    enu: np.ndarray | None = None  # (n_ut, 3, 3) the UTs' WGS 84 frames, None on the sphere
    decision: StepResult | None = None  # controller decision (ids global)
    best_snr_db: np.ndarray | None = None  # (n_ut,) the best candidate's SNR [dB], NaN if none
    best_unserved: tuple | None = None  # (UTs without a serving link, their best cell)
    n_visible: np.ndarray | None = None  # (n_ut,) satellites above the minimum elevation
    rlf_blocked: np.ndarray | None = None  # (n_ut,) re-establishing after an RLF, or None

    @property
    def t_s(self) -> float:
        return float(self.times_s[self.k])

    @property
    def recording(self) -> bool:
        return self.k >= self.n_warmup


def satellite_motion(env, state, ephemeris, epoch_s):
    """Move every satellite once per epoch (the ephemeris is evaluated per block)."""
    n = len(state.times_s)
    for lo in range(0, n, EPHEMERIS_BLOCK):
        pos, vel, acc = ephemeris(state.times_s[lo : lo + EPHEMERIS_BLOCK])
        for i in range(pos.shape[0]):
            state.sat_pos_m, state.sat_vel_m_s, state.sat_acc_m_s2 = pos[i], vel[i], acc[i]
            yield env.timeout(epoch_s)


def ut_motion(env, state, population, ut_slice, epoch_s):
    """Move one mobility population (its UTs are ``ut_slice`` of the shared arrays)."""
    for t in state.times_s:
        s = population.state(float(t))
        state.ut_pos_m[ut_slice] = s.pos_m
        state.ut_vel_m_s[ut_slice] = s.vel_m_s
        state.ut_acc_m_s2[ut_slice] = s.acc_m_s2
        state.ut_lat_rad[ut_slice] = s.lat_rad
        state.ut_lon_rad[ut_slice] = s.lon_rad
        state.ut_alt_m[ut_slice] = s.alt_m
        yield env.timeout(epoch_s)


def candidate_satellites(sat_pos_m, ut_pos_m, min_elevation_rad, serving_sats, radius_m):
    """Satellites that may be above ``min_elevation_rad`` for some UT, plus the serving ones.

    A cheap cone test around the UTs' mean direction (O(n_sat + n_ut)), so that the
    engine's (UT x satellite x beam) call only sees the few satellites that matter.
    """
    n_sat = len(sat_pos_m)
    if n_sat <= 64:
        return np.arange(n_sat)
    up = ut_pos_m / np.linalg.norm(ut_pos_m, axis=1, keepdims=True)
    centre = up.mean(axis=0)
    norm = np.linalg.norm(centre)
    if norm < 1e-6:  # UTs all over the globe: no useful cone
        return np.arange(n_sat)
    centre /= norm
    spread = np.arccos(np.clip(up @ centre, -1.0, 1.0)).max()
    r_sat = np.linalg.norm(sat_pos_m, axis=1)
    # Earth-central angle of the coverage edge at the minimum elevation.
    reach = np.pi / 2 - min_elevation_rad - np.arcsin(radius_m * np.cos(min_elevation_rad) / r_sat)
    angle = np.arccos(np.clip(sat_pos_m @ centre / r_sat, -1.0, 1.0))
    near = angle <= spread + reach + 1e-3
    near[serving_sats[serving_sats >= 0]] = True
    return np.flatnonzero(near)


class _Decider:
    """Finds every UT's candidate cells and runs ``controller.step`` on them.

    ``ellipsoidal``: the UTs' latitudes are geodetic (WGS 84) and their local frame is the
    ellipsoid's, handed to the engine; otherwise the engine takes the sphere's radial up.
    ``prune``: screen the (UT, satellite) pairs before evaluating them (the same table,
    :mod:`leolink.sim.search`); False evaluates every pair (the reference).
    """

    def __init__(
        self,
        engine,
        policy,
        min_snr_db,
        handover_time_s,
        min_elevation_rad,
        radius_m,
        future_state,
        epoch_s=1.0,
        ellipsoidal=False,
        prune=True,
        rlf=None,
    ):
        self.engine, self.policy = engine, policy
        self.rlf = rlf  # leolink.sim.rlf_run.RlfRun or None
        # A policy with per-cell state decides through its own run (leolink.sim.trigger_run).
        run = getattr(policy, "run", None)
        self.trigger = run(engine, min_snr_db, radius_m, future_state, epoch_s) if run else None
        self.min_snr_db, self.handover_time_s = min_snr_db, handover_time_s
        # With interference from other satellites, every satellite above the horizon counts.
        self.min_el = 0.0 if engine.other_satellites else min_elevation_rad
        self.radius_m = radius_m
        self.future_state = future_state  # t -> (ut_pos, sat_pos, sat_vel), for prediction
        self.epoch_s, self.ellipsoidal = float(epoch_s), bool(ellipsoidal)
        self.search = CandidateSearch(engine, neighbour_window_db(policy), prune)

    def up(self, state):
        """The UTs' local frames (WGS 84) and up rows, or (None, None) on the sphere."""
        if not self.ellipsoidal:
            return None, None
        enu = enu_basis(state.ut_lat_rad, state.ut_lon_rad)
        return enu, enu[:, 2, :]

    def __call__(self, state):
        nb = self.engine.n_beam
        c = state.controller
        serving_sats = np.unique(c.serving[c.serving >= 0] // nb)
        sats = candidate_satellites(
            state.sat_pos_m, state.ut_pos_m, self.min_el, serving_sats, self.radius_m
        )
        enu, up = self.up(state)
        found = self.search(
            state.ut_pos_m, state.sat_pos_m[sats], state.sat_vel_m_s[sats], sats, c.serving, up
        )
        state.best_snr_db, state.n_visible = found.best_snr_db, found.n_visible
        future = None
        if self.policy.lookahead_s > 0.0:
            # The UTs' frames of now: over a lookahead they turn by (distance / R), 0.02 deg
            # for an aircraft over 10 s.
            future = self._future(found.table, state.t_s + self.policy.lookahead_s, up)
        t, table, target = state.t_s, found.table, None
        if self.rlf is not None:  # re-establishing UTs have no candidate yet
            state.rlf_blocked = self.rlf.blocked(t)
            table = table.like(np.where(state.rlf_blocked[:, None], np.nan, table.snr_db))
        if self.trigger is not None:
            pos, vel = state.sat_pos_m, state.sat_vel_m_s
            target = self.trigger.target(t, table, c.serving, state.ut_pos_m, pos, vel, up)
        res = step(
            t, table, c, self.policy, self.min_snr_db, self.handover_time_s, nb, future, target
        )
        resumed = resumed_events(t, self.epoch_s, res.state, found.table)
        res.events = concat_events(res.events, resumed)
        unserved = np.flatnonzero(res.sat_id < 0)
        state.best_unserved = (unserved, found.best_cell[unserved])
        state.cand_sats, state.decision, state.enu = sats, res, enu
        state.controller = res.state

    def _future(self, table, t_s, up):
        """The table's cells at ``t_s`` (the same cells; NaN where not visible then)."""
        eng, nb = self.engine, self.engine.n_beam
        ut_f, sat_pos_f, sat_vel_f = self.future_state(t_s)
        rows = np.broadcast_to(np.arange(table.n_ut)[:, None], table.shape)
        valid = table.cell >= 0
        key = rows[valid] * len(sat_pos_f) + table.cell[valid] // nb
        pairs, inverse = np.unique(key, return_inverse=True)
        ut, sat = np.divmod(pairs, len(sat_pos_f))
        links = eng.evaluate_pairs(ut_f, sat_pos_f, sat_vel_f, ut, sat, ut_up=up)
        snr = links.snr_db_bm(eng.beam_ix, eng.beam_iy)  # (n_beam, n_pair)
        out = np.full(table.shape, np.nan)
        out[valid] = snr[table.cell[valid] % nb, inverse.reshape(-1)]
        return table.like(out)


def beam_controller(env, state, decide, epoch_s):
    """Re-pick the serving (satellite, beam) of every UT once per epoch."""
    for k in range(len(state.times_s)):
        state.k = k
        decide(state)
        yield env.timeout(epoch_s)


class _Monitor:
    """Serving links of every UT -> epoch frames for the sinks.

    In outage rows where a satellite is above the minimum elevation, the geometry and
    budget columns are those of the best candidate (``best_snr_db``); the link columns
    (SNR, SINR, SE, throughput) are NaN. In a handover epoch SE and throughput are the
    epoch's means: the link's, times the part of the epoch with service.
    """

    _LINK = ("snr_db", "sinr_db", "se_bps_hz", "throughput_bps")

    def __init__(
        self, engine, sink, fading_k=None, ut_keys=None, epoch_s=1.0, population=(), rlf=None
    ):
        self.engine, self.sink, self.rlf = engine, sink, rlf
        self.fading_k, self.ut_keys = fading_k, ut_keys
        self.epoch_s = float(epoch_s)
        self.population = np.asarray(population, dtype=object)
        self.ut_id = None

    def _fading(self, state, links, served):
        if self.fading_k is None or not served.any():
            return None
        n_lin = 10.0 ** (np.broadcast_to(links.rx_db, served.shape) / 10.0)
        # Instantaneous over mean gain (mean 1); the mean receive gain stands in for the
        # LoS gain N, which is off by 1/K = 0.1 in N = 576 for the paper's UPA.
        g = complex_normal(self.ut_keys, state.k)
        k = self.fading_k
        return rician_gain_from_draws_lin(n_lin, k, g) / mean_rician_gain_lin(n_lin, k)

    def _serve(self, state, geo_sat, geo_beam):
        """The engine's link of every UT on ``(geo_sat, geo_beam)`` (global ids; -1: none)."""
        eng = self.engine
        n_ut = len(geo_sat)
        served = geo_sat >= 0
        if not served.any():
            return eng.serve_pairs(None, np.full(n_ut, -1), geo_beam, state.ut_vel_m_s)
        u = np.arange(n_ut)
        s = np.where(served, geo_sat, geo_sat[served][0])
        sats, local = np.unique(s, return_inverse=True)
        up = None if state.enu is None else state.enu[:, 2, :]
        links = eng.evaluate_pairs(
            state.ut_pos_m, state.sat_pos_m[sats], state.sat_vel_m_s[sats], u, local, ut_up=up
        )
        i_other = None
        cone = state.cand_sats
        if eng.other_satellites and len(cone) > 1:
            snap = eng.evaluate(
                state.ut_pos_m, state.sat_pos_m[cone], state.sat_vel_m_s[cone], ut_enu=state.enu
            )
            s_cone = np.where(served, np.searchsorted(cone, s), 0)
            i_other = eng.other_satellites_interference(snap, s_cone, np.maximum(geo_beam, 0), u)
        with np.errstate(divide="ignore", invalid="ignore"):
            fading = self._fading(state, links, served)
        return eng.serve_pairs(
            links,
            np.where(served, u, -1),
            geo_beam,
            state.ut_vel_m_s,
            state.ut_acc_m_s2,
            state.sat_vel_m_s[s],
            state.sat_acc_m_s2[s],
            rx_fading_lin=fading,
            i_other=i_other,
            ut_pos_m=state.ut_pos_m,
            ut_enu=state.enu,
        )

    def _columns(self, state):
        res, nb = state.decision, self.engine.n_beam
        n_ut = len(state.ut_pos_m)
        if self.ut_id is None:
            self.ut_id = np.arange(n_ut, dtype=np.int64)
        geo_sat, geo_beam = res.sat_id.copy(), res.beam_id.copy()
        unserved, best = state.best_unserved
        if unserved.size:  # outage rows: the best candidate's geometry, where there is one
            geo_sat[unserved] = np.where(best >= 0, best // nb, -1)
            geo_beam[unserved] = np.where(best >= 0, best % nb, -1)
        cols = self._serve(state, geo_sat, geo_beam)
        outage = res.service == SERVICE_OUTAGE
        if outage.any():
            for name in self._LINK:
                cols[name] = np.where(outage, np.nan, cols[name])
        gap_s = interruption_s(state.t_s, self.epoch_s, res.state)
        handover = res.service == SERVICE_HANDOVER
        if handover.any():  # the served part of the epoch only
            served = 1.0 - gap_s / self.epoch_s
            cols["se_bps_hz"] = np.where(handover, cols["se_bps_hz"] * served, cols["se_bps_hz"])
            cols["throughput_bps"] = np.where(
                handover, cols["throughput_bps"] * served, cols["throughput_bps"]
            )
        reason = res.service.astype(np.int8)  # served -> none, handover -> handover
        reason[outage] = np.where(state.n_visible[outage] > 0, 3, 2)
        cols.update(
            time_s=np.full(n_ut, state.t_s),
            ut_id=self.ut_id,
            sat_id=res.sat_id,
            beam_id=res.beam_id,
            lat_deg=np.degrees(state.ut_lat_rad),
            lon_deg=np.degrees(state.ut_lon_rad),
            service=res.service,
            outage_reason=reason,
            n_visible=state.n_visible.astype(np.int64),
            best_snr_db=state.best_snr_db,
            alt_m=state.ut_alt_m.copy(),
            population=self.population,
            interruption_s=gap_s,
        )
        return cols

    def __call__(self, state):
        if not state.recording and self.rlf is None:
            return
        res = state.decision
        cols, events, dwells = self._columns(state), res.events, res.dwells
        if self.rlf is not None:  # RLF monitoring runs in the warm-up too
            state.controller, events, dwells = self.rlf.merge(state, cols, events, dwells)
        if not state.recording:
            return
        start_s = state.times_s[state.n_warmup]
        frame = EpochFrame(
            state.k - state.n_warmup,
            state.t_s,
            cols,
            events,
            warmup_censored(dwells, start_s),
        )
        self.sink.epoch(frame)


def link_monitor(env, state, monitor, epoch_s):
    """Evaluate the serving links of every UT once per epoch and record them."""
    for _ in range(len(state.times_s)):
        monitor(state)
        yield env.timeout(epoch_s)


def warmup_censored(dwells, record_start_s):
    """Dwells that began before recording (in the warm-up) are cut by the start: censored."""
    return {
        **dwells,
        "censored_start": dwells["censored_start"] | (dwells["start_s"] < record_start_s),
    }


def final_dwells(state, t_end_s, n_beam):
    """Dwells still open at the end of the run (censored at the end)."""
    dwells = close_dwells(state.controller, t_end_s, n_beam)
    return warmup_censored(dwells, state.times_s[state.n_warmup])
