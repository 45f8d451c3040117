"""Coverage maps: beam cells, agreement with ``leolink budget``, and the CSV contract."""

import numpy as np
import pandas as pd
import pytest

from leolink.app.coverage import COVERAGE_COLUMNS, coverage_grid
from leolink.app.reports import codebook_table, link_budget_at_elevation
from leolink.app.scenario import build_engine, overhead_satellite
from leolink.config import load_config
from leolink.coverage import evaluate_points
from leolink.geometry import look_angles, roi_to_ground

PAPER = "configs/paper.toml"


@pytest.fixture(scope="module")
def paper_grid():
    return coverage_grid(load_config(PAPER), n_grid=81, margin=1.1)


def test_each_beam_cell_contains_its_footprint_centre():
    cfg = load_config(PAPER)
    engine = build_engine(cfg)
    info = codebook_table(cfg)
    x = np.array([b["x_m"] for b in info["beams"]])
    y = np.array([b["y_m"] for b in info["beams"]])
    sat_pos, sat_vel, sat_acc = overhead_satellite(cfg)
    ground = roi_to_ground(x, y, sat_pos[0], sat_vel[0], cfg.earth.radius_m)
    cols = evaluate_points(engine, ground, sat_pos, sat_vel, sat_acc)
    np.testing.assert_array_equal(cols["best_beam"], [b["beam_id"] for b in info["beams"]])


def test_grid_cells_match_beam_gains(paper_grid):
    df = paper_grid
    assert list(df.columns) == COVERAGE_COLUMNS
    # Every beam of the codebook owns a cell inside the ROI (the paper's rectangular tiling).
    owned = set(df.loc[df.in_roi, "best_beam"])
    assert owned == set(range(15))
    assert np.all(df.sinr_db <= df.snr_db + 1e-12)


def test_snr_at_roi_centre_matches_budget(paper_grid):
    cfg = load_config(PAPER)
    centre = paper_grid.loc[(paper_grid.x_m.abs() < 1e-6) & (paper_grid.y_m.abs() < 1e-6)]
    assert len(centre) == 1
    budget = link_budget_at_elevation(cfg, 90.0)
    assert centre.snr_db.iloc[0] == pytest.approx(budget["snr_db"], abs=1e-9)
    assert centre.sinr_db.iloc[0] == pytest.approx(budget["sinr_db"], abs=1e-9)
    # Straight under the satellite its velocity is horizontal: no Doppler.
    assert abs(centre.doppler_hz.iloc[0]) < 1e-6


def test_elevation_of_grid_points_is_consistent():
    cfg = load_config(PAPER)
    sat_pos, sat_vel, _ = overhead_satellite(cfg)
    x = np.array([0.0, 534.1e3, 0.0])
    y = np.array([0.0, 0.0, 170.5e3])
    ground = roi_to_ground(x, y, sat_pos[0], sat_vel[0], cfg.earth.radius_m)
    el, _, rng = look_angles(ground, sat_pos[0])
    # Nadir: 90 deg and h; ROI tip: the geometry of leolink.geometry, independently.
    assert np.degrees(el[0]) == pytest.approx(90.0, abs=1e-9)
    assert rng[0] == pytest.approx(1.3e6, abs=1e-3)
    # ROI tip x = 534.1 km: central angle a = atan(x / R); seen from the ground point the
    # satellite is (R + h) cos a - R up and (R + h) sin a across (was: "60 < el < 70").
    a = np.arctan(534.1e3 / cfg.earth.radius_m)
    r_sat = cfg.earth.radius_m + cfg.constellation.altitude_m
    el_tip = np.arctan2(r_sat * np.cos(a) - cfg.earth.radius_m, r_sat * np.sin(a))
    assert el[1] == pytest.approx(el_tip, abs=1e-12)


def test_coverage_cli_writes_csv(tmp_path):
    from leolink.cli import main

    code = main(
        ["coverage", PAPER, "--out", str(tmp_path), "--grid", "21", "--no-plots", "--quiet"]
    )
    assert code == 0
    df = pd.read_csv(tmp_path / "coverage.csv")
    assert list(df.columns) == COVERAGE_COLUMNS
    assert len(df) == 21 * 21
    assert (tmp_path / "config.resolved.toml").exists()
    assert not list(tmp_path.glob("*.partial"))


@pytest.mark.parametrize("rotation", ["false", "true"])
def test_roi_axis_heading_is_the_ground_track_of_the_pass(rotation):
    """The ROI x axis (used to place UTs) follows the pass's ground track: compare with
    the bearing between the sub-satellite points 1 s before and after the overhead time."""
    import math

    from leolink.app.scenario import ephemeris_from_config, track_heading_rad
    from leolink.geometry import ecef_to_geodetic

    cfg = load_config(PAPER, [f"earth.rotation={rotation}"])
    pos = ephemeris_from_config(cfg)(np.array([59.0, 61.0]))[0][:, 0]
    lat, lon, _ = ecef_to_geodetic(pos)
    # Initial bearing of the great circle from the first to the second point.
    dlon = lon[1] - lon[0]
    bearing = math.atan2(
        math.sin(dlon) * math.cos(lat[1]),
        math.cos(lat[0]) * math.sin(lat[1]) - math.sin(lat[0]) * math.cos(lat[1]) * math.cos(dlon),
    )
    # 2 s of a ~6 km/s track curves the bearing by far less than 1e-3 rad.
    assert track_heading_rad(cfg) == pytest.approx(bearing, abs=1e-3)


def test_grid_recomputed_with_explicit_steering_vectors(paper_grid):
    """Every in-ROI grid point of ``leolink coverage`` recomputed another way
    (tests/independent.py): the ROI plane mapped by the central projection of Sec. 3.1,
    the satellite overhead on a Clairaut-heading orbit, explicit steering-vector gains of
    all 15 beams, the CODATA budget. Replaces a check of the engine against itself."""
    import math

    import independent as ind

    cfg = load_config(PAPER)
    df = paper_grid[paper_grid.in_roi & (paper_grid.best_beam >= 0)]
    lat_c, lon_c = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    c, e, L = cfg.constellation, cfg.earth, cfg.link
    a_m, inc = e.radius_m + c.altitude_m, math.radians(c.inclination_deg)
    orbit = ind.PassOrbit(lat_c, lon_c, 0.0, a_m, inc, c.ascending, e.gm_m3_s2, False)
    sat, vel = orbit(0.0)[0, 0], ind.velocity(orbit, 0.0)[0, 0]
    up, ex, ey = ind.roi_frame(lat_c, lon_c, vel)
    ut = np.array(
        [ind.roi_point(x, y, up, ex, ey, e.radius_m) for x, y in zip(df.x_m, df.y_m, strict=True)]
    )
    np.testing.assert_allclose(df.lat_deg, np.degrees(np.arcsin(ut[:, 2] / e.radius_m)), atol=1e-9)
    np.testing.assert_allclose(df.lon_deg, np.degrees(np.arctan2(ut[:, 1], ut[:, 0])), atol=1e-9)
    a = cfg.satellite_array
    u = ind.body_cosines(np.broadcast_to(sat, ut.shape), np.broadcast_to(vel, ut.shape), ut)
    g = ind.beam_gains_lin(u, build_engine(cfg).codebook.u_xy, a.n_x // a.n_rf_x, a.n_y // a.n_rf_y)
    best = g.argmax(axis=1)
    np.testing.assert_array_equal(df.best_beam, best)
    rho = np.linalg.norm(sat - ut, axis=1)
    grx = 10 * np.log10(cfg.terminal.upa.n_x * cfg.terminal.upa.n_y + 1 / L.rician_k)
    path_db = L.ptx_dbw - L.cable_loss_db + grx - ind.fspl_p525_db(rho, L.freq_hz)
    path_db -= cfg.atmosphere.fixed.loss_db + ind.noise_dbw(L.noise_temp_dbk, L.bandwidth_hz)
    g_sig = g[np.arange(len(best)), best]
    snr = 10 ** (path_db / 10) * g_sig
    sinr = snr / (10 ** (path_db / 10) * (g.sum(axis=1) - g_sig) + 1)
    np.testing.assert_allclose(df.snr_db, 10 * np.log10(snr), rtol=0, atol=1e-6)
    np.testing.assert_allclose(df.sinr_db, 10 * np.log10(sinr), rtol=0, atol=1e-6)
    # Static points: Doppler from the satellite's velocity alone, (f/c) <v, l_su>.
    l_su = (ut - sat) / rho[:, None]
    np.testing.assert_allclose(df.doppler_hz, L.freq_hz / ind.C_M_S * (l_su @ vel), atol=1e-3)
