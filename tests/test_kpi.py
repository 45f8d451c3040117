"""Handover KPIs recomputed by hand on small tables, and the streaming percentiles
against numpy.percentile on the same samples."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.sim.handover.kpi import (
    PERCENTILES,
    GroupedPercentileHistogram,
    PercentileHistogram,
    handover_rates,
    ping_pong_fraction,
    ping_pong_mask,
    stays,
    summarize,
    time_of_stay,
)


def events(*rows):
    """rows: (time_s, ut_id, kind, from_sat, from_beam, to_sat, to_beam)."""
    cols = ("time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat", "to_beam")
    return {c: np.array([r[i] for r in rows]) for i, c in enumerate(cols)}


def dwells(*rows):
    """rows: (ut_id, sat_id, beam_id, start_s, end_s, censored_start, censored_end)."""
    cols = ("ut_id", "sat_id", "beam_id", "start_s", "end_s", "censored_start", "censored_end")
    return {c: np.array([r[i] for r in rows]) for i, c in enumerate(cols)}


B, S = "beam_handover", "sat_handover"


def test_handover_rate_per_ut_minute_overall_and_by_kind():
    ev = events(
        (1.0, 0, B, 0, 0, 0, 1),
        (2.0, 0, S, 0, 1, 1, 3),
        (3.0, 1, B, 2, 0, 2, 1),
        (4.0, 1, "outage_start", 2, 1, -1, -1),
    )
    r = handover_rates(ev, observed_s=np.array([120.0, 60.0]), n_ut=2)
    assert r["overall"] == pytest.approx(3 / 3.0)  # 3 handovers in 3 UT-minutes
    assert r["by_kind"] == {B: pytest.approx(2 / 3.0), S: pytest.approx(1 / 3.0)}
    np.testing.assert_allclose(r["per_ut"], [2 / 2.0, 1 / 1.0])
    np.testing.assert_allclose(r["per_ut_by_kind"][S], [0.5, 0.0])


def test_ping_pong_is_a_return_to_the_previous_cell_within_ping_pong_s():
    ev = events(
        (10.0, 0, B, 0, 0, 0, 1),  # A -> B
        (10.5, 0, B, 0, 1, 0, 0),  # B -> A after 0.5 s: ping-pong
        (12.0, 0, B, 0, 0, 0, 1),  # A -> B after 1.5 s: not (stay in A long enough)
        (13.0, 0, B, 0, 1, 0, 0),  # B -> A after exactly 1.0 s: not (strictly sooner)
        (20.0, 1, B, 0, 0, 0, 1),  # another UT: A -> B
        (20.2, 1, B, 0, 1, 0, 2),  # B -> C: not a return
    )
    assert ping_pong_mask(ev, 1.0).tolist() == [False, True, False, False, False, False]
    frac, n_pp, n_ho = ping_pong_fraction(ev, 1.0)
    assert (n_pp, n_ho) == (1, 6) and frac == pytest.approx(1 / 6)


def test_every_bounce_counts_and_an_outage_in_between_breaks_the_pair():
    ev = events(
        (1.0, 0, B, 5, 0, 5, 1),
        (1.2, 0, B, 5, 1, 5, 0),  # pp
        (1.4, 0, B, 5, 0, 5, 1),  # pp
        (1.5, 0, "outage_start", 5, 1, -1, -1),
        (1.6, 0, "outage_end", -1, -1, 5, 1),
        (1.8, 0, B, 5, 1, 5, 0),  # back within 0.4 s of the last handover, but the
    )  # previous serving change is the outage: not a ping-pong
    assert ping_pong_mask(ev, 1.0).tolist() == [False, True, True, False, False, False]


def test_unsorted_tables_give_the_same_ping_pongs():
    ev = events(
        (10.5, 0, B, 0, 1, 0, 0),
        (3.0, 1, B, 0, 0, 0, 1),
        (10.0, 0, B, 0, 0, 0, 1),
        (3.4, 1, B, 0, 1, 0, 0),
    )
    assert ping_pong_mask(ev, 1.0).tolist() == [True, False, False, True]


def test_satellite_ping_pong_ignores_beam_changes_inside_the_other_satellite():
    ev = events(
        (1.0, 0, S, 1, 0, 2, 4),  # sat 1 -> 2
        (1.3, 0, B, 2, 4, 2, 5),  # beam change inside sat 2
        (1.6, 0, S, 2, 5, 1, 2),  # back to sat 1 within 1 s: satellite ping-pong
    )
    assert ping_pong_mask(ev, 1.0, "satellite").tolist() == [False, False, True]
    assert ping_pong_mask(ev, 1.0, "cell").tolist() == [False, False, False]
    assert ping_pong_fraction(ev, 1.0, "satellite")[0] == pytest.approx(1 / 2)


def test_time_of_stay_excludes_censored_dwells():
    dw = dwells(
        (0, 0, 0, 0.0, 4.0, True, False),  # censored at the start
        (0, 0, 1, 4.0, 6.0, False, False),
        (0, 1, 0, 6.0, 9.0, False, False),
        (0, 1, 1, 9.0, 20.0, False, True),  # censored at the end
        (1, 3, 3, 2.0, 7.0, False, False),
    )
    beam = time_of_stay(dw, "beam")
    assert beam["durations_s"].tolist() == [2.0, 3.0, 5.0]
    assert beam["mean_s"] == pytest.approx(10 / 3) and beam["n_censored"] == 2
    # linear interpolation at rank (n - 1) q: 2 + 0.2 * (3 - 2), 3 + 0.8 * (5 - 3)
    assert (beam["median_s"], beam["p10_s"], beam["p90_s"]) == pytest.approx((3.0, 2.2, 4.6))
    sat = time_of_stay(dw, "satellite")
    # UT 0: sat 0 from 0 to 6 (censored start), sat 1 from 6 to 20 (censored end)
    assert sat["durations_s"].tolist() == [5.0] and sat["n_censored"] == 2


def test_satellite_stays_join_only_touching_dwells_of_one_satellite():
    dw = dwells(
        (0, 7, 0, 0.0, 2.0, False, False),
        (0, 7, 1, 2.0, 3.0, False, False),
        (0, 7, 2, 4.0, 5.0, False, False),  # a gap (outage) from 3 to 4: a new stay
        (0, 8, 0, 5.0, 6.0, False, False),
    )
    st = stays(dw, "satellite")
    assert list(zip(st["sat_id"], st["start_s"], st["end_s"], strict=True)) == [
        (7, 0.0, 3.0),
        (7, 4.0, 5.0),
        (8, 5.0, 6.0),
    ]


def test_time_of_stay_without_complete_stays_is_nan():
    got = time_of_stay(dwells((0, 0, 0, 0.0, 9.0, True, True)), "beam")
    assert math.isnan(got["mean_s"]) and got["n_complete"] == 0


RES_DB = 0.01


def test_histogram_percentiles_match_numpy_within_half_a_bin():
    rng = np.random.default_rng(11)
    acc = PercentileHistogram(-60.0, 80.0, RES_DB)
    chunks = [rng.normal(8, 9, 5000), rng.uniform(-50, 70, 3000), rng.normal(-5, 0.02, 7)]
    for c in chunks:  # streamed in pieces of different sizes
        acc.add(c)
    x = np.concatenate(chunks)
    expected = np.percentile(x, PERCENTILES)
    np.testing.assert_allclose(acc.percentiles(), expected, rtol=0, atol=RES_DB / 2 + 1e-9)
    assert acc.n == x.size


@pytest.mark.parametrize("n", [1, 2, 3, 10, 101])
def test_histogram_small_samples_and_extreme_percentiles(n):
    x = np.random.default_rng(n).uniform(-3, 3, n)
    acc = PercentileHistogram(-10, 10, RES_DB)
    acc.add(x)
    q = [0, 1, 37.5, 50, 99, 100]
    np.testing.assert_allclose(acc.percentiles(q), np.percentile(x, q), atol=RES_DB / 2 + 1e-9)


def test_unserved_epochs_are_counted_below_every_sinr():
    rng = np.random.default_rng(5)
    served = rng.normal(10, 4, 900)
    acc = PercentileHistogram(-60, 80, RES_DB)
    acc.add(np.concatenate([served, np.full(100, np.nan)]))  # 10 % unserved UT-epochs
    p = dict(zip(PERCENTILES, acc.percentiles(), strict=True))
    assert p[1] == -np.inf and p[5] == -np.inf
    stand_in = np.concatenate([served, np.full(100, -1e3)])  # any value below all SINRs
    for q in (50, 90, 99):
        assert p[q] == pytest.approx(np.percentile(stand_in, q), abs=RES_DB / 2 + 1e-9)
    assert p[50] < np.percentile(served, 50)  # counting them moves the median down


def test_unserved_throughput_counts_as_zero():
    acc = PercentileHistogram(0.0, 1e9, 1e4, unserved_value=0.0)
    acc.add(np.array([np.nan, np.nan, 5e8, 7e8]))
    np.testing.assert_allclose(
        acc.percentiles([0, 50, 100]), np.percentile([0, 0, 5e8, 7e8], [0, 50, 100]), atol=5e3
    )


def test_histogram_slots_at_the_edges():
    """Slot 0 below lo (however little), 1..n_bins the bins (a value on an edge in the bin
    above it), n_bins + 1 at or above hi; NaN in the slot of ``unserved_value``."""
    tput = PercentileHistogram(0.0, 1e9, 1e8, unserved_value=0.0)  # 10 bins
    x = [-1e-320, -np.inf, 0.0, 1e8, 2.5e8, np.nextafter(1e9, 0.0), 1e9, np.inf, np.nan]
    np.testing.assert_array_equal(tput.slots(x), [0, 0, 1, 2, 3, 10, 11, 11, 1])
    sinr = PercentileHistogram(-10.0, 10.0, 0.5)  # 40 bins, NaN as -inf
    x = [np.nan, -10.0, -9.75, np.nextafter(-10.0, -20.0), 9.9, 10.0, 1e300]
    np.testing.assert_array_equal(sinr.slots(np.array(x)), [0, 1, 1, 0, 40, 41, 41])
    with pytest.raises(ValueError, match="not NaN"):  # (its slot would be NaN's again)
        PercentileHistogram(-10.0, 10.0, 0.5, unserved_value=np.nan)


def test_histogram_merge_equals_one_stream():
    rng = np.random.default_rng(2)
    x = rng.normal(0, 5, 2000)
    a, b, whole = (PercentileHistogram(-40, 40, 0.05) for _ in range(3))
    a.add(x[:700])
    b.add(x[700:])
    whole.add(x)
    a.merge(b)
    np.testing.assert_array_equal(a.counts, whole.counts)


def test_summary_block_names_and_values():
    ev = events(
        (1.0, 0, B, 0, 0, 0, 1),
        (1.5, 0, B, 0, 1, 0, 0),
        (9.0, 1, "rlf", 2, 0, -1, -1),
    )
    dw = dwells((0, 0, 0, 1.5, 4.0, False, False), (1, 2, 0, 0.0, 9.0, True, False))
    kpi = summarize(ev, dw, observed_s=60.0, n_ut=2)
    assert kpi["handover_rate_per_ut_min"] == pytest.approx(1.0)
    assert kpi["ping_pong_fraction"] == pytest.approx(0.5)
    assert kpi["rlf_count"] == 1
    assert kpi["mean_time_of_stay_s"] == {"beam": 2.5, "satellite": 2.5}


def test_grouped_histogram_percentiles_match_numpy_per_group_within_half_a_bin():
    """Per-UT percentiles (summary.json / per_ut.parquet): streamed in epochs of every
    group, compacted several times, against numpy.percentile on each group's samples."""
    rng = np.random.default_rng(8)
    n_group, res = 300, 0.1
    acc = GroupedPercentileHistogram(n_group, -200.0, 200.0, res)
    acc.MIN_PENDING = 1000  # compact often: the merge of sorted tables is what is tested
    samples = [[] for _ in range(n_group)]
    centre = rng.uniform(-20, 30, n_group)
    for _ in range(40):  # epochs: every group, plus a few groups twice
        g = np.r_[np.arange(n_group), rng.integers(0, n_group, 50)]
        v = centre[g] + rng.normal(0, 3, g.size)
        acc.add(g, v)
        for gi, vi in zip(g, v, strict=True):
            samples[gi].append(vi)
    acc.add(np.array([5]), np.array([250.0]))  # above the range: counted as +inf
    samples[5].append(np.inf)
    got = acc.percentiles([0, 5, 50, 95])
    expected = np.array([np.percentile(s, [0, 5, 50, 95]) for s in samples])
    np.testing.assert_allclose(got[:, :3], expected[:, :3], rtol=0, atol=res / 2 + 1e-9)
    finite = np.arange(n_group) != 5
    np.testing.assert_allclose(got[finite, 3], expected[finite, 3], rtol=0, atol=res / 2 + 1e-9)
    np.testing.assert_array_equal(acc.counts(), [len(s) for s in samples])


@settings(max_examples=60, deadline=None)
@given(
    n_group=st.integers(1, 30),
    n_add=st.integers(1, 25),
    min_pending=st.sampled_from([1, 7, 100]),
    seed=st.integers(0, 2**32 - 1),
)
def test_grouped_histogram_table_is_the_count_of_every_key(n_group, n_add, min_pending, seed):
    """However often it is compacted, the sparse table holds each occupied (group, slot)
    key once, sorted, with its number of samples: np.unique over every sample's key."""
    rng = np.random.default_rng(seed)
    acc = GroupedPercentileHistogram(n_group, -5.0, 5.0, 0.5)
    acc.MIN_PENDING = min_pending
    keys = []
    for _ in range(n_add):
        g = rng.integers(0, n_group, rng.integers(0, 40))
        v = rng.choice([np.nan, -np.inf, np.inf, -9.0, 9.0, 0.0, 4.99], g.size)
        v = np.where(rng.random(g.size) < 0.5, rng.normal(0, 3, g.size), v)
        acc.add(g, v)
        keys.append(g * acc._n_slot + acc.grid.slots(v))
    acc._compact()
    want_keys, want_counts = np.unique(np.concatenate(keys), return_counts=True)
    np.testing.assert_array_equal(acc._keys, want_keys)
    np.testing.assert_array_equal(acc._counts, want_counts)
    assert acc._keys.dtype == np.int32 and acc._counts.dtype == np.int64


def test_grouped_histogram_empty_groups_are_nan():
    acc = GroupedPercentileHistogram(4, -10.0, 10.0, 0.1)
    acc.add(np.array([1, 1, 3]), np.array([0.0, 1.0, 2.0]))
    got = acc.percentiles([50])
    assert np.isnan(got[0, 0]) and np.isnan(got[2, 0])
    assert got[1, 0] == pytest.approx(0.5, abs=0.05 + 1e-9)


# -- mobility robustness (TS 38.300 15.5.2.2.2) -----------------------------------------


def _mro_events(*rows):
    """Events from (time_s, ut, kind, from (sat, beam), to (sat, beam)) rows."""
    cols = {k: [] for k in ("time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat",
                            "to_beam")}  # fmt: skip
    for t, ut, kind, src, dst in rows:
        for k, v in zip(cols, (t, ut, kind, *src, *dst), strict=True):
            cols[k].append(v)
    return {k: np.asarray(v) for k, v in cols.items()}


S_, T_, X_, NONE = (1, 0), (2, 0), (3, 0), (-1, -1)  # source, target, a third cell


def _classes(*rows, window_s=1.0, level="cell"):
    from leolink.sim.handover.kpi import mro_counts

    return mro_counts(_mro_events(*rows), window_s, level)


def test_rlf_soon_after_a_handover_back_in_the_source_is_too_early():
    got = _classes((10.0, 0, "sat_handover", S_, T_), (10.6, 0, "rlf", T_, NONE),
                   (11.0, 0, "outage_end", NONE, S_))  # fmt: skip
    assert got == {"handover_failure_count": 0, "too_early_count": 1, "too_late_count": 0,
                   "wrong_cell_count": 0}  # fmt: skip


def test_a_handover_failure_back_in_the_source_is_too_early_whatever_the_window():
    got = _classes((10.0, 0, "sat_handover", S_, T_), (10.03, 0, "handover_failure", S_, T_),
                   (11.0, 0, "outage_end", NONE, S_), window_s=0.01)  # fmt: skip
    assert (got["handover_failure_count"], got["too_early_count"]) == (1, 1)


def test_rlf_soon_after_a_handover_in_a_third_cell_is_wrong_cell():
    got = _classes((10.0, 0, "sat_handover", S_, T_), (10.5, 0, "rlf", T_, NONE),
                   (11.0, 0, "outage_end", NONE, X_))  # fmt: skip
    assert (got["wrong_cell_count"], got["too_early_count"], got["too_late_count"]) == (1, 0, 0)


def test_rlf_after_a_long_stay_in_another_cell_is_too_late_and_in_the_same_cell_nothing():
    late = _classes((10.0, 0, "sat_handover", S_, T_), (11.0, 0, "rlf", T_, NONE),
                    (12.0, 0, "outage_end", NONE, X_))  # fmt: skip
    assert (late["too_late_count"], late["wrong_cell_count"]) == (1, 0)  # 1 s: not < 1 s
    same = _classes((10.0, 0, "sat_handover", S_, T_), (15.0, 0, "rlf", T_, NONE),
                    (16.0, 0, "outage_end", NONE, T_))  # fmt: skip
    assert sum(same.values()) == 0
    never = _classes((15.0, 0, "rlf", T_, NONE), (16.0, 0, "outage_end", NONE, S_))
    assert never["too_late_count"] == 1  # no handover at all


def test_rlf_soon_after_a_handover_back_in_the_target_has_no_class():
    got = _classes((10.0, 0, "sat_handover", S_, T_), (10.2, 0, "rlf", T_, NONE),
                   (11.0, 0, "outage_end", NONE, T_))  # fmt: skip
    assert sum(got.values()) == 0


def test_mro_pairs_each_failure_with_its_own_uts_events_and_needs_a_reestablishment():
    got = _classes((10.0, 1, "sat_handover", S_, T_), (10.5, 0, "rlf", T_, NONE),
                   (11.0, 0, "outage_end", NONE, S_), (12.0, 1, "rlf", T_, NONE))  # fmt: skip
    # UT 0 had no handover: too late (S_ != T_); UT 1 never re-establishes: no class
    assert (got["too_late_count"], got["too_early_count"]) == (1, 0)


def test_satellite_level_compares_satellites():
    rows = ((10.0, 0, "beam_handover", (1, 0), (1, 4)), (10.5, 0, "rlf", (1, 4), NONE),
            (11.0, 0, "outage_end", NONE, (1, 7)))  # fmt: skip
    assert _classes(*rows)["wrong_cell_count"] == 1  # beam (1, 7) is a third cell
    sat = _classes(*rows, level="satellite")
    assert (sat["wrong_cell_count"], sat["too_early_count"]) == (0, 1)  # satellite 1: source


# --- Written from the survivors of a mutation run (issue 45, docs/testing.md) ----------


def test_summary_block_with_non_default_windows_by_hand():
    """Every key of ``overall.kpi`` on a table worked out by hand, with ping_pong_s = 2 s,
    mro_window_s = 0.5 s at satellite level, and per-UT observation times (2 + 1 min)."""
    ev = events(
        (1.0, 0, S, 1, 0, 2, 0),  # sat 1 -> 2
        (2.5, 0, S, 2, 0, 1, 0),  # back after 1.5 s < 2 s: a ping-pong at both levels
        (3.0, 0, B, 1, 0, 1, 1),
        (3.2, 0, "rlf", 1, 1, -1, -1),  # 0.2 s after the beam handover (1, 0) -> (1, 1)
        (3.4, 0, "outage_end", -1, -1, 1, 2),  # re-established on satellite 1: the source
        (5.0, 1, B, 3, 0, 3, 1),
    )
    dw = dwells(
        (0, 1, 0, 0.0, 1.0, True, False),
        (0, 2, 0, 1.0, 2.5, False, False),
        (0, 1, 0, 2.5, 3.0, False, False),
        (0, 1, 1, 3.0, 3.2, False, False),
        (0, 1, 2, 3.4, 120.0, False, True),
        (1, 3, 0, 0.0, 5.0, True, False),
        (1, 3, 1, 5.0, 60.0, False, True),
    )
    kpi = summarize(ev, dw, observed_s=np.array([120.0, 60.0]), n_ut=2, ping_pong_s=2.0,
                    mro_window_s=0.5, mro_level="satellite")  # fmt: skip
    want = {
        "handover_rate_per_ut_min": 4 / 3,
        "handover_rate_per_ut_min_by_kind": {B: 2 / 3, S: 2 / 3},
        "ping_pong_s": 2.0,
        "ping_pong_fraction": 1 / 4,  # cells: the return to (1, 0) of 4 handovers
        "ping_pong_count": 1,
        "ping_pong_fraction_satellite": 1 / 2,  # of the 2 satellite handovers
        "ping_pong_count_satellite": 1,
        "rlf_count": 1,
        # satellite level: the failure 0.2 s < 0.5 s after a handover from satellite 1,
        # re-established on satellite 1: too early
        "handover_failure_count": 0,
        "too_early_count": 1,
        "too_late_count": 0,
        "wrong_cell_count": 0,
        "mro_window_s": 0.5,
        "rlf_rate_per_ut_min": 1 / 3,
        # beam stays 1.5, 0.5, 0.2 s; satellite stays 1.5 and 0.7 (2.5-3.0 and 3.0-3.2
        # joined; 3.4 s is after a gap); percentiles interpolate at rank (n - 1) q
        "mean_time_of_stay_s": {"beam": 2.2 / 3, "satellite": 1.1},
        "time_of_stay_s": {
            "beam": _stay(0.5, 0.26, 1.3, 3, 4),
            "satellite": _stay(1.1, 0.78, 1.42, 2, 3),
        },
    }
    assert _nested_approx(kpi, want)
    # the same failure at cell level is in a third cell ((1, 2): neither (1, 0), (1, 1))
    cell = summarize(ev, dw, np.array([120.0, 60.0]), 2, 2.0, 0.5)
    assert (cell["wrong_cell_count"], cell["too_early_count"]) == (1, 0)
    # with the default 1 s the return after 1.5 s is no ping-pong
    assert summarize(ev, dw, np.array([120.0, 60.0]), 2)["ping_pong_count"] == 0


def _stay(median_s, p10_s, p90_s, n_complete, n_censored):
    return {"median_s": median_s, "p10_s": p10_s, "p90_s": p90_s, "n_complete": n_complete,
            "n_censored": n_censored}  # fmt: skip


def _nested_approx(got, want):
    assert got.keys() == want.keys()
    for k, v in want.items():
        if isinstance(v, dict):
            _nested_approx(got[k], v)
        else:
            assert got[k] == pytest.approx(v, rel=1e-12), k
            assert type(got[k]) is type(v) or isinstance(v, float), k
    return True


def test_handover_rates_count_the_given_kinds_and_take_one_observation_time_for_all():
    ev = events((1.0, 0, B, 0, 0, 0, 1), (2.0, 1, S, 0, 1, 1, 3), (3.0, 1, "rlf", 1, 3, -1, -1))
    r = handover_rates(ev, observed_s=30.0, n_ut=3, kinds=(S, "rlf"))
    assert r["by_kind"] == {S: pytest.approx(1 / 1.5), "rlf": pytest.approx(1 / 1.5)}
    np.testing.assert_allclose(r["per_ut"], [0.0, 4.0, 0.0])  # 2 events in half a minute
    with pytest.raises(ValueError, match="^observed_s must be > 0 for every UT$"):
        handover_rates(ev, observed_s=np.array([60.0, 0.0, 60.0]), n_ut=3)


def test_unknown_levels_are_refused_by_name():
    ev = events((1.0, 0, B, 0, 0, 0, 1))
    with pytest.raises(ValueError, match="^level = 'beam'; use 'cell' or 'satellite'$"):
        ping_pong_mask(ev, 1.0, "beam")
    with pytest.raises(ValueError, match="^level = 'cell'; use 'beam' or 'satellite'$"):
        stays(dwells((0, 0, 0, 0.0, 1.0, False, False)), "cell")


def test_ping_pong_fraction_without_handovers_is_nan_and_counts_only_its_level():
    ev = events((1.0, 0, "outage_start", 0, 0, -1, -1), (1.5, 0, "outage_end", -1, -1, 0, 0))
    frac, n_pp, n_ho = ping_pong_fraction(ev, 1.0)
    assert math.isnan(frac) and (n_pp, n_ho) == (0, 0)
    ev = events((1.0, 0, B, 0, 0, 0, 1), (1.2, 0, B, 0, 1, 0, 0))
    assert ping_pong_fraction(ev, 1.0, "satellite")[1:] == (0, 0)
    assert math.isnan(ping_pong_fraction(ev, 1.0, "satellite")[0])


def test_defaults_are_one_second_windows_at_cell_and_beam_level():
    """TR 36.839's minimum time of stay (1 s) and leolink's 1 s MRO window: a return after
    1.5 s is no ping-pong, a failure 1.5 s after a handover is too late; stays are beams."""
    from leolink.sim.handover.kpi import mro_classes, mro_counts

    ev = events((1.0, 0, B, 0, 0, 0, 1), (2.5, 0, B, 0, 1, 0, 0), (4.0, 0, "rlf", 0, 0, -1, -1),
                (4.5, 0, "outage_end", -1, -1, 0, 2))  # fmt: skip
    assert not ping_pong_mask(ev).any() and ping_pong_fraction(ev)[1] == 0
    assert ping_pong_mask(ev, 1.6).tolist() == [False, True, False, False]
    assert mro_counts(ev)["too_late_count"] == 1 and mro_classes(ev)["too_late"][2]
    assert mro_counts(ev, 1.6)["wrong_cell_count"] == 1  # (0, 2): neither (0, 1) nor (0, 0)
    # at satellite level (0, 2) is the source satellite: too early, not wrong cell
    assert mro_counts(ev, 1.6, "satellite")["too_early_count"] == 1
    dw = dwells((0, 0, 0, 0.0, 1.0, False, False), (0, 0, 1, 1.0, 3.0, False, False))
    assert stays(dw)["end_s"].tolist() == [1.0, 3.0]  # beams: not joined
    assert time_of_stay(dw)["durations_s"].tolist() == [1.0, 2.0]
    kpi = summarize(ev, dw, 60.0, 1)
    assert (kpi["ping_pong_count"], kpi["too_late_count"], kpi["mro_window_s"]) == (0, 1, 1.0)


def test_ping_pong_needs_the_previous_serving_change_to_be_a_handover():
    """A handover failure names both cells but is no handover: a handover back to where it
    started is not a return of a ping-pong pair."""
    ev = events(
        (1.0, 0, B, 0, 0, 0, 1),
        (1.2, 0, "handover_failure", 0, 1, 0, 2),
        (1.4, 0, B, 0, 2, 0, 1),
    )
    assert ping_pong_mask(ev, 1.0).tolist() == [False, False, False]


def test_ping_pong_compares_each_pair_not_the_first_handover():
    """Satellites 1 -> 2 at 0 s, 2 -> 3 at 5 s, 3 -> 2 at 5.3 s: only the last returns, to
    satellite 2, 0.3 s after leaving it (the first handover is 5.3 s earlier)."""
    ev = events((0.0, 0, S, 1, 0, 2, 0), (5.0, 0, S, 2, 0, 3, 0), (5.3, 0, S, 3, 0, 2, 0))
    for level in ("cell", "satellite"):
        assert ping_pong_mask(ev, 1.0, level).tolist() == [False, False, True]


def test_stays_of_an_empty_table_and_the_ut_of_each_joined_stay():
    empty = dwells()
    empty = {k: np.zeros(0, float if k.endswith("_s") else int) for k in empty}
    for level in ("beam", "satellite"):
        got = time_of_stay(empty, level)
        assert (got["n_complete"], got["n_censored"]) == (0, 0) and math.isnan(got["mean_s"])
        assert all(len(v) == 0 for v in stays(empty, level).values())
    dw = dwells((4, 7, 0, 0.0, 2.0, False, False), (2, 7, 1, 2.0, 3.0, False, False),
                (4, 7, 1, 2.0, 3.0, False, True))  # fmt: skip
    st = stays(dw, "satellite")
    assert st["ut_id"].tolist() == [2, 4] and st["end_s"].tolist() == [3.0, 3.0]
    assert st["censored_end"].tolist() == [False, True]


def test_mro_never_borrows_another_uts_handover_or_re_establishment():
    from leolink.sim.handover.kpi import mro_counts

    # UT 0 hands over; UT 1 fails 0.5 s later without a handover of its own: too late
    got = _classes((10.0, 0, "sat_handover", S_, T_), (10.5, 1, "rlf", X_, NONE),
                   (11.0, 1, "outage_end", NONE, S_))  # fmt: skip
    assert (got["too_late_count"], got["too_early_count"]) == (1, 0)
    # one UT, never re-established: no class, whatever its handover
    ev = _mro_events((10.0, 0, "sat_handover", S_, T_), (10.5, 0, "rlf", T_, NONE))
    assert sum(mro_counts(ev).values()) == 0


def test_a_handover_failure_re_established_in_a_third_cell_is_wrong_cell():
    got = _classes((10.0, 0, "sat_handover", S_, T_), (10.03, 0, "handover_failure", S_, T_),
                   (11.0, 0, "outage_end", NONE, X_))  # fmt: skip
    assert (got["handover_failure_count"], got["wrong_cell_count"], got["too_early_count"]) == (
        1, 1, 0)  # fmt: skip


def test_handover_rates_with_no_counted_kind_are_zero():
    r = handover_rates(events((1.0, 0, B, 0, 0, 0, 1)), observed_s=60.0, n_ut=2, kinds=())
    assert r["overall"] == 0.0 and r["per_ut"].tolist() == [0.0, 0.0] and r["by_kind"] == {}
