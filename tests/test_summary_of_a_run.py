"""summary.json against the trace and events of the same real run, counted here with pandas.

A run with outages (the pass starts and ends low) and handover interruptions
(``handover_time_s`` = 2 s), so that a fraction counted from the wrong service code, or
a count taken from the wrong column, differs from the right one.
"""

import numpy as np
import pytest

from leolink.app.run import run
from leolink.config import load_config
from scopes import shared_run_scope


@pytest.fixture(scope=shared_run_scope)
def result():
    cfg = load_config(
        "configs/paper.toml",
        [
            "output.plots.enabled=false",
            "run.start_s=-150",
            "run.duration_s=420",
            "controller.handover_time_s=2.0",
        ],
    )
    res = run(cfg)
    return res.summary, res.trace, res.events


def test_the_run_has_outages_and_interruptions(result):
    _, trace, _ = result
    counts = trace.service.value_counts()
    assert counts["handover"] > 10 and counts["outage"] > 10
    assert counts["handover"] != counts["outage"]


def test_outage_and_interruption_fractions_per_ut_and_overall(result):
    summary, trace, _ = result
    by_ut = trace.groupby("ut_id").service
    outage = by_ut.apply(lambda s: (s == "outage").mean())
    interrupted = by_ut.apply(lambda s: (s == "handover").mean())
    for ut in summary["per_ut"]:
        i = ut["ut_id"]
        assert ut["n_epochs"] == (trace.ut_id == i).sum()
        assert ut["outage_fraction"] == pytest.approx(outage[i], abs=1e-15)
        assert ut["handover_interruption_fraction"] == pytest.approx(interrupted[i], abs=1e-15)
    o = summary["overall"]
    assert o["outage_fraction"] == pytest.approx((trace.service == "outage").mean(), abs=1e-15)
    assert o["handover_interruption_fraction"] == pytest.approx(
        (trace.service == "handover").mean(), abs=1e-15
    )


def test_interrupted_epochs_follow_the_handovers(result):
    """Each handover interrupts service for handover_time_s = 2 epochs of 1 s (a later
    handover inside an interruption is not possible), and interrupted epochs carry no
    throughput."""
    summary, trace, events = result
    n_ho = events.kind.isin(["beam_handover", "sat_handover"]).sum()
    n_int = (trace.service == "handover").sum()
    assert n_int <= 2 * n_ho
    assert n_int >= 2 * n_ho - trace.ut_id.nunique() * 2  # the last ones may be cut by the end
    assert (trace.throughput_bps[trace.service == "handover"] == 0).all()


def test_handover_counts_snr_stats_and_extremes(result):
    summary, trace, events = result
    for ut in summary["per_ut"]:
        i = ut["ut_id"]
        ev = events[events.ut_id == i]
        for kind in ("beam_handover", "sat_handover", "outage_start", "outage_end"):
            assert ut["handovers"][kind] == (ev.kind == kind).sum(), kind
        rows = trace[trace.ut_id == i]
        snr = rows.snr_db.dropna()
        assert ut["snr_db"]["mean"] == pytest.approx(snr.mean(), rel=1e-12)
        assert ut["snr_db"]["p50"] == pytest.approx(np.percentile(snr, 50), abs=1e-5)  # float32
        assert ut["max_abs_doppler_hz"] == pytest.approx(rows.doppler_hz.abs().max(), rel=1e-15)
        assert ut["max_angular_speed_deg_s"] == pytest.approx(
            rows.angular_speed_deg_s.max(), rel=1e-15
        )
        tput = rows.throughput_bps.fillna(0.0).mean()
        assert ut["mean_throughput_bps"] == pytest.approx(tput, rel=1e-12)


@pytest.fixture(scope=shared_run_scope)
def paper():
    res = run(load_config("configs/paper.toml", ["output.plots.enabled=false"]))
    return res.summary, res.trace, res.events


def test_dwells_are_the_gaps_between_handover_events(paper):
    """Every UT of the paper's pass is served throughout (no outage), so its complete
    dwells are exactly the time between consecutive handovers, its first and last dwells
    are censored by the run, and the pooled statistics are those of all UTs' dwells."""
    summary, trace, events = paper
    assert (trace.service == "served").all()
    pooled = []
    for ut in summary["per_ut"]:
        t = np.sort(
            events[(events.ut_id == ut["ut_id"]) & events.kind.str.endswith("handover")].time_s
        )
        d = ut["dwell"]
        np.testing.assert_allclose(sorted(d["complete_s"]), sorted(np.diff(t)), atol=1e-9)
        assert d["n_complete"] == max(len(t) - 1, 0)
        assert len(d["censored"]) == (2 if len(t) else 1)
        if len(t) > 1:
            assert d["mean_s"] == pytest.approx(np.diff(t).mean(), abs=1e-9)
            assert d["median_s"] == pytest.approx(np.median(np.diff(t)), abs=1e-9)
        pooled += list(np.diff(t))
    o = summary["overall"]["dwell"]
    assert o["n_complete"] == len(pooled) > 10
    np.testing.assert_allclose(sorted(o["complete_s"]), sorted(pooled), atol=1e-9)
    assert o["mean_s"] == pytest.approx(np.mean(pooled), abs=1e-9)
    assert o["median_s"] == pytest.approx(np.median(pooled), abs=1e-9)
    assert o["n_censored"] == sum(len(u["dwell"]["censored"]) for u in summary["per_ut"])
    assert summary["overall"]["n_ut"] == trace.ut_id.nunique() == len(summary["per_ut"])
