"""The parts of summary.json by hand: the environment blocks, the per-UT records, the
streamed dB statistics (leolink.io.summary.environment, .records, .stats).

Every expectation is counted or divided by hand from the small inputs written here.
"""

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from leolink.io.summary.environment import by_environment, with_environment
from leolink.io.summary.records import handover_counts, nanmax, per_ut_records
from leolink.io.summary.stats import DbStats, grouped_percentiles, running_sum
from leolink.sim.handover.events import EVENT_KINDS


# -- environment ----------------------------------------------------------------------------
def _acc(environment=("urban", "rural", "urban", "sea")):
    """Four UTs, 2 s epochs; the sea UT was never recorded (every count 0)."""
    return SimpleNamespace(
        environment=environment,
        epoch_s=2.0,
        n_epochs=np.array([10, 4, 6, 0]),
        n_outage=np.array([3, 1, 2, 0]),
        n_no_satellite=np.array([1, 0, 1, 0]),
        n_below_threshold=np.array([1, 1, 0, 0]),
        n_blocked=np.array([1, 0, 1, 0]),
        interrupted_s=np.array([2.0, 0.0, 1.0, 0.0]),
        n_los=np.array([5, 2, 3, 0]),
        n_link=np.array([8, 4, 5, 0]),
    )


COUNTS = {
    "beam_handover": np.array([2, 1, 0, 0]),
    "sat_handover": np.array([1, 0, 3, 0]),
    "rlf": np.array([0, 1, 1, 0]),
}


def test_by_environment_pools_the_uts_of_each_environment():
    """Urban: UTs 0 and 2, 16 epochs = 32 UT-s; rural: UT 1, 4 epochs = 8 UT-s; sea: no
    epoch, so no fraction. Environments in the order they first appear."""
    out = by_environment(_acc().environment, _acc(), COUNTS)
    assert list(out) == ["urban", "rural", "sea"]
    assert out["urban"] == {
        "n_ut": 2,
        "n_ut_epochs": 16,
        "outage_fraction": 5 / 16,
        "outage_fraction_by_reason": {
            "no_satellite": 2 / 16,
            "below_threshold": 1 / 16,
            "blocked": 2 / 16,
            "handover": 3.0 / 32,
        },
        "handovers": {"beam_handover": 2, "sat_handover": 4, "rlf": 1, "handovers_total": 6},
        "handovers_per_ut_hour": 6 * 3600 / 32,
        "los_fraction": 8 / 13,
    }
    assert out["rural"] == {
        "n_ut": 1,
        "n_ut_epochs": 4,
        "outage_fraction": 1 / 4,
        "outage_fraction_by_reason": {
            "no_satellite": 0.0,
            "below_threshold": 1 / 4,
            "blocked": 0.0,
            "handover": 0.0,
        },
        "handovers": {"beam_handover": 1, "sat_handover": 0, "rlf": 1, "handovers_total": 1},
        "handovers_per_ut_hour": 3600 / 8,
        "los_fraction": 2 / 4,
    }
    sea = out["sea"]
    assert (sea["n_ut"], sea["n_ut_epochs"], sea["handovers"]["handovers_total"]) == (1, 0, 0)
    fractions = [sea["outage_fraction"], sea["handovers_per_ut_hour"], sea["los_fraction"]]
    assert fractions + list(sea["outage_fraction_by_reason"].values()) == [None] * 7


def test_with_environment_adds_the_blocked_fractions_and_the_environment_block():
    acc = _acc()
    per_ut = [{"outage_fraction_by_reason": {"no_satellite": 0.1}} for _ in range(4)]
    out = {"overall": {"outage_fraction_by_reason": {"no_satellite": 0.1}}, "per_ut": per_ut}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the 0 / 0 of the unrecorded UT is NaN, silently
        got = with_environment(acc, out, COUNTS)
    assert got is out
    assert out["overall"]["outage_fraction_by_reason"] == {"no_satellite": 0.1, "blocked": 2 / 20}
    blocked = [row["outage_fraction_by_reason"]["blocked"] for row in per_ut]
    assert blocked[:3] == [1 / 10, 0.0, 1 / 6] and np.isnan(blocked[3])  # 0 / 0 epochs
    assert out["overall"]["by_environment"] == by_environment(acc.environment, acc, COUNTS)
    assert list(out["overall"]["by_environment"]) == ["urban", "rural", "sea"]


def test_with_environment_without_per_ut_rows_or_epochs():
    """Beyond 1,000 UTs there are no per-UT rows; a run with no recorded epoch has no
    blocked fraction."""
    acc = _acc(("urban",) * 4)
    acc.n_epochs = np.zeros(4, np.int64)
    out = with_environment(acc, {"overall": {"outage_fraction_by_reason": {}}}, COUNTS)
    assert out["overall"]["outage_fraction_by_reason"] == {"blocked": None}
    assert list(out["overall"]["by_environment"]) == ["urban"]


def test_without_environments_the_summary_is_left_as_it_was():
    out = {"overall": {"outage_fraction_by_reason": {"no_satellite": 0.5}}}
    got = with_environment(_acc(()), out, COUNTS)
    assert got is out and out == {"overall": {"outage_fraction_by_reason": {"no_satellite": 0.5}}}


# -- records ----------------------------------------------------------------------------------
def _dwells():
    """UT 0: a censored start, then two complete dwells (7 s, 8 s); UT 1: one complete
    (7 s), then a censored end; UT 2: none."""
    rows = [  # ut, sat, beam, start, end, censored start, censored end
        (0, 3, 1, 0.0, 5.0, True, False),
        (0, 3, 2, 5.0, 12.0, False, False),
        (0, 4, 0, 12.0, 20.0, False, False),
        (1, 7, 5, 2.0, 9.0, False, False),
        (1, 8, 1, 9.0, 20.0, False, True),
    ]
    cols = list(zip(*rows, strict=True))
    names = ("ut_id", "sat_id", "beam_id", "start_s", "end_s", "censored_start", "censored_end")
    d = {k: np.array(c) for k, c in zip(names, cols, strict=True)}
    d["duration_s"] = d["end_s"] - d["start_s"]
    return d, ~(d["censored_start"] | d["censored_end"])


def _table():
    """Three UTs' columns, each value distinct (UT i, column j: 100 j + i, or by hand)."""
    names = [
        "n_dwell_complete", "dwell_mean_s", "dwell_median_s", "outage_fraction",
        "outage_fraction_no_satellite", "outage_fraction_below_threshold",
        "handover_interruption_fraction", "outage_fraction_rlf", "mean_throughput_bps",
        "max_abs_doppler_hz", "max_angular_speed_deg_s",
        *(f"{s}_{k}_db" for s in ("snr", "sinr") for k in ("mean", "p5", "p50", "p95")),
        *(f"n_{k}" for k in EVENT_KINDS),
    ]  # fmt: skip
    table = {"ut_id": np.arange(3), "n_epochs": np.array([20, 18, 0])}
    table.update({k: 100.0 * j + np.arange(3) for j, k in enumerate(names, start=1)})
    return table


def test_per_ut_records_lay_out_each_uts_columns_and_dwells():
    d, complete = _dwells()
    table = _table()
    link, kpi = [{"link": i} for i in range(3)], [{"kpi": i} for i in range(3)]
    out = per_ut_records(table, d, complete, link, kpi)
    assert len(out) == 3
    t = {k: v[1] for k, v in table.items()}  # UT 1's row
    # the complete dwells' durations stay an array (to_jsonable converts the summary)
    complete_s = [r["dwell"].pop("complete_s").tolist() for r in out]
    assert complete_s == [[7.0, 8.0], [7.0], []]
    kinds = {k: int(t[f"n_{k}"]) for k in EVENT_KINDS}
    assert out[1] == {
        "ut_id": 1,
        "n_epochs": 18,
        "handovers": {**kinds, "handovers_total": kinds["beam_handover"] + kinds["sat_handover"]},
        "dwell": {
            "n_complete": t["n_dwell_complete"],
            "mean_s": t["dwell_mean_s"],
            "median_s": t["dwell_median_s"],
            "censored": [
                {
                    "sat_id": 8,
                    "beam_id": 1,
                    "start_s": 9.0,
                    "end_s": 20.0,
                    "duration_s": 11.0,
                    "censored_start": False,
                    "censored_end": True,
                },
            ],  # fmt: skip
        },
        "outage_fraction": t["outage_fraction"],
        "outage_fraction_by_reason": {
            "no_satellite": t["outage_fraction_no_satellite"],
            "below_threshold": t["outage_fraction_below_threshold"],
            "handover": t["handover_interruption_fraction"],
            "rlf": t["outage_fraction_rlf"],
        },
        "handover_interruption_fraction": t["handover_interruption_fraction"],
        "snr_db": {k: t[f"snr_{k}_db"] for k in ("mean", "p5", "p50", "p95")},
        "sinr_db": {k: t[f"sinr_{k}_db"] for k in ("mean", "p5", "p50", "p95")},
        "mean_throughput_bps": t["mean_throughput_bps"],
        "max_abs_doppler_hz": t["max_abs_doppler_hz"],
        "max_angular_speed_deg_s": t["max_angular_speed_deg_s"],
        "link": {"link": 1},
        "kpi": {"kpi": 1},
    }
    assert out[0]["dwell"]["censored"] == [
        {"sat_id": 3, "beam_id": 1, "start_s": 0.0, "end_s": 5.0, "duration_s": 5.0,
         "censored_start": True, "censored_end": False},
    ]  # fmt: skip
    assert out[2]["dwell"]["censored"] == []
    assert [r["ut_id"] for r in out] == [0, 1, 2] and out[2]["n_epochs"] == 0
    # The values are Python's (JSON-ready), not numpy scalars.
    assert type(out[1]["n_epochs"]) is int and type(out[1]["outage_fraction"]) is float


def test_per_ut_records_without_link_or_kpi_blocks():
    d, complete = _dwells()
    out = per_ut_records(_table(), d, complete)
    assert all("link" not in r and "kpi" not in r for r in out)


def test_handover_counts_total_beam_and_satellite_handovers_only():
    got = handover_counts({"beam_handover": np.int64(2), "sat_handover": 3, "rlf": 4.0})
    assert got == {"beam_handover": 2, "sat_handover": 3, "rlf": 4, "handovers_total": 5}
    assert all(type(v) is int for v in got.values())


def test_nanmax_ignores_nan_and_is_none_without_a_finite_value():
    assert nanmax(np.array([np.nan, 3.0, -5.0])) == 3.0
    assert type(nanmax(np.array([np.nan, 3.0]))) is float
    assert nanmax(np.array([np.nan, np.nan])) is None
    assert nanmax(np.zeros(0)) is None


# -- streamed statistics ----------------------------------------------------------------------
def test_running_sum_adds_each_groups_values_one_by_one_in_order():
    """1e16 + 1 rounds back to 1e16 (ties to even, spacing 2): added one by one, two 1s
    leave 1e16; added together first they would make 1e16 + 2."""
    got = running_sum(
        np.array([1e16, 2.0, 3.0]), np.array([0, 2, 0, 2]), np.array([1.0, 10.0, 1.0, 30.0])
    )
    assert got.tolist() == [1e16, 2.0, 43.0]


def test_db_stats_per_ut_and_overall_statistics():
    """UT 0: 1, 2, 3 dB; UT 1: 10 dB (its NaN and inf skipped); UT 2: nothing. numpy's
    linear percentiles of 1, 2, 3: p5 1.1, p50 2, p95 2.9; the histograms' within half a
    bin (0.1 dB per UT, 0.01 dB pooled)."""
    stats = DbStats(3)
    stats.add(np.array([0, 1, 0]), np.array([1.0, np.nan, 2.0]))
    stats.add(np.array([1, 0, 1]), np.array([10.0, 3.0, np.inf]))
    assert stats.count.tolist() == [3, 1, 0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # UT 2's 0 / 0 mean is NaN, silently
        per_ut = stats.per_ut_stats()
    assert per_ut.shape == (3, 4)
    np.testing.assert_allclose(per_ut[0], [2.0, 1.1, 2.0, 2.9], atol=0.05)
    np.testing.assert_allclose(per_ut[1], [10.0] * 4, atol=0.05)
    assert np.isnan(per_ut[2]).all()
    overall = stats.overall()
    assert list(overall) == ["mean", "p5", "p50", "p95"]
    assert overall["mean"] == 16.0 / 4
    pooled = np.percentile([1.0, 2.0, 3.0, 10.0], [5, 50, 95])
    np.testing.assert_allclose([overall[k] for k in ("p5", "p50", "p95")], pooled, atol=0.005)


def test_db_stats_without_values_have_no_overall_statistics():
    stats = DbStats(2)
    stats.add(np.array([0, 1]), np.array([np.nan, -np.inf]))
    assert stats.overall() == {"mean": None, "p5": None, "p50": None, "p95": None}
    assert np.isnan(stats.per_ut_stats()).all()


def test_grouped_percentiles_of_no_values_are_nan():
    out = grouped_percentiles(np.zeros(0, np.int64), np.zeros(0), 3, [50.0, 95.0])
    assert out.shape == (3, 2) and np.isnan(out).all()


# -- latitude bands ---------------------------------------------------------------------------
def test_band_of_puts_an_edge_in_the_band_above_and_90_deg_in_the_last():
    from leolink.io.summary.bands import band_of

    lat = [-95.0, -90.0, -80.0001, -80.0, -0.1, 0.0, 89.9, 90.0, 95.0]
    assert band_of(lat).tolist() == [0, 0, 0, 1, 8, 9, 17, 17, 17]


def _bands():
    """Four UTs, 2 s epochs. Frame 1 (t = 0): UTs 0-2 at -85, 5, 5 deg (bands 0, 9, 9);
    frame 2: UT 0 at -75 deg (band 1) at t = 2 s, UT 1 at 15 deg (band 10) at t = 2 s and
    25 deg (band 11) at t = 3 s; UT 3 has no row."""
    from leolink.io.summary.bands import LatitudeBands

    bands = LatitudeBands(4, 2.0)
    rows = bands.note_rows(np.zeros(3), np.array([0, 1, 2]), np.array([-85.0, 5.0, 5.0]))
    assert rows.tolist() == [0, 9, 9]
    bands.fold(rows, np.array([False, True, False]), np.array([np.nan, 3.0, 4.0]))
    rows = bands.note_rows(np.array([2.0, 2.0, 3.0]), np.array([0, 1, 1]),
                           np.array([-75.0, 15.0, 25.0]))  # fmt: skip
    bands.fold(rows, np.array([False, True, False]), np.array([5.0, 7.0, -2.0]))
    return bands


def test_handovers_count_in_the_band_of_their_ut_at_their_epoch():
    """Found in the latest frame (UT 0 at 2 s: band 1; UT 1 at 2 s, within 1 us: band 10);
    else the UT's latest row (UT 0 at 3 s: band 1; UT 1 at 0 s and 5 s: band 11, its row
    at 3 s; UT 2, not in the frame: band 9); UT 3, without rows, nowhere; not handovers
    (outage_start) nowhere."""
    bands = _bands()
    bands.add_events(np.array([3.0]), np.array([1]), np.array(["outage_start"]))
    assert bands.n_handover.sum() == 0
    time_s = [2.0, 3.0, 2.0000005, 0.0, 5.0, 2.0, 2.0, 3.0]
    ut = [0, 0, 1, 1, 1, 2, 3, 1]
    kind = ["sat_handover", "beam_handover", "beam_handover", "sat_handover", "beam_handover",
            "beam_handover", "sat_handover", "outage_start"]  # fmt: skip
    bands.add_events(np.array(time_s), np.array(ut), np.array(kind))
    assert {b: int(n) for b, n in enumerate(bands.n_handover) if n} == {1: 2, 9: 1, 10: 1, 11: 2}


def test_handovers_before_any_row_count_nowhere():
    from leolink.io.summary.bands import LatitudeBands

    bands = LatitudeBands(2, 1.0)
    bands.add_events(np.array([0.0]), np.array([1]), np.array(["sat_handover"]))
    assert bands.n_handover.sum() == 0 and bands.summary() == []


def test_the_bands_summary_by_hand():
    """UT-minutes = UT-epochs x 2 s / 60; rate = handovers / UT-minutes; band 0 has no
    finite SINR (None), band 9 the mean of 3 and 4 dB."""
    bands = _bands()
    time_s, ut = np.array([2.0, 3.0, 2.0, 0.0, 5.0, 2.0]), np.array([0, 0, 1, 1, 1, 2])
    bands.add_events(time_s, ut, np.array(["beam_handover"] * 6))
    got = bands.summary()
    # band, UT-epochs, handovers, outage fraction, SINR mean
    want = [(0, 1, 0, 0.0, None), (1, 1, 2, 0.0, 5.0), (9, 2, 1, 0.5, 3.5),
            (10, 1, 1, 1.0, 7.0), (11, 1, 2, 0.0, -2.0)]  # fmt: skip
    assert len(got) == len(want)
    for row, (b, n, n_ho, outage, sinr) in zip(got, want, strict=True):
        minutes = n * 2.0 / 60.0
        assert row == {
            "lat_min_deg": -90.0 + 10.0 * b,
            "lat_max_deg": -80.0 + 10.0 * b,
            "n_ut_epochs": n,
            "ut_minutes": pytest.approx(minutes, rel=1e-15),
            "n_handovers": n_ho,
            "handover_rate_per_ut_min": pytest.approx(n_ho / minutes, rel=1e-15),
            "outage_fraction": outage,
            "sinr_mean_db": sinr,
        }
        assert type(row["n_ut_epochs"]) is int and type(row["ut_minutes"]) is float


# -- link figures -----------------------------------------------------------------------------
def _link_stats():
    """Four UTs, 2 s epochs; UT 3 never fed. Rows (UT, service, MODCOD, margin dB, gap s,
    Shannon b/s): (0, served, QPSK 1/4, 1, 0, 1e6), (0, handover, none, -2, 0.5, NaN),
    (1, outage, code 3, NaN, NaN, 0), (2, served, QPSK 1/3, 3, NaN, 2e6); then by name,
    no margin: (1, served, QPSK 1/3, 0.5, 4e6), (1, served, "bogus" = none, 0.5, 5e6)."""
    from leolink.io.summary.link import LinkStats

    stats = LinkStats(4, DbStats, epoch_s=2.0)
    columns = {
        "margin_db": np.array([1.0, -2.0, np.nan, 3.0]),
        "modcod": np.array([0, -1, 3, 1]),
        "throughput_shannon_bps": np.array([1e6, np.nan, 0.0, 2e6]),
    }
    gap = np.array([0.0, 0.5, np.nan, np.nan])
    stats.add(columns, np.array([0, 0, 1, 2]), np.array([0, 1, 2, 0]), gap)
    columns = {"modcod": np.array(["QPSK 1/3", "bogus"]),
               "throughput_shannon_bps": np.array([4e6, 5e6])}  # fmt: skip
    stats.add(columns, np.array([1, 1]), np.array([0, 0]), 0.5)
    return stats


def test_link_blocks_overall_by_hand():
    """Margins 1, -2, 3 dB: mean 2/3, one of three negative. Served rows (not outage):
    QPSK 1/4 once, QPSK 1/3 twice, none twice. Served time 2 + 1.5 + 2 + 1.5 + 1.5 =
    8.5 UT-s, 3 of it without a MODCOD. Shannon 12 Mb/s over 7 UT-epochs."""
    overall, per_ut = _link_stats().summary(np.array([2, 3, 1, 1]), per_ut=False)
    assert per_ut is None
    margin = overall["margin_db"]
    assert margin["mean"] == pytest.approx(2.0 / 3.0, rel=1e-15)
    assert margin["p50"] == pytest.approx(1.0, abs=0.005)
    assert margin["fraction_negative"] == 1 / 3
    usage = overall["modcod_usage"]
    assert list(usage) == ["QPSK 1/4", "QPSK 1/3", "none"]  # the table's order
    assert usage == {"QPSK 1/4": 0.2, "QPSK 1/3": 0.4, "none": 0.4}
    assert overall["served_without_modcod"] == {"fraction": 3.0 / 8.5, "ut_s": 3.0}
    assert overall["mean_throughput_bps"] == {"shannon": 12e6 / 7, "dvbs2x": None}


def test_link_blocks_per_ut_by_hand():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # UTs without margins: 0 / 0 is NaN, silently
        _, per_ut = _link_stats().summary(np.array([2, 3, 1, 1]))
    assert len(per_ut) == 4
    ut0, ut1, ut2, ut3 = per_ut
    assert ut0["margin_db"]["mean"] == -0.5 and ut0["margin_db"]["fraction_negative"] == 0.5
    assert ut0["margin_db"]["p50"] == pytest.approx(-0.5, abs=0.05 + 1e-9)  # half a bin
    assert ut0["modcod_usage"] == {"QPSK 1/4": 0.5, "none": 0.5}
    assert ut0["served_without_modcod"] == {"fraction": 1.5 / 3.5, "ut_s": 1.5}
    assert ut0["mean_throughput_bps"] == {"shannon": 1e6 / 2, "dvbs2x": None}
    assert np.isnan(ut1["margin_db"]["mean"]) and np.isnan(ut1["margin_db"]["fraction_negative"])
    assert ut1["modcod_usage"] == {"QPSK 1/3": 0.5, "none": 0.5}
    assert ut1["served_without_modcod"] == {"fraction": 0.5, "ut_s": 1.5}
    assert ut1["mean_throughput_bps"]["shannon"] == 9e6 / 3
    assert ut2["margin_db"]["mean"] == 3.0 and ut2["margin_db"]["fraction_negative"] == 0.0
    assert ut2["modcod_usage"] == {"QPSK 1/3": 1.0}
    assert ut2["served_without_modcod"] == {"fraction": 0.0, "ut_s": 0.0}
    assert ut2["mean_throughput_bps"]["shannon"] == 2e6
    assert ut3["modcod_usage"] == {} and ut3["mean_throughput_bps"]["shannon"] == 0.0
    assert ut3["served_without_modcod"] == {"fraction": None, "ut_s": 0.0}
    assert set(ut3) == {"margin_db", "modcod_usage", "served_without_modcod",
                        "mean_throughput_bps"}  # fmt: skip
    assert list(ut3["margin_db"]) == ["mean", "p5", "p50", "p95", "fraction_negative"]


def test_link_defaults_and_margins_over_several_adds():
    """1 s epochs and no gap by default: one served row without a MODCOD is 1 s of served
    time, all of it without one. Margins -1; -3, 2, 0, 0.5 dB over two adds: two of five
    below 0 (0 itself is not)."""
    from leolink.io.summary.link import LinkStats

    stats = LinkStats(1, DbStats)
    stats.add({"margin_db": np.array([-1.0]), "modcod": np.array(["none"])}, np.array([0]),
              np.array([0]))  # fmt: skip
    stats.add({"margin_db": np.array([-3.0, 2.0, 0.0, 0.5])}, np.zeros(4, np.int64), np.zeros(4))
    overall, per_ut = stats.summary(np.array([5]))
    assert overall["served_without_modcod"] == {"fraction": 1.0, "ut_s": 1.0}
    assert overall["modcod_usage"] == {"none": 1.0}
    assert overall["margin_db"]["fraction_negative"] == 2 / 5
    assert per_ut[0]["margin_db"]["fraction_negative"] == 2 / 5


def test_link_blocks_of_nothing():
    """No rows: no fraction, no usage, no throughput (not seen); seen but no epoch: None."""
    from leolink.io.summary.link import LinkStats

    stats = LinkStats(2, DbStats)
    overall, _ = stats.summary(np.zeros(2, np.int64))
    assert overall["margin_db"]["fraction_negative"] is None and overall["modcod_usage"] == {}
    assert overall["served_without_modcod"] == {"fraction": None, "ut_s": 0.0}
    assert overall["mean_throughput_bps"] == {"shannon": None, "dvbs2x": None}
    stats.add({"throughput_dvbs2x_bps": np.array([1e6])}, np.array([0]), np.array([0]))
    overall, per_ut = stats.summary(np.zeros(2, np.int64))
    assert overall["mean_throughput_bps"] == {"shannon": None, "dvbs2x": None}
    overall, per_ut = stats.summary(np.array([4, 1]))
    assert overall["mean_throughput_bps"] == {"shannon": None, "dvbs2x": 1e6 / 5}
    assert per_ut[0]["mean_throughput_bps"] == {"shannon": None, "dvbs2x": 1e6 / 4}


# -- handover KPIs ----------------------------------------------------------------------------
def _kpi(beam_switch_s=None):
    """Three UTs. UT 0: beam 0 -> 1 at 10 s and back at 12 s (a ping-pong, within 5 s);
    UT 1: a satellite handover at 20 s, two beam switches, an RLF at 40 s; UT 2: a
    handover failure at 50 s. SINR samples 1 and 3 dB served, two unserved."""
    from leolink.io.summary.kpi import KpiAccumulator

    acc = KpiAccumulator(3, ping_pong_s=5.0, mro_window_s=2.0, beam_switch_s=beam_switch_s)
    acc.add_trace({"sinr_db": [1.0, np.nan], "throughput_bps": [1e6, 0.0]})
    acc.add_trace({"sinr_db": [3.0, np.nan], "throughput_bps": [2e6, np.nan]})
    rows = [  # time, ut, kind, from (sat, beam), to (sat, beam)
        (10.0, 0, "beam_handover", 1, 0, 1, 1),
        (12.0, 0, "beam_handover", 1, 1, 1, 0),
        (20.0, 1, "sat_handover", 2, 0, 3, 0),
        (30.0, 1, "beam_switch", 3, 0, 3, 1),
        (31.0, 1, "beam_switch", 3, 1, 3, 2),
        (40.0, 1, "rlf", 3, 2, -1, -1),
        (50.0, 2, "handover_failure", 4, 0, 5, 0),
    ]
    cols = list(zip(*rows, strict=True))
    names = ("time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat", "to_beam")
    events = {k: np.array(c) for k, c in zip(names, cols, strict=True)}
    acc.add_events({k: v[:3] for k, v in events.items()})
    acc.add_events({k: v[3:5] for k, v in events.items()})  # beam switches alone: none kept
    acc.add_events({k: v[5:] for k, v in events.items()})
    return acc


def _dwells_none(n_ut):
    from leolink.io.summary.accumulator import SummaryAccumulator

    return SummaryAccumulator(n_ut).dwell_table()


def test_kpi_accumulator_keeps_the_serving_changes_and_counts_beam_switches():
    acc = _kpi()
    ev = acc.events()
    assert ev["kind"].tolist() == ["beam_handover", "beam_handover", "sat_handover", "rlf",
                                   "handover_failure"]  # fmt: skip
    assert ev["time_s"].tolist() == [10.0, 12.0, 20.0, 40.0, 50.0]
    assert ev["to_beam"].tolist() == [1, 0, 0, -1, 0]
    assert acc.n_beam_switch.tolist() == [0, 2, 0]
    assert (acc.n_samples, acc.n_unserved) == (4, 2)


def test_kpi_summary_by_hand():
    """Observed 60, 120, 30 s = 1, 2, 0.5 UT-min: rates 2, 0.5, 0 per UT-min. Three
    handovers share 3 s of interruption: 1 s each. Half the samples unserved; the served
    SINRs' median 2 dB (within half a 0.01 dB bin)."""
    acc = _kpi()
    interruption = {"handover": 3.0, "rlf": 2.0, "outage": 1.0}
    overall, per_ut = acc.summary(_dwells_none(3), np.array([60.0, 120.0, 30.0]), interruption)
    assert overall["interruption_s"] == interruption
    assert overall["interruption_per_handover_s"] == 1.0
    assert overall["unserved_fraction"] == 0.5
    assert overall["sinr_db_percentiles_served"]["p50"] == pytest.approx(2.0, abs=0.005 + 1e-9)
    # All samples, unserved as -inf dB and 0 b/s: sorted -inf, -inf, 1, 3 dB and 0, 0, 1, 2
    # Mb/s; linear p95 at position 2.85: 2.7 dB; p99 at 2.97: 1.97 Mb/s (half a bin).
    assert overall["sinr_db_percentiles"]["p5"] == -np.inf
    assert overall["sinr_db_percentiles"]["p95"] == pytest.approx(2.7, abs=0.005 + 1e-9)
    assert overall["throughput_bps_percentiles"]["p99"] == pytest.approx(1.97e6, abs=5e4 + 1)
    assert overall["rlf_count"] == 1 and overall["ping_pong_count"] == 1
    assert overall["handover_rate_per_ut_min"] == 3 / 3.5
    assert overall["rlf_rate_per_ut_min"] == 1 / 3.5
    assert "beam_switch_count" not in overall
    zero = {"too_early_count": 0, "too_late_count": 0, "wrong_cell_count": 0}
    assert per_ut == [
        {"handover_rate_per_ut_min": 2.0, "ping_pong_count": 1, "rlf_count": 0,
         "handover_failure_count": 0, **zero},
        {"handover_rate_per_ut_min": 0.5, "ping_pong_count": 0, "rlf_count": 1,
         "handover_failure_count": 0, **zero},
        {"handover_rate_per_ut_min": 0.0, "ping_pong_count": 0, "rlf_count": 0,
         "handover_failure_count": 1, **zero},
    ]  # fmt: skip


def test_kpi_summary_with_beam_switches_apart():
    """Cells are satellites, 0.2 s a switch: 2 switches in 3.5 UT-min, 0.4 s taken out of
    the handovers' 3 s (2.6 s over 3 handovers); never below 0."""
    acc = _kpi(beam_switch_s=0.2)
    interruption = {"handover": 3.0, "rlf": 2.0, "outage": 1.0}
    overall, per_ut = acc.summary(_dwells_none(3), np.array([60.0, 120.0, 30.0]), interruption)
    assert overall["beam_switch_count"] == 2
    assert overall["beam_switch_rate_per_ut_min"] == 2 / 3.5
    assert overall["interruption_per_beam_switch_s"] == 0.2
    assert overall["interruption_s"] == {"handover": 3.0 - 0.4, "rlf": 2.0, "outage": 1.0,
                                         "beam_switch": 0.4}  # fmt: skip
    assert overall["interruption_per_handover_s"] == (3.0 - 0.4) / 3
    assert [row["beam_switch_count"] for row in per_ut] == [0, 2, 0]
    interruption = {"handover": 0.1, "rlf": 0.0, "outage": 0.0}
    overall, _ = acc.summary(_dwells_none(3), np.array([60.0, 120.0, 30.0]), interruption)
    assert overall["interruption_s"]["handover"] == 0.0
    assert overall["interruption_s"]["beam_switch"] == 0.4


def test_kpi_summary_of_nothing():
    """An unobserved UT (or none): no KPI at all; no events and no samples: no mean
    interruption, no unserved fraction, no beam switch interruption."""
    from leolink.io.summary.kpi import KpiAccumulator

    assert _kpi().summary(_dwells_none(3), np.array([60.0, 0.0, 30.0]), {}) == ({}, [{}] * 3)
    assert KpiAccumulator(0).summary(_dwells_none(0), np.zeros(0), {}) == ({}, [])
    acc = KpiAccumulator(2, beam_switch_s=0.2)
    ev = acc.events()
    assert list(ev) == ["time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat", "to_beam"]
    assert all(ev[k].size == 0 for k in ev) and ev["time_s"].dtype == float
    assert ev["kind"].dtype.kind == "U"  # names, as the kept events'
    overall, per_ut = acc.summary(_dwells_none(2), np.array([60.0, 60.0]),
                                  {"handover": 0.0, "rlf": 0.0, "outage": 0.0})  # fmt: skip
    assert overall["interruption_per_handover_s"] is None
    assert overall["unserved_fraction"] is None
    assert overall["interruption_per_beam_switch_s"] is None and overall["beam_switch_count"] == 0
    assert per_ut[1]["handover_rate_per_ut_min"] == 0.0


def test_a_frame_time_is_matched_within_1_us_only_and_band_0_counts():
    """Rows, in row order: UT 0 at -85 deg (band 0) at t0 + 5 s, then -75 deg (band 1) at
    t0 + 10 s; UT 1 at -55 deg (band 3) at t0 + 10 s, then -65 deg (band 2) at t0 + 5 s
    (t0 = 1e6 s). An event at a row's time finds that row's band (0, 2; then 1, 3); one
    5 s or more from every row (t0, t0 + 20 s), however large the times, the UT's last
    row's (1; 2). Two calls add up."""
    from leolink.io.summary.bands import LatitudeBands

    bands = LatitudeBands(2, 1.0)
    t0 = 1e6
    bands.note_rows(np.array([t0 + 5, t0 + 10, t0 + 10, t0 + 5]), np.array([0, 0, 1, 1]),
                    np.array([-85.0, -75.0, -55.0, -65.0]))  # fmt: skip
    ho = np.array(["sat_handover"] * 3)
    bands.add_events(np.array([t0 + 5, t0 + 5, t0]), np.array([0, 1, 0]), ho)
    assert {b: int(n) for b, n in enumerate(bands.n_handover) if n} == {0: 1, 1: 1, 2: 1}
    bands.add_events(np.array([t0 + 10, t0 + 10, t0 + 20]), np.array([0, 1, 1]), ho)
    assert {b: int(n) for b, n in enumerate(bands.n_handover) if n} == {0: 1, 1: 2, 2: 2, 3: 1}


def test_one_band_is_one_row_and_no_warning_for_a_band_without_sinr():
    from leolink.io.summary.bands import LatitudeBands

    bands = LatitudeBands(1, 1.0)
    band = bands.note_rows(np.zeros(1), np.array([0]), np.array([45.0]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # 0 / 0 SINR values: None, silently
        bands.fold(band, np.array([False]), np.array([np.nan]))
        got = bands.summary()
    assert [(r["lat_min_deg"], r["n_ut_epochs"], r["sinr_mean_db"]) for r in got] == [
        (40.0, 1, None)
    ]


def _mro_events(rlf_s):
    """One UT: beam 0 -> 1 of satellite 1 at 10 s, an RLF in beam 1 at ``rlf_s``, service
    back in beam 2 of satellite 1 at ``rlf_s + 0.5`` s."""
    rows = [
        (10.0, 0, "beam_handover", 1, 0, 1, 1),
        (rlf_s, 0, "rlf", 1, 1, -1, -1),
        (rlf_s + 0.5, 0, "outage_end", -1, -1, 1, 2),
    ]
    names = ("time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat", "to_beam")
    return {k: np.array(c) for k, c in zip(names, zip(*rows, strict=True), strict=True)}


def _mro_of(acc):
    """The classes counted for the UT, the same in its ``kpi`` and the overall one."""
    overall, per_ut = acc.summary(_dwells_none(1), np.array([60.0]), {"handover": 0.0})
    got = {k.removesuffix("_count") for k, v in per_ut[0].items() if k.endswith("count") and v}
    names = ("handover_failure", "too_early", "too_late", "wrong_cell", "rlf")
    assert got == {k for k in names if overall[f"{k}_count"]}
    return got


@pytest.mark.parametrize(
    "level,window_s,rlf_s,classes",
    [
        # TS 38.300 15.5.2.2.2: failure shortly after the handover, back in a third cell
        ("cell", 2.0, 11.5, {"wrong_cell", "rlf"}),
        # cells are satellites: back in the source satellite
        ("satellite", 2.0, 11.5, {"too_early", "rlf"}),
        # not shortly after (1.5 s > 1 s, the default window): too late
        (None, None, 11.5, {"too_late", "rlf"}),
        (None, None, 10.5, {"wrong_cell", "rlf"}),
    ],
)
def test_kpi_mro_classes_at_the_configured_level_and_window(level, window_s, rlf_s, classes):
    """``None``: the defaults, cells (sat, beam) and a 1 s window."""
    from leolink.io.summary.kpi import KpiAccumulator

    kwargs = {} if level is None else {"mro_level": level, "mro_window_s": window_s}
    acc = KpiAccumulator(1, **kwargs)
    acc.add_events(_mro_events(rlf_s))
    assert _mro_of(acc) == classes


def test_kpi_defaults_and_a_short_observation():
    """Default ping-pong time and MRO window 1 s; a UT observed 0.5 s has KPIs."""
    from leolink.io.summary.kpi import KpiAccumulator

    acc = KpiAccumulator(1)
    overall, per_ut = acc.summary(_dwells_none(1), np.array([0.5]), {"handover": 0.0})
    assert (overall["ping_pong_s"], overall["mro_window_s"]) == (1.0, 1.0)
    assert per_ut[0]["handover_rate_per_ut_min"] == 0.0


def test_kpi_percentiles_beyond_their_ranges_are_infinite():
    """SINR over -60 to 80 dB, throughput over 0 to 10 Gb/s (module docstring); an
    unserved epoch's throughput is 0 b/s (p5 of zeros: within half a 100 kb/s bin)."""
    from leolink.io.summary.kpi import KpiAccumulator

    acc = KpiAccumulator(1)
    acc.add_trace(
        {"sinr_db": [-60.5] * 3 + [80.5] * 3, "throughput_bps": [np.nan] * 3 + [1e10] * 3}
    )
    acc.add_trace({"sinr_db": [-59.9, 79.9], "throughput_bps": [0.0, 0.0]})
    overall, _ = acc.summary(_dwells_none(1), np.array([60.0]), {"handover": 0.0})
    sinr, tput = overall["sinr_db_percentiles"], overall["throughput_bps_percentiles"]
    assert (sinr["p5"], sinr["p95"]) == (-np.inf, np.inf)
    assert tput["p5"] == pytest.approx(0.0, abs=5e4 + 1) and tput["p95"] == np.inf
    served = overall["sinr_db_percentiles_served"]
    assert (served["p5"], served["p95"]) == (-np.inf, np.inf)


@pytest.mark.parametrize("n_group", [3, 40_000, 70_000])
def test_grouped_percentiles_of_many_groups_are_each_groups_own(n_group):
    """Group g holds 1e5 j + g for j = 1 ... 5 (the groups interleave by value), given
    shuffled: p0, p25, p50, p100 are 1e5 (1, 2, 3, 5) + g (numpy's linear rule on five
    values), for few groups and for more than a 16-bit id holds (2**15 and 2**16)."""
    rng = np.random.default_rng(5)
    group = np.repeat(np.arange(n_group), 5)
    values = 1e5 * np.tile(np.arange(1.0, 6.0), n_group) + group
    shuffle = rng.permutation(group.size)
    got = grouped_percentiles(group[shuffle], values[shuffle], n_group, [0.0, 25.0, 50.0, 100.0])
    want = 1e5 * np.array([1.0, 2.0, 3.0, 5.0]) + np.arange(n_group)[:, None]
    np.testing.assert_array_equal(got, want)
