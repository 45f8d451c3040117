"""A real run over PER_UT_IN_JSON_MAX UTs: summary.json stays small, the per-UT statistics
and dwells go to per_ut.parquet and dwells.parquet, checked against the run's own trace and
events (counted here with pandas), and the report reads them."""

import json
import tomllib

import numpy as np
import pandas as pd
import pytest

from leolink.io.report.rebuild import stats_from_dir
from leolink.io.summary.accumulator import PER_UT_IN_JSON_MAX
from report_helpers import PAPER, cli

N_UT = PER_UT_IN_JSON_MAX + 1
PER_UT_BIN_DB = 0.1  # docs/outputs.md: per-UT percentiles from 0.1 dB bins


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    out = tmp_path_factory.mktemp("large")
    cli(
        "run", PAPER, "--out", out, "--quiet",
        "--set", "run.duration_s=20.0",
        "--set", f"population.1.count={N_UT - 3}",
        "--set", 'population.1.placement="random"',
        "--set", "population.1.x_m=[]",
        "--set", "population.1.y_m=[]",
        "--set", "output.plots.enabled=false",
        "--set", "output.report.animation=false",
    )  # fmt: skip
    return out


def test_summary_json_points_to_the_tables(out):
    summary = json.loads((out / "summary.json").read_text())
    assert "per_ut" not in summary and "complete_s" not in summary["overall"]["dwell"]
    assert summary["per_ut_file"] == "per_ut.parquet"
    assert summary["dwells_file"] == "dwells.parquet"
    assert summary["overall"]["n_ut"] == N_UT
    assert (out / "summary.json").stat().st_size < 16 * 1024
    listed = {f["path"] for f in json.loads((out / "run.json").read_text())["files"]}
    assert {"per_ut.parquet", "dwells.parquet", "summary.json"} <= listed


def test_per_ut_table_against_the_trace(out):
    per_ut = pd.read_parquet(out / "per_ut.parquet")
    trace = pd.read_csv(out / "trace.csv")
    assert len(per_ut) == N_UT and (per_ut.ut_id.to_numpy() == np.arange(N_UT)).all()
    by_ut = trace.groupby("ut_id")
    np.testing.assert_array_equal(per_ut.n_epochs, by_ut.size().reindex(range(N_UT)))
    outage = by_ut.service.apply(lambda s: (s == "outage").mean())
    np.testing.assert_allclose(per_ut.outage_fraction, outage, rtol=0, atol=1e-15)
    snr = trace.dropna(subset=["snr_db"]).groupby("ut_id").snr_db
    np.testing.assert_allclose(per_ut.snr_mean_db, snr.mean(), rtol=1e-12)
    np.testing.assert_allclose(
        per_ut.snr_p50_db, snr.median(), rtol=0, atol=PER_UT_BIN_DB / 2 + 1e-9
    )
    np.testing.assert_allclose(
        per_ut.max_abs_doppler_hz, by_ut.doppler_hz.apply(lambda x: x.abs().max()), rtol=1e-15
    )
    tput = trace.throughput_bps.fillna(0.0).groupby(trace.ut_id).mean()
    np.testing.assert_allclose(per_ut.mean_throughput_bps, tput, rtol=1e-12)


def test_per_ut_table_has_the_kpis_and_outage_reasons_of_summary_json(out):
    """The per-UT fields summary.json would hold: the handover KPIs (rate per UT-minute
    from the events file, RLF count) and the outage fraction of every reason."""
    per_ut = pd.read_parquet(out / "per_ut.parquet")
    events = pd.read_csv(out / "events.csv")
    trace = pd.read_csv(out / "trace.csv", usecols=["ut_id", "outage_reason"])
    epoch_s = tomllib.loads((out / "config.resolved.toml").read_text())["run"]["epoch_s"]
    kinds = events.kind.str.endswith("handover")
    ho = events[kinds].groupby("ut_id").size().reindex(range(N_UT), fill_value=0)
    minutes = per_ut.n_epochs * epoch_s / 60.0
    assert ho.sum() > 0
    np.testing.assert_allclose(per_ut.handover_rate_per_ut_min, ho / minutes, rtol=1e-12)
    rlf = events[events.kind == "rlf"].groupby("ut_id").size()
    np.testing.assert_array_equal(per_ut.rlf_count, rlf.reindex(range(N_UT), fill_value=0))
    assert per_ut.ping_pong_count.dtype.kind == "i" and (per_ut.ping_pong_count >= 0).all()
    for reason in ("no_satellite", "below_threshold", "rlf"):
        share = trace.outage_reason.eq(reason).groupby(trace.ut_id).mean()
        np.testing.assert_allclose(per_ut[f"outage_fraction_{reason}"], share, atol=1e-15)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["overall"]["kpi"]["handover_rate_per_ut_min"] > 0


def test_dwells_table_against_the_events(out):
    """Every UT of the pass is served throughout: its dwells are its handovers + 1, the
    first and the last censored by the run."""
    dwells = pd.read_parquet(out / "dwells.parquet")
    events = pd.read_csv(out / "events.csv")
    trace = pd.read_csv(out / "trace.csv", usecols=["ut_id", "service"])
    served = trace.groupby("ut_id").service.apply(lambda s: (s == "served").all())
    ho = events[events.kind.str.endswith("handover")].groupby("ut_id").size()
    ho = ho.reindex(range(N_UT), fill_value=0)
    n = dwells.groupby("ut_id").size().reindex(range(N_UT), fill_value=0)
    assert served.sum() > N_UT // 2
    np.testing.assert_array_equal(n[served], ho[served] + 1)
    np.testing.assert_allclose(dwells.duration_s, dwells.end_s - dwells.start_s, atol=1e-12)
    per_ut = pd.read_parquet(out / "per_ut.parquet")
    complete = ~(dwells.censored_start | dwells.censored_end)
    assert per_ut.n_dwell_complete.sum() == complete.sum()


def test_report_shows_the_per_ut_file(out):
    page = (out / "report.html").read_text()
    assert f"of {N_UT:,} UTs shown" in page and "all are in per_ut.parquet" in page
    first = pd.read_parquet(out / "per_ut.parquet").iloc[0]
    assert f"<td>{first.snr_mean_db:.4g}</td>" in page


def test_report_from_the_folder_reads_the_dwells_file(out):
    stats = stats_from_dir(out, (0, 1))
    dwells = pd.read_parquet(out / "dwells.parquet")
    censored = dwells.censored_start | dwells.censored_end
    assert stats.dwell_complete.sum() == (~censored).sum()
    assert stats.dwell_censored.sum() == censored.sum() > 0
