"""Ephemeris errors (ephemeris_error.py, sim/ephemeris_monitor.py, io/ephemeris_sink.py).

References: a circular orbit perturbed along-track is the same orbit a time ``delta / v``
later (to ``delta^2 / 2r``, 26 m for 20 km at 7671 km), so a known along-track offset
shifts the controller's beam switches by that time; the true switches are the closed
form of analysis/fig11_snr_vs_time.py (crossovers of the DFT lattice at
``u = (2k + 1) / (O N_x)``, central angle ``gamma(u) = asin((R + h) u / R) - asin(u)``).
Angles are recomputed by brute force from unit vectors.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import leolink
from leolink.antenna.array import explicit_gain, steering_vector
from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.ephemeris_error import EstimatedEphemeris, RtnError, rtn_to_frame
from leolink.errors import LeolinkError
from leolink.geometry import direction_cosines
from leolink.io.ephemeris_sink import EphemerisErrorSink
from leolink.orbit import orbital_speed_m_s
from leolink.sim.ephemeris_monitor import pointing_error
from leolink.sim.runner import run_simulation

PAPER = "configs/paper.toml"
RTN = ["ephemeris_error.model=rtn"]


def _offset(along=0.0, cross=0.0, radial=0.0):
    return [*RTN, f"ephemeris_error.rtn.along_track_offset_m={along}",
            f"ephemeris_error.rtn.cross_track_offset_m={cross}",
            f"ephemeris_error.rtn.radial_offset_m={radial}"]  # fmt: skip


def _run(overrides):
    """Trace, events and the ephemeris rows of the paper's pass."""
    scen = build_scenario(load_config(PAPER, overrides))
    from leolink.io.sinks import MemorySink

    mem, eph = MemorySink(), EphemerisErrorSink(None)
    run_simulation(scen, [mem, eph])
    return mem.trace(), mem.events(), eph.table(), scen


def test_an_offset_is_along_track_cross_track_and_radial():
    pos, vel = np.array([[7e6, 1e6, 2e6]]), np.array([[100.0, 7e3, -2e3]])
    d = rtn_to_frame(pos, vel, np.array([[10.0, 20.0, 30.0]]))[0]
    r_hat = pos[0] / np.linalg.norm(pos[0])
    t = vel[0] - (vel[0] @ r_hat) * r_hat
    t_hat = t / np.linalg.norm(t)
    assert d @ t_hat == pytest.approx(10.0) and d @ r_hat == pytest.approx(30.0)
    assert d @ np.cross(r_hat, t_hat) == pytest.approx(20.0)  # y = z x x


def test_rtn_draws_are_seeded_per_period_and_grow_along_track():
    m = RtnError((100.0, 50.0, 10.0), (0.0, 0.0, 0.0), 0.0, 3600.0, 7200.0, seed=5)
    t = np.array([0.0, 3600.0, 7199.0, 7200.0])
    dpos, dvel = m.offsets(t, 3)
    again, _ = m.offsets(t[::-1], 3)
    np.testing.assert_array_equal(dpos, again[::-1])  # a pure function of time
    # Along-track sigma 100 m + 1 m/s of age: the same draw, scaled, within a period.
    np.testing.assert_allclose(dpos[1, :, 0] / dpos[0, :, 0], 3700.0 / 100.0)
    np.testing.assert_allclose(dpos[1, :, 1:], dpos[0, :, 1:])  # no growth across track
    np.testing.assert_allclose(dvel[0, :, 0], dpos[0, :, 0] / 100.0)  # d/dt of the growth
    assert not np.allclose(dpos[3], dpos[0])  # an update: new draws, age 0


def test_pointing_error_is_the_angle_between_the_directions():
    ut, up = np.array([[0.0, 0.0, 6.371e6]]), np.array([[0.0, 0.0, 1.0]])
    sat = np.array([[1e6, 0.0, 7.0e6]])  # to the east (x), 57 deg up
    for shift, psi in (([0.0, 0.0, 2e4], 0.0), ([0.0, 2e4, 0.0], np.pi / 2)):
        off, got_psi = pointing_error(ut, up, sat, sat + np.array([shift]))
        a, b = sat[0] - ut[0], sat[0] + shift - ut[0]
        brute = math.acos(a @ b / np.linalg.norm(a) / np.linalg.norm(b))
        assert off[0] == pytest.approx(brute, rel=1e-9)
        # Up (higher elevation) is psi = 0; north, to the left of a UT looking east, pi / 2.
        assert got_psi[0] == pytest.approx(psi, abs=0.02)


def test_zero_error_is_the_error_free_run():
    base, base_ev, none_rows, scen = _run([])
    zero, zero_ev, rows, scen0 = _run(RTN)
    assert scen0.estimated_ephemeris is None and rows.empty and none_rows.empty
    assert base.equals(zero) and base_ev.equals(zero_ev)


def _closed_form_handovers_s(cfg, codebook):
    radius, h = cfg.earth.radius_m, cfg.constellation.altitude_m
    w = orbital_speed_m_s(h, radius, cfg.earth.gm_m3_s2) / (radius + h)
    step = 2.0 / (codebook.oversampling * codebook.n_sub_x)
    u = np.array([0.5, 1.5]) * step  # the crossovers the UT meets, both sides of overhead
    gamma = np.arcsin((radius + h) / radius * u) - np.arcsin(u)
    t_pass = cfg.constellation.pass_time_s
    return np.sort(np.concatenate([t_pass - gamma / w, t_pass + gamma / w]))


@pytest.mark.parametrize("along_m", [20e3, -12e3])
def test_a_known_along_track_offset_gives_the_closed_form_wrong_beam_epochs(along_m):
    cfg = load_config(PAPER)
    trace, events, rows, scen = _run(_offset(along=along_m))
    cb = scen.engine.codebook
    t_k = _closed_form_handovers_s(cfg, cb)
    h = cfg.constellation.altitude_m
    tau = along_m / orbital_speed_m_s(h, cfg.earth.radius_m, cfg.earth.gm_m3_s2)
    # The believed satellite is tau later on its orbit: it switches at t_k - tau.
    switch = np.sort(events[(events.ut_id == 0) & (events.kind == "beam_handover")].time_s)
    np.testing.assert_allclose(switch, np.ceil(t_k - tau), atol=1e-9)  # 1 s epochs
    ut0 = rows[rows.ut_id == 0]
    wrong = set(ut0.time_s[ut0.wrong_beam == 1.0])
    lo, hi = np.minimum(t_k - tau, t_k), np.maximum(t_k - tau, t_k)
    expected = {float(t) for t in ut0.time_s if ((t >= lo) & (t < hi)).any()}
    assert wrong == expected and len(wrong) >= 4 * math.floor(abs(tau))
    right = ut0[ut0.wrong_beam == 0.0]  # the true best beam: the UT's pointing loss only
    np.testing.assert_allclose(right.snr_loss_db, right.pointing_loss_db, atol=1e-9)
    bad = ut0[ut0.wrong_beam == 1.0]
    assert (bad.snr_loss_db > bad.pointing_loss_db).all()


def test_twenty_km_errors_give_wrong_beams_and_pointing_losses():
    over = [*RTN, *(f"ephemeris_error.rtn.{a}_m=20000" for a in ("along_track", "cross_track",
                                                                     "radial"))]  # fmt: skip
    trace, events, rows, scen = _run(over)
    assert 0.01 < rows.wrong_beam.mean() < 0.5
    assert (rows.pointing_error_deg > 0.1).all() and (rows.pointing_loss_db > 0.0).all()
    assert (rows.snr_loss_db >= rows.pointing_loss_db - 1e-9).all()
    # The trace is the true link: its receive gain is the terminal's, minus the loss.
    served = trace.service == "served"
    g0 = scen.engine.terminal.gain_db(np.radians(trace.elevation_deg[served]))
    np.testing.assert_allclose(g0 - trace.gain_rx_db[served], rows.pointing_loss_db, atol=1e-9)


def test_earth_fixed_beams_are_mispointed_by_the_believed_position():
    over = ["satellite_array.steering=earth_fixed", *_offset(along=20e3, cross=5e3)]
    trace, events, rows, scen = _run(over)
    steer, cb = scen.engine.steering, scen.engine.codebook
    ut0 = trace[trace.ut_id == 0].set_index("time_s")
    true = scen.ephemeris
    est = scen.estimated_ephemeris
    assert isinstance(est, EstimatedEphemeris)
    ut = load_config(PAPER).roi
    lat, lon = math.radians(ut.center_lat_deg), math.radians(ut.center_lon_deg)
    ut_pos = 6_371_000.0 * np.array([math.cos(lat) * math.cos(lon),
                                     math.cos(lat) * math.sin(lon), math.sin(lat)])  # fmt: skip
    for t in (0.0, 30.0, 60.0, 119.0):
        p, v, _ = true(np.array([t]))
        pe, ve, _ = est(np.array([t]))
        b = int(ut0.beam_id[t])
        centre = direction_cosines(pe[0, 0], ve[0, 0], steer.cells_m[0, b])  # as steered
        u = direction_cosines(p[0, 0], v[0, 0], ut_pos)  # where the UT truly is
        w = steering_vector(centre, cb.n_sub_x, cb.n_sub_y)[:, None]
        ref_db = 10 * np.log10(explicit_gain(u, w, cb.n_sub_x, cb.n_sub_y)[0])
        assert ut0.gain_tx_db[t] == pytest.approx(ref_db, abs=1e-9)
        assert ut0.gain_tx_db[t] < 10 * np.log10(288) - 0.05  # mispointed


def test_all_satellites_interference_with_errors_is_refused():
    with pytest.raises(LeolinkError, match="ephemeris_error.model = 'rtn'.*all_satellites"):
        build_scenario(load_config(PAPER, [*_offset(along=1.0),
                                           "link.interference=all_satellites"]))  # fmt: skip


def test_a_run_with_errors_writes_its_files(tmp_path):
    quiet = ["output.report.enabled=false", "output.plots.enabled=false"]
    res = leolink.run(
        load_config(PAPER, [*_offset(along=20e3), "run.duration_s=20", *quiet]), tmp_path
    )
    assert res is not None
    import json

    data = json.loads((tmp_path / "ephemeris_errors.json").read_text())
    assert data["rows"] == 7 * 20 and data["position_error_m"]["max"] == pytest.approx(20e3)
    manifest = (tmp_path / "run.json").read_text()
    assert "ephemeris_errors.csv" in manifest


def test_the_wired_precoder_sees_the_believed_and_the_true_satellite(monkeypatch):
    """In a run, the precoder's inputs carry the serving satellite's true position and the
    one the controller believes (both recomputed here from the two ephemerides)."""
    from leolink.sim.beams.service import BeamService

    seen, apply = [], BeamService.apply

    def spy(self, cols, sat_id, beam_id, served, lit, inputs):
        seen.append((sat_id.copy(), served.copy(), inputs()))
        return apply(self, cols, sat_id, beam_id, served, lit, inputs)

    monkeypatch.setattr(BeamService, "apply", spy)
    over = [*_offset(along=20e3, radial=3e3), "ephemeris_error.rtn.velocity_m_s=5",
            "scheduler.kind=round_robin", "link.precoder=zf"]  # fmt: skip
    trace, _, _, scen = _run(over)
    times = np.unique(trace.time_s)
    assert len(seen) == times.size
    for t, (sat_id, served, inp) in zip(times, seen, strict=True):
        true, true_vel, _ = scen.ephemeris(np.array([t]))
        est, est_vel, _ = scen.estimated_ephemeris(np.array([t]))
        s = sat_id[served]
        assert s.size > 0
        np.testing.assert_allclose(inp["sat_pos_m"][served], true[0, s], rtol=0, atol=1e-6)
        np.testing.assert_allclose(inp["sat_pos_est_m"][served], est[0, s], rtol=0, atol=1e-6)
        np.testing.assert_allclose(inp["sat_vel_est_m"][served], est_vel[0, s], atol=1e-9)
        assert np.linalg.norm(inp["sat_vel_est_m"][served] - true_vel[0, s], axis=1).min() > 0.1
        off = np.linalg.norm(inp["sat_pos_est_m"][served] - inp["sat_pos_m"][served], axis=1)
        np.testing.assert_allclose(off, math.hypot(20e3, 3e3), rtol=1e-9)


@pytest.mark.parametrize(
    ("sets", "what"),
    [(["satellite_array.steering=earth_fixed"], "steering = 'earth_fixed'"),
     (["satellite_array.phase_bits=3"], "phase_bits")],
)  # fmt: skip
def test_a_precoder_with_re_steered_or_quantized_beams_is_refused(sets, what):
    from leolink.errors import ConfigError

    over = [*sets, "scheduler.kind=round_robin", "link.precoder=mmse"]
    with pytest.raises(ConfigError, match=f"link.precoder = 'mmse' is not allowed with "
                                          f"satellite_array.{what}"):  # fmt: skip
        load_config(PAPER, over)


def test_fading_of_the_true_link_is_on_top_of_the_pointing_loss():
    """20 km errors with Rician fading: each served row's SNR with fading minus without
    is the draw's factor ``10 log10(|sqrt(N) + g / sqrt(K)|^2 / (N + 1/K))`` (``N`` the
    terminal's gain at the true elevation, ``g`` the run's draw for that UT and epoch),
    1e-9 dB: the pointing loss is in both SNRs, the fading in one."""
    from leolink.rng import complex_normal, ut_keys

    axes = ("along_track", "cross_track", "radial")
    over = [*RTN, "run.duration_s=60", *(f"ephemeris_error.rtn.{a}_m=20000" for a in axes)]
    mean, _, rows, scen = _run(over)
    fading, _, _, _ = _run([*over, 'link.fading="rician"'])
    ok = (mean.service == "served") & (fading.service == "served")
    assert ok.sum() > 100 and (rows.pointing_loss_db[ok.to_numpy()] > 0.0).all()
    cfg = load_config(PAPER, over)
    epoch = np.round((mean.time_s - cfg.run.start_s) / cfg.run.epoch_s).astype(int)
    keys = ut_keys(cfg.run.seed, int(mean.ut_id.max()) + 1)
    g = np.array([complex_normal(keys[[u]], k)[0] for u, k in zip(mean.ut_id, epoch, strict=True)])
    n = 10 ** (scen.engine.terminal.gain_db(np.radians(mean.elevation_deg.to_numpy())) / 10)
    k_r = cfg.link.rician_k
    factor_db = 10 * np.log10(np.abs(np.sqrt(n) + g / np.sqrt(k_r)) ** 2 / (n + 1 / k_r))
    got = (fading.snr_db - mean.snr_db).to_numpy()
    assert (np.abs(factor_db[ok]) > 1e-3).mean() > 0.9
    np.testing.assert_allclose(got[ok], factor_db[ok], rtol=0, atol=1e-9)
