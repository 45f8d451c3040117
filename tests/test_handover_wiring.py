"""The trigger policies, RLF and the KPIs in real runs, checked against hand computations
and against the run's own trace and events recomputed independently."""

import numpy as np
import pandas as pd
import pytest

import leolink
from leolink.config import load_config
from leolink.geometry import direction_cosines

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"
WALKER = ROOT / "configs" / "examples" / "walker.toml"
QUIET = ["output.plots.enabled=false"]


def _run(path, sets, out_dir=None):
    return leolink.run(load_config(path, QUIET + sets), out_dir=out_dir)


@pytest.fixture(scope="module")
def walker_max_snr():
    return _run(WALKER, ["run.duration_s=200"])


def test_a3_without_offset_hysteresis_ttt_or_filter_is_max_snr_in_a_constellation(
    walker_max_snr,
):
    a3 = _run(WALKER, ["run.duration_s=200", "controller.policy=a3", "controller.filter.k=0"])
    assert walker_max_snr.summary["overall"]["handovers"]["sat_handover"] > 3
    pd.testing.assert_frame_equal(a3.trace, walker_max_snr.trace)
    pd.testing.assert_frame_equal(a3.events, walker_max_snr.events)


@pytest.mark.parametrize("damping", ["hysteresis_db=2", "time_to_trigger_s=3"])
def test_hysteresis_or_ttt_never_increases_the_a3_handover_count(damping):
    base = ["run.duration_s=200", "controller.policy=a3", "controller.filter.k=0"]
    plain = _run(WALKER, base).summary["per_ut"]
    damped = _run(WALKER, [*base, f"controller.a3.{damping}"]).summary["per_ut"]
    counts = [(p["handovers"]["handovers_total"], d["handovers"]["handovers_total"])
              for p, d in zip(plain, damped, strict=True)]  # fmt: skip
    assert all(d <= p for p, d in counts)
    assert sum(d for _, d in counts) < sum(p for p, _ in counts)


@pytest.mark.parametrize(
    "reestablishment_s, rlf_s, end_s, down_s",
    [
        (0.2, [1, 4, 7], [2, 5, 8], [1, 4, 7]),
        (1.5, [1, 5, 9], [3, 7], [1, 2, 5, 6, 9]),
    ],
)
def test_rlf_timing_by_hand(reestablishment_s, rlf_s, end_s, down_s):
    """Q_out above every SINR: each monitored epoch is out-of-sync. N310 = 1 starts T310
    at the first served epoch (t = 0); T310 = 1 s expires one epoch later: RLF, and that
    epoch is an outage. Re-establishment ends at the first epoch >= RLF +
    reestablishment_s (``outage_end``, served again); that epoch gives no indication
    (leolink.sim.handover.rlf), the next one restarts T310. With 1 s epochs t = 0 ... 9: RLF at 1,
    4, 7 (0.2 s), or at 1, 5, 9 (1.5 s: the epoch at RLF + 1 s is still re-establishing)."""
    sets = [
        "run.duration_s=10",
        "controller.rlf.enabled=true",
        "controller.rlf.q_out_db=90",
        "controller.rlf.q_in_db=95",
        f"controller.rlf.reestablishment_s={reestablishment_s}",
    ]
    res = _run(PAPER, sets)
    ev, tr = res.events, res.trace
    moved = set(ev.ut_id[ev.kind.isin(["beam_handover", "sat_handover"])])
    steady = [u for u in range(res.summary["overall"]["n_ut"]) if u not in moved]
    assert len(steady) >= 3  # a handover resets T310: those UTs follow another schedule
    for ut in steady:
        mine = ev[ev.ut_id == ut]
        assert list(mine[mine.kind == "rlf"].time_s) == rlf_s
        assert list(mine[mine.kind == "outage_end"].time_s) == end_s
        rows = tr[tr.ut_id == ut].set_index("time_s")
        down = list(rows.index[rows.outage_reason == "rlf"])
        assert down == down_s
        assert np.isnan(rows.sinr_db[down]).all() and (rows.service[down] == "outage").all()
    # A handover stops T310 (38.331 5.3.10.3, reconfiguration with sync): the handover
    # epoch's out-of-sync restarts it, so the next RLF comes T310 = 1 s later, never at
    # the handover itself.
    n_checked = 0
    for ut in moved:
        mine = ev[(ev.ut_id == ut) & (ev.kind != "service_resumed")].reset_index(drop=True)
        for i in np.flatnonzero(mine.kind.str.endswith("handover").to_numpy()):
            nxt = mine.iloc[i + 1] if i + 1 < len(mine) else None
            if nxt is None or nxt.kind.endswith("handover"):
                continue
            assert nxt.kind == "rlf" and nxt.time_s == mine.time_s[i] + 1.0
            n_checked += 1
    assert n_checked > 0
    kpi = res.summary["overall"]["kpi"]
    assert kpi["rlf_count"] == (ev.kind == "rlf").sum()
    n_down = (tr.outage_reason == "rlf").sum()
    assert kpi["interruption_s"]["rlf"] == n_down * 1.0
    assert res.summary["overall"]["outage_fraction_by_reason"]["rlf"] == n_down / len(tr)
    # unserved epochs count in the SINR percentiles, below every SINR
    assert kpi["unserved_fraction"] == n_down / len(tr)
    sinr = np.where(np.isnan(tr.sinr_db), -np.inf, tr.sinr_db)
    for q in (1, 5, 10, 50, 90):
        with np.errstate(invalid="ignore"):  # numpy interpolates -inf to -inf as NaN
            want = np.percentile(sinr, q)
        got = kpi["sinr_db_percentiles"][f"p{q}"]
        if np.isnan(want) or want == -np.inf:
            assert got is None
        else:
            assert abs(got - want) <= 0.005 + 1e-9


def test_rlf_monitoring_changes_nothing_while_links_hold():
    plain = _run(PAPER, ["run.duration_s=60"])
    res = _run(PAPER, ["run.duration_s=60", "controller.rlf.enabled=true"])
    assert res.summary["overall"]["kpi"]["rlf_count"] == 0
    pd.testing.assert_frame_equal(res.events, plain.events)
    pd.testing.assert_frame_equal(res.trace, plain.trace)


def _stays(trace):
    """Complete stays (a run of one serving cell, not touching the run's ends) from the
    trace alone [s]."""
    out = []
    for _, rows in trace.groupby("ut_id"):
        key = list(zip(rows.sat_id, rows.beam_id, strict=True))
        t = list(rows.time_s)
        starts = [0] + [i for i in range(1, len(key)) if key[i] != key[i - 1]]
        for a, b in zip(starts[1:-1], starts[2:], strict=True):
            if key[a][0] >= 0:
                out.append(t[b] - t[a])
    return np.array(out)


def test_kpis_equal_the_trace_and_events_recomputed(tmp_path):
    """a4 with a low threshold hands over to the best neighbour every epoch: many
    handovers and returns (ping-pongs) to count."""
    sets = ["run.duration_s=120", "controller.policy=a4", "controller.a4.threshold_db=0",
            "kpi.ping_pong_s=2.5", 'output.trace.formats=["csv"]']  # fmt: skip
    res = _run(WALKER, sets, out_dir=tmp_path)
    kpi = res.summary["overall"]["kpi"]
    ev, tr = pd.read_csv(tmp_path / "events.csv"), pd.read_csv(tmp_path / "trace.csv")
    n_ut, minutes = tr.ut_id.nunique(), tr.time_s.nunique() / 60.0
    ho = ev[ev.kind.isin(["beam_handover", "sat_handover"])]
    assert kpi["handover_rate_per_ut_min"] == pytest.approx(len(ho) / (n_ut * minutes), rel=1e-12)
    n_pp = 0
    for _, e in ev[ev.kind != "service_resumed"].groupby("ut_id"):
        e = e.sort_values("time_s", kind="stable").to_dict("records")
        for prev, cur in zip(e, e[1:], strict=False):
            ho_pair = {prev["kind"], cur["kind"]} <= {"beam_handover", "sat_handover"}
            back = (cur["to_sat"], cur["to_beam"]) == (prev["from_sat"], prev["from_beam"])
            n_pp += ho_pair and back and cur["time_s"] - prev["time_s"] < 2.5
    assert n_pp > 10 and kpi["ping_pong_count"] == n_pp
    assert kpi["ping_pong_fraction"] == pytest.approx(n_pp / len(ho))
    stays = _stays(tr)
    assert kpi["mean_time_of_stay_s"]["beam"] == pytest.approx(stays.mean(), rel=1e-12)
    sinr = np.where(np.isnan(tr.sinr_db), -np.inf, tr.sinr_db)
    tput = np.nan_to_num(tr.throughput_bps.to_numpy(), nan=0.0)
    for q in (1, 5, 10, 50, 90, 95, 99):  # histogram bins: 0.01 dB, 100 kb/s
        want = np.percentile(sinr, q)
        got = kpi["sinr_db_percentiles"][f"p{q}"]
        assert (got is None and want == -np.inf) or abs(got - want) <= 0.005 + 1e-9
        assert abs(kpi["throughput_bps_percentiles"][f"p{q}"] - np.percentile(tput, q)) <= 5e4
        served = np.percentile(tr.sinr_db.dropna(), q)  # the served UT-epochs only
        assert abs(kpi["sinr_db_percentiles_served"][f"p{q}"] - served) <= 0.005 + 1e-9
    assert kpi["interruption_s"] == {"handover": 0.0, "rlf": 0.0, "outage": 0.0}


def test_d1_references_are_the_beams_ground_centres():
    """The ground point of each cell, seen from its satellite, has the beam's direction
    cosines (the inverse of the ray cast that placed it)."""
    from leolink.app.scenario import build_scenario
    from leolink.sim.handover.local_axis import LocalAxis
    from leolink.sim.handover.trigger_policies import horizon_s  # noqa: F401  (registers)

    cfg = load_config(WALKER, [*QUIET, "controller.policy=d1"])
    scen = build_scenario(cfg)
    run = scen.policy.run(scen.engine, -10.0, cfg.earth.radius_m, None, 1.0)
    pos, vel, _ = scen.ephemeris(np.array([0.0]))
    ut = np.array([[cfg.earth.radius_m, 0.0, 0.0]])
    axis = LocalAxis.union(1, scen.engine.n_beam, [0, 0], [3, 7])
    usable = np.ones((1, axis.n_cand), bool)
    ref = run._fields(0.0, axis, usable, ut, pos[0], vel[0], None)["ref_pos_m"]
    u_xy = np.asarray(scen.engine.codebook.u_xy)
    for s, sat in enumerate([3, 7]):
        cells = ref[0, s * len(u_xy) : (s + 1) * len(u_xy)]
        np.testing.assert_allclose(np.linalg.norm(cells, axis=1), cfg.earth.radius_m, rtol=1e-12)
        got = direction_cosines(pos[0][sat], vel[0][sat], cells)
        np.testing.assert_allclose(got, u_xy, atol=1e-9)


def test_rlf_that_never_fires_leaves_the_run_as_without_rlf(walker_max_snr):
    """With RLF on the monitor evaluates the links every epoch (the next decision needs
    the SINR) instead of once per block; with Q_out below every SINR nothing fails, and
    the frames must be those of the block path, bit for bit."""
    sets = ["run.duration_s=200", "controller.rlf.enabled=true"]
    res = _run(WALKER, [*sets, "controller.rlf.q_out_db=-200", "controller.rlf.q_in_db=-199"])
    pd.testing.assert_frame_equal(res.trace, walker_max_snr.trace)
    pd.testing.assert_frame_equal(res.events, walker_max_snr.events)


def test_a2a4_cuts_the_handovers_of_a4_to_worse_cells():
    """Issue 46: A4 alone hands over to worse cells; gated by A2 it waits for a weak serving
    cell. With the gate always open the run is A4's, event for event."""
    sets = ["run.duration_s=200", "controller.filter.k=0"]
    a4 = _run(WALKER, [*sets, "controller.policy=a4", "controller.a4.threshold_db=-2"])
    gated = ["controller.policy=a2a4", "controller.a2a4.a4_threshold_db=-2"]
    open_gate = _run(WALKER, [*sets, *gated, "controller.a2a4.a2_threshold_db=1000"])
    pd.testing.assert_frame_equal(open_gate.events, a4.events)
    a2a4 = _run(WALKER, [*sets, *gated, "controller.a2a4.a2_threshold_db=-1"])

    def worse(res):
        ho = res.events[res.events.kind.isin(["beam_handover", "sat_handover"])]
        return int((ho.snr_after_db < ho.snr_before_db).sum()), len(ho)

    (w4, n4), (wg, ng) = worse(a4), worse(a2a4)
    assert w4 > 100 and wg < w4 / 10 and ng < n4 / 10


def test_a_negative_cell_offset_keeps_the_trigger_policies_off_that_satellite():
    sets = ["run.duration_s=200", "controller.policy=a3", "controller.filter.k=0"]
    base = _run(WALKER, sets)
    ho = base.events[base.events.kind.isin(["beam_handover", "sat_handover"])]
    sat = int(ho.to_sat.value_counts().index[0])
    off = _run(WALKER, [*sets, f"controller.cell_offsets=[{{sat_id={sat}, offset_db=-20}}]"])
    ho_off = off.events[off.events.kind.isin(["beam_handover", "sat_handover"])]
    assert (ho.to_sat == sat).sum() >= 5 and (ho_off.to_sat == sat).sum() == 0
    with pytest.raises(leolink.errors.ConfigError, match=r"cell_offsets.0.sat_id = 999 is not"):
        _run(WALKER, [*sets, "controller.cell_offsets=[{sat_id=999, offset_db=3}]"])
