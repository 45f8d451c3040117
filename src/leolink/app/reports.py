"""What ``leolink budget`` and ``leolink codebook`` print: the budget term by term, the beams."""

from __future__ import annotations

import math

import numpy as np

from leolink.antenna.aperture import circular_aperture_gain_db
from leolink.antenna.codebook import (
    CANONICAL_ALONG_TRACK,
    canonical_satellite,
    footprint_centres,
)
from leolink.app.codebook import codebook_design_from_config
from leolink.app.scenario import (
    atmosphere_from,
    build_engine,
    ptx_per_beam_dbw,
    terminal_from,
    track_heading_rad,
)
from leolink.errors import ConfigError
from leolink.geometry import (
    ecef_to_geodetic,
    enu_basis,
    geodetic_to_ecef,
    nadir_angle_rad,
    roi_to_ground,
    slant_range_from_elevation_m,
)
from leolink.io.tables import NO_MODCOD_NAME
from leolink.link.acm import LinkFigureParams, esn0_and_modcod
from leolink.link.budget import LinkBudget
from leolink.link.figures import (
    cn0_dbhz,
    cnr_db,
    eirp_density_dbw_mhz,
    g_over_t_db_k,
    margin_db,
    symbol_rate_baud,
)
from leolink.link.modcod import modcod_names, modcod_throughput_bps
from leolink.orbit import orbital_speed_m_s

__all__ = ["codebook_table", "link_budget_at_elevation"]


def _budget_satellite(cfg):
    """The codebook's canonical satellite with its orbital speed: (1, 3) position, velocity."""
    c, e = cfg.constellation, cfg.earth
    speed = float(orbital_speed_m_s(c.altitude_m, e.radius_m, e.gm_m3_s2))
    return canonical_satellite(c.altitude_m, e.radius_m)[None], speed * CANONICAL_ALONG_TRACK[None]


def _engine_terms(cfg, elevation_rad):
    """Geometry, gains and SINR of the hybrid UPA's best beam on a UT at ``elevation_rad``
    (the UT in the satellite's along-track plane, ahead of the satellite)."""
    engine = build_engine(cfg)
    radius, h = cfg.earth.radius_m, cfg.constellation.altitude_m
    central = math.pi / 2 - elevation_rad - float(nadir_angle_rad(elevation_rad, h, radius))
    ut = np.array([[radius * math.sin(central), 0.0, radius * math.cos(central)]])
    sat_pos, sat_vel = _budget_satellite(cfg)
    snap = engine.evaluate(ut, sat_pos, sat_vel)
    best = int(np.nanargmax(snap.gain_tx_lin[0, 0]))
    zero = np.zeros((1, 3))
    cols = engine.serve(snap, np.array([0]), np.array([best]), zero, zero, sat_vel, zero)
    terms = {k: float(cols[k][0]) for k in ("slant_range_m", "gain_tx_db", "gain_rx_db", "atm_db")}
    return {
        **terms,
        "ptx_dbw": engine.params.ptx_dbw,
        "bandwidth_hz": engine.bandwidth_hz,
        "sinr_db": float(cols["sinr_db"][0]),
        "engine_snr_db": float(cols["snr_db"][0]),
        "best_beam": best,
        "n_beam": engine.n_beam,
    }


def _aperture_terms(cfg, elevation_rad):
    """The same terms for the TR 38.811 Sec. 6.4.1 circular aperture, its one beam centred
    on the UT (boresight gain G_max; no other beam, so SINR = SNR)."""
    a = cfg.satellite_array
    gain_tx = float(circular_aperture_gain_db(0.0, cfg.link.freq_hz, a.aperture_diameter_m,
                                              a.aperture_gain_dbi))  # fmt: skip
    terminal = terminal_from(cfg)
    return {
        "slant_range_m": float(
            slant_range_from_elevation_m(
                elevation_rad, cfg.constellation.altitude_m, cfg.earth.radius_m
            )
        ),
        "gain_tx_db": gain_tx,
        "gain_rx_db": float(terminal.gain_db(elevation_rad)),
        "atm_db": float(atmosphere_from(cfg)(elevation_rad)),
        "ptx_dbw": ptx_per_beam_dbw(cfg.link, 1, a.aperture_gain_dbi),
        "bandwidth_hz": cfg.link.bandwidth_hz / cfg.link.reuse_colors,
        "sinr_db": None,
        "engine_snr_db": None,
        "best_beam": 0,
        "n_beam": 1,
    }


def _figures(cfg, budget, sinr_db):
    """EIRP density, G/T, C/N0, CNR, Es/N0, margin and MODCOD of a budget (link.figures)."""
    m, bw = cfg.modcod, budget["bandwidth_hz"]
    t_dbk = cfg.link.system_noise_temp_dbk
    gt = float(g_over_t_db_k(budget["gain_rx_db"], noise_temp_dbk=t_dbk))
    path_db = budget["fspl_db"] + budget["atm_db"] + budget["other_loss_db"]
    cn0 = float(cn0_dbhz(budget["eirp_dbw"], path_db, gt))
    rs = float(symbol_rate_baud(bw, m.rolloff))
    # Es/N0 and the MODCOD from the CNR (the budget's SNR) or the engine's SINR: link.acm's
    metric = m.metric if sinr_db is not None else "snr"
    params = LinkFigureParams(0.0, 0.0, bw, m.rolloff, m.implementation_margin_db,
                              m.required_esn0_db, metric)  # fmt: skip
    _, esn0, row = esn0_and_modcod(float(cnr_db(cn0, bw)), sinr_db, params)
    esn0, row = float(esn0), int(row)
    shannon_sinr = budget["snr_db"] if sinr_db is None else sinr_db
    return {
        "eirp_density_dbw_mhz": float(eirp_density_dbw_mhz(budget["eirp_dbw"], bw)),
        "noise_temp_dbk": t_dbk,
        "g_over_t_db_k": gt,
        "cn0_dbhz": cn0,
        "cnr_db": float(cnr_db(cn0, bw)),
        "rolloff": m.rolloff,
        "symbol_rate_baud": rs,
        "esn0_metric": metric,
        "esn0_db": esn0,
        "required_esn0_db": params.threshold_db,
        "margin_db": float(margin_db(esn0, params.threshold_db)),
        "modcod": str(modcod_names(row)) or NO_MODCOD_NAME,
        "throughput_dvbs2x_bps": float(modcod_throughput_bps(row, rs)),
        "throughput_shannon_bps": bw * math.log2(1.0 + 10.0 ** (shannon_sinr / 10.0)),
    }


def link_budget_at_elevation(cfg, elevation_deg):
    """The link budget, term by term, for one UT at ``elevation_deg`` under the best beam,
    with the link figures (EIRP, G/T, C/N0, CNR, Es/N0, margin, MODCOD, throughputs).

    With the hybrid UPA the engine gives the geometry, the gains and the SINR; with the
    circular aperture (``satellite_array.antenna``) the aperture's beam is centred on the UT.
    The CNR is TR 38.821 Sec. 6.1.3.1's: ``C/N0 - 10 log10(B)``, the SNR of the budget.
    Below ``constellation.min_elevation_deg`` the engine serves no link (its figures are
    NaN) and ``note`` says so in one line.
    """
    if not 0.0 < elevation_deg <= 90.0:
        raise ConfigError(f"--elevation-deg = {elevation_deg!r} is not allowed; use (0, 90] deg")
    el = math.radians(elevation_deg)
    aperture = cfg.satellite_array.antenna == "circular_aperture"
    t = _aperture_terms(cfg, el) if aperture else _engine_terms(cfg, el)
    # The budget term by term with the link module's formulas (Sec. 2.2); the engine gave
    # the geometry, the gains and the SINR (tests check that both SNRs agree).
    budget = LinkBudget.compute(
        elevation_deg=elevation_deg,
        slant_range_m=t["slant_range_m"],
        freq_hz=cfg.link.freq_hz,
        ptx_dbw=t["ptx_dbw"],
        gain_tx_db=t["gain_tx_db"],
        gain_rx_db=t["gain_rx_db"],
        noise_temp_dbk=cfg.link.system_noise_temp_dbk,
        bandwidth_hz=t["bandwidth_hz"],
        atm_db=t["atm_db"],
        cable_db=cfg.link.cable_loss_db,
        other_loss_db=cfg.link.other_loss_db,
    ).as_dict()
    budget.update(freq_hz=cfg.link.freq_hz, bandwidth_hz=t["bandwidth_hz"])
    out = {
        **budget,
        "sinr_db": t["sinr_db"],
        "engine_snr_db": t["engine_snr_db"],
        **_figures(cfg, budget, t["sinr_db"]),
        "best_beam": t["best_beam"],
        "n_beam": t["n_beam"],
        "satellite_antenna": cfg.satellite_array.antenna,
        "terminal": cfg.terminal.kind,
    }
    mask_deg = cfg.constellation.min_elevation_deg
    if not aperture and elevation_deg < mask_deg:  # the engine serves no link below it
        out["note"] = (
            f"{elevation_deg:g} deg is below constellation.min_elevation_deg = {mask_deg:g} deg: "
            "no link is served there, so sinr_db, engine_snr_db, esn0_db, margin_db and the "
            "Shannon throughput are NaN (the budget terms above them are the geometry's)"
        )
    return out


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
