"""NTN timing columns (timing.py, sim/monitor.py) and ``leolink export-ntn`` (app/export_ntn.py).

References: every expected value is recomputed here from positions, not from the code's
helpers: the UTs' states from their mobility models, the satellites' from the (true or
believed) ephemeris, ranges as vector norms, Doppler as a finite difference of the true
range, the cell's far edge by bisection on the elevation of ground points. The paper's
pass (moving UTs included) with and without an ephemeris error.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import leolink
from leolink.app.export_ntn import export_ntn, sib19_records
from leolink.app.orbits import ephemeris_from_config
from leolink.app.scenario import build_scenario
from leolink.cli import EXIT_USAGE, main
from leolink.config import load_config
from leolink.io.sinks import MemorySink
from leolink.sim.mobility.models import concat_states
from leolink.sim.runner import run_simulation
from leolink.timing import T_C_S, TIMING_COLUMNS, k_offset_ms

C_M_S = 299_792_458.0
ONE_NS = 1e-9  # the tolerance on delay and TA
PAPER = "configs/paper.toml"
SHORT = ["run.duration_s=20", "run.epoch_s=0.5"]
TIMING = [*SHORT, "timing.enabled=true"]
# 2 km ahead, 300 m off-track and 100 m up: the believed range differs by 10s of metres
ERROR = ["ephemeris_error.model=rtn", "ephemeris_error.rtn.along_track_offset_m=2000",
         "ephemeris_error.rtn.cross_track_offset_m=300",
         "ephemeris_error.rtn.radial_offset_m=100"]  # fmt: skip
# a finite-difference step for the Doppler check [s]: truncation ~ rho''' h^2 ~ 1e-5 m/s
FD_STEP_S = 1e-3
DOPPLER_FD_HZ = 0.5  # 1e-5 m/s of range rate is 4e-4 Hz at 11.45 GHz; float rounding 0.1 Hz


def _run(overrides):
    scen = build_scenario(load_config(PAPER, overrides))
    mem = MemorySink()
    run_simulation(scen, [mem])
    return mem.trace(), scen


def _ut_states(scen, t_s):
    """UT positions and velocities (n_ut, 3) at ``t_s`` from the mobility models."""
    s = concat_states([p.state(t_s) for _, p in scen.populations])
    return s.pos_m, s.vel_m_s


def _rows_states(trace, scen, ephemeris, dt=0.0):
    """Per served trace row: UT position and velocity, satellite position (at t + dt)."""
    rows = trace[trace["sat_id"] >= 0]
    ut_p, ut_v, sat_p = [], [], []
    for t, group in rows.groupby("time_s", sort=False):
        u = group["ut_id"].to_numpy()
        p, v = _ut_states(scen, t + dt)
        ut_p.append(p[u])
        ut_v.append(v[u])
        sat_p.append(ephemeris(np.array([t + dt]))[0][0, group["sat_id"].to_numpy()])
    return rows, np.concatenate(ut_p), np.concatenate(ut_v), np.concatenate(sat_p)


@pytest.fixture(scope="module")
def clean():
    return _run(TIMING)


@pytest.fixture(scope="module")
def erred():
    return _run([*TIMING, *ERROR])


def test_timing_columns_appear_only_with_timing_on(clean):
    off, _ = _run(SHORT)
    assert not set(TIMING_COLUMNS) & set(off.columns)
    trace, _ = clean
    assert list(trace.columns[-len(TIMING_COLUMNS) :]) == list(TIMING_COLUMNS)
    # the columns before them are the run's without [timing], in the same order
    assert list(trace.columns[: len(off.columns)]) == list(off.columns)


def test_delay_is_the_true_slant_range_over_c(erred):
    trace, scen = erred
    rows, ut, _, sat = _rows_states(trace, scen, scen.ephemeris)
    expected = np.linalg.norm(sat - ut, axis=-1) / C_M_S
    np.testing.assert_allclose(rows["delay_s"], expected, rtol=0, atol=ONE_NS)


@pytest.mark.parametrize("which", ["clean", "erred"])
def test_ta_is_twice_the_believed_range_over_c_minus_the_common_ta(which, request):
    trace, scen = request.getfixturevalue(which)
    believed = scen.estimated_ephemeris or scen.ephemeris
    rows, ut, _, sat = _rows_states(trace, scen, believed)
    common = 2.0 * (np.linalg.norm(sat, axis=-1) - 6_371_000.0) / C_M_S  # the nadir's RTT
    np.testing.assert_allclose(rows["common_ta_s"], common, rtol=0, atol=ONE_NS)
    expected = 2.0 * np.linalg.norm(sat - ut, axis=-1) / C_M_S - common
    np.testing.assert_allclose(rows["ta_s"], expected, rtol=0, atol=ONE_NS)


def test_an_ephemeris_error_moves_the_ta_off_the_true_range(erred):
    trace, scen = erred
    rows = trace[trace["sat_id"] >= 0]
    believed_rtt = rows["ta_s"] + rows["common_ta_s"]
    # 2 km along, 300 m across, 100 m up: ~100 m of range off, where the line of sight
    # is not nearly perpendicular to the error; far beyond 1 ns (0.15 m) everywhere here
    off_s = np.abs(believed_rtt - 2.0 * rows["delay_s"])
    assert np.median(off_s) > 1000 * ONE_NS and off_s.min() > 10 * ONE_NS


def test_residual_doppler_is_zero_without_an_ephemeris_error(clean):
    trace, _ = clean
    served = trace[trace["sat_id"] >= 0]
    assert len(served) > 100
    assert np.abs(served["doppler_residual_hz"]).max() < 1e-6


def test_residual_doppler_is_true_minus_believed_range_rate(erred):
    trace, scen = erred
    f = 11.45e9
    rows, ut, ut_v, _ = _rows_states(trace, scen, scen.ephemeris)
    # true Doppler: -(f / c) d|r_sat - r_ut| / dt by a central difference of positions
    _, ut_p, _, sat_p = _rows_states(trace, scen, scen.ephemeris, FD_STEP_S)
    _, ut_m, _, sat_m = _rows_states(trace, scen, scen.ephemeris, -FD_STEP_S)
    rate = (np.linalg.norm(sat_p - ut_p, axis=-1) - np.linalg.norm(sat_m - ut_m, axis=-1)) / (
        2 * FD_STEP_S
    )
    np.testing.assert_allclose(rows["doppler_hz"], -f / C_M_S * rate, atol=DOPPLER_FD_HZ)
    # pre-compensated: the line of sight to the believed position, the believed velocity
    t = rows["time_s"].to_numpy()
    pos, vel, _ = scen.estimated_ephemeris(np.unique(t))
    k = np.searchsorted(np.unique(t), t)
    s = rows["sat_id"].to_numpy()
    los = pos[k, s] - ut
    los /= np.linalg.norm(los, axis=-1, keepdims=True)
    believed = -f / C_M_S * np.sum(los * (vel[k, s] - ut_v), axis=-1)
    residual = rows["doppler_residual_hz"].to_numpy()
    np.testing.assert_allclose(residual, rows["doppler_hz"] - believed, atol=1e-3)
    assert np.abs(residual).max() > 100.0  # a 2 km error: hundreds of Hz at Ku band


def _far_edge_m(altitude_m, min_el_rad, radius_m=6_371_000.0):
    """Slant range to the ground point seen at ``min_el_rad``: bisection on the central
    angle, elevations from vectors."""
    sat = np.array([0.0, 0.0, radius_m + altitude_m])
    lo, hi = 0.0, math.acos(radius_m / (radius_m + altitude_m))
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        g = radius_m * np.array([math.sin(mid), 0.0, math.cos(mid)])
        d = sat - g
        el = math.asin(d @ g / np.linalg.norm(d) / radius_m)
        lo, hi = (mid, hi) if el > min_el_rad else (lo, mid)
    g = radius_m * np.array([math.sin(lo), 0.0, math.cos(lo)])
    return float(np.linalg.norm(sat - g))


@pytest.mark.parametrize("altitude_m, min_el_deg", [(550e3, 25.0), (1300e3, 10.0), (600e3, 40.0)])
def test_k_offset_is_the_cells_largest_ta_in_whole_slots(altitude_m, min_el_deg):
    common = 2 * altitude_m / C_M_S
    for n_ta_offset in (0, 39936):
        ta_max = 2 * _far_edge_m(altitude_m, math.radians(min_el_deg)) / C_M_S - common
        ta_max += n_ta_offset * 1.0 / (480e3 * 4096)
        got = k_offset_ms(altitude_m, math.radians(min_el_deg), 6_371_000.0, common, n_ta_offset)
        assert got == math.ceil(ta_max / 1e-3)
    assert T_C_S == pytest.approx(0.509e-9, rel=1e-3)  # TS 38.211 4.1: 0.509 ns


def test_the_satellite_reference_point_has_no_common_ta(clean):
    trace, _ = _run([*TIMING, "timing.reference_point=satellite", "timing.n_ta_offset=25600"])
    served = trace[trace["sat_id"] >= 0]
    assert (served["common_ta_s"] == 0).all()
    expected = 2 * served["delay_s"] + 25600 / (480e3 * 4096)
    np.testing.assert_allclose(served["ta_s"], expected, rtol=0, atol=ONE_NS)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    root = tmp_path_factory.mktemp("ntn")
    cfg = load_config(PAPER, [*TIMING, *ERROR, 'run.start_utc="2025-03-01T10:00:00Z"'])
    leolink.run(cfg, out_dir=root / "run")
    export_ntn(root / "run", root / "ntn")
    return root, cfg


def test_export_ntn_writes_the_series_per_ut_and_a_sib19_ephemeris(exported):
    import pandas as pd

    root, cfg = exported
    series = pd.read_csv(root / "ntn" / "ntn_series.csv")
    trace = pd.read_csv(root / "run" / "trace.csv")
    assert len(series) == len(trace)
    assert (np.diff(series["ut_id"]) >= 0).all()  # sorted per UT, then in time
    for _, one in series.groupby("ut_id"):
        assert (np.diff(one["time_s"]) > 0).all()
    assert set(TIMING_COLUMNS) <= set(series.columns)
    doc = json.loads((root / "ntn" / "sib19_ephemeris.json").read_text())
    assert doc["format"] == "leolink-sib19/1" and doc["time_zero_utc"].startswith("2025-03-01")
    served = series[series["sat_id"] >= 0]
    periods = {
        (int(s), math.floor(t / 10.0))
        for s, t in zip(served["sat_id"], served["time_s"], strict=True)
    }
    got = {(r["sat_id"], round(r["epoch_s"] / 10.0)) for r in doc["records"]}
    assert got == periods  # one record per validity period in which a satellite served
    scen = build_scenario(cfg)
    for r in doc["records"]:
        pos, vel, _ = scen.estimated_ephemeris(np.array([r["epoch_s"]]))
        np.testing.assert_allclose(r["position_m"], pos[0, r["sat_id"]], atol=1e-6)
        np.testing.assert_allclose(r["velocity_m_s"], vel[0, r["sat_id"]], atol=1e-9)
        h = np.linalg.norm(pos[0, r["sat_id"]]) - 6_371_000.0
        assert r["ta_common_s"] == pytest.approx(2 * h / C_M_S, abs=ONE_NS)
        assert r["validity_s"] == 10.0


def test_ta_common_drift_is_the_rate_of_the_common_ta():
    """The ISS's TLE (eccentricity 5e-4: its altitude moves by metres a second)."""
    import pandas as pd

    cfg = load_config("configs/examples/tle.toml", ["timing.sib19_validity_s=5"])
    eph = ephemeris_from_config(cfg)
    t = np.arange(0.0, 600.0, 60.0)
    served = pd.DataFrame({"time_s": t, "sat_id": np.zeros(t.size, np.int64)})
    records = sib19_records(cfg, served, eph)
    assert [r["epoch_s"] for r in records] == list(t)
    rates = []
    for r in records:
        p2, _, _ = eph(np.array([r["epoch_s"] - 0.05, r["epoch_s"] + 0.05]))
        h2 = np.linalg.norm(p2[:, 0], axis=-1) - cfg.earth.radius_m
        rates.append(2 * (h2[1] - h2[0]) / 0.1 / C_M_S)
        assert r["ta_common_s"] == pytest.approx(2 * np.mean(h2) / C_M_S, abs=ONE_NS)
    got = [r["ta_common_drift_s_s"] for r in records]
    # sgp4's velocity is its own series, not the derivative of its position: they differ by
    # ~6 mm/s here (4e-11 s/s of drift); 1e-10 s/s is 1.5 cm/s of altitude rate
    np.testing.assert_allclose(got, rates, rtol=0, atol=1e-10)
    assert max(np.abs(rates)) > 1e-9  # the orbit is not circular: a drift to check


def test_export_ntn_of_a_folder_that_is_not_a_run_says_so_in_one_line(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("not a run")
    out = tmp_path / "out"
    assert main(["export-ntn", str(tmp_path), "--out", str(out)]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a finished leolink run folder" in err
    assert not out.exists()  # nothing written


def test_export_ntn_refuses_the_run_folder_as_its_output(exported, capsys):
    root, _ = exported
    before = sorted(p.name for p in (root / "run").iterdir())
    assert main(["export-ntn", str(root / "run"), "--out", str(root / "run")]) == EXIT_USAGE
    assert "is the run folder" in capsys.readouterr().err
    assert sorted(p.name for p in (root / "run").iterdir()) == before
