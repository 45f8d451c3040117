"""SimPy processes: one per population, sharing state through arrays.

Every epoch, in this order (SimPy runs same-time events first in, first out, and all
processes start together and wait one epoch each, so the order holds):

1. :func:`satellite_motion` moves all satellites (ephemeris evaluated in blocks of epochs);
2. :func:`ut_motion`, one per mobility population that moves, moves that population's
   UTs (static ones keep their first state: ``moves = False``, no process);
3. :func:`beam_controller` finds every UT's candidate cells and re-picks the serving
   cell of every UT with the configured policy (:class:`leolink.sim.decide.Decider`);
4. :func:`link_monitor` records the epoch; the serving links of a block of epochs are
   evaluated at once and streamed to the sinks (:class:`leolink.sim.monitor.Monitor`).

The motion of satellites and UTs is a pure function of time, evaluated per block of
epochs (:mod:`leolink.sim.motion`), so that the engine works on whole blocks. SimPy owns
time only; all decisions are pure functions (``controller.step``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.sim.candidates.tiles import group_cones
from leolink.sim.handover.controller import ControllerState, StepResult, close_dwells

#: Trace ``outage_reason`` code -> name (index = code): served; handover execution;
#: no satellite above the minimum elevation; satellites above it but no beam above the
#: service threshold; the environment (blockage, shadowing, clutter: ``leolink.sim.environment``)
#: took every beam below the threshold that the best beam reaches in open country;
#: re-establishing after a radio link failure (:mod:`leolink.sim.handover.rlf_run`).
OUTAGE_REASONS = ("none", "handover", "no_satellite", "below_threshold", "blocked", "rlf")

__all__ = [
    "OUTAGE_REASONS",
    "SimState",
    "beam_controller",
    "candidate_satellites",
    "link_monitor",
    "satellite_motion",
    "ut_motion",
]


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
    channel: object = None  # EpochChannel of the UTs' environments, None in open country
    open_snr_db: np.ndarray | None = None  # (n_ut,) best SNR without the environment [dB]
    rlf_blocked: np.ndarray | None = None  # (n_ut,) re-establishing after an RLF, or None

    @property
    def t_s(self) -> float:
        return float(self.times_s[self.k])

    @property
    def recording(self) -> bool:
        return self.k >= self.n_warmup


def satellite_motion(env, state, motion, epoch_s):
    """Move every satellite once per epoch (from the motion blocks: the ephemeris is
    evaluated per block of epochs)."""
    for k in range(len(state.times_s)):
        b = motion.block_of(k)
        i = k - b.k0
        state.sat_pos_m, state.sat_vel_m_s = b.sat_pos_m[i], b.sat_vel_m_s[i]
        state.sat_acc_m_s2 = b.sat_acc_m_s2[i]
        yield env.timeout(epoch_s)


def ut_motion(env, state, motion, ut_slice, epoch_s):
    """Move one mobility population (its UTs are ``ut_slice`` of the shared arrays), from
    the motion blocks (each population's states evaluated once per block of epochs)."""
    for k in range(len(state.times_s)):
        b = motion.block_of(k)
        i = k - b.k0
        state.ut_pos_m[ut_slice] = b.ut_pos_m[i, ut_slice]
        state.ut_vel_m_s[ut_slice] = b.ut_vel_m_s[i, ut_slice]
        state.ut_acc_m_s2[ut_slice] = b.ut_acc_m_s2[i, ut_slice]
        state.ut_lat_rad[ut_slice] = b.ut_lat_rad[i, ut_slice]
        state.ut_lon_rad[ut_slice] = b.ut_lon_rad[i, ut_slice]
        state.ut_alt_m[ut_slice] = b.ut_alt_m[i, ut_slice]
        yield env.timeout(epoch_s)


def candidate_satellites(sat_pos_m, ut_pos_m, min_elevation_rad, serving_sats, ut_up=None):
    """Satellites that may be above ``min_elevation_rad`` for some UT, plus the serving ones.

    The cap of every UT as one group (:func:`leolink.sim.candidates.tiles.group_cones`:
    O(n_sat + n_ut)), so that the engine's (UT x satellite x beam) call only sees the few
    satellites that matter; ``ut_up`` (n_ut, 3): each UT's local up (WGS 84), None: radial.
    """
    n_sat = len(sat_pos_m)
    if n_sat <= 64:
        return np.arange(n_sat)
    group = np.zeros(len(ut_pos_m), np.int64)
    cone = group_cones(sat_pos_m, ut_pos_m, ut_up, min_elevation_rad, group, 1).sat
    serving = serving_sats[serving_sats >= 0]
    return np.union1d(cone, serving) if serving.size else cone


def beam_controller(env, state, decide, epoch_s):
    """Re-pick the serving (satellite, beam) of every UT once per epoch."""
    for k in range(len(state.times_s)):
        state.k = k
        decide(state)
        yield env.timeout(epoch_s)


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
