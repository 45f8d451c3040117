"""From a validated :class:`~leolink.config.Config` to the objects a run needs.

This is the one place that reads config sections and builds physics objects: the
codebook, the terminal antenna, the atmosphere, the link engine, the ephemeris and the
UT populations. ``leolink budget`` and ``leolink codebook`` are answered here too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC

import numpy as np

from leolink.antenna.codebook import build_codebook, find_oversampling, footprint_centres
from leolink.antenna.terminal import terminal_from_config
from leolink.engine import LinkEngine, LinkParams, reuse_colors
from leolink.errors import ConfigError
from leolink.geometry import (
    ecef_to_geodetic,
    enu_basis,
    geodetic_to_ecef,
    nadir_angle_rad,
    roi_to_ground,
)
from leolink.link.atmosphere import atmosphere_model
from leolink.link.budget import LinkBudget
from leolink.orbit import Ephemeris, pass_over, read_tle_file, walker_delta

__all__ = [
    "Scenario",
    "build_engine",
    "build_scenario",
    "codebook_from_config",
    "codebook_table",
    "ephemeris_from_config",
    "link_budget_at_elevation",
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
    t = cfg.terminal
    params = {
        "isotropic": {},
        "upa": {"n_x": t.n_x, "n_y": t.n_y, "rician_k": cfg.link.rician_k},
        "leaky_wave": {"n_x": t.n_x, "n_y": t.n_y, "leakage": t.leakage},
        "metasurface": {"peak_gain_db": t.peak_gain_db, "rolloff": t.rolloff},
    }[t.kind]
    return terminal_from_config(t.kind, **params)


def atmosphere_from(cfg):
    """``callable(elevation_rad) -> loss_db`` for the configured model and ROI site.

    The slow models are tabulated once from just below the minimum elevation, every 2 deg:
    the table interpolates loss / air mass, which is smooth, so this stays within 2e-4
    (relative) of direct ITU-R P.676 calls (0.5 deg steps: 1.5e-5, at 3.4x the set-up time).
    """
    a, site, f = cfg.atmosphere, cfg.roi, cfg.link.freq_hz
    if a.model == "fixed":
        return atmosphere_model("fixed", f, loss_db=a.fixed_db)
    table = {
        "min_elevation_deg": max(0.0, cfg.constellation.min_elevation_deg - 2.0),
        "step_deg": 2.0,
    }
    here = {"lat_deg": site.center_lat_deg, "lon_deg": site.center_lon_deg}
    if a.model == "itu_p676":
        return atmosphere_model("itu_p676", f, **here, **table)
    if a.model == "itu_p618":
        return atmosphere_model(
            "itu_p618",
            f,
            **here,
            p_percent=a.exceedance_percent,
            diameter_m=a.antenna_diameter_m,
            **table,
        )
    return atmosphere_model("paper", f, **table)


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


@dataclass
class Scenario:
    """Everything a run builds from its config, once."""

    cfg: object
    codebook: object
    engine: LinkEngine
    ephemeris: Ephemeris
    heading_rad: float
    roi_axes_m: tuple


def build_scenario(cfg):
    codebook = codebook_from_config(cfg)
    eph = ephemeris_from_config(cfg)
    return Scenario(
        cfg,
        codebook,
        build_engine(cfg, codebook),
        eph,
        track_heading_rad(cfg),
        cfg.roi_semi_axes_m(),
    )


def _canonical_satellite(cfg):
    """Satellite over the pole of a canonical frame, moving along +x (body = ECI axes)."""
    r_sat = cfg.earth.radius_m + cfg.constellation.altitude_m
    from leolink.orbit import orbital_speed_m_s

    v = float(
        orbital_speed_m_s(cfg.constellation.altitude_m, cfg.earth.radius_m, cfg.earth.gm_m3_s2)
    )
    return np.array([[0.0, 0.0, r_sat]]), np.array([[v, 0.0, 0.0]])


def link_budget_at_elevation(cfg, elevation_deg):
    """The link budget, term by term, for one UT at ``elevation_deg`` under the best beam.

    The UT is in the satellite's along-track plane, ahead of the satellite.
    """
    if not 0.0 < elevation_deg <= 90.0:
        raise ConfigError(f"--elevation-deg = {elevation_deg!r} is not allowed; use (0, 90] deg")
    engine = build_engine(cfg)
    radius, h = cfg.earth.radius_m, cfg.constellation.altitude_m
    el = math.radians(elevation_deg)
    central = math.pi / 2 - el - float(nadir_angle_rad(el, h, radius))
    ut = np.array([[radius * math.sin(central), 0.0, radius * math.cos(central)]])
    sat_pos, sat_vel = _canonical_satellite(cfg)
    snap = engine.evaluate(ut, sat_pos, sat_vel)
    best = int(np.nanargmax(snap.gain_tx_lin[0, 0]))
    zero = np.zeros((1, 3))
    cols = engine.serve(snap, np.array([0]), np.array([best]), zero, zero, sat_vel, zero)
    p = engine.params
    # The budget term by term with the link module's formulas (Sec. 2.2); the engine gave
    # the geometry, the gains and the SINR (tests check that both SNRs agree).
    budget = LinkBudget.compute(
        elevation_deg=elevation_deg,
        slant_range_m=float(cols["slant_range_m"][0]),
        freq_hz=p.freq_hz,
        ptx_dbw=p.ptx_dbw,
        gain_tx_db=float(cols["gain_tx_db"][0]),
        gain_rx_db=float(cols["gain_rx_db"][0]),
        noise_temp_dbk=p.noise_temp_dbk,
        bandwidth_hz=engine.bandwidth_hz,
        atm_db=float(cols["atm_db"][0]),
        cable_db=p.cable_loss_db,
    ).as_dict()
    return {
        **budget,
        "freq_hz": p.freq_hz,
        "bandwidth_hz": engine.bandwidth_hz,
        "sinr_db": float(cols["sinr_db"][0]),
        "engine_snr_db": float(cols["snr_db"][0]),
        "best_beam": best,
        "n_beam": engine.n_beam,
        "terminal": cfg.terminal.kind,
    }


def codebook_table(cfg):
    """The codebook as a JSON-ready dict: ``oversampling`` and a list of ``beams``."""
    cb = codebook_from_config(cfg)
    x, y = footprint_centres(cb, cfg.constellation.altitude_m, radius_m=cfg.earth.radius_m)
    # Footprints on the ground at the pass instant, in the ROI frame of the centre.
    lat_c, lon_c = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    centre = geodetic_to_ecef(lat_c, lon_c, cfg.constellation.altitude_m, cfg.earth.radius_m)
    east, north, _ = enu_basis(lat_c, lon_c)
    hd = track_heading_rad(cfg)
    along = math.sin(hd) * east + math.cos(hd) * north
    ground = roi_to_ground(np.asarray(x), np.asarray(y), centre, along, cfg.earth.radius_m)
    lat, lon, _ = ecef_to_geodetic(ground, cfg.earth.radius_m)
    beams = [
        {
            "beam_id": int(cb.beam_id[k]),
            "u_x": float(cb.u_xy[k, 0]),
            "u_y": float(cb.u_xy[k, 1]),
            "x_m": float(x[k]),
            "y_m": float(y[k]),
            "lat_deg": float(np.degrees(lat[k])),
            "lon_deg": float(np.degrees(lon[k])),
        }
        for k in range(len(cb.u_xy))
    ]
    rx, ry = cfg.roi_semi_axes_m()
    return {
        "oversampling": float(cb.oversampling),
        "n_sub_x": int(cb.n_sub_x),
        "n_sub_y": int(cb.n_sub_y),
        "roi_semi_axes_m": [rx, ry],
        "beams": beams,
    }
