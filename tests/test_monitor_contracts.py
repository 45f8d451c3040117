"""The monitor's paths the paper's pass does not take (sim/monitor.py), on real runs.

- UTs that never see a satellite beside UTs that are served, in the same motion blocks:
  their rows have no link (NaN), the others are those of a run without them;
- a Walker constellation (several satellites serve in one block): each row's Doppler is
  ``-f/c d(range)/dt`` of the ephemeris' own positions, by central differences;
- fading inside an environment: the fading factor of each row is the one of the same UT
  and epoch in open country (the draws are per UT and epoch), on top of the
  environment's loss;
- fading with scan loss: each row's factor is its draw over the mean of its own receive
  gain;
- beam sharing with the digital precoder and active beams (more beams than RF chains):
  each UT's precoded SE is the one of explicit steering vectors on the lit beams' chains;
- the other satellites' interference on WGS 84 with reuse colours and active beams: each
  row's SNR, SINR and interference against an explicit sum of the received powers of every
  lit beam of every satellite above the UT's (geodetic) horizon, and its azimuth in the
  geodetic frame;
- the same in an urban environment (every beam lit), flat and tilted panels: each
  interfering path scaled by the loss of its own (UT, satellite) channel state, as the
  run's channel tracker gave it, the UT array in its panel's axes;
- the same with exactly two satellites, both in view;
- a scenario without a service link (``Scenario.link`` None): the engine's figures;
- one demand-lit beam and a UT that never sees a satellite;
- (ninth pass) serving pairs the pruned search left out, against ``prune = False``; the
  epoch frames of RLF runs; fading in a block whose only link is pair 0; the explicit
  interference sum across two motion blocks, with Earth-fixed beams, and with the ZF
  precoder; a handover row's SE at 0.5 s epochs; an open-country SNR exactly at the
  threshold (``blocked``).

Not tested, equivalent: ``Monitor._share``'s ``served`` is ``sat_id >= 0 & service !=
outage``, and ``|`` for ``&`` gives the same rows: every controller state has ``in_outage
=> serving == -1`` (``ControllerState.initial``: none in outage; ``step``: an
``outage_start`` UT gets ``-1``, one staying in outage keeps its ``-1``, one leaving it
adopts a cell; RLF's ``_drop_serving`` sets both), so ``service_codes`` gives outage
exactly where ``serving < 0``, i.e. where ``sat_id = -1``. ``Monitor.population`` built
with numpy's default dtype (``<U`` strings) instead of ``object``: the array reaches only
the trace's ``population`` column, and every sink that reads that column (the trace
writer's ``Vocabulary.codes``, ``to_table`` of the in-memory and plot sinks) takes
``values.astype(str)``, the same array from both; the output files of two runs are the
same bytes (docs/testing_log.md, eighth pass).
"""

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from leolink.app.run import run
from leolink.app.scenario import build_scenario, ephemeris_from_config
from leolink.config import load_config
from leolink.constants import BOLTZMANN_J_K, SPEED_OF_LIGHT_M_S
from leolink.geometry import geodetic_to_ecef
from leolink.io.sinks import MemorySink
from leolink.sim.monitor import Monitor
from leolink.sim.runner import run_simulation
from test_active_beams import _cfg as _paper_drop
from test_active_beams import _explicit_se
from test_active_beams import _run as _run_in_memory
from test_engine_contracts import _tx_gains, _upa

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"
WALKER = ROOT / "configs" / "examples" / "walker.toml"
TOWN = ROOT / "configs" / "examples" / "town.toml"
QUIET = ["output.plots.enabled=false"]
GEOMETRY = ("elevation_deg", "slant_range_m", "gain_tx_db", "fspl_db", "snr_db", "doppler_hz")


def _with_populations(tmp_path, base, populations, overrides=()):
    head = base.read_text().split("[[population]]")[0]
    path = tmp_path / "cfg.toml"
    path.write_text(head + populations)
    return load_config(path, [*QUIET, *overrides])


FAR = """[[population]]
name = "near"
kind = "static"
placement = "points"
x_m = [0.0, 200000.0]
y_m = [0.0, -100000.0]

[[population]]
name = "far"
kind = "static"
placement = "points"
x_m = [0.0]
y_m = [4000000.0]
"""


def test_a_ut_without_any_satellite_in_view_has_no_link_beside_served_uts(tmp_path):
    """A UT 4,000 km cross-track never sees the pass above the 10 deg mask (its ground
    range at 10 deg is 2,794 km): every column of its link is NaN, while the two UTs near
    the centre, in the same blocks, get the links of a run without it."""
    cfg = _with_populations(tmp_path, PAPER, FAR, ["run.duration_s=60.0"])
    tr = run(cfg).trace
    far, near = tr[tr.ut_id == 2], tr[tr.ut_id < 2]
    assert (far.n_visible == 0).all() and (far.sat_id == -1).all()
    for col in GEOMETRY:
        assert far[col].isna().all(), col
    assert (far.outage_reason == "no_satellite").all()
    assert near.snr_db.notna().all()
    alone = run(_with_populations(tmp_path, PAPER, FAR.split("\n\n")[0] + "\n",
                                  ["run.duration_s=60.0"])).trace  # fmt: skip
    for col in GEOMETRY:
        np.testing.assert_array_equal(near[col].to_numpy(), alone[col].to_numpy())


def test_with_one_demand_lit_beam_a_ut_without_any_satellite_has_no_link(tmp_path):
    """One beam (one RF chain, a 3 km ROI) lit on demand: the UT 4,000 km cross-track
    that never sees the pass has NaN links and the two UTs under the beam, in the same
    blocks, get the links of a run without it (an unserved row's placeholder beam must
    be one the codebook has: beam 0)."""
    over = ["run.duration_s=10.0", "roi.semi_axis_x_m=3000.0", "roi.semi_axis_y_m=3000.0",
            "satellite_array.n_rf_x=1", "satellite_array.n_rf_y=1",
            'satellite_array.oversampling="auto"',
            "satellite_array.active_beams=demand"]  # fmt: skip
    pops = FAR.replace("[0.0, 200000.0]", "[0.0, 1000.0]").replace(
        "[0.0, -100000.0]", "[0.0, -1000.0]"
    )
    scen, tr = _run_in_memory(_with_populations(tmp_path, PAPER, pops, over))
    assert scen.engine.n_beam == 1
    far, near = tr[tr.ut_id == 2], tr[tr.ut_id < 2]
    assert (far.n_visible == 0).all() and far.snr_db.isna().all()
    assert near.snr_db.notna().sum() >= 10
    _, alone = _run_in_memory(
        _with_populations(tmp_path, PAPER, pops.split("\n\n")[0] + "\n", over)
    )
    for col in GEOMETRY:
        np.testing.assert_array_equal(near[col].to_numpy(), alone[col].to_numpy())


def test_walker_doppler_of_every_row_is_the_range_rate_of_its_satellite():
    """Walker (several satellites in one block): each served row's Doppler against
    ``-f/c (|s(t + h) - u| - |s(t - h) - u|) / 2h`` of the ephemeris (static UTs, no
    Earth rotation); h = 1 ms, truncation ~h^2/6 d3(range)/dt3, far below 0.01 Hz."""
    cfg = load_config(WALKER, [*QUIET, "run.duration_s=120.0"])
    tr = run(cfg).trace
    served = tr[tr.sat_id >= 0]
    assert served.sat_id.nunique() >= 2
    eph = ephemeris_from_config(cfg)
    lat, lon = np.radians(served.lat_deg.to_numpy()), np.radians(served.lon_deg.to_numpy())
    ut = geodetic_to_ecef(lat, lon, served.alt_m.to_numpy())
    t, sat = served.time_s.to_numpy(), served.sat_id.to_numpy()
    h = 1e-3
    rho = []
    for d in (h, -h):
        pos = np.stack([eph(np.array([ti + d]))[0][0, si] for ti, si in zip(t, sat, strict=True)])
        rho.append(np.linalg.norm(pos - ut, axis=1))
    expected = -cfg.link.freq_hz / SPEED_OF_LIGHT_M_S * (rho[0] - rho[1]) / (2 * h)
    np.testing.assert_allclose(served.doppler_hz.to_numpy(), expected, atol=0.01)


SUBURBAN = """[[population]]
name = "crowd"
kind = "static"
placement = "points"
x_m = [0.0, 5000.0, -5000.0, 0.0, 8000.0, -3000.0]
y_m = [0.0, 0.0, 2000.0, -4000.0, 6000.0, -7000.0]
environment = "{env}"
"""


def test_fading_inside_an_environment_is_the_open_country_fading(tmp_path):
    """Per row, ``snr(fading) - snr(mean)`` in a suburban environment equals the same
    difference in open country (same UTs, epochs and seed: the same draws), wherever both
    are served by the same beam; the environment's loss is there too."""
    over = ["run.duration_s=40.0", "run.start_s=-20.0"]
    fade, env = 'link.fading="rician"', "suburban"
    out = {}
    for name in ("open", env):
        for f in (False, True):
            cfg = _with_populations(tmp_path, TOWN, SUBURBAN.format(env=name),
                                    [*over, fade] if f else over)  # fmt: skip
            out[name, f] = run(cfg).trace
    d_open = out["open", True].snr_db - out["open", False].snr_db
    d_env = out[env, True].snr_db - out[env, False].snr_db
    same = (out["open", True].beam_id == out[env, True].beam_id) & d_open.notna() & d_env.notna()
    same &= out[env, False].beam_id == out[env, True].beam_id
    assert same.sum() > 100
    assert (d_open[same].abs() > 1e-3).mean() > 0.9  # the draws move the SNR
    np.testing.assert_allclose(d_env[same], d_open[same], rtol=0, atol=1e-9)
    # ... on top of the environment's own loss (shadowing, clutter): the SNRs differ
    loss = out["open", False].snr_db[same] - out[env, False].snr_db[same]
    assert (loss.abs() > 0.1).mean() > 0.5


def test_fading_of_every_row_is_its_draw_over_the_mean_of_its_own_receive_gain():
    """Scan loss on (the receive gain differs row by row): each row's SNR with fading
    minus without is ``10 log10(|sqrt(N) + g / sqrt(K)|^2 / (N + 1/K))`` (paper Sec. 4.1)
    with ``N`` the row's own mean receive gain and ``g`` the run's draw for that UT and
    epoch (counter-based, ``leolink.rng``); float rounding only (1e-9 dB)."""
    from leolink.rng import complex_normal, ut_keys

    over = [*QUIET, "run.duration_s=30.0", "run.start_s=-15.0", "terminal.upa.scan_loss=true"]
    cfg = load_config(PAPER, over)
    mean = run(cfg).trace
    fading = run(load_config(PAPER, [*over, 'link.fading="rician"'])).trace
    ok = mean.snr_db.notna() & fading.snr_db.notna()
    assert ok.sum() > 100 and mean.gain_rx_db[ok].nunique() > 100
    n_ut = mean.ut_id.max() + 1
    epoch = np.round((mean.time_s - mean.time_s.min()) / cfg.run.epoch_s).astype(int)
    keys = ut_keys(cfg.run.seed, n_ut)
    g = np.array([complex_normal(keys[[u]], k)[0] for u, k in zip(mean.ut_id, epoch, strict=True)])
    n, k = 10 ** (mean.gain_rx_db.to_numpy() / 10), cfg.link.rician_k
    factor_db = 10 * np.log10(np.abs(np.sqrt(n) + g / np.sqrt(k)) ** 2 / (n + 1 / k))
    got = (fading.snr_db - mean.snr_db).to_numpy()
    np.testing.assert_allclose(got[ok], factor_db[ok], rtol=0, atol=1e-9)


@pytest.mark.parametrize("fading", [False, True], ids=["mean", "rician"])
def test_precoded_se_with_more_beams_than_chains_is_that_of_the_lit_beams_chains(tmp_path, fading):
    """O = 2 (47 beams, 15 RF chains), demand-lit beams, round robin and ZF, 30 UTs (up to
    4 per beam): each served UT's SE (times its beam's UT count, the round-robin share)
    is the mean ``log2(1 + SINR)`` over its slots of explicit steering vectors of the
    60 x 72 array, the lit beams by ascending id on chains 0, 1, ...
    (``test_active_beams._explicit_se``), its path SNR from the engine called by hand on
    the row's position, times the row's fading factor with Rician draws (the trace's SNR
    over the engine's mean one: the draws move the precoder's channel too); float
    rounding only (1e-9). Demand lights the cells holding UTs by their best beam and each
    UT is served by its best lit beam, so the lit beams are the epoch's served beams."""
    sets = ["satellite_array.oversampling=2.0", "satellite_array.active_beams=demand",
            "scheduler.kind=round_robin", "link.precoder=zf", "run.duration_s=3"]  # fmt: skip
    if fading:
        sets.append('link.fading="rician"')
    scen, tr = _run_in_memory(_paper_drop(tmp_path, 30, sets))
    eng = scen.engine
    assert eng.n_beam == 47 and (tr.service == "served").all() and tr.n_sharing.max() >= 3
    for t, on in tr.groupby("time_s"):
        beam = on.beam_id.to_numpy()
        assert np.unique(beam).size == 15  # every chain drives a beam: ids up to 46
        lat, lon = np.radians(on.lat_deg.to_numpy()), np.radians(on.lon_deg.to_numpy())
        ut = geodetic_to_ecef(lat, lon, on.alt_m.to_numpy())
        pos, vel = (a[0] for a in scen.ephemeris(np.array([t]))[:2])
        snap = eng.evaluate(ut, pos, vel)
        path = snap.path_snr_lin[:, 0]
        mean_db = snap.snr_db[np.arange(beam.size), 0, beam]
        factor = 10 ** ((on.snr_db.to_numpy() - mean_db) / 10)
        if fading:
            assert np.std(10 * np.log10(factor)) > 0.03  # K = 10, N = 576: ~0.08 dB
        else:
            np.testing.assert_allclose(factor, 1.0, rtol=1e-12)
        path = path * factor
        lit = np.zeros(eng.n_beam, bool)
        lit[beam] = True
        want = _explicit_se(ut, pos[0], vel[0], path, beam, "zf", eng.colors,
                            np.asarray(eng.codebook.u_xy, float), lit)  # fmt: skip
        got = (on.se_bps_hz * on.n_sharing).to_numpy()
        np.testing.assert_allclose(got, want, rtol=1e-9)


#: WGS 84 (NIMA TR8350.2, 3rd ed., Table 3.1): semi-major axis [m], flattening.
WGS84_A_M, WGS84_F = 6378137.0, 1 / 298.257223563
NEAR = """
[[population]]
name = "near"
kind = "static"
placement = "points"
x_m = [150000.0, -200000.0, 0.0, 300000.0, -400000.0]
y_m = [0.0, 100000.0, -250000.0, 350000.0, -100000.0]
"""


def _geodetic_frame(lat_rad, lon_rad, h_m):
    """Position on the WGS 84 ellipsoid and the local east, north, up of its normal."""
    e2 = WGS84_F * (2 - WGS84_F)
    n = WGS84_A_M / math.sqrt(1 - e2 * math.sin(lat_rad) ** 2)
    cl, sl, co, so = math.cos(lat_rad), math.sin(lat_rad), math.cos(lon_rad), math.sin(lon_rad)
    pos = np.array([(n + h_m) * cl * co, (n + h_m) * cl * so, (n * (1 - e2) + h_m) * sl])
    up, east = np.array([cl * co, cl * so, sl]), np.array([-so, co, 0.0])
    return pos, east, np.cross(up, east), up


def _sphere_frames(rows):
    """Each trace row with its UT's position (from its latitude, longitude and height) and
    the radial frame there: ``(row, ut, east, north, up)``."""
    lat, lon = np.radians(rows.lat_deg.to_numpy()), np.radians(rows.lon_deg.to_numpy())
    ut = geodetic_to_ecef(lat, lon, rows.alt_m.to_numpy())
    up = ut / np.linalg.norm(ut, axis=1)[:, None]
    for i, r in enumerate(rows.itertuples()):
        east = np.array([-math.sin(lon[i]), math.cos(lon[i]), 0.0])
        yield r, ut[i], east, np.cross(up[i], east), up[i]


def _check_row(r, powers, noise_w):
    """A trace row's SNR and SINR against the received powers ``(n_sat, n_beam)`` [W] of
    every beam (the serving one at the row's satellite and beam), 1e-9 dB, and its
    interference over noise ``10^((SNR - SINR)/10) - 1`` to 1e-6 of itself; returns the
    interference power [W]."""
    signal = powers[r.sat_id, r.beam_id]
    i_w = powers.sum() - signal
    assert r.snr_db == pytest.approx(10 * math.log10(signal / noise_w), abs=1e-9)
    assert r.sinr_db == pytest.approx(10 * math.log10(signal / (i_w + noise_w)), abs=1e-9)
    i_over_n = 10 ** ((r.snr_db - r.sinr_db) / 10) - 1
    assert i_over_n == pytest.approx(i_w / noise_w, rel=1e-6, abs=1e-300)
    return i_w


def _received_w(eng, cfg, ut, east, north, up, pos, vel, s, b, lit, axes=None, beams=None):
    """(n_sat, n_beam) received powers [W] at one UT served by beam ``b`` of satellite
    ``s``: every lit beam of the serving beam's colour of every satellite above the UT's
    horizon; the satellite beams by explicit steering-vector sums in the body frame (x
    along the velocity's part across the radius, z radial), the UT's 24 x 24 UPA steered
    at ``s`` in its local east and north, or in its panel's ``axes`` (x, y) if given
    (gain ``N + 1/K`` on the serving satellite, the array factor off the beam plus
    ``1/K`` on the others), free space, fixed atmosphere. ``beams``: each satellite's
    steering vectors ``(n_sat, n_beam, n_el)`` (None: the codebook's for all)."""
    if axes is not None:
        east, north = axes
    p, cb = eng.params, eng.codebook
    if beams is None:
        beams = [_upa(np.asarray(cb.u_xy, float), cb.n_sub_x, cb.n_sub_y)] * len(pos)
    n_ut_x, k_r = 24, cfg.link.rician_k
    ptx_w = 10 ** ((p.ptx_dbw - p.cable_loss_db - p.other_loss_db) / 10)
    atm = 10 ** (cfg.atmosphere.fixed.loss_db / 10)
    d_s = (pos[s] - ut) / np.linalg.norm(pos[s] - ut)
    w = _upa(np.array([d_s @ east, d_s @ north]), n_ut_x, n_ut_x)
    powers = np.zeros(lit.shape)
    for k in range(len(pos)):
        rho = np.linalg.norm(pos[k] - ut)
        d = (pos[k] - ut) / rho
        if d @ up <= 0:
            continue
        g_tx = _tx_gains(cb, beams[k], pos[k], vel[k], d)
        if k == s:
            g_rx = n_ut_x**2 + 1 / k_r
        else:
            a_ut = _upa(np.array([d @ east, d @ north]), n_ut_x, n_ut_x)
            g_rx = np.abs(a_ut.conj() @ w) ** 2 / n_ut_x**2 + 1 / k_r
        loss = (4 * np.pi * rho * p.freq_hz / SPEED_OF_LIGHT_M_S) ** 2 * atm
        on = lit[k] & (eng.colors == eng.colors[b])
        powers[k] = np.where(on, ptx_w * g_tx * g_rx / loss, 0.0)
    return powers


def test_other_satellites_on_wgs84_with_colours_and_lit_beams_are_the_explicit_sum(tmp_path):
    """Walker, every satellite interfering, WGS 84 (geodetic local frames), 3 reuse
    colours, demand-lit beams, 9 static UTs around a ROI under satellite 0 at 40 N (it
    serves 6 of them on beams of all 3 colours, two other satellites the rest): each row's
    SNR and SINR against the explicit received powers of every satellite above the UT's
    geodetic horizon (``_received_w``), 1e-9 dB, and its interference over noise
    ``10^((SNR - SINR)/10) - 1`` to 1e-6 of itself (float rounding: 1e-13 dB and 1e-10;
    the sphere's radial frames would be off by 10 %, the serving colour of a wrong beam
    by 1.6 %); its azimuth is that of the geodetic east and north, 1e-9 deg (the
    sphere's frame is off by 0.4 deg here). The lit beams are the served cells
    (demand lights each UT's best cell)."""
    text = WALKER.read_text() + NEAR
    path = tmp_path / "walker.toml"
    path.write_text(text)
    over = [*QUIET, "run.duration_s=3.0", "run.start_s=1000.0", 'earth.model="wgs84"',
            'link.interference="all_satellites"', "link.reuse_colors=3",
            'satellite_array.active_beams="demand"', "roi.center_lat_deg=40.0",
            "roi.center_lon_deg=39.5"]  # fmt: skip
    cfg = load_config(path, over)
    scen, tr = _run_in_memory(cfg)
    eng, eph = scen.engine, ephemeris_from_config(cfg)
    assert (tr.sat_id >= 0).all() and tr.sat_id.nunique() >= 3
    assert np.unique(eng.colors[tr.beam_id[tr.sat_id == 0]]).size == 3
    p = eng.params
    noise_w = BOLTZMANN_J_K * 10 ** (p.noise_temp_dbk / 10) * p.bandwidth_hz / 3
    other = []
    for t, rows in tr.groupby("time_s"):
        pos, vel = (a[0] for a in eph(np.array([t]))[:2])
        lit = np.zeros((len(pos), eng.n_beam), bool)
        lit[rows.sat_id, rows.beam_id] = True
        for r in rows.itertuples():
            ut, east, north, up = _geodetic_frame(math.radians(r.lat_deg),
                                                  math.radians(r.lon_deg), r.alt_m)  # fmt: skip
            powers = _received_w(eng, cfg, ut, east, north, up, pos, vel, r.sat_id, r.beam_id,
                                 lit)  # fmt: skip
            _check_row(r, powers, noise_w)
            d = pos[r.sat_id] - ut  # azimuth in the geodetic frame: clockwise from north
            az_deg = math.degrees(math.atan2(d @ east, d @ north)) % 360.0
            assert r.azimuth_deg == pytest.approx(az_deg, abs=1e-9)
            other.append((powers.sum() - powers[r.sat_id].sum()) / noise_w)
    assert np.count_nonzero(other) >= len(tr) // 2  # the other satellites do interfere


def test_in_an_environment_only_outage_rows_that_open_country_serves_are_blocked(tmp_path):
    """Suburban UTs: an outage row's reason is ``blocked`` exactly where the same UT and
    epoch is served in open country (same UTs, seed and epochs: the environment took the
    link away), and every served row's reason stays ``none``."""
    over = ["run.duration_s=20.0", "run.start_s=-10.0"]
    env, open_ = (run(_with_populations(tmp_path, TOWN, SUBURBAN.format(env=name), over)).trace
                  for name in ("suburban", "open"))  # fmt: skip
    assert (env.service == "served").sum() > 50 and (env.service == "outage").sum() > 5
    assert (env.outage_reason[env.service != "outage"] == "none").all()
    out = env.service == "outage"
    np.testing.assert_array_equal(env.outage_reason[out] == "blocked",
                                  open_.service[out] != "outage")  # fmt: skip


def test_an_outage_row_with_a_satellite_in_view_has_its_best_beams_budget(tmp_path):
    """Beam hopping with the ``wait`` fallback (47 beams, 15 lit a dwell): UTs whose best
    beam is dark are in outage with a satellite in view; their budget columns are those
    of their best candidate, ``P - L_cable - L_other + G_tx + G_rx - FSPL - A - 10 log10(k
    T B) = best_snr_db`` to 1e-9 dB (float rounding: 4e-14). 60 UTs: some of them have
    cell 0 (satellite 0, beam 0) as their best, a valid candidate too (3 outage rows)."""
    sets = ["satellite_array.oversampling=2.0", "satellite_array.active_beams=hopping",
            "run.duration_s=4"]  # fmt: skip
    scen, tr = _run_in_memory(_paper_drop(tmp_path, 60, sets))
    p = scen.engine.params
    out = tr[(tr.service == "outage") & (tr.n_visible > 0)]
    assert len(out) > 20 and out.snr_db.isna().all()
    noise_db = 10 * math.log10(BOLTZMANN_J_K * p.bandwidth_hz) + p.noise_temp_dbk
    budget = (p.ptx_dbw - p.cable_loss_db - p.other_loss_db + out.gain_tx_db + out.gain_rx_db
              - out.fspl_db - out.atm_db - noise_db)  # fmt: skip
    np.testing.assert_allclose(budget, out.best_snr_db, rtol=0, atol=1e-9)


@pytest.mark.parametrize("tilt_deg", [0.0, 15.0], ids=["flat", "tilted"])
def test_other_satellites_in_an_environment_each_path_with_its_own_loss(
    tmp_path, monkeypatch, tilt_deg
):
    """Walker, every satellite interfering, 3 reuse colours, every beam lit, the 5 UTs of
    ``NEAR`` in an urban environment (TR 38.811 LoS states, shadowing, clutter per path):
    each served row's SNR, SINR and interference over noise against the explicit received
    powers of every satellite above the UT's horizon (``_received_w``), each satellite's
    powers (the serving one's other beams share its path) scaled by ``10^(-L/10)`` of that
    (UT, satellite) path's loss ``L = shadow + clutter`` in the channel state the run used
    (``ChannelTracker.step``'s return, captured epoch by epoch; the serving path's terms
    are the trace's). 1e-9 dB and 1e-6 of I/N, as on WGS 84 (float rounding: measured
    8e-14 dB and 4e-15). The tolerance must be that tight: here the other satellites are
    4e-5 to 2.5e-3 of the interference (the serving satellite's other beams are the
    rest), and ``11^(-L/10)`` for their loss moves the SINR by 4.5e-5 dB. The
    interfering paths' losses must differ from the serving one's (half of them by over
    1 dB), or a loss taken from the wrong path would pass."""
    from leolink.sim.environment import ChannelTracker

    channels = []
    step = ChannelTracker.step

    def captured(self, *args, **kwargs):
        channels.append(step(self, *args, **kwargs))
        return channels[-1]

    monkeypatch.setattr(ChannelTracker, "step", captured)
    path = tmp_path / "walker.toml"
    path.write_text(WALKER.read_text() + NEAR + 'environment = "urban"\n')
    over = [*QUIET, "run.duration_s=3.0", "run.start_s=1000.0", 'earth.model="wgs84"',
            'link.interference="all_satellites"', "link.reuse_colors=3",
            "roi.center_lat_deg=40.0", "roi.center_lon_deg=39.5",
            f"population.2.panel_tilt_deg={tilt_deg}"]  # fmt: skip
    cfg = load_config(path, over)
    scen, tr = _run_in_memory(cfg)
    eng, eph = scen.engine, ephemeris_from_config(cfg)
    times = np.unique(tr.time_s)
    tilt = math.radians(tilt_deg)
    assert len(channels) == times.size  # one state per epoch, no warm-up
    p = eng.params
    noise_w = BOLTZMANN_J_K * 10 ** (p.noise_temp_dbk / 10) * p.bandwidth_hz / 3
    served = 0
    spread_db = []
    for ch, t in zip(channels, times, strict=True):
        rows = tr[tr.time_s == t]
        pos, vel = (a[0] for a in eph(np.array([t]))[:2])
        # (n_ut, n_sat) loss of every path with a state [dB], 0 without (below the horizon)
        loss_db = np.zeros((len(rows), len(pos)))
        has = ch.sat_id >= 0
        u_idx, slot = np.nonzero(has)
        terms = ch.terms
        loss_db[u_idx, ch.sat_id[has]] = (terms.shadow_db + terms.clutter_db)[u_idx, slot]
        for r in rows.itertuples():
            if r.service != "served":
                continue
            served += 1
            u, s = r.ut_id, r.sat_id
            j = int(np.flatnonzero(ch.sat_id[u] == s)[0])  # the serving path: the trace's
            assert r.shadow_db == pytest.approx(terms.shadow_db[u, j], abs=1e-12)
            assert r.clutter_db == pytest.approx(terms.clutter_db[u, j], abs=1e-12)
            ut, east, north, up = _geodetic_frame(math.radians(r.lat_deg),
                                                  math.radians(r.lon_deg), r.alt_m)  # fmt: skip
            lit = np.ones((len(pos), eng.n_beam), bool)
            axes = None
            if r.population == "near":  # x east, tilted down: the normal towards x (east)
                x_axis = math.cos(tilt) * east - math.sin(tilt) * up
                normal = math.sin(tilt) * east + math.cos(tilt) * up
                axes = (x_axis, np.cross(normal, x_axis))
            powers = _received_w(eng, cfg, ut, east, north, up, pos, vel, s, r.beam_id, lit,
                                 axes)  # fmt: skip
            powers = powers * 10 ** (-loss_db[u] / 10)[:, None]
            _check_row(r, powers, noise_w)
            other = powers.sum(axis=1) > 0
            other[s] = False
            spread_db += list(np.abs(loss_db[u, other] - loss_db[u, s]))
    assert served >= 10
    # the interferers' own losses: many differ from the serving path's by over 1 dB
    assert np.mean(np.array(spread_db) > 1.0) > 0.3


def test_a_scenario_without_a_service_link_gets_the_engines_figures():
    """``Scenario.link`` None (its default: a scenario built by hand) gives the monitor the
    link figures of the engine's power, cable loss and bandwidth with the ``[modcod]``
    defaults, and the controller's service: the trace of the config's own (default)
    figures, and the EIRP is ``P - L_cable + G_tx`` (1.5 dB of cable loss, so that power
    and loss cannot be swapped unseen), float rounding only."""
    import dataclasses

    from leolink.io.sinks import MemorySink
    from leolink.sim.runner import run_simulation

    cfg = load_config(PAPER, [*QUIET, "run.duration_s=10.0", "link.cable_loss_db=1.5"])
    scen, want = _run_in_memory(cfg)
    mem = MemorySink()
    run_simulation(dataclasses.replace(scen, link=None), [mem])
    got = mem.trace()
    p = scen.engine.params
    link = got[got.snr_db.notna()]
    assert len(link) > 0.9 * len(got) and link.modcod.nunique() > 3  # the figures are there
    np.testing.assert_allclose(link.eirp_dbw, p.ptx_dbw - 1.5 + link.gain_tx_db, rtol=0,
                               atol=1e-9)  # fmt: skip
    assert list(got.columns) == list(want.columns)
    for col in got.columns:
        np.testing.assert_array_equal(got[col].to_numpy(), want[col].to_numpy(), err_msg=col)


TWO = """
[[population]]
name = "between"
kind = "static"
placement = "points"
x_m = [10000.0, 30000.0, -30000.0, 5000.0, 20000.0]
y_m = [5000.0, 0.0, 20000.0, -30000.0, 30000.0]
"""


@pytest.mark.parametrize("start_s", [292.0, 229.0], ids=["one_block", "two_blocks"])
def test_other_satellites_with_exactly_two_in_view_are_the_explicit_sum(
    tmp_path, start_s, blocks_of_64
):
    """A Walker constellation of 2 satellites (2 planes at 53 deg, phasing 1: they cross
    at the nodes), every satellite interfering, 292 s after they met at the ascending
    node: 25 deg of arc apart, both 34 deg above the UTs near the equator between them
    (the monitor's cone is both: at most 64 satellites are never screened). Each row's
    SNR, SINR (1e-9 dB) and I/N (1e-6) against ``_received_w`` in the sphere's radial
    frame, and the other satellite must matter (over 1e-5 of the interference; measured
    3e-4 to 1e-3: without it the SINR is 3e-3 dB off). The rows of 292-294 s are checked;
    from 229 s they are the last epoch of the first 64-epoch motion block and the first
    two of the second (an epoch's index in its block is ``k - k0``)."""
    path = tmp_path / "walker.toml"
    path.write_text(WALKER.read_text().split("[[population]]")[0] + TWO)
    # the midpoint of the two satellites at t = 292 s (from the ephemeris: 0 N, 9.615 E)
    over = [*QUIET, f"run.duration_s={295.0 - start_s}", f"run.start_s={start_s}",
            "constellation.n_planes=2", "constellation.sats_per_plane=1",
            "constellation.phasing=1", 'link.interference="all_satellites"',
            "roi.center_lat_deg=0.0", "roi.center_lon_deg=9.615"]  # fmt: skip
    cfg = load_config(path, over)
    scen, tr = _run_in_memory(cfg)
    assert blocks_of_64 == ([(0, 64), (64, 66)] if start_s == 229.0 else [(0, 3)])
    tr = tr[tr.time_s >= 292.0]
    assert tr.time_s.nunique() == 3
    eng, eph = scen.engine, ephemeris_from_config(cfg)
    assert (tr.sat_id >= 0).all() and eph.n_sat == 2
    p = eng.params
    noise_w = BOLTZMANN_J_K * 10 ** (p.noise_temp_dbk / 10) * p.bandwidth_hz
    share = []
    for t, rows in tr.groupby("time_s"):
        pos, vel = (a[0] for a in eph(np.array([t]))[:2])
        for r, ut, east, north, up in _sphere_frames(rows):
            assert ((pos - ut) @ up > 0).all()  # both satellites up
            lit = np.ones((len(pos), eng.n_beam), bool)
            s = r.sat_id
            powers = _received_w(eng, cfg, ut, east, north, up, pos, vel, s, r.beam_id, lit)
            i_w = _check_row(r, powers, noise_w)
            share.append(powers[1 - s].sum() / i_w)
    assert min(share) > 1e-5


def test_every_satellite_interfering_with_a_single_satellite_changes_nothing():
    """``link.interference = "all_satellites"`` on the paper's single pass: there is no
    other satellite, so every column of every epoch (the blocks hold several epochs, the
    cone one satellite) is the default run's, bit for bit."""
    over = [*QUIET, "run.duration_s=20.0"]
    want = run(load_config(PAPER, over)).trace
    got = run(load_config(PAPER, [*over, 'link.interference="all_satellites"'])).trace
    assert len(got) == len(want) > 100
    for col in want.columns:
        np.testing.assert_array_equal(got[col].to_numpy(), want[col].to_numpy(), err_msg=col)


def test_a_dwell_that_begins_at_the_first_recorded_epoch_is_not_censored():
    """The paper's centre UT hands over at 14, 45, 76 and 107 s (31 s dwells). With a 14 s
    warm-up the dwell from 14 s begins with the recording, it is not cut by it: three
    complete 31 s dwells; the one from 0 to 14 s began in the warm-up (censored), the last
    one is cut by the end."""
    cfg = load_config(PAPER, [*QUIET, "run.warmup_s=14", "run.duration_s=100"])
    res = run(cfg.model_copy(update={"population": cfg.population[:1]}))
    assert res.trace.time_s.min() == 14.0
    dwell = res.summary["per_ut"][0]["dwell"]
    assert dwell["complete_s"] == pytest.approx([31.0, 31.0, 31.0])
    starts = [(d["start_s"], d["censored_start"]) for d in dwell["censored"]]
    assert starts == [(0.0, True), (107.0, False)]


def test_one_beam_two_satellites_interfering_and_a_ut_without_any(tmp_path):
    """The two-satellite Walker above with one beam (one RF chain, a 3 km ROI) and every
    satellite interfering, plus a UT 4,000 km away that sees neither: its rows have no
    link, and the two UTs under the beam get the links of a run without it (a row
    without a satellite must not pick a beam the codebook lacks)."""
    pops = FAR.replace("[0.0, 200000.0]", "[500.0, 1000.0]").replace(
        "[0.0, -100000.0]", "[300.0, -1000.0]"
    )
    head = WALKER.read_text().split("[[population]]")[0]
    over = [*QUIET, "run.duration_s=3.0", "run.start_s=292.0", "constellation.n_planes=2",
            "constellation.sats_per_plane=1", "constellation.phasing=1",
            'link.interference="all_satellites"', "roi.center_lat_deg=0.0",
            "roi.center_lon_deg=9.615", "roi.semi_axis_x_m=3000.0",
            "roi.semi_axis_y_m=3000.0", "satellite_array.n_rf_x=1",
            "satellite_array.n_rf_y=1", 'satellite_array.oversampling="auto"',
            "controller.min_snr_db=-60.0"]  # fmt: skip
    # (the one beam points at the satellite's nadir, 12.5 deg of arc away: -50 dB SNR)
    out = []
    for text in (pops, pops.split("\n\n")[0] + "\n"):
        path = tmp_path / "walker.toml"
        path.write_text(head + text)
        out.append(_run_in_memory(load_config(path, over)))
    (scen, tr), (_, alone) = out
    assert scen.engine.n_beam == 1
    far, near = tr[tr.ut_id == 2], tr[tr.ut_id < 2]
    assert (far.n_visible == 0).all() and far.snr_db.isna().all()
    assert near.sinr_db.notna().all() and (near.sinr_db < near.snr_db).all()
    for col in (*GEOMETRY, "sinr_db"):
        np.testing.assert_array_equal(near[col].to_numpy(), alone[col].to_numpy())


def test_serving_pairs_the_pruned_search_left_out_get_their_own_links(monkeypatch, blocks_of_64):
    """Hysteresis (window 0 dB: the pruned search keeps only the pairs that can hold a
    UT's best cell) on a rotating Walker with moving UTs: the controller keeps serving
    satellites whose pairs the search left out, 3 rows of one block and 2 of another,
    which the monitor evaluates itself. The trace equals that of ``prune = False`` (every
    pair of the cone evaluated, none left to the monitor), bit for bit: each left-out row
    has the link of its own pair, not of another row's."""
    over = [*QUIET, 'constellation.kind="walker"', "constellation.n_planes=12",
            "constellation.sats_per_plane=10", "constellation.min_elevation_deg=25",
            'satellite_array.oversampling="auto"', "earth.rotation=true",
            "run.duration_s=600", "run.epoch_s=5", 'controller.policy="hysteresis"',
            "controller.hysteresis.margin_db=1.0", "controller.handover_time_s=5.0",
            "controller.min_snr_db=-25.0", "population.1.count=6",
            'population.1.placement="random"']  # fmt: skip
    left_out = []
    pair_links = Monitor._pair_links

    def counted(self, rows, geo_sat, served, n_ut):
        pair = self.decider.block.find_pairs(rows, geo_sat)
        left_out.append(int((served & (pair < 0)).sum()))
        return pair_links(self, rows, geo_sat, served, n_ut)

    monkeypatch.setattr(Monitor, "_pair_links", counted)
    traces = []
    for prune in (True, False):
        scen = build_scenario(load_config(PAPER, over))
        scen.prune = prune
        sink = MemorySink()
        run_simulation(scen, [sink])
        traces.append(sink.trace())
        if prune:
            assert max(left_out) >= 2  # several left-out rows in one block
            assert len(left_out) == 2 and blocks_of_64 == [(0, 64), (64, 120)]
            left_out.clear()
    assert sum(left_out) == 0
    assert (traces[0].sat_id >= 0).sum() > 500
    pd.testing.assert_frame_equal(traces[0], traces[1])


class _EpochCapture:
    """The ``k`` and ``t_s`` of every epoch frame, and the rows' times (epoch-only sink)."""

    def start(self, info):
        self.info, self.frames = info, []

    def epoch(self, frame):
        self.frames.append((frame.k, frame.t_s, np.unique(frame.columns["time_s"])))

    def finish(self, final):
        pass

    def abort(self):
        pass


def test_with_rlf_each_epoch_frame_is_numbered_from_the_recording_at_its_time():
    """With radio link failure monitoring the monitor sends each epoch as it is decided
    (after RLF), one :class:`EpochFrame` each: after a 3 s warm-up at 0.5 s epochs the
    frames are numbered 0, 1, ... from the first recorded epoch, at ``start + 3 s + k
    0.5 s``, the time of their rows."""
    cfg = load_config(PAPER, [*QUIET, "controller.rlf.enabled=true", "run.epoch_s=0.5",
                              "run.warmup_s=3.0", "run.duration_s=10.0"])  # fmt: skip
    cap = _EpochCapture()
    run_simulation(build_scenario(cfg), [cap])
    k, t_s, rows_t = zip(*cap.frames, strict=True)
    assert list(k) == list(range(20)) and cap.info.n_epochs == 20
    want = cfg.run.start_s + 3.0 + 0.5 * np.arange(20)
    np.testing.assert_allclose(t_s, want, rtol=0, atol=1e-9)
    assert all(r.tolist() == [t] for r, t in zip(rows_t, want, strict=True))


def test_fading_in_a_block_whose_only_link_is_its_first_pair(blocks_of_64):
    """One UT, 65 epochs: the second motion block holds the last epoch alone, whose only
    link is the block's pair 0. Its row too gets its Rician draw, as every other row: SNR
    with fading minus without is ``10 log10(|sqrt(N) + g / sqrt(K)|^2 / (N + 1/K))`` with
    the UT's receive gain ``N`` and the run's draw ``g`` for that UT and epoch."""
    from leolink.rng import complex_normal, ut_keys

    over = [*QUIET, "run.duration_s=65.0", "run.start_s=-15.0"]
    cfg = load_config(PAPER, over)
    cfg = cfg.model_copy(update={"population": cfg.population[:1]})
    mean = run(cfg).trace
    cfg_f = load_config(PAPER, [*over, 'link.fading="rician"'])
    fading = run(cfg_f.model_copy(update={"population": cfg_f.population[:1]})).trace
    assert len(mean) == 65 and mean.snr_db.notna().all() and fading.snr_db.notna().all()
    assert blocks_of_64 == [(0, 64), (64, 65)] * 2
    keys = ut_keys(cfg.run.seed, 1)
    g = np.array([complex_normal(keys, k)[0] for k in range(65)])
    n, k = 10 ** (mean.gain_rx_db.to_numpy() / 10), cfg.link.rician_k
    factor_db = 10 * np.log10(np.abs(np.sqrt(n) + g / np.sqrt(k)) ** 2 / (n + 1 / k))
    assert abs(factor_db[-1]) > 0.01
    got = (fading.snr_db - mean.snr_db).to_numpy()
    np.testing.assert_allclose(got, factor_db, rtol=0, atol=1e-9)


def _earth_fixed_beams(cb, cells, pos, vel, sin_min_el, cos_for):
    """Steering vectors ``(n_sat, n_beam, n_el)`` of beams re-steered at each satellite's
    ground cells ``cells (n_sat, n_beam, 3)``, in its body frame (as ``_tx_gains``), and
    which beams are on: the cell sees the satellite at or above the minimum elevation
    and the cell is within the field of regard (angle off nadir)."""
    beams, on = [], []
    for c, sp, sv in zip(cells, pos, vel, strict=True):
        z = sp / np.linalg.norm(sp)
        x = sv - (sv @ z) * z
        x /= np.linalg.norm(x)
        d = (c - sp) / np.linalg.norm(c - sp, axis=1)[:, None]  # satellite -> cell
        v = np.stack([d @ x, d @ np.cross(z, x)], axis=-1)
        sin_el = -np.einsum("bk,bk->b", d, c / np.linalg.norm(c, axis=1)[:, None])
        with np.errstate(invalid="ignore"):
            on.append((sin_el >= sin_min_el) & (-d @ z >= cos_for))
        beams.append(_upa(np.where(on[-1][:, None], v, 0.0), cb.n_sub_x, cb.n_sub_y))
    return np.array(beams), np.array(on)


def test_other_satellites_with_earth_fixed_beams_are_the_explicit_sum(tmp_path):
    """Walker, every satellite interfering, beams re-steered to Earth-fixed cells (each
    satellite its own footprint's cells at the reference instant, read from the engine's
    steering mode): each row's SNR, SINR (1e-9 dB) and I/N (1e-6) against the explicit
    received powers of every satellite above the UT's horizon, each satellite's beams
    steered at its own cells (``_earth_fixed_beams``); the cone's satellites are not the
    first ones of the constellation (a satellite row of the interference sum is not its
    id)."""
    path = tmp_path / "walker.toml"
    path.write_text(WALKER.read_text() + NEAR)
    over = [*QUIET, "run.duration_s=3.0", 'link.interference="all_satellites"',
            'satellite_array.steering="earth_fixed"']  # fmt: skip
    cfg = load_config(path, over)
    scen, tr = _run_in_memory(cfg)
    eng, eph = scen.engine, ephemeris_from_config(cfg)
    st = eng.steering
    assert (tr.sat_id >= 0).all() and tr.sat_id.nunique() >= 2 and len(st.cells_m) == eph.n_sat
    p = eng.params
    noise_w = BOLTZMANN_J_K * 10 ** (p.noise_temp_dbk / 10) * p.bandwidth_hz
    other = []
    for t, rows in tr.groupby("time_s"):
        pos, vel = (a[0] for a in eph(np.array([t]))[:2])
        beams, on = _earth_fixed_beams(eng.codebook, st.cells_m, pos, vel, st.sin_min_el,
                                       st.cos_for)  # fmt: skip
        for r, ut, east, north, up in _sphere_frames(rows):
            powers = _received_w(eng, cfg, ut, east, north, up, pos, vel, r.sat_id,
                                 r.beam_id, on, beams=beams)  # fmt: skip
            i_w = _check_row(r, powers, noise_w)
            other.append((powers.sum() - powers[r.sat_id].sum()) / i_w)
    assert min(other) > 1e-4


def test_precoded_sinr_with_other_satellites_is_the_explicit_sum(tmp_path):
    """The two-satellite Walker above, 4 UTs 150 km apart (no beam shared), with the ZF
    precoder (one slot per UT, whose SINR the trace keeps): ZF cancels the serving
    satellite's own beams, so a
    row's SINR is ``S / (1 + I_o)`` with every satellite interfering and ``S`` without
    (``link.interference`` does not change the decisions or the precoder), ``I_o`` the
    other satellite's explicit received power over the noise (``_received_w``): 1e-9 dB
    (the other satellite takes 1e-4 to 0.03 dB off here)."""
    # (UT 0 1 km off the centre: at the centre both satellites tie exactly, and the last
    # bit of each path's rounding would choose)
    spread = TWO.replace(
        "[10000.0, 30000.0, -30000.0, 5000.0, 20000.0]", "[1000.0, 150000.0, -150000.0, 0.0]"
    )
    spread = spread.replace(
        "[5000.0, 0.0, 20000.0, -30000.0, 30000.0]", "[0.0, 0.0, 0.0, 150000.0]"
    )
    path = tmp_path / "walker.toml"
    path.write_text(WALKER.read_text().split("[[population]]")[0] + spread)
    over = [*QUIET, "run.duration_s=3.0", "run.start_s=292.0", "constellation.n_planes=2",
            "constellation.sats_per_plane=1", "constellation.phasing=1",
            'link.precoder="zf"', 'scheduler.kind="round_robin"', "roi.center_lat_deg=0.0",
            "roi.center_lon_deg=9.615"]  # fmt: skip
    cfg = load_config(path, [*over, 'link.interference="all_satellites"'])
    scen, tr = _run_in_memory(cfg)
    _, alone = _run_in_memory(load_config(path, over))
    eng, eph = scen.engine, ephemeris_from_config(cfg)
    assert (tr.sat_id >= 0).all() and tr.sat_id.nunique() == 2
    assert not tr.duplicated(["time_s", "sat_id", "beam_id"]).any()  # one UT per beam
    for col in ("sat_id", "beam_id", "snr_db"):
        np.testing.assert_array_equal(tr[col].to_numpy(), alone[col].to_numpy())
    p = eng.params
    noise_w = BOLTZMANN_J_K * 10 ** (p.noise_temp_dbk / 10) * p.bandwidth_hz
    i_o = []
    for t, rows in tr.groupby("time_s"):
        pos, vel = (a[0] for a in eph(np.array([t]))[:2])
        for r, ut, east, north, up in _sphere_frames(rows):
            lit = np.ones((len(pos), eng.n_beam), bool)
            powers = _received_w(eng, cfg, ut, east, north, up, pos, vel, r.sat_id,
                                 r.beam_id, lit)  # fmt: skip
            i_o.append(powers[1 - r.sat_id].sum() / noise_w)
    i_o = np.array(i_o)
    want = alone.sinr_db.to_numpy() - 10 * np.log10(1 + i_o)
    assert (10 * np.log10(1 + i_o)).min() > 1e-4
    np.testing.assert_allclose(tr.sinr_db.to_numpy(), want, rtol=0, atol=1e-9)


def test_a_handover_epochs_se_is_the_served_part_of_a_half_second_epoch():
    """0.5 s epochs, 0.2 s handover execution: a handover row's SE and throughput are the
    link's ``log2(1 + SINR)`` times the served part of its epoch, ``1 - 0.2 / 0.5``, and
    its interruption is 0.2 s; the other served rows get the whole link."""
    cfg = load_config(PAPER, [*QUIET, "run.epoch_s=0.5", "run.duration_s=60.0",
                              "controller.handover_time_s=0.2"])  # fmt: skip
    tr = run(cfg).trace
    se_link = np.log2(1 + 10 ** (tr.sinr_db / 10))
    ho, served = tr[tr.service == "handover"], tr[tr.service == "served"]
    assert len(ho) >= 5 and len(served) > 100
    np.testing.assert_allclose(ho.interruption_s, 0.2, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ho.se_bps_hz, se_link[ho.index] * (1 - 0.2 / 0.5), rtol=1e-9)
    np.testing.assert_allclose(ho.throughput_bps, ho.se_bps_hz * cfg.link.bandwidth_hz, rtol=1e-9)
    np.testing.assert_allclose(served.se_bps_hz, se_link[served.index], rtol=1e-9)


def test_an_outage_row_whose_open_country_snr_is_the_threshold_exactly_is_blocked(tmp_path):
    """Suburban UTs with ``controller.min_snr_db`` set to the open-country best SNR of one
    row, exactly (a candidate at the threshold is usable): open country serves that row,
    the environment's loss puts it in outage, so it is ``blocked``; and, as above, the
    outage rows are ``blocked`` exactly where open country serves."""
    over = ["run.duration_s=20.0", "run.start_s=-10.0"]

    def both(sets):
        return [run(_with_populations(tmp_path, TOWN, SUBURBAN.format(env=name), sets)).trace
                for name in ("suburban", "open")]  # fmt: skip

    env0, open0 = both(over)
    lost = open0.best_snr_db - env0.best_snr_db
    r = int(np.flatnonzero((lost > 1.0) & (open0.service == "served"))[0])
    x = float(open0.best_snr_db[r])
    env, open_ = both([*over, f"controller.min_snr_db={x!r}"])
    assert open_.best_snr_db[r] == x and open_.service[r] == "served"
    assert env.service[r] == "outage" and env.outage_reason[r] == "blocked"
    out = env.service == "outage"
    np.testing.assert_array_equal(env.outage_reason[out] == "blocked",
                                  open_.service[out] != "outage")  # fmt: skip
