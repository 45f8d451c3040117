"""From a validated config to the objects a run needs: the wiring, in one place.

This is where config sections become physics objects: the codebook, the terminal
antennas, the atmosphere, the link engine, the ephemeris, the UT populations and the
policy, gathered in a :class:`leolink.sim.runner.Scenario`. Pluggable kinds are built
through their registries (``section.build(context)``), never by name here. Satellites,
real time and the ROI frame: :mod:`leolink.app.orbits`.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from leolink.antenna.array import HybridArray
from leolink.antenna.panel import PanelOrientation
from leolink.antenna.terminal import TerminalGroups, pruning_terminal
from leolink.app.codebook import codebook_from_config
from leolink.app.orbits import ephemeris_from_config, overhead_satellite, roi_frame
from leolink.app.steering import steering_from_config, surface_point
from leolink.engine import LinkEngine, LinkParams, reuse_colors
from leolink.ephemeris_error import EstimatedEphemeris
from leolink.errors import ConfigError
from leolink.io.sites import with_sites
from leolink.link.acm import LinkFigureParams
from leolink.link.figures import eirp_from_density_dbw
from leolink.registry import REGISTRIES
from leolink.rng import ut_keys
from leolink.sim.beams.service import BeamService
from leolink.sim.environment import environment_models
from leolink.sim.handover.config import build_rlf, build_signalling
from leolink.sim.mobility.models import OnWgs84, take_uts
from leolink.sim.mobility.populations import PopulationContext
from leolink.sim.runner import Scenario, epoch_times
from leolink.sim.service_link import ServiceLink
from leolink.timing import TimingParams

__all__ = [
    "beams_from",
    "build_engine",
    "build_populations",
    "build_scenario",
    "ptx_per_beam_dbw",
    "service_link",
    "codebook_from_config",
    "ephemeris_from_config",
    "overhead_satellite",
    "panel_orientation",
    "track_heading_rad",
    "ut_terminals",
]


def _terminal(cfg, section, key):
    """The UT antenna of a ``[terminal]``-shaped section (the Rician factor is the link's)."""
    terminal = section.build(SimpleNamespace(rician_k=cfg.link.rician_k))
    if cfg.link.interference == "all_satellites" and terminal.pattern_lin is None:
        raise ConfigError(
            f"link.interference = 'all_satellites' needs the terminal's pattern, and "
            f"{key}.kind = {section.kind!r} has none (the paper gives the "
            "metasurface's peak gain and roll-off only); use 'serving_satellite' or another "
            "terminal"
        )
    pruning_terminal(terminal, f"{key}.kind = {section.kind!r}")  # refuses what it cannot bound
    return terminal


def terminal_from(cfg):
    """The UT antenna of ``[terminal]``, the default of every population."""
    return _terminal(cfg, cfg.terminal, "terminal")


def ut_terminals(cfg, populations):
    """The UT antenna of every UT: ``[terminal]``, or a population's own ``terminal``.

    Returns the ``[terminal]`` antenna itself when no population has its own (the engine's
    path of one antenna), else a :class:`~leolink.antenna.terminal.TerminalGroups`.
    """
    sections = [(getattr(p, "terminal", None), i) for i, p in enumerate(cfg.population)]
    if all(sec is None for sec, _ in sections):
        return terminal_from(cfg)
    distinct, built, group = [], [], []
    for (sec, i), (_, model) in zip(sections, populations, strict=True):
        sec, key = (cfg.terminal, "terminal") if sec is None else (sec, f"population.{i}.terminal")
        if sec not in distinct:  # equal tables share one antenna
            distinct.append(sec)
            built.append(_terminal(cfg, sec, key))
        group += [distinct.index(sec)] * model.n_ut
    return built[0] if len(built) == 1 else TerminalGroups(built, group)


def atmosphere_from(cfg):
    """``callable(elevation_rad) -> loss_db`` of ``[atmosphere]`` at the ROI centre."""
    return cfg.atmosphere.build(
        SimpleNamespace(
            freq_hz=cfg.link.freq_hz,
            site_lat_deg=cfg.roi.center_lat_deg,
            site_lon_deg=cfg.roi.center_lon_deg,
            table_min_elevation_deg=cfg.constellation.min_elevation_deg - 2.0,
        )
    )


def ptx_per_beam_dbw(link, n_beam, peak_gain_dbi):
    """Power per beam [dBW] of ``[link]``: ``ptx_dbw`` (split over the beams with
    ``power_mode = "split_total"``), or from the EIRP density at the beam peak,
    ``density + 10 log10(B / 1 MHz) - G_peak + L_cable`` (TR 38.821 Table 6.1.1.1-1)."""
    if link.eirp_density_dbw_mhz is not None:
        eirp = float(eirp_from_density_dbw(link.eirp_density_dbw_mhz, link.bandwidth_hz))
        return eirp - peak_gain_dbi + link.cable_loss_db
    if link.power_mode == "split_total":
        return link.ptx_dbw - 10.0 * math.log10(n_beam)
    return link.ptx_dbw


def service_link(cfg, engine):
    """The monitor's :class:`~leolink.sim.service_link.ServiceLink` of ``[modcod]`` and
    ``controller.service_metric``."""
    m, p = cfg.modcod, engine.params
    figures = LinkFigureParams(
        ptx_dbw=p.ptx_dbw,
        cable_loss_db=p.cable_loss_db,
        bandwidth_hz=engine.bandwidth_hz,
        rolloff=m.rolloff,
        implementation_margin_db=m.implementation_margin_db,
        required_esn0_db=m.required_esn0_db,
        metric=m.metric,
        throughput_model=m.throughput_model,
    )
    metric = cfg.controller.service_metric
    threshold = cfg.controller.min_snr_db if metric == "sinr" else None
    return ServiceLink(figures, threshold, metric)


def build_engine(cfg, codebook=None, terminal=None, ephemeris=None):
    """The :class:`~leolink.engine.LinkEngine` of the config (``terminal``: the UT
    antennas, default ``[terminal]``; :func:`ut_terminals` gives the per-population ones;
    ``ephemeris``: the run's, for Earth-fixed beams' cells, built when needed if None)."""
    codebook = codebook_from_config(cfg) if codebook is None else codebook
    n_beam = len(codebook.u_xy)
    peak_dbi = 10.0 * math.log10(codebook.n_sub_x * codebook.n_sub_y)
    params = LinkParams(
        freq_hz=cfg.link.freq_hz,
        bandwidth_hz=cfg.link.bandwidth_hz,
        ptx_dbw=ptx_per_beam_dbw(cfg.link, n_beam, peak_dbi),
        cable_loss_db=cfg.link.cable_loss_db,
        noise_temp_dbk=cfg.link.system_noise_temp_dbk,
        min_elevation_rad=math.radians(cfg.constellation.min_elevation_deg),
        other_loss_db=cfg.link.other_loss_db,
    )
    colors = reuse_colors(codebook.lattice_index, cfg.link.reuse_colors)
    return LinkEngine(
        codebook,
        terminal_from(cfg) if terminal is None else terminal,
        params,
        atmosphere_from(cfg),
        colors,
        other_satellites=cfg.link.interference == "all_satellites",
        steering=steering_from_config(cfg, codebook, ephemeris),
    )


def track_heading_rad(cfg, ephemeris=None):
    """Azimuth (from north, clockwise) of the ROI x axis at the ROI centre [rad]
    (:func:`leolink.app.orbits.roi_frame`)."""
    return roi_frame(cfg, ephemeris).heading_rad


def build_populations(cfg, heading_rad, rng):
    """``[(name, motion model), ...]`` of every ``[[population]]``, in config order.

    With ``earth.model = "wgs84"`` every model is carried onto the ellipsoid
    (:class:`~leolink.sim.mobility.models.OnWgs84`): its latitudes are geodetic.
    """
    rx, ry = cfg.roi_semi_axes_m()
    ctx = PopulationContext(
        center_lat_rad=math.radians(cfg.roi.center_lat_deg),
        center_lon_rad=math.radians(cfg.roi.center_lon_deg),
        semi_axes_m=(rx, ry),
        track_heading_rad=heading_rad,
        rng=rng,
        t0_s=cfg.run.start_s,
        radius_m=cfg.earth.radius_m,
        time_zero_utc=cfg.utc_of_time_zero(),
    )
    mobility = REGISTRIES["population.kind"]
    pops = [(p.name, mobility.build(p.kind, with_sites(p), ctx)) for p in cfg.population]
    if cfg.earth.model == "wgs84":
        pops = [(name, OnWgs84(model, cfg.earth.radius_m)) for name, model in pops]
    return pops


def beams_from(cfg, engine):
    """``(selector, service)`` of the active beams, the scheduler and the precoder; None
    for each part that keeps today's run (every beam lit; no sharing)."""
    a = cfg.satellite_array
    n_rf = a.n_rf_x * a.n_rf_y
    selector = a.build(SimpleNamespace(n_beam=engine.n_beam, n_rf=n_rf))
    scheduler = cfg.scheduler.build()
    precoder = cfg.link.build()
    service = None
    if scheduler.shares or precoder.kind != "none" or not selector.lights_all:
        array = HybridArray(a.n_x, a.n_y, a.n_rf_x, a.n_rf_y)
        service = BeamService(engine, scheduler, precoder, array)
    return (None if selector.lights_all else selector), service


def panel_orientation(cfg, populations):
    """The UTs' :class:`~leolink.antenna.panel.PanelOrientation` from each population's
    ``panel_tilt_deg`` and ``panel_azimuth_deg``; None when every panel lies flat with x
    east (the default frame: the engine's path of today)."""
    counts = [model.n_ut for _, model in populations]
    motion = [p.panel_azimuth_deg == "motion" for p in cfg.population]
    az_deg = [
        90.0 if m else p.panel_azimuth_deg for p, m in zip(cfg.population, motion, strict=True)
    ]
    tilt_deg = [p.panel_tilt_deg for p in cfg.population]
    if not any(motion) and all(t == 0.0 for t in tilt_deg) and all(a == 90.0 for a in az_deg):
        return None
    return PanelOrientation(
        np.repeat(np.radians(tilt_deg), counts),
        np.repeat(np.radians(az_deg), counts),
        np.repeat(motion, counts),
    )


def part_populations(populations, ut_ids):
    """The UTs ``ut_ids`` (run-wide ids, increasing) of ``[(name, model), ...]``: every
    population kept (some with no UT), each with its UTs among ``ut_ids``."""
    out, lo = [], 0
    for name, model in populations:
        mine = ut_ids[(ut_ids >= lo) & (ut_ids < lo + model.n_ut)] - lo
        out.append((name, take_uts(model, mine)))
        lo += model.n_ut
    return out


def build_scenario(cfg, ut_ids=None):
    """The :class:`~leolink.sim.runner.Scenario` of a validated config; with ``ut_ids``
    (increasing run-wide UT ids), of those UTs only, with their keys of the whole run: a
    part of a split run (:mod:`leolink.app.split`)."""
    codebook = codebook_from_config(cfg)
    ephemeris = ephemeris_from_config(cfg)
    frame = roi_frame(cfg, ephemeris)
    heading = frame.heading_rad
    rng = np.random.default_rng(np.random.SeedSequence(cfg.run.seed))
    r = cfg.run
    times, n_warm = epoch_times(r.start_s, r.epoch_s, r.warmup_s, r.duration_s)
    populations, keys = build_populations(cfg, heading, rng), None
    if ut_ids is not None:
        populations = part_populations(populations, ut_ids)
        keys = ut_keys(r.seed, None, ut_ids)
    engine = build_engine(cfg, codebook, ut_terminals(cfg, populations), ephemeris)
    selector, service = beams_from(cfg, engine)
    return Scenario(
        engine=engine,
        ephemeris=ephemeris,
        populations=populations,
        policy=_policy(cfg, ephemeris.n_sat, engine.n_beam),
        min_snr_db=cfg.controller.min_snr_db,
        handover_time_s=cfg.controller.handover_time_s,
        min_elevation_rad=math.radians(cfg.constellation.min_elevation_deg),
        radius_m=cfg.earth.radius_m,
        times_s=times,
        n_warmup=n_warm,
        epoch_s=r.epoch_s,
        seed=r.seed,
        fading_k=cfg.link.rician_k if cfg.link.fading == "rician" else None,
        ellipsoidal=cfg.earth.model == "wgs84",
        environments=_environments(cfg),
        rlf=build_rlf(cfg.controller.rlf),
        signalling=build_signalling(cfg.controller.signalling),
        beam_switch_s=cfg.cells.beam_switch_s if cfg.cells.per == "satellite" else None,
        selector=selector,
        service=service,
        link=service_link(cfg, engine),
        panels=panel_orientation(cfg, populations),
        estimated_ephemeris=estimated_ephemeris(cfg, ephemeris),
        roi_frame=frame,
        ut_keys=keys,
        timing=timing_params(cfg),
    )


def timing_params(cfg):
    """The :class:`~leolink.timing.TimingParams` of ``[timing]``, None when it is off."""
    t = cfg.timing
    if not t.enabled:
        return None
    return TimingParams(t.reference_point, t.n_ta_offset,
                        math.radians(cfg.constellation.min_elevation_deg), cfg.earth.radius_m,
                        cfg.link.freq_hz)  # fmt: skip


def _policy(cfg, n_sat, n_beam):
    """The controller's policy; a measurement model only where a trigger policy reads it."""
    policy = cfg.controller.build(_policy_context(cfg, n_sat, n_beam))
    m = cfg.controller.measurement
    if not hasattr(policy, "run") and m != type(m)():
        changed = next(k for k, v in m if v != getattr(type(m)(), k))
        raise ConfigError(
            f"controller.measurement.{changed} = {getattr(m, changed)!r} is not allowed with "
            f"controller.policy = {cfg.controller.policy!r}: the measurement model feeds the "
            "3GPP trigger policies (a3, a4, a5, a2a4, d1, d2, t1, elevation, time_to_exit, cho)"
        )
    return policy


def _policy_context(cfg, n_sat, n_beam):
    """What the policies are built with: the L3 filter, the level of ``[cells]``, the
    ``[[controller.cell_offsets]]`` and ``[[controller.reference_points]]`` (each cell checked
    against the constellation), the beams per satellite, the epoch and the UTC second of time
    0 (``slotted``'s grid)."""
    for table in ("cell_offsets", "reference_points"):
        for i, c in enumerate(getattr(cfg.controller, table)):
            for key, value, n in (("sat_id", c.sat_id, n_sat), ("beam_id", c.beam_id, n_beam)):
                if value is not None and value >= n:
                    raise ConfigError(
                        f"controller.{table}.{i}.{key} = {value} is not allowed: use 0 .. "
                        f"{n - 1} (the run has {n})"
                    )
    utc0 = cfg.utc_of_time_zero()
    return SimpleNamespace(
        filter=cfg.controller.filter,
        level="satellite" if cfg.cells.per == "satellite" else None,
        cell_offsets=cfg.controller.cell_offsets,
        n_beam=n_beam,
        epoch_s=cfg.run.epoch_s,
        # seconds past the UTC minute of simulation time 0 (the slotted policy's grid)
        utc_offset_s=0.0 if utc0 is None else utc0.second + utc0.microsecond * 1e-6,
        reference_points=_reference_points(cfg),
        steering=cfg.satellite_array.steering,
        measurement=cfg.controller.measurement,
        noise_temp_dbk=cfg.link.system_noise_temp_dbk,
    )


def _reference_points(cfg):
    """``[[controller.reference_points]]`` as ``(sat_id, beam_id or None, (x, y, z) [m])``,
    on the run's Earth (the satellites' Earth-fixed frame)."""
    out = []
    for c in cfg.controller.reference_points:
        pos = surface_point(cfg, math.radians(c.lat_deg), math.radians(c.lon_deg))
        out.append((c.sat_id, c.beam_id, tuple(np.asarray(pos, float).ravel())))
    return tuple(out)


def estimated_ephemeris(cfg, ephemeris):
    """The ephemeris the controller believes (``[ephemeris_error]``), None without error."""
    model = cfg.ephemeris_error.build(SimpleNamespace(seed=cfg.run.seed))
    if model.is_zero:  # the error-free run, bit for bit
        return None
    if cfg.link.interference == "all_satellites":
        raise ConfigError(
            f"ephemeris_error.model = {cfg.ephemeris_error.model!r} with link.interference = "
            "'all_satellites' is not supported yet; use 'serving_satellite'"
        )
    return EstimatedEphemeris(ephemeris, model)


def _environments(cfg):
    """The populations' TR 38.811 environments (None: all open country)."""
    models = environment_models(cfg.population, cfg.link.freq_hz)
    if models and cfg.atmosphere.model == "itu_p618" and any(m.scintillation for m in models):
        raise ConfigError(
            "population.channel.scintillation = true is not allowed with atmosphere.model = "
            "'itu_p618' (it contains scintillation already); use one of the two"
        )
    return models
