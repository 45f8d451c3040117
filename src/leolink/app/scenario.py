"""From a validated config to the objects a run needs: the wiring, in one place.

This is where config sections become physics objects: the codebook, the terminal
antenna, the atmosphere, the link engine, the ephemeris, the UT populations and the
policy, gathered in a :class:`leolink.sim.runner.Scenario`. Pluggable kinds are built
through their registries (``section.build(context)``), never by name here.
"""

from __future__ import annotations

import math
from datetime import UTC
from types import SimpleNamespace

import numpy as np

from leolink.antenna.codebook import build_codebook, find_oversampling
from leolink.engine import LinkEngine, LinkParams, reuse_colors
from leolink.errors import ConfigError
from leolink.geometry import enu_basis
from leolink.io.tle import read_tle_file
from leolink.orbit import Ephemeris, pass_over, walker_delta
from leolink.registry import REGISTRIES
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
]


def codebook_from_config(cfg):
    """The pruned DFT codebook of the config (``oversampling = 'auto'`` solved here)."""
    a = cfg.satellite_array
    n_sub_x, n_sub_y = a.n_x // a.n_rf_x, a.n_y // a.n_rf_y
    rx, ry = cfg.roi_semi_axes_m()
    h, radius = cfg.constellation.altitude_m, cfg.earth.radius_m
    o = a.oversampling
    n_rf = a.n_rf_x * a.n_rf_y
    if o == "auto":
        o = find_oversampling(n_sub_x, n_sub_y, n_rf, rx, ry, h, radius_m=radius)
    cb = build_codebook(n_sub_x, n_sub_y, float(o), rx, ry, h, radius_m=radius)
    if cb.n_beam > n_rf:
        # Each RF chain drives one subarray and so one beam (paper Sec. 2.1): a codebook
        # with more beams than chains cannot be radiated at once.
        raise ConfigError(
            f"satellite_array.oversampling = {o!r} gives {cb.n_beam} beams over the "
            f"{rx / 1e3:.1f} x {ry / 1e3:.1f} km ROI, but {n_rf} RF chains drive one beam each; "
            'use a smaller oversampling ("auto" picks one with a beam per RF chain), more '
            "RF chains or a smaller ROI"
        )
    if cb.n_beam == 0:
        raise ConfigError(
            f"satellite_array.oversampling = {o!r} leaves no beam pointing into the "
            f'{rx / 1e3:.1f} x {ry / 1e3:.1f} km ROI; use a larger oversampling or "auto"'
        )
    return cb


def terminal_from(cfg):
    """The UT antenna of ``[terminal]`` (the Rician factor is the link's)."""
    terminal = cfg.terminal.build(SimpleNamespace(rician_k=cfg.link.rician_k))
    if cfg.link.interference == "all_satellites" and terminal.pattern_lin is None:
        raise ConfigError(
            f"link.interference = 'all_satellites' needs the terminal's pattern, and "
            f"terminal.kind = {cfg.terminal.kind!r} has none (the paper gives the "
            "metasurface's peak gain and roll-off only); use 'serving_satellite' or another "
            "terminal"
        )
    return terminal


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


def build_engine(cfg, codebook=None):
    """The :class:`~leolink.engine.LinkEngine` of the config."""
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
        terminal_from(cfg),
        params,
        atmosphere_from(cfg),
        colors,
        other_satellites=cfg.link.interference == "all_satellites",
    )


def ephemeris_from_config(cfg):
    """Satellite ephemeris: one pass over the ROI centre, a Walker constellation, or TLEs."""
    c, e = cfg.constellation, cfg.earth
    inc = math.radians(c.inclination_deg)
    if c.kind == "tle":
        from datetime import datetime

        from sgp4.api import jday

        tles = read_tle_file(c.tle_file)
        when = datetime.fromisoformat(c.tle_epoch_utc) if c.tle_epoch_utc else None
        if when is None:
            from sgp4.api import Satrec

            s = Satrec.twoline2rv(tles[0][1], tles[0][2])
            jd, fr = s.jdsatepoch, s.jdsatepochF
        else:
            when = when.astimezone(UTC) if when.tzinfo else when
            jd, fr = jday(
                when.year,
                when.month,
                when.day,
                when.hour,
                when.minute,
                when.second + when.microsecond * 1e-6,
            )
        return Ephemeris.from_tles(tles, jd, fr, earth_rotation=e.rotation, gm_m3_s2=e.gm_m3_s2)
    if c.kind == "walker":
        el = walker_delta(c.n_planes * c.sats_per_plane, c.n_planes, c.phasing, inc, c.altitude_m)
    else:
        el = pass_over(
            math.radians(cfg.roi.center_lat_deg),
            math.radians(cfg.roi.center_lon_deg),
            c.pass_time_s,
            c.altitude_m,
            inc,
            ascending=c.ascending,
            earth_rotation=e.rotation,
            radius_m=e.radius_m,
            gm_m3_s2=e.gm_m3_s2,
        )
    return Ephemeris.from_elements(
        el, earth_rotation=e.rotation, radius_m=e.radius_m, gm_m3_s2=e.gm_m3_s2
    )


def overhead_satellite(cfg):
    """Position, velocity and acceleration, each (1, 3), of a satellite of the configured
    orbit (altitude, inclination, ascending or descending) right over the ROI centre."""
    c, e = cfg.constellation, cfg.earth
    el = pass_over(
        math.radians(cfg.roi.center_lat_deg),
        math.radians(cfg.roi.center_lon_deg),
        0.0,
        c.altitude_m,
        math.radians(c.inclination_deg),
        ascending=c.ascending,
        earth_rotation=e.rotation,
        radius_m=e.radius_m,
        gm_m3_s2=e.gm_m3_s2,
    )
    eph = Ephemeris.from_elements(
        el, earth_rotation=e.rotation, radius_m=e.radius_m, gm_m3_s2=e.gm_m3_s2
    )
    pos, vel, acc = eph(0.0)
    return pos[0], vel[0], acc[0]


def track_heading_rad(cfg):
    """Azimuth (from north, clockwise) of the ROI x axis at the ROI centre.

    The velocity, in the local horizon of the centre, of a satellite of the configured
    orbit passing right over it (with Earth rotation on: its Earth-fixed velocity, i.e.
    the direction of its ground track there).
    """
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    _, vel, _ = overhead_satellite(cfg)
    east, north, _ = enu_basis(lat, lon)
    return math.atan2(float(vel[0] @ east), float(vel[0] @ north))


def build_populations(cfg, heading_rad, rng):
    """``[(name, motion model), ...]`` of every ``[[population]]``, in config order."""
    rx, ry = cfg.roi_semi_axes_m()
    ctx = PopulationContext(
        center_lat_rad=math.radians(cfg.roi.center_lat_deg),
        center_lon_rad=math.radians(cfg.roi.center_lon_deg),
        semi_axes_m=(rx, ry),
        track_heading_rad=heading_rad,
        rng=rng,
        t0_s=cfg.run.start_s,
        radius_m=cfg.earth.radius_m,
    )
    mobility = REGISTRIES["population.kind"]
    return [(p.name, mobility.build(p.kind, p, ctx)) for p in cfg.population]


def build_scenario(cfg):
    """The :class:`~leolink.sim.runner.Scenario` of a validated config."""
    codebook = codebook_from_config(cfg)
    heading = track_heading_rad(cfg)
    rng = np.random.default_rng(np.random.SeedSequence(cfg.run.seed))
    r = cfg.run
    times, n_warm = epoch_times(r.start_s, r.epoch_s, r.warmup_s, r.duration_s)
    return Scenario(
        engine=build_engine(cfg, codebook),
        ephemeris=ephemeris_from_config(cfg),
        populations=build_populations(cfg, heading, rng),
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
    )
