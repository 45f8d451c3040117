"""Run a :class:`Scenario`: SimPy processes move satellites and UTs, pick beams, stream out.

The scenario is built elsewhere (``leolink.app.scenario`` from a config, or by hand from
Python); the caller supplies the sinks (:mod:`leolink.sim.streams`). Nothing here reads
a config or writes a file.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Sequence

import numpy as np
import simpy

from leolink.antenna.panel import PanelOrientation
from leolink.engine import LinkEngine
from leolink.orbit import Ephemeris
from leolink.rng import ut_keys
from leolink.sim.beams.selectors import BeamSelector
from leolink.sim.beams.service import BeamService
from leolink.sim.decide import Decider, Rules, Sky
from leolink.sim.environment import ChannelTracker
from leolink.sim.ephemeris_monitor import TrueLinkMonitor
from leolink.sim.handover.controller import ControllerState
from leolink.sim.handover.decisions import ConditionalHandover
from leolink.sim.handover.policies import Policy
from leolink.sim.handover.procedure import Procedure
from leolink.sim.handover.rlf_run import RLF_REASON, RlfRun
from leolink.sim.mobility.models import concat_states
from leolink.sim.mobility.populations import MotionModel
from leolink.sim.monitor import FadingDraws, Monitor
from leolink.sim.motion import MotionBlocks
from leolink.sim.motion import states as motion_states
from leolink.sim.processes import (
    OUTAGE_REASONS,
    SimState,
    beam_controller,
    final_dwells,
    link_monitor,
    satellite_motion,
    ut_motion,
)
from leolink.sim.service_link import ServiceLink
from leolink.sim.streams import FinalFrame, RunInfo, SinkGroup
from leolink.timing import TIMING_COLUMNS

__all__ = ["RunStats", "Scenario", "epoch_times", "run_simulation"]

#: Progress callbacks are called about this many times per run.
PROGRESS_SLICES = 200


@dataclasses.dataclass
class Scenario:
    """Everything a run needs, built once (from a config by ``leolink.app.scenario``).

    Attributes
    ----------
    engine : LinkEngine
    ephemeris : Ephemeris
    populations : list of (name, motion model)
        Motion models of :mod:`leolink.sim.mobility.populations`, UTs numbered in this order.
    policy : Policy
    min_snr_db : float [dB], service threshold.
    handover_time_s : float [s], service interruption per handover.
    min_elevation_rad : float [rad], lowest usable elevation.
    radius_m : float [m], Earth radius.
    times_s : ndarray (n_epoch,), every epoch, warm-up included [s].
    n_warmup : int, epochs before recording starts.
    epoch_s : float [s]
    seed : int, of the per-UT random draws.
    fading_k : float or None, Rician factor of random fading draws; None: mean gain.
    ellipsoidal : bool, UT latitudes are geodetic (WGS 84): the engine gets their
        ellipsoidal local frames (else the sphere's radial up).
    prune : bool, screen the (UT, satellite) pairs and evaluate only those that can hold a
        cell the policy needs (:mod:`leolink.sim.candidates.search`; the same outputs); False
        evaluates every pair of the cone-selected satellites (the reference).
    rlf : leolink.sim.handover.rlf.RlfParams or None, radio link failure monitoring
        (:mod:`leolink.sim.handover.rlf_run`); None: off.
    signalling : leolink.sim.handover.procedure.SignallingParams or None, the handover
        procedure in simulated time (needs ``rlf``); None: ``handover_time_s`` per handover.
    beam_switch_s : float or None, cells are satellites (:mod:`leolink.sim.handover.cells`):
        a beam change inside one is a ``beam_switch`` of this interruption [s]; None:
        cells are beams.
    link : ServiceLink or None, the link figures and the SINR service threshold (None:
        default figures, service on SNR).
    panels : PanelOrientation or None, the UTs' turned or tilted panels (None: flat).
    environments : list of EnvironmentModel or None, one per population
        (:func:`leolink.sim.environment.environment_models`); None: every UT in open
        country, the paper's link.
    selector : BeamSelector or None, active beams (:mod:`leolink.sim.beams.selectors`);
        None: every beam lit.
    service : BeamService or None, beam sharing and precoding
        (:mod:`leolink.sim.beams.service`; adds the ``n_sharing`` trace column); None: none.
    estimated_ephemeris : callable or None, the ephemeris the controller believes
        (:mod:`leolink.ephemeris_error`; called as ``(t_s, sats=None)``, as
        :class:`~leolink.orbit.Ephemeris`); the links are evaluated on ``ephemeris``
        (:mod:`leolink.sim.ephemeris_monitor`). None: no ephemeris error.
    roi_frame : leolink.app.orbits.RoiFrame or None, the ROI frame the populations were
        placed in (the run's notes say it); None: not known (a scenario built by hand).
    timing : leolink.timing.TimingParams or None, the NTN timing columns of ``[timing]``
        (``ta_s``, ``common_ta_s``, ``k_offset_ms``, ``doppler_residual_hz``); None: off.
    ut_keys : ndarray of uint64 (n_ut,) or None, the UTs' random keys; None:
        ``leolink.rng.ut_keys(seed, n_ut)``. A part of a split run carries its UTs' keys of
        the whole run (:mod:`leolink.app.split`), so its draws are the whole run's.
    """

    engine: LinkEngine
    ephemeris: Ephemeris
    populations: list[tuple[str, MotionModel]]
    policy: Policy
    min_snr_db: float
    handover_time_s: float
    min_elevation_rad: float
    radius_m: float
    times_s: np.ndarray
    n_warmup: int
    epoch_s: float
    seed: int = 0
    fading_k: float | None = None
    ellipsoidal: bool = False
    prune: bool = True
    link: ServiceLink | None = None
    panels: PanelOrientation | None = None
    environments: list | None = None
    rlf: object | None = None
    signalling: object | None = None
    beam_switch_s: float | None = None
    selector: BeamSelector | None = None
    service: BeamService | None = None
    estimated_ephemeris: Callable | None = None
    roi_frame: object | None = None
    ut_keys: np.ndarray | None = None
    timing: object | None = None


@dataclasses.dataclass(frozen=True)
class RunStats:
    """What :func:`run_simulation` reports besides the stream."""

    info: RunInfo
    end_s: float
    wall_time_s: float
    split: dict | None = None  # a split run's parts and workers (leolink.app.split)


def epoch_times(start_s, epoch_s, warmup_s, duration_s):
    """Epoch times ``start + k epoch`` over warm-up and recording; returns (times, n_warmup)."""
    n_warm = int(round(warmup_s / epoch_s))
    n_rec = int(round(duration_s / epoch_s))
    return start_s + np.arange(n_warm + n_rec) * epoch_s, n_warm


def _advance(env, times, epoch_s, progress):
    """Run the environment to the end; with ``progress(done_epochs, n_epochs)``, in slices
    of about ``1 / PROGRESS_SLICES`` of the run, each ending on whole epochs."""
    if progress is None:
        env.run()
        return
    step = max(1, len(times) // PROGRESS_SLICES)
    for done in range(step, len(times) + step, step):
        done = min(done, len(times))
        # Stop half an epoch before the next slice so each slice ends on whole epochs.
        env.run(until=float(times[0]) + (done - 0.5) * epoch_s)
        progress(done, len(times))
    env.run()


def _initial_state(scen, pops):
    times = scen.times_s
    first = concat_states([p.state(float(times[0])) for _, p in pops])
    return SimState(
        times,
        scen.n_warmup,
        first.pos_m.copy(),
        first.vel_m_s.copy(),
        first.acc_m_s2.copy(),
        first.lat_rad.copy(),
        first.lon_rad.copy(),
        first.alt_m.copy(),
        ControllerState.initial(first.n_ut, float(times[0])),
    )


def _processes(env, scen, state, motion, decide, monitor):
    epoch = scen.epoch_s
    env.process(satellite_motion(env, state, motion, epoch))
    lo = 0
    for _, pop in scen.populations:
        if getattr(pop, "moves", True):  # static UTs keep their first state: no process
            env.process(ut_motion(env, state, motion, slice(lo, lo + pop.n_ut), epoch))
        lo += pop.n_ut
    env.process(beam_controller(env, state, decide, epoch))
    env.process(link_monitor(env, state, monitor, epoch))


def _monitor(scen, sink, decide, keys, names):
    """The run's monitor; with an ephemeris error, the links on the true states."""
    fading = None if scen.fading_k is None else FadingDraws(scen.fading_k, keys)
    args = (sink, decide, fading, names, scen.link)
    kw = dict(service=scen.service, timing=scen.timing)
    if scen.estimated_ephemeris is None:
        return Monitor(*args, **kw)
    return TrueLinkMonitor(*args, **kw, true_ephemeris=scen.ephemeris)


def _future_state(populations, believed, t, sats=None, uts=True):
    """UT positions, satellite positions and velocities at ``t`` [s], by the ``believed``
    ephemeris: a scalar gives (n_ut, 3), (n_sat, 3), (n_sat, 3); 1-D times the same with a
    leading time axis, in one call per population and one of the ephemeris; ``sats``
    (1-D ids): those satellites' alone, in that order (None: every satellite); ``uts``
    False: no UT positions (None), the satellites' alone."""
    times = np.atleast_1d(np.asarray(t, float))
    ut = None
    if uts:
        ut = np.concatenate([motion_states(p, times).pos_m for _, p in populations], axis=1)
    pos, vel, _ = believed(times) if sats is None else believed(times, sats)
    if np.ndim(t) == 0:
        return (None if ut is None else ut[0]), pos[0], vel[0]
    return ut, pos, vel


def _future(populations, believed):
    """:func:`_future_state` bound to the run; its ``n_sat_whole``: the satellites' count
    when ``believed`` cannot propagate some satellites alone (TLEs, an ephemeris error:
    some cost the whole set, so the look-ahead asks for every one at once), else None."""
    future = functools.partial(_future_state, populations, believed)
    some = getattr(believed, "propagates_some", False)
    future.n_sat_whole = None if some else believed.n_sat  # type: ignore[attr-defined]
    return future


def run_simulation(
    scen: Scenario,
    sinks: Sequence,
    progress: Callable[[int, int], None] | None = None,
) -> RunStats:
    """Run ``scen`` and stream every recorded epoch to ``sinks``.

    Parameters
    ----------
    scen : Scenario
    sinks : sequence of :class:`~leolink.sim.streams.Sink`
        Each gets ``start``, the recorded epochs (one ``block`` per motion block if it has
        ``block``, else one ``epoch`` per epoch: :func:`~leolink.sim.streams.deliver`) and
        ``finish``, or ``abort`` if the run fails or is interrupted (the exception
        propagates).
    progress : callable, optional
        ``progress(done_epochs, n_epochs)``, called about 200 times.

    Returns
    -------
    RunStats
    """
    sink = SinkGroup(sinks, background=True)  # the sinks take a block while the next is computed
    state = _initial_state(scen, scen.populations)
    n_ut = state.ut_pos_m.shape[0]

    believed = scen.ephemeris if scen.estimated_ephemeris is None else scen.estimated_ephemeris

    future_state = _future(scen.populations, believed)
    times = scen.times_s
    rlf = None
    if scen.rlf is not None:
        rlf = RlfRun(scen.rlf, n_ut, scen.engine.n_beam, OUTAGE_REASONS.index(RLF_REASON))
    motion = MotionBlocks(believed, scen.populations, times, scen.ephemeris.n_sat, n_ut)
    rules = Rules(scen.policy, scen.min_snr_db, scen.handover_time_s, scen.selector, scen.prune)
    sky = Sky(scen.min_elevation_rad, scen.radius_m, scen.ellipsoidal, scen.panels)
    decide = Decider(scen.engine, rules, sky, motion, future_state, scen.epoch_s, rlf)
    decide.beam_switch_s = scen.beam_switch_s
    if scen.signalling is not None:
        if rlf is None:
            raise ValueError("the handover procedure (signalling) needs RLF monitoring (rlf)")
        conditional = isinstance(getattr(scen.policy, "inner", None), ConditionalHandover)
        decide.procedure = rlf.procedure = Procedure(
            scen.signalling, n_ut, scen.engine.n_beam, scen.epoch_s, conditional
        )
    keys = None
    measuring = getattr(decide.trigger, "measurement", None)  # the trigger's measurement stage
    needs_keys = measuring is not None and measuring.needs_ut_keys
    if scen.fading_k is not None or scen.environments or needs_keys:
        keys = ut_keys(scen.seed, n_ut) if scen.ut_keys is None else scen.ut_keys
    if measuring is not None and needs_keys:
        measuring.ut_keys = keys
    names = tuple(name for name, pop in scen.populations for _ in range(pop.n_ut))
    environment = ()
    if scen.environments:
        counts = [pop.n_ut for _, pop in scen.populations]
        decide.with_channel(ChannelTracker(scen.environments, counts, keys, decide.min_el))
        environment = decide.channel.environment
    monitor = _monitor(scen, sink, decide, keys, names)
    env = simpy.Environment(initial_time=float(times[0]))
    _processes(env, scen, state, motion, decide, monitor)
    info = RunInfo(
        n_ut, scen.ephemeris.n_sat, scen.engine.n_beam, scen.epoch_s,
        float(times[scen.n_warmup]), len(times) - scen.n_warmup, names, environment,
        ("n_sharing",) * (scen.service is not None) + TIMING_COLUMNS * (scen.timing is not None),
    )  # fmt: skip
    t_wall = time.perf_counter()
    try:  # start inside: a signal while the later sinks start aborts the earlier ones
        sink.start(info)
        _advance(env, times, scen.epoch_s, progress)
        t_end = float(times[-1]) + scen.epoch_s
        sink.finish(FinalFrame(t_end, final_dwells(state, t_end, scen.engine.n_beam)))
    except BaseException:
        sink.abort()  # nothing half-written is left behind
        raise
    return RunStats(info, t_end, time.perf_counter() - t_wall)
