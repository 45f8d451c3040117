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
        # Per-UT percentiles from 0.1 dB bins (docs/outputs.md): within half a bin.
        assert ut["snr_db"]["p50"] == pytest.approx(np.percentile(snr, 50), abs=0.05 + 1e-5)
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


def test_overall_statistics_against_the_trace(result):
    summary, trace, events = result
    o = summary["overall"]
    assert o["n_ut"] == trace.ut_id.nunique() and o["n_ut_epochs"] == len(trace)
    for key in ("snr_db", "sinr_db"):
        v = trace[key].dropna().to_numpy()
        assert o[key]["mean"] == pytest.approx(v.mean(), rel=1e-12)
        for q in (5, 50, 95):  # pooled: 0.01 dB bins (docs/outputs.md), float32 samples
            assert o[key][f"p{q}"] == pytest.approx(np.percentile(v, q), abs=0.005 + 1e-5)
    assert o["mean_throughput_bps"] == pytest.approx(
        trace.throughput_bps.fillna(0).mean(), rel=1e-12
    )
    assert o["max_abs_doppler_hz"] == pytest.approx(trace.doppler_hz.abs().max(), rel=1e-15)
    assert o["max_angular_speed_deg_s"] == pytest.approx(trace.angular_speed_deg_s.max(), rel=1e-15)
    for kind in ("beam_handover", "sat_handover", "outage_start", "outage_end"):
        assert o["handovers"][kind] == (events.kind == kind).sum()
    assert o["handovers"]["handovers_total"] == events.kind.str.endswith("handover").sum()


def test_the_trace_read_back_gives_the_same_summary(result):
    """Fed the trace as written (service as names, not codes), the accumulator gives the
    run's summary: the string path of the service column counts the same."""
    from leolink.io.summary.accumulator import SummaryAccumulator

    summary, trace, events = result
    acc = SummaryAccumulator(trace.ut_id.nunique())
    acc.add_trace({c: trace[c].to_numpy() for c in trace.columns})
    again = acc.summary()["overall"]
    for key in ("outage_fraction", "handover_interruption_fraction", "mean_throughput_bps"):
        assert again[key] == pytest.approx(summary["overall"][key], rel=1e-12), key


def test_rows_folded_in_many_small_buffers_give_the_same_per_ut_statistics(result, monkeypatch):
    """The accumulator folds its buffered rows every _POOL_BUFFER rows: fed the run's
    trace epoch by epoch with a buffer of a few epochs' rows, every per-UT statistic is
    the one of the run (per-UT sums still added in row order)."""
    import leolink.io.summary.accumulator as S

    summary, trace, _ = result
    n_ut, n_epoch = trace.ut_id.nunique(), trace.time_s.nunique()
    assert n_epoch % 8  # rows are left in the buffer at the end
    monkeypatch.setattr(S, "_POOL_BUFFER", 8 * n_ut)  # a fold every 8 epochs
    acc = S.SummaryAccumulator(n_ut)
    for _, rows in trace.groupby("time_s", sort=True):
        acc.add_trace({c: rows[c].to_numpy() for c in trace.columns})
    table = acc.per_ut_table()
    for ut in summary["per_ut"]:
        i = ut["ut_id"]
        assert table["n_epochs"][i] == ut["n_epochs"]
        assert table["snr_mean_db"][i] == pytest.approx(ut["snr_db"]["mean"], rel=1e-12)
        assert table["snr_p50_db"][i] == ut["snr_db"]["p50"]
        assert table["mean_throughput_bps"][i] == pytest.approx(
            ut["mean_throughput_bps"], rel=1e-12
        )
        assert table["handover_interruption_fraction"][i] == pytest.approx(
            ut["handover_interruption_fraction"], rel=1e-12
        )
        assert table["max_abs_doppler_hz"][i] == ut["max_abs_doppler_hz"]
    assert acc.summary()["overall"]["snr_db"] == summary["overall"]["snr_db"]


def test_grouped_percentiles_of_tiny_and_empty_groups():
    from leolink.io.summary.accumulator import grouped_percentiles

    group = np.array([0, 2, 2, 3, 3, 3])
    values = np.array([4.0, 1.0, 3.0, 5.0, 2.0, 9.0])
    q = [0.0, 25.0, 50.0, 90.0, 100.0]
    out = grouped_percentiles(group, values, 5, q)
    for g in range(5):
        v = values[group == g]
        want = np.percentile(v, q) if v.size else np.full(len(q), np.nan)
        np.testing.assert_allclose(out[g], want, rtol=0, atol=1e-12)
    # More groups than 2**15 (the int64 sort path): same answer as one at a time.
    big = np.repeat(np.arange(40_000), 2)
    vals = np.tile([1.0, 3.0], 40_000)
    np.testing.assert_allclose(grouped_percentiles(big, vals, 40_000, [50.0])[:, 0], 2.0)
