"""The simulator end to end: dwell times against the coverage map, determinism,
hysteresis, time-to-trigger, satellite handovers and the output contract."""

import math

import numpy as np
import pandas as pd
import pytest

from leolink.app.reports import codebook_table
from leolink.app.run import run
from leolink.app.scenario import build_engine, ephemeris_from_config, track_heading_rad
from leolink.config import load_config, parse_config, updated
from leolink.coverage import evaluate_points
from leolink.geometry import ground_to_roi, roi_to_ground
from leolink.placement import roi_points_to_geodetic

PAPER = "configs/paper.toml"
TRACE_COLUMNS = (
    "time_s ut_id sat_id beam_id lat_deg lon_deg elevation_deg slant_range_m "
    "gain_tx_db gain_rx_db fspl_db atm_db snr_db sinr_db se_bps_hz throughput_bps "
    "doppler_hz doppler_sat_hz doppler_ut_hz doppler_rate_hz_s "
    "angular_speed_deg_s"
).split()
EVENT_COLUMNS = (
    "time_s ut_id kind from_sat from_beam to_sat to_beam snr_before_db snr_after_db"
).split()


def _one_ut(extra=()):
    return load_config(PAPER, ["output.plots.enabled=false", *extra])


def _centre_only(cfg):
    return cfg.model_copy(update={"population": cfg.population[:1]})


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper")
    cfg = load_config(PAPER, ['output.trace.formats=["csv", "parquet"]'])
    return run(cfg, out_dir=out), out


def test_output_contract(paper_run):
    result, out = paper_run
    trace = pd.read_csv(out / "trace.csv")
    assert list(trace.columns[: len(TRACE_COLUMNS)]) == TRACE_COLUMNS
    assert len(trace) == 7 * 120
    events = pd.read_csv(out / "events.csv")
    assert list(events.columns) == EVENT_COLUMNS
    assert set(events.kind) <= {"beam_handover", "sat_handover", "outage_start", "outage_end"}
    pq = pd.read_parquet(out / "trace.parquet")
    pd.testing.assert_frame_equal(pq[TRACE_COLUMNS], trace[TRACE_COLUMNS], check_dtype=False)
    for name in ("summary.json", "config.resolved.toml", "snr_time.png", "dwell_hist.png"):
        assert (out / name).exists(), name
    assert not list(out.glob("*.partial"))
    # The resolved config reproduces the run's config.
    resolved = load_config(out / "config.resolved.toml").model_copy(update={"source": ""})
    expected = load_config(PAPER, ['output.trace.formats=["csv", "parquet"]'])
    assert resolved == expected.model_copy(update={"source": ""})


def test_dwell_times_of_centre_ut_match_coverage_map_along_track():
    """UT 0 under max-SNR: the beams it is served by equal the coverage map's best beam at
    its ROI-plane position relative to the moving satellite, epoch by epoch."""
    cfg = _centre_only(_one_ut())
    result = run(cfg)
    trace = result.trace
    # The coverage map of the overhead satellite, evaluated along the UT's relative track.
    eph = ephemeris_from_config(cfg)
    times = trace.time_s.to_numpy()
    pos, vel, _ = eph(times)
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    from leolink.geometry import geodetic_to_ecef

    ut = geodetic_to_ecef(lat, lon)
    x, y = ground_to_roi(ut, pos[:, 0], vel[:, 0])
    from leolink.app.scenario import overhead_satellite

    sp, sv, sa = overhead_satellite(cfg)
    ground = roi_to_ground(x, y, sp[0], sv[0])
    best = evaluate_points(build_engine(cfg), ground, sp, sv, sa)["best_beam"]
    np.testing.assert_array_equal(trace.beam_id.to_numpy(), best)

    change = np.flatnonzero(np.diff(best)) + 1
    bounds = np.concatenate([[0], change, [len(best)]])
    dwell_s = np.diff(times[np.minimum(bounds, len(times) - 1)])
    dwell_s[-1] += cfg.run.epoch_s  # the last dwell runs to the end of the run
    per_ut = result.summary["per_ut"][0]["dwell"]
    np.testing.assert_allclose(per_ut["complete_s"], dwell_s[1:-1])
    first, last = per_ut["censored"][0], per_ut["censored"][-1]
    assert first["censored_start"] and not first["censored_end"]
    assert last["censored_end"] and not last["censored_start"]
    assert first["duration_s"] == pytest.approx(dwell_s[0])
    assert last["duration_s"] == pytest.approx(dwell_s[-1])
    # The paper: "the user is illuminated by the same beam for a period of around 30 seconds".
    assert np.all(np.abs(np.asarray(per_ut["complete_s"]) - 30.0) < 3.0)


def test_same_seed_same_trace_whatever_the_chunk_size(tmp_path):
    over = [
        "output.plots.enabled=false",
        'population.1.placement="random"',
        "population.1.count=20",
        "population.2.count=5",
        'population.2.placement="random"',
        'population.2.heading_deg="random"',
        'link.fading="rician"',
    ]
    a = run(load_config(PAPER, [*over, "output.trace.chunk_rows=7"]), out_dir=tmp_path / "a")
    b = run(load_config(PAPER, [*over, "output.trace.chunk_rows=100000"]), out_dir=tmp_path / "b")
    assert (tmp_path / "a/trace.csv").read_bytes() == (tmp_path / "b/trace.csv").read_bytes()
    assert (tmp_path / "a/events.csv").read_bytes() == (tmp_path / "b/events.csv").read_bytes()
    assert a.summary["overall"] == b.summary["overall"]
    run(load_config(PAPER, [*over, "run.seed=1"]), out_dir=tmp_path / "c")
    assert (tmp_path / "c/trace.csv").read_bytes() != (tmp_path / "a/trace.csv").read_bytes()


def _zigzag_config():
    """A UT flying back and forth across the cross-track boundary between two beams."""
    cfg = _one_ut()
    info = codebook_table(cfg)
    # Cell edge between the nadir row (u_y = 0) and the row at u_y > 0, near x = 0.
    y_row = max(b["y_m"] for b in info["beams"] if abs(b["u_x"]) < 1e-12)
    y_edge = 0.5 * y_row
    heading = track_heading_rad(cfg)
    t = np.arange(0.0, 121.0, 15.0)
    y = y_edge + np.where(np.arange(len(t)) % 2 == 0, -6000.0, 6000.0)
    lat, lon = roi_points_to_geodetic(
        np.zeros_like(t),
        y,
        math.radians(cfg.roi.center_lat_deg),
        math.radians(cfg.roi.center_lon_deg),
        heading,
    )
    rows = [
        [float(a), math.degrees(b), math.degrees(c), 0.0]
        for a, b, c in zip(t, lat, lon, strict=False)
    ]
    data = cfg.model_dump(mode="json")
    data["population"] = [{"kind": "waypoints", "waypoints": rows, "name": "zigzag"}]
    return parse_config(data)


def _count(result, kind="beam_handover"):
    ev = result.events
    return int((ev.kind == kind).sum())


def _with_controller(cfg, policy=None, **params):
    """``cfg`` with another policy and its parameters, or shared controller keys."""
    sets = [f"controller.policy={policy}"] if policy else []
    prefix = f"controller.{policy}." if policy else "controller."
    sets += [f"{prefix}{k}={v}" for k, v in params.items()]
    return updated(cfg, sets)


def test_hysteresis_removes_ping_pong():
    cfg = _zigzag_config()
    plain = run(cfg)
    hyst = run(_with_controller(cfg, policy="hysteresis", margin_db=3.0))
    ev = plain.events
    # Ping-pong: a handover straight back to the beam just left.
    back = (
        (ev.to_beam.to_numpy()[1:] == ev.from_beam.to_numpy()[:-1])
        & (ev.from_beam.to_numpy()[1:] == ev.to_beam.to_numpy()[:-1])
    ).sum()
    assert back >= 3
    assert _count(hyst) < _count(plain)
    hev = hyst.events
    hback = (
        (hev.to_beam.to_numpy()[1:] == hev.from_beam.to_numpy()[:-1])
        & (hev.from_beam.to_numpy()[1:] == hev.to_beam.to_numpy()[:-1])
        & (np.diff(hev.time_s.to_numpy()) < 15.0)
    ).sum()
    assert hback == 0


@pytest.mark.parametrize("margin_db", [0.5, 1.0, 3.0])
def test_hysteresis_never_increases_handovers(margin_db):
    over = [
        "output.plots.enabled=false",
        'population.1.placement="random"',
        "population.1.count=30",
    ]
    cfg = load_config(PAPER, over)
    plain = run(cfg).summary["overall"]["handovers"]["beam_handover"]
    hyst = run(_with_controller(cfg, policy="hysteresis", margin_db=margin_db))
    assert hyst.summary["overall"]["handovers"]["beam_handover"] <= plain


def test_time_to_trigger_delays_handovers_by_the_configured_time():
    cfg = _centre_only(_one_ut())
    plain = run(cfg).events
    ttt = run(_with_controller(cfg, policy="hysteresis", time_to_trigger_s=3.0)).events
    assert len(plain) == len(ttt) > 0
    np.testing.assert_allclose(ttt.time_s.to_numpy() - plain.time_s.to_numpy(), 3.0)


@pytest.mark.parametrize("handover_s", [2.0, 2.5, 0.3])
def test_handover_time_interrupts_service_until_it_ends(handover_s):
    """Service stops at the handover and resumes at t + handover_time_s exactly: whole
    epochs inside carry no throughput, the epoch where it resumes carries its served part,
    and a ``service_resumed`` event is stamped with the resume time."""
    cfg = _with_controller(_centre_only(_one_ut()), handover_time_s=handover_s)
    plain = run(_with_controller(cfg, handover_time_s=0.0)).trace.set_index("time_s")
    res = run(cfg)
    tr, ev = res.trace.set_index("time_s"), res.events
    handovers = ev[ev.kind.str.endswith("handover")]
    resumed = ev[ev.kind == "service_resumed"]
    assert len(handovers) == len(resumed) > 0
    np.testing.assert_allclose(resumed.time_s.to_numpy(), handovers.time_s.to_numpy() + handover_s)
    for t in handovers.time_s:
        for k in range(int(np.ceil(handover_s)) + 1):
            row, ref = tr.loc[t + k], plain.loc[t + k]
            gap = min(max(handover_s - k, 0.0), 1.0)  # the epoch is [t + k, t + k + 1)
            assert row.interruption_s == pytest.approx(gap, abs=1e-12)
            assert row.service == ("handover" if gap > 0 else "served")
            assert row.throughput_bps == pytest.approx(ref.throughput_bps * (1 - gap), rel=1e-12)
    s = res.summary["overall"]
    n_ut_s = len(tr) * cfg.run.epoch_s
    assert s["handover_interruption_fraction"] == pytest.approx(
        len(handovers) * handover_s / n_ut_s, abs=1e-12
    )


def test_walker_constellation_gives_satellite_handovers():
    over = [
        'constellation.kind="walker"',
        "constellation.n_planes=12",
        "constellation.sats_per_plane=10",
        "constellation.min_elevation_deg=25",
        "run.duration_s=900",
        "run.epoch_s=5",
        "output.plots.enabled=false",
    ]
    cfg = load_config(PAPER, over)
    cfg = cfg.model_copy(update={"population": cfg.population[:2]})
    res = run(cfg)
    kinds = res.events.kind.value_counts()
    assert kinds.get("sat_handover", 0) + kinds.get("outage_start", 0) > 0
    tr = res.trace
    served = tr[tr.sat_id >= 0]
    assert (served.elevation_deg >= 25.0 - 1e-9).all()
    assert served.sat_id.nunique() >= 2


def test_predictive_policy_hands_over_earlier_on_a_pass():
    """With the ephemeris, the predictive policy leaves a fading beam before max-SNR does:
    same beam sequence on a pass over a static UT, each handover no later."""
    cfg = _centre_only(_one_ut())
    plain = run(cfg).events
    pred = run(_with_controller(cfg, policy="predictive", lookahead_s=10.0)).events
    np.testing.assert_array_equal(pred.to_beam.to_numpy(), plain.to_beam.to_numpy())
    lead = plain.time_s.to_numpy() - pred.time_s.to_numpy()
    assert np.all(lead >= 0.0) and np.all(lead <= 10.0)
    assert lead.max() > 0.0


@pytest.mark.parametrize("policy", ["max_snr", "hysteresis", "predictive"])
def test_trace_events_and_summary_tell_the_same_story(policy):
    """Invariants across the three outputs, on a small Walker constellation with Earth
    rotation, moving UTs, handover execution time and outages."""
    over = [
        'constellation.kind="walker"',
        "constellation.n_planes=12",
        "constellation.sats_per_plane=10",
        "constellation.min_elevation_deg=25",
        'satellite_array.oversampling="auto"',
        "earth.rotation=true",
        "run.duration_s=600",
        "run.epoch_s=5",
        "output.plots.enabled=false",
        f'controller.policy="{policy}"',
        "controller.hysteresis.margin_db=1.0",
        "controller.predictive.lookahead_s=15.0",
        "controller.handover_time_s=5.0",
        "controller.min_snr_db=-25.0",
        "population.1.count=6",
        'population.1.placement="random"',
    ]
    res = run(load_config(PAPER, over))
    tr = res.trace.sort_values(["ut_id", "time_s"])
    outage = tr.service == "outage"
    assert ((tr.sat_id == -1) == outage).all() and ((tr.beam_id == -1) == outage).all()
    assert tr.snr_db[outage].isna().all() and tr.snr_db[~outage].notna().all()
    ev = res.events
    # Every change of serving (satellite, beam) between two served epochs is an event.
    prev = tr.groupby("ut_id")[["sat_id", "beam_id"]].shift()
    served_both = (tr.sat_id >= 0) & (prev.sat_id >= 0)
    changed = served_both & ((tr.sat_id != prev.sat_id) | (tr.beam_id != prev.beam_id))
    n_handovers = ev.kind.isin(["beam_handover", "sat_handover"]).sum()
    assert changed.sum() == n_handovers
    sat_change = served_both & (tr.sat_id != prev.sat_id)
    assert sat_change.sum() == (ev.kind == "sat_handover").sum() > 0
    counts = res.summary["overall"]["handovers"]
    for kind in ("beam_handover", "sat_handover", "outage_start", "outage_end"):
        assert counts[kind] == (ev.kind == kind).sum()
    assert res.summary["overall"]["outage_fraction"] == pytest.approx(outage.mean())
