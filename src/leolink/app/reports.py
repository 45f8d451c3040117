"""What ``leolink budget`` and ``leolink codebook`` print: the budget term by term, the beams."""

from __future__ import annotations

import math

import numpy as np

from leolink.antenna.codebook import (
    CANONICAL_ALONG_TRACK,
    canonical_satellite,
    footprint_centres,
)
from leolink.app.codebook import codebook_design_from_config
from leolink.app.scenario import build_engine, track_heading_rad
from leolink.errors import ConfigError
from leolink.geometry import (
    ecef_to_geodetic,
    enu_basis,
    geodetic_to_ecef,
    nadir_angle_rad,
    roi_to_ground,
)
from leolink.link.budget import LinkBudget
from leolink.orbit import orbital_speed_m_s

__all__ = ["codebook_table", "link_budget_at_elevation"]


def _budget_satellite(cfg):
    """The codebook's canonical satellite with its orbital speed: (1, 3) position, velocity."""
    c, e = cfg.constellation, cfg.earth
    speed = float(orbital_speed_m_s(c.altitude_m, e.radius_m, e.gm_m3_s2))
    return canonical_satellite(c.altitude_m, e.radius_m)[None], speed * CANONICAL_ALONG_TRACK[None]


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
    sat_pos, sat_vel = _budget_satellite(cfg)
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
    """The codebook as a JSON-ready dict: ``oversampling``, the design figures (RF chains,
    idle chains, worst-case loss inside the ROI and where) and a list of ``beams``."""
    design = codebook_design_from_config(cfg)
    cb = design.codebook
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
        "n_rf": design.n_rf,
        "idle_rf_chains": design.idle_rf,
        "worst_roi_loss_db": design.loss.loss_db,
        "worst_roi_point_m": [design.loss.x_m, design.loss.y_m],
        "holes": design.holes,
        "design": design.describe(),
        "n_sub_x": int(cb.n_sub_x),
        "n_sub_y": int(cb.n_sub_y),
        "roi_semi_axes_m": [rx, ry],
        "beams": beams,
    }
