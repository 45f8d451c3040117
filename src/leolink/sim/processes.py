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

from leolink.engine import Snapshot
from leolink.link.fading import mean_rician_gain_lin, rician_gain_from_draws_lin
from leolink.rng import complex_normal
from leolink.sim.controller import SERVICE_HANDOVER, ControllerState, StepResult, close_dwells, step
from leolink.sim.streams import EpochFrame

__all__ = [
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
    controller: ControllerState
    k: int = 0  # current epoch index
    sat_pos_m: np.ndarray | None = None  # (n_sat, 3)
    sat_vel_m_s: np.ndarray | None = None
    sat_acc_m_s2: np.ndarray | None = None
    snapshot: Snapshot | None = None  # engine Snapshot of the candidate satellites
    cand_sats: np.ndarray | None = None  # global ids of the snapshot's satellites
    decision: StepResult | None = None  # controller decision (ids global)

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


def _local(cand, n_beam, local_of_sat):
    """Global candidate (sat * n_beam + beam) -> local, -1 if its satellite is absent."""
    sat, beam = cand // n_beam, cand % n_beam
    loc = np.where(cand >= 0, local_of_sat[np.maximum(sat, 0)], -1)
    return np.where(loc >= 0, loc * n_beam + beam, -1)


def _global(cand, n_beam, sats):
    """Local candidate -> global; -1 stays -1 (``sats`` may be empty)."""
    sats = np.append(sats, -1)  # index -1 // n_beam lands here when there is no candidate
    return np.where(cand >= 0, sats[np.maximum(cand, 0) // n_beam] * n_beam + cand % n_beam, -1)


class _Decider:
    """Runs ``controller.step`` on the candidate satellites, translating ids."""

    def __init__(
        self, engine, policy, min_snr_db, handover_time_s, min_elevation_rad, radius_m, future_state
    ):
        self.engine, self.policy = engine, policy
        self.min_snr_db, self.handover_time_s = min_snr_db, handover_time_s
        # With interference from other satellites, every satellite above the horizon counts.
        self.min_el = 0.0 if engine.other_satellites else min_elevation_rad
        self.radius_m = radius_m
        self.future_state = future_state  # t -> (ut_pos, sat_pos, sat_vel), for prediction

    def __call__(self, state):
        eng, nb = self.engine, self.engine.n_beam
        c = state.controller
        serving_sats = np.unique(c.serving[c.serving >= 0] // nb)
        sats = candidate_satellites(
            state.sat_pos_m, state.ut_pos_m, self.min_el, serving_sats, self.radius_m
        )
        snap = eng.evaluate(state.ut_pos_m, state.sat_pos_m[sats], state.sat_vel_m_s[sats])
        n_ut = len(state.ut_pos_m)
        snr = snap.snr_db.reshape(n_ut, -1)
        future = None
        if self.policy.lookahead_s > 0.0:
            ut_f, sat_pos_f, sat_vel_f = self.future_state(state.t_s + self.policy.lookahead_s)
            future = eng.evaluate(ut_f, sat_pos_f[sats], sat_vel_f[sats]).snr_db.reshape(n_ut, -1)
        if len(sats) == len(state.sat_pos_m):  # every satellite: ids need no translation
            res = step(
                state.t_s, snr, c, self.policy, self.min_snr_db, self.handover_time_s, nb, future
            )
            res.local_sat = res.sat_id  # index into the snapshot's satellites
        else:
            res = self._step_on_subset(state, snr, future, sats)
        state.snapshot, state.cand_sats, state.decision = snap, sats, res
        state.controller = res.state

    def _step_on_subset(self, state, snr, future, sats):
        """``controller.step`` on a subset of the satellites, ids translated both ways."""
        c, nb = state.controller, self.engine.n_beam
        local_of = np.full(len(state.sat_pos_m), -1)
        local_of[sats] = np.arange(len(sats))
        local = dataclasses.replace(
            c, serving=_local(c.serving, nb, local_of), pending=_local(c.pending, nb, local_of)
        )
        res = step(
            state.t_s, snr, local, self.policy, self.min_snr_db, self.handover_time_s, nb, future
        )
        res.state = dataclasses.replace(
            res.state,
            serving=_global(res.state.serving, nb, sats),
            pending=_global(res.state.pending, nb, sats),
        )
        padded = np.append(sats, -1)  # safe lookup when no satellite is a candidate
        for table, keys in ((res.events, ("from_sat", "to_sat")), (res.dwells, ("sat_id",))):
            for key in keys:
                table[key] = np.where(table[key] >= 0, padded[table[key]], -1)
        res.local_sat = res.sat_id.copy()
        res.sat_id = np.where(res.sat_id >= 0, padded[res.sat_id], -1)
        return res


def beam_controller(env, state, decide, epoch_s):
    """Re-pick the serving (satellite, beam) of every UT once per epoch."""
    for k in range(len(state.times_s)):
        state.k = k
        decide(state)
        yield env.timeout(epoch_s)


class _Monitor:
    """Serving links of every UT -> epoch frames for the sinks."""

    def __init__(self, engine, sink, fading_k=None, ut_keys=None):
        self.engine, self.sink = engine, sink
        self.fading_k, self.ut_keys = fading_k, ut_keys
        self.ut_id = None

    def __call__(self, state):
        res, snap = state.decision, state.snapshot
        n_ut = len(state.ut_pos_m)
        if self.ut_id is None:
            self.ut_id = np.arange(n_ut, dtype=np.int64)
        sats = state.cand_sats
        fading = None
        if self.fading_k is not None and len(sats):
            s = np.maximum(res.local_sat, 0)
            n_lin = 10.0 ** (snap.gain_rx_db[self.ut_id, s] / 10.0)
            # Instantaneous over mean gain (mean 1); the mean receive gain stands in for the
            # LoS gain N, which is off by 1/K = 0.1 in N = 576 for the paper's UPA.
            g = complex_normal(self.ut_keys, state.k)
            k = self.fading_k
            fading = rician_gain_from_draws_lin(n_lin, k, g) / mean_rician_gain_lin(n_lin, k)
        cols = self.engine.serve(
            snap,
            res.local_sat,
            res.beam_id,
            state.ut_vel_m_s,
            state.ut_acc_m_s2,
            state.sat_vel_m_s[sats],
            state.sat_acc_m_s2[sats],
            rx_fading_lin=fading,
        )
        handover = res.service == SERVICE_HANDOVER  # handover execution: no throughput
        cols["se_bps_hz"] = np.where(handover, 0.0, cols["se_bps_hz"])
        cols["throughput_bps"] = np.where(handover, 0.0, cols["throughput_bps"])
        cols.update(
            time_s=np.full(n_ut, state.t_s),
            ut_id=self.ut_id,
            sat_id=res.sat_id,
            beam_id=res.beam_id,
            lat_deg=np.degrees(state.ut_lat_rad),
            lon_deg=np.degrees(state.ut_lon_rad),
            service=res.service,
        )
        if state.recording:
            start_s = state.times_s[state.n_warmup]
            frame = EpochFrame(
                state.k - state.n_warmup,
                state.t_s,
                cols,
                res.events,
                warmup_censored(res.dwells, start_s),
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
