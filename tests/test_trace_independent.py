"""Every trace column of a real run, recomputed UT by UT another way (tests/independent.py).

Four scenario kinds: the paper's pass (static, car and aircraft UTs), a Walker
constellation on a rotating Earth (satellite handovers), a TLE propagated with sgp4 on a
rotating Earth, and moving UTs of every heading kind on a rotating Earth (also recorded
after a warm-up). For every row
the satellite and UT positions come from an orbit and a track computed independently,
velocities and accelerations from finite differences, gains from explicit steering
vectors, the budget from CODATA constants; the serving (satellite, beam) must be the best
one found by brute force (max-SNR policy).

Tolerances are set by the independent computation's own error, far below the effects a
wrong column would show (a 1 mm range, a 1 mHz Doppler, 1e-6 dB: a car's Doppler is
1.1 kHz, a beam's gain varies by 3 dB across its cell).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from skyfield.api import load

import independent as ind
from leolink.app.run import run
from leolink.app.scenario import build_engine
from leolink.config import load_config, parse_config
from leolink.io.tle import read_tle_file
from leolink.sim.mobility.models import SPEED_PRESETS_M_S
from scopes import shared_run_scope

ROOT = Path(__file__).resolve().parents[1]

RANGE_TOL_M = 1e-3  # orbit built two ways: agreement ~1e-8 m; 1 ms of epoch error is 7 m
ANGLE_TOL_DEG = 1e-7  # lat/lon/elevation: 1e-7 deg = 1 cm on the ground
GAIN_TOL_DB = 1e-6  # explicit sums vs closed form: round-off ~1e-12 dB
DOPPLER_TOL_HZ = 1e-3  # finite-difference velocity error ~1e-7 m/s x f/c = 4e-6 Hz
RATE_TOL_HZ_S = 1e-3  # second difference error < 1e-8 m/s^2 x f/c
# leolink's TLE acceleration is two-body (orbit.tle_state); sgp4's positions carry J2
# and drag: |a_J2| <= 3 J2 g (R/r)^2 = 0.025 m/s^2 at the ISS, x f/c = 38 Hz/(m/s^2).
TLE_RATE_TOL_HZ_S = 0.025 * 11.45e9 / ind.C_M_S
ANG_SPEED_RTOL = 1e-7
# TLE run: leolink takes the GMST at the epoch from one float JD (40 us, 3e-9 rad) and
# turns at the IERS rate, not GMST-1982's (1e-9 rad in 120 s): 2-3 cm at the satellite.
TLE_RANGE_TOL_M = 0.05
TLE_ANGLE_TOL_DEG = 2e-6  # 5e-9 rad at the satellite, x r_sat / rho < 20 seen from the UT
TLE_DOPPLER_PART_TOL_HZ = 0.05  # 3 cm over 400 km turns the 7.7 km/s velocity by 6e-4 m/s
# sgp4's velocity is not the derivative of its position (1.2 cm/s for this TLE, measured):
# leolink uses the velocity, the finite differences the position: 2 cm/s x f/c.
TLE_DOPPLER_TOL_HZ = 0.02 * 11.45e9 / ind.C_M_S
TLE_ANG_SPEED_TOL_DEG_S = float(np.degrees(0.02 / 400e3))  # 2 cm/s over >= 400 km
# The body frame follows the velocity: the 3e-9 rad of the GMST moves the beam cosines by
# ~1e-8, a few 1e-6 dB on a beam's flank (40 dB per unit of u).
TLE_GAIN_TOL_DB = 1e-5


def _toml(path):
    with open(ROOT / path, "rb") as f:
        return tomllib.load(f)


def _config(data, source):
    data.setdefault("output", {})["plots"] = {"enabled": False}
    return parse_config(data, source=str(source))


def _paper():
    return load_config(ROOT / "configs/paper.toml", ["output.plots.enabled=false"])


def _walker_rotating():
    d = _toml("configs/examples/walker.toml")
    d["earth"]["rotation"] = True
    d["run"]["duration_s"] = 400.0
    d["population"] = [
        {"name": "centre", "kind": "static", "placement": "center"},
        {
            "name": "spread",
            "kind": "static",
            "placement": "points",
            "x_m": [300e3, -200e3],
            "y_m": [-150e3, 250e3],
        },
        {
            "name": "ship",
            "kind": "constant_velocity",
            "placement": "points",
            "x_m": [-100e3],
            "y_m": [50e3],
            "speed_m_s": 12.0,
            "heading_deg": 200.0,
        },
    ]
    return _config(d, ROOT / "configs/examples/walker.toml")


def _tle():
    return load_config(ROOT / "configs/examples/tle.toml", ["output.plots.enabled=false"])


def _moving_rotating():
    d = _toml("configs/paper.toml")
    d["earth"]["rotation"] = True
    d["population"] = [
        {
            "name": h,
            "kind": "constant_velocity",
            "placement": "points",
            "x_m": [20e3 * i],
            "y_m": [-10e3 * i],
            "alt_m": 3000.0 * i,
            "speed_m_s": 200.0,
            "heading_deg": h,
        }
        for i, h in enumerate(("along_track", "against_track", "cross_track"))
    ] + [
        {
            "name": "numeric",
            "kind": "constant_velocity",
            "placement": "points",
            "x_m": [-40e3],
            "y_m": [60e3],
            "speed": "train",
            "heading_deg": 30.0,
        }
    ]
    return _config(d, ROOT / "configs/paper.toml")


def _moving_after_warmup():
    """The moving UTs recorded after 7 s of warm-up: the run's one motion block holds
    epochs that are not recorded, so the monitor takes its rows' states by row."""
    cfg = _moving_rotating()
    return cfg.model_copy(update={"run": cfg.run.model_copy(update={"warmup_s": 7.0})})


SCENARIOS = {
    "paper_pass": _paper,
    "walker_rotating": _walker_rotating,
    "tle_rotating": _tle,
    "moving_rotating": _moving_rotating,
    "moving_after_warmup": _moving_after_warmup,
}


# --- the independent scenario ------------------------------------------------------------
def _orbit(cfg):
    c, e = cfg.constellation, cfg.earth
    a = e.radius_m + c.altitude_m
    inc = math.radians(c.inclination_deg)
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    if c.kind == "pass":
        return ind.PassOrbit(lat, lon, c.pass_time_s, a, inc, c.ascending, e.gm_m3_s2, e.rotation)
    if c.kind == "walker":
        return ind.WalkerOrbits(
            c.n_planes, c.sats_per_plane, c.phasing, a, inc, e.gm_m3_s2, e.rotation
        )
    assert c.kind == "tle"
    ((_, l1, l2),) = read_tle_file(c.tle_file)
    t0_utc = cfg.run.utc_of_time_zero()
    # UT1 - UTC from skyfield's own timescale (leolink reads the same IERS table its own way).
    dut1_s = float(load.timescale(builtin=True).from_datetime(t0_utc).dut1)
    return ind.TleOrbit(l1, l2, t0_utc, e.rotation, dut1_s)


def _track_direction(cfg):
    """ROI x axis: the ground-track direction at the centre (Earth-fixed velocity when the
    Earth rotates). A pass: its satellite overhead. Otherwise (the rule of
    ``leolink.app.orbits.roi_frame``, found here by brute force): the satellite highest
    above the centre at ``run.start_s``, at its highest elevation on that pass (a 1 s grid
    over +-20 min, then scipy's bounded Brent search to 1 us)."""
    c, e = cfg.constellation, cfg.earth
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    if c.kind == "pass":
        orbit = ind.PassOrbit(
            lat,
            lon,
            0.0,
            e.radius_m + c.altitude_m,
            math.radians(c.inclination_deg),
            c.ascending,
            e.gm_m3_s2,
            e.rotation,
        )
        return ind.velocity(orbit, 0.0)[0, 0]
    orbit, t0 = _orbit(cfg), cfg.run.start_s
    centre = e.radius_m * ind.unit_up(lat, lon)
    sats = orbit(t0)[0]
    sat = int(np.argmax(ind.elevation_rad(centre[None], sats)))
    t = t0 + np.arange(-1200.0, 1201.0)
    d = -ind.elevation_rad(centre[None], orbit(t)[:, sat])
    i = int(np.argmin(d))
    t_close = minimize_scalar(
        lambda x: -float(ind.elevation_rad(centre, orbit(x)[0, sat])),
        bounds=(t[i - 1], t[i + 1]),
        method="bounded",
        options={"xatol": 1e-6},
    ).x
    return ind.velocity(orbit, t_close)[0, sat]


HEADING_OFFSET_RAD = {"along_track": 0.0, "against_track": math.pi, "cross_track": math.pi / 2}


def _uts(cfg):
    """One track per UT, in config order: ``t -> pos (n_t, 3)``."""
    lat_c, lon_c = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    up, ex, ey = ind.roi_frame(lat_c, lon_c, _track_direction(cfg))
    track_heading = ind.heading_of(ex, lat_c, lon_c)
    rad = cfg.earth.radius_m
    uts = []
    for p in cfg.population:
        if p.placement == "center":
            xs, ys = [0.0] * p.count, [0.0] * p.count
        else:
            assert p.placement == "points", "the independent check places points only"
            xs, ys = p.x_m, p.y_m
        for x, y in zip(xs, ys, strict=True):
            g = ind.roi_point(x, y, up, ex, ey, rad)
            lat, lon = math.asin(g[2] / rad), math.atan2(g[1], g[0])
            speed, heading = 0.0, 0.0
            if p.kind == "constant_velocity":
                speed = p.speed_m_s if p.speed_m_s is not None else SPEED_PRESETS_M_S[p.speed]
                if isinstance(p.heading_deg, str):
                    heading = track_heading + HEADING_OFFSET_RAD[p.heading_deg]
                else:
                    heading = math.radians(p.heading_deg)
            else:
                assert p.kind == "static"
            uts.append(ind.GreatCircleUT(lat, lon, p.alt_m, heading, speed, rad, cfg.run.start_s))
    return uts


def _positions(models, ids, t):
    """Positions (n, 3) of model ``ids[i]`` at ``t[i]`` (+ dt), grouped by model."""
    out = np.empty((len(t), 3))
    for i in np.unique(ids):
        rows = ids == i
        out[rows] = models[i](t[rows])
    return out


class Recomputed:
    """The rows of a trace, recomputed: satellites (n_row, n_sat, 3), UTs (n_row, 3)."""

    def __init__(self, cfg, trace):
        self.cfg, self.trace = cfg, trace
        self.orbit, self.uts = _orbit(cfg), _uts(cfg)
        self.t = trace.time_s.to_numpy()
        self.ut_id = trace.ut_id.to_numpy()
        self.served = trace.sat_id.to_numpy() >= 0
        self.rows = np.flatnonzero(self.served)
        self.sat_id = trace.sat_id.to_numpy()[self.served]

    def sats(self, dt=0.0):
        return self.orbit(self.t + dt)

    def sat_vel(self):
        return ind.velocity(self.orbit, self.t)

    def ut(self, dt=0.0):
        return _positions(self.uts, self.ut_id, self.t + dt)

    def serving(self, dt=0.0):
        """Serving satellite and UT positions of the served rows, each (n_served, 3)."""
        return self.sats(dt)[self.rows, self.sat_id], self.ut(dt)[self.rows]

    def serving_sat_vel(self):
        return self.sat_vel()[self.rows, self.sat_id]


@pytest.fixture(scope=shared_run_scope, params=list(SCENARIOS))
def case(request):
    cfg = SCENARIOS[request.param]()
    result = run(cfg)
    return request.param, cfg, result.trace, Recomputed(cfg, result.trace)


def _beam_gains(cfg, sat, sat_vel, ut):
    """Explicit steering-vector gains of every beam towards each UT, (n, n_beam) [lin]."""
    a = cfg.satellite_array
    u = ind.body_cosines(sat, sat_vel, ut)
    beams = build_engine(cfg).codebook.u_xy
    return ind.beam_gains_lin(u, beams, a.n_x // a.n_rf_x, a.n_y // a.n_rf_y)


def _grx_db(cfg):
    """The UT's mean receive gain N + 1/K of a matched 24 x 24 UPA (Sec. 4.1)."""
    n = cfg.terminal.upa.n_x * cfg.terminal.upa.n_y
    return 10 * np.log10(n + 1 / cfg.link.rician_k)


def _path_db(cfg, rho_m):
    """Link budget without the TX gain: P_TX - L_cable + G_RX - FSPL - L_atm [dBW]."""
    L = cfg.link
    fspl = ind.fspl_p525_db(rho_m, L.freq_hz)
    return L.ptx_dbw - L.cable_loss_db + _grx_db(cfg) - fspl - cfg.atmosphere.fixed.loss_db


def _noise_db(cfg):
    return ind.noise_dbw(cfg.link.noise_temp_dbk, cfg.link.bandwidth_hz)


# --- the checks --------------------------------------------------------------------------
def test_lat_lon_follow_the_ut_track(case):
    name, cfg, tr, rec = case
    # Nearly every row is served, so every column below is checked on most rows.
    assert rec.served.mean() > 0.9
    ut = rec.ut()
    lat = np.degrees(np.arcsin(ut[:, 2] / np.linalg.norm(ut, axis=1)))
    lon = np.degrees(np.arctan2(ut[:, 1], ut[:, 0]))
    np.testing.assert_allclose(tr.lat_deg, lat, rtol=0, atol=ANGLE_TOL_DEG)
    np.testing.assert_allclose(tr.lon_deg, lon, rtol=0, atol=ANGLE_TOL_DEG)


def test_range_elevation_and_losses(case):
    name, cfg, tr, rec = case
    s = rec.served
    sat, ut = rec.serving()
    rho = np.linalg.norm(sat - ut, axis=1)
    tol = TLE_RANGE_TOL_M if name == "tle_rotating" else RANGE_TOL_M
    np.testing.assert_allclose(tr.slant_range_m[s], rho, rtol=0, atol=tol)
    el = np.degrees(ind.elevation_rad(ut, sat))
    tol = TLE_ANGLE_TOL_DEG if name == "tle_rotating" else ANGLE_TOL_DEG
    # At the zenith the arcsine turns an ulp of its argument into ~1e-6 deg: sines there
    zenith = el > 89.9
    np.testing.assert_allclose(tr.elevation_deg[s][~zenith], el[~zenith], rtol=0, atol=tol)
    sin_got, sin_want = (
        np.sin(np.radians(tr.elevation_deg[s][zenith])),
        np.sin(np.radians(el[zenith])),
    )
    np.testing.assert_allclose(sin_got, sin_want, rtol=0, atol=np.radians(tol))
    assert (el >= cfg.constellation.min_elevation_deg).all()
    np.testing.assert_allclose(
        tr.fspl_db[s], ind.fspl_p525_db(rho, cfg.link.freq_hz), rtol=0, atol=GAIN_TOL_DB
    )
    assert cfg.atmosphere.model == "fixed"
    np.testing.assert_allclose(tr.atm_db[s], cfg.atmosphere.fixed.loss_db, rtol=0, atol=1e-12)
    # Outage rows: every column NaN.
    assert tr.loc[~s, "slant_range_m":"angular_speed_deg_s"].isna().all().all()


def test_gains_snr_sinr_and_throughput(case):
    name, cfg, tr, rec = case
    L = cfg.link
    assert (L.fading, L.reuse_colors, L.interference, L.power_mode) == (
        "mean",
        1,
        "serving_satellite",
        "per_beam",
    )
    s = rec.served
    sat, ut = rec.serving()
    g = _beam_gains(cfg, sat, rec.serving_sat_vel(), ut)
    beam = tr.beam_id.to_numpy()[s]
    g_sig = g[np.arange(len(beam)), beam]
    tol = TLE_GAIN_TOL_DB if name == "tle_rotating" else GAIN_TOL_DB
    np.testing.assert_allclose(tr.gain_tx_db[s], 10 * np.log10(g_sig), rtol=0, atol=tol)
    # UT: 24 x 24 UPA steered at the satellite, mean Rician gain N + 1/K (Sec. 4.1).
    t = cfg.terminal
    assert t.kind == "upa"
    a_ut = ind.upa_steering(0.3, -0.2, t.upa.n_x, t.upa.n_y)  # any direction, matched
    n_los = abs(np.vdot(a_ut, a_ut)) ** 2 / np.vdot(a_ut, a_ut).real
    grx_db = 10 * np.log10(n_los + 1 / L.rician_k)
    assert grx_db == pytest.approx(_grx_db(cfg), abs=1e-12)
    np.testing.assert_allclose(tr.gain_rx_db[s], grx_db, rtol=0, atol=GAIN_TOL_DB)
    path_db, noise = _path_db(cfg, np.linalg.norm(sat - ut, axis=1)), _noise_db(cfg)
    snr_db = path_db + 10 * np.log10(g_sig) - noise
    tol = TLE_GAIN_TOL_DB if name == "tle_rotating" else GAIN_TOL_DB
    np.testing.assert_allclose(tr.snr_db[s], snr_db, rtol=0, atol=tol)
    # SINR: the serving satellite's other beams interfere at full power (full reuse).
    i_over_n = (g.sum(axis=1) - g_sig) * 10 ** ((path_db - noise) / 10)
    sinr = 10 ** (snr_db / 10) / (i_over_n + 1)
    np.testing.assert_allclose(tr.sinr_db[s], 10 * np.log10(sinr), rtol=0, atol=tol)
    se = np.log2(1 + sinr)
    np.testing.assert_allclose(tr.se_bps_hz[s], se, rtol=1e-6)
    np.testing.assert_allclose(tr.throughput_bps[s], se * L.bandwidth_hz, rtol=1e-6)


def test_serving_link_is_the_best_visible_satellite_and_beam(case):
    """Max-SNR policy: no (satellite, beam) above the mask beats the serving one, and a
    UT is in outage only when no satellite is above the mask."""
    name, cfg, tr, rec = case
    assert cfg.controller.policy == "max_snr"
    check_serving_is_the_best(cfg, tr, rec)
    if name == "walker_rotating":  # the scenario must exercise satellite handovers
        assert tr[rec.served].groupby("ut_id").sat_id.nunique().min() >= 2


def check_serving_is_the_best(cfg, tr, rec):
    """Outage exactly where no visible (satellite, beam) reaches ``controller.min_snr_db``;
    elsewhere the serving link is the best one, by brute force over every (satellite, beam)
    above the mask (also the reference of tests/test_trigger_floor.py's pruned tables)."""
    sats, vel, ut = rec.sats(), rec.sat_vel(), rec.ut()
    el = np.degrees(ind.elevation_rad(ut[:, None, :], sats))  # (n_row, n_sat)
    row, sat = np.nonzero(el >= cfg.constellation.min_elevation_deg)
    g = _beam_gains(cfg, sats[row, sat], vel[row, sat], ut[row])
    rho = np.linalg.norm(sats[row, sat] - ut[row], axis=1)
    snr = 10 * np.log10(g) + (_path_db(cfg, rho) - _noise_db(cfg))[:, None]
    best = np.full(len(tr), -np.inf)
    np.maximum.at(best, row, snr.max(axis=1))
    # Outage exactly where no visible (satellite, beam) reaches the minimum SNR.
    assert np.array_equal(best >= cfg.controller.min_snr_db, rec.served)
    is_serving = sat == tr.sat_id.to_numpy()[row]
    assert np.array_equal(row[is_serving], rec.rows)  # the serving satellite is visible
    got = snr[is_serving][np.arange(len(rec.rows)), tr.beam_id.to_numpy()[rec.rows]]
    np.testing.assert_allclose(got, best[rec.served], rtol=0, atol=GAIN_TOL_DB)


def test_doppler_doppler_rate_and_angular_speed(case):
    name, cfg, tr, rec = case
    s, k = rec.served, cfg.link.freq_hz / ind.C_M_S
    sat, ut = rec.serving()
    (sat_p, ut_p), (sat_m, ut_m) = rec.serving(ind.H_VEL_S), rec.serving(-ind.H_VEL_S)
    v_sat = rec.serving_sat_vel()
    v_ut = (ut_p - ut_m) / (2 * ind.H_VEL_S)
    rho = np.linalg.norm(sat - ut, axis=1)
    l_us = (sat - ut) / rho[:, None]
    # Satellite part: its velocity towards the UT; UT part: the UT's towards the satellite.
    dsat = k * np.sum(v_sat * -l_us, axis=1)
    dut = k * np.sum(v_ut * l_us, axis=1)
    tol = TLE_DOPPLER_PART_TOL_HZ if name == "tle_rotating" else DOPPLER_TOL_HZ
    np.testing.assert_allclose(tr.doppler_sat_hz[s], dsat, rtol=0, atol=tol)
    np.testing.assert_allclose(tr.doppler_ut_hz[s], dut, rtol=0, atol=tol)
    if name in ("paper_pass", "moving_rotating", "walker_rotating"):
        assert (np.abs(dut) > 100.0).any()  # moving UTs: the UT part is exercised
    # Total: minus the range rate, by finite differences of the range.
    fd_rate_m_s = (np.linalg.norm(sat_p - ut_p, axis=1) - np.linalg.norm(sat_m - ut_m, axis=1)) / (
        2 * ind.H_VEL_S
    )
    np.testing.assert_allclose(tr.doppler_hz[s], dsat + dut, rtol=0, atol=tol)
    tol = TLE_DOPPLER_TOL_HZ if name == "tle_rotating" else DOPPLER_TOL_HZ
    np.testing.assert_allclose(tr.doppler_hz[s], -k * fd_rate_m_s, rtol=0, atol=tol)
    h = ind.H_ACC_S
    r_p = np.linalg.norm(np.subtract(*rec.serving(h)), axis=1)
    r_m = np.linalg.norm(np.subtract(*rec.serving(-h)), axis=1)
    rate = -k * (r_p - 2 * rho + r_m) / h**2
    tol = TLE_RATE_TOL_HZ_S if name == "tle_rotating" else RATE_TOL_HZ_S
    np.testing.assert_allclose(tr.doppler_rate_hz_s[s], rate, rtol=0, atol=tol)
    # Angular speed: |dl/dt| of the unit line of sight, by finite differences.
    l_p = (sat_p - ut_p) / np.linalg.norm(sat_p - ut_p, axis=1)[:, None]
    l_m = (sat_m - ut_m) / np.linalg.norm(sat_m - ut_m, axis=1)[:, None]
    w_deg_s = np.degrees(np.linalg.norm(l_p - l_m, axis=1) / (2 * ind.H_VEL_S))
    tol = TLE_ANG_SPEED_TOL_DEG_S if name == "tle_rotating" else 0.0
    np.testing.assert_allclose(tr.angular_speed_deg_s[s], w_deg_s, rtol=ANG_SPEED_RTOL, atol=tol)
