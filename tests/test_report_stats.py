"""Streamed report statistics recomputed another way from the whole trace of real runs."""

import shutil

import numpy as np
import pandas as pd
import pytest

from leolink.io.report.rebuild import stats_from_dir
from leolink.io.report.stats import ReportStats
from report_helpers import WALKER, cli, make_run


@pytest.fixture(scope="module", params=["paper", "walker"])
def run(request, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param)
    out = make_run(out) if request.param == "paper" else make_run(out, WALKER)
    # Chunks of 7 rows cut epochs and UTs apart: the result must not depend on chunking.
    stats = stats_from_dir(out, series_ut=[0, 2], n_sample_ut=3, max_frames=25, chunk_rows=7)
    return out, stats, pd.read_csv(out / "trace.csv")


def test_cdfs_are_the_empirical_fractions_of_the_trace(run):
    _, stats, trace = run
    for key in ("snr_db", "sinr_db"):
        x, f = stats.cdf(key)
        v = trace[key].to_numpy()
        v = v[np.isfinite(v)]
        for q in (0.01, 0.1, 0.5, 0.9, 0.99):  # at the bin edges the CDF is exact
            i = np.searchsorted(x, np.quantile(v, q))
            assert f[i] == pytest.approx(np.mean(v < x[i]), abs=1e-12)
    x, f = stats.cdf("throughput_bps")
    tput = np.nan_to_num(trace["throughput_bps"].to_numpy(), nan=0.0)
    assert f[0] == pytest.approx(np.mean(tput <= 0.0), abs=1e-12)
    i = np.searchsorted(x, np.median(tput[tput > 0]))
    assert f[i] == pytest.approx(np.mean(tput < x[i]), abs=1e-12)


def test_service_and_outage_counts_are_the_trace_counts(run):
    _, stats, trace = run
    assert stats.service_counts == trace["service"].value_counts().to_dict()
    n_outage = int((trace["service"] == "outage").sum())
    assert sum(stats.outage_reason_counts.values()) == n_outage


def _dwells_from_trace(trace):
    """Complete and censored dwell durations [s]: runs of one (sat, beam) per UT."""
    complete, censored = [], []
    for _, g in trace.sort_values(["ut_id", "time_s"]).groupby("ut_id"):
        key = (g["sat_id"].astype(str) + ":" + g["beam_id"].astype(str)).to_numpy()
        beam = g["beam_id"].to_numpy()
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        for a, e in zip(starts, np.r_[starts[1:], key.size], strict=True):
            if beam[a] >= 0:  # an outage is no dwell
                (censored if a == 0 or e == key.size else complete).append(float(e - a))
    return np.asarray(complete), np.asarray(censored)


def test_dwell_histograms_hold_the_trace_dwells_complete_and_censored_apart(run):
    _, stats, trace = run
    complete, censored = _dwells_from_trace(trace)  # epoch_s = 1 s in both runs
    edges = stats.dwell_edges_s
    for counts, durations in ((stats.dwell_complete, complete), (stats.dwell_censored, censored)):
        assert counts.sum() == durations.size > 0
        expected = np.bincount(
            np.searchsorted(edges, durations, side="right") - 1, minlength=counts.size
        )
        np.testing.assert_array_equal(counts, expected)


def test_series_are_the_trace_rows_of_the_chosen_uts(run):
    _, stats, trace = run
    series = stats.series()
    rows = trace[trace["ut_id"].isin([0, 2])].sort_values(["ut_id", "time_s"])
    assert len(series) == len(rows)
    for col in ("time_s", "beam_id", "snr_db", "doppler_rate_hz_s", "angular_speed_deg_s"):
        np.testing.assert_array_equal(series[col].to_numpy(), rows[col].to_numpy())


def test_sampled_uts_at_kept_epochs_match_the_trace(run):
    _, stats, trace = run
    assert stats.keep_times_s.size <= 25 and 0 in stats.sample_ut and 2 in stats.sample_ut
    for k, t_s in enumerate(stats.keep_times_s):
        rows = trace[trace["time_s"] == t_s].set_index("ut_id").loc[stats.sample_ut]
        np.testing.assert_array_equal(stats.ut_beam[k], rows["beam_id"].to_numpy())
        np.testing.assert_array_equal(stats.ut_sat[k], rows["sat_id"].to_numpy())
        np.testing.assert_allclose(stats.ut_lat_deg[k], rows["lat_deg"].to_numpy())


def test_save_and_load_keep_everything(run, tmp_path):
    _, stats, _ = run
    back = ReportStats.load(stats.save(tmp_path / "report_stats.npz"))
    for key in (
        "keep_times_s",
        "ut_beam",
        "ut_lon_deg",
        "sat_pos_m",
        "beam_u_xy",
        "dwell_censored",
    ):
        np.testing.assert_array_equal(getattr(back, key), getattr(stats, key))
    pd.testing.assert_frame_equal(back.series(), stats.series())
    pd.testing.assert_frame_equal(back.events(), stats.events())
    assert back.service_counts == stats.service_counts and back.n_sub_xy == stats.n_sub_xy
    for key in ("snr_db", "throughput_bps"):
        np.testing.assert_array_equal(back.cdf(key)[1], stats.cdf(key)[1])


def test_parquet_trace_gives_the_same_statistics_as_csv(tmp_path):
    out = make_run(tmp_path / "pq", WALKER, "--parquet")
    csv_stats = stats_from_dir(out, series_ut=[1], max_frames=10)
    shutil.move(out / "trace.csv", tmp_path / "trace.csv")  # now only trace.parquet
    pq_stats = stats_from_dir(out, series_ut=[1], max_frames=10, chunk_rows=500)
    for key in ("snr_db", "sinr_db", "log10_throughput_bps"):
        np.testing.assert_array_equal(pq_stats.hist[key], csv_stats.hist[key])
    np.testing.assert_array_equal(pq_stats.ut_beam, csv_stats.ut_beam)
    assert pq_stats.service_counts == csv_stats.service_counts


def test_cli_is_on_the_path():
    assert "codebook" in cli("--help")


def test_fast_histogram_bins_like_searchsorted_even_next_to_the_edges():
    from leolink.io.report.stats import DB_EDGES, LOG_TPUT_EDGES, _hist

    rng = np.random.default_rng(7)
    for edges in (DB_EDGES, LOG_TPUT_EDGES):
        v = np.r_[
            rng.uniform(edges[0] - 5, edges[-1] + 5, 100_000),
            edges,
            np.nextafter(edges, -np.inf),
            np.nextafter(edges, np.inf),
            np.nan,
            np.inf,
        ]
        finite = v[np.isfinite(v)]
        expected = np.bincount(
            np.searchsorted(edges, finite, side="right"), minlength=edges.size + 1
        )
        np.testing.assert_array_equal(_hist(v, edges), expected)
