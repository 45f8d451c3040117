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

from leolink.antenna.terminal import TerminalGroups
from leolink.app.codebook import codebook_from_config
from leolink.app.orbits import ephemeris_from_config, overhead_satellite, roi_frame
from leolink.app.steering import steering_from_config
from leolink.engine import LinkEngine, LinkParams, reuse_colors
from leolink.ephemeris_error import EstimatedEphemeris
from leolink.errors import ConfigError
from leolink.registry import REGISTRIES
from leolink.sim.mobility import OnWgs84
from leolink.sim.populations import PopulationContext
from leolink.sim.runner import Scenario, epoch_times

__all__ = [
    "build_engine",
    "build_populations",
    "build_scenario",
    "codebook_from_config",
    "ephemeris_from_config",
    "overhead_satellite",
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


def build_engine(cfg, codebook=None, terminal=None, ephemeris=None):
    """The :class:`~leolink.engine.LinkEngine` of the config (``terminal``: the UT
    antennas, default ``[terminal]``; :func:`ut_terminals` gives the per-population ones;
    ``ephemeris``: the run's, for Earth-fixed beams' cells, built when needed if None)."""
    codebook = codebook_from_config(cfg) if codebook is None else codebook
    n_beam = len(codebook.u_xy)
    ptx = cfg.link.ptx_dbw
    if cfg.link.power_mode == "split_total":
        ptx -= 10.0 * math.log10(n_beam)
    params = LinkParams(
        freq_hz=cfg.link.freq_hz,
        bandwidth_hz=cfg.link.bandwidth_hz,
        ptx_dbw=ptx,
        cable_loss_db=cfg.link.cable_loss_db,
        noise_temp_dbk=cfg.link.noise_temp_dbk,
        min_elevation_rad=math.radians(cfg.constellation.min_elevation_deg),
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
    (:class:`~leolink.sim.mobility.OnWgs84`): its latitudes are geodetic.
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
    pops = [(p.name, mobility.build(p.kind, p, ctx)) for p in cfg.population]
    if cfg.earth.model == "wgs84":
        pops = [(name, OnWgs84(model, cfg.earth.radius_m)) for name, model in pops]
    return pops


def build_scenario(cfg):
    """The :class:`~leolink.sim.runner.Scenario` of a validated config."""
    codebook = codebook_from_config(cfg)
    ephemeris = ephemeris_from_config(cfg)
    heading = track_heading_rad(cfg, ephemeris)
    rng = np.random.default_rng(np.random.SeedSequence(cfg.run.seed))
    r = cfg.run
    times, n_warm = epoch_times(r.start_s, r.epoch_s, r.warmup_s, r.duration_s)
    populations = build_populations(cfg, heading, rng)
    return Scenario(
        engine=build_engine(cfg, codebook, ut_terminals(cfg, populations), ephemeris),
        ephemeris=ephemeris,
        populations=populations,
        policy=cfg.controller.build(),
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
        estimated_ephemeris=estimated_ephemeris(cfg, ephemeris),
    )


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
