"""The percentile histograms (sim/histograms.py) by hand: the slots at the edges of the
bins and the values the slots stand for, the refusals, what is read (float32 values,
blocks of any shape, int32 groups) and counted (integers), a percentile that falls on a
rank beside an infinite sample, the keys of many groups and of their documented form,
and the bound on the pending keys. Written from the histograms' first mutation run
(2026-12-07; the percentiles against numpy are in test_kpi.py)."""

import warnings

import numpy as np
import pytest

from leolink.sim.histograms import GroupedPercentileHistogram, PercentileHistogram


def test_slot_values_are_the_bin_middles_and_infinite_outside_the_bins():
    h = PercentileHistogram(-10.0, 10.0, 0.5)  # 40 bins of 0.5, slots 1 .. 40
    got = h.slot_values(np.array([0, 1, 2, 39, 40, 41]))
    np.testing.assert_array_equal(got, [-np.inf, -9.75, -9.25, 9.25, 9.75, np.inf])


def test_a_value_at_hi_is_above_the_bins_where_the_division_rounds_below_the_bin_count():
    """43 bins of 0.1 from 0 end at 4.3, but 4.3 / 0.1 is 42.99999999999999 in floats:
    4.3 itself is still above the bins (slot 44), the float below it in the last bin."""
    h = PercentileHistogram(0.0, 4.3, 0.1)
    assert h.n_bins == 43 and h.hi == 4.3
    np.testing.assert_array_equal(h.slots([4.3, np.nextafter(4.3, 0.0), 4.25]), [44, 43, 43])


def test_a_float32_value_falls_in_the_bin_of_its_exact_value():
    """float32(50.01) = 50.0099983... lies below the edge at 50.01, in the bin [50.00,
    50.01): slot 1 + 11,000 of bins of 0.01 from -60 (in float32 arithmetic, 110.01 /
    0.01 would round up to the next bin)."""
    h = PercentileHistogram(-60.0, 80.0, 0.01)
    assert float(np.float32(50.01)) < 50.01 - 1e-6
    np.testing.assert_array_equal(h.slots(np.float32([50.01, -59.995])), [11001, 1])


def test_a_block_of_any_shape_counts_each_of_its_values():
    h = PercentileHistogram(-10.0, 10.0, 0.5)
    h.add(np.array([[-10.0, -9.9, np.nan], [9.9, 10.0, 0.1]]))  # (epochs, UTs)
    # slots by hand: -10 and -9.9 in the first bin, NaN (-inf) below, 9.9 in the last
    # bin, 10 above, 0.1 in bin 21 ([0, 0.5))
    expected = np.bincount([1, 1, 0, 40, 41, 21], minlength=42)
    np.testing.assert_array_equal(h.counts, expected)


@pytest.mark.parametrize(
    ("lo", "hi", "resolution"),
    [(1.0, 1.0, 0.5), (1.0, 0.0, 0.5), (0.0, 1.0, 0.0), (0.0, 1.0, -0.5)],
)
def test_an_empty_or_reversed_range_or_a_resolution_not_above_zero_is_refused(lo, hi, resolution):
    with pytest.raises(ValueError, match=r"^need hi > lo and resolution > 0 \(got "):
        PercentileHistogram(lo, hi, resolution)


def test_a_nan_unserved_value_is_refused_with_its_message():
    with pytest.raises(ValueError, match=r"^unserved_value must be a number or \+-inf, not NaN$"):
        PercentileHistogram(-10.0, 10.0, 0.5, unserved_value=np.nan)


def test_merging_histograms_of_other_bins_is_refused():
    h = PercentileHistogram(-10.0, 10.0, 0.5)
    others = [(-10.0, 10.0, 0.25), (-9.0, 10.0, 0.5), (-10.0, 11.0, 0.5)]
    for lo, hi, resolution in others:
        other = PercentileHistogram(lo, hi, resolution)
        other.add([0.0])
        with pytest.raises(ValueError, match="^cannot merge histograms with different bins$"):
            h.merge(other)
    assert h.n == 0


def test_counts_are_integers():
    """Counts of samples: exact integers (a float64 count stops counting at 2^53)."""
    h = PercentileHistogram(-10.0, 10.0, 0.5)
    h.add([0.0, 1.0])
    g = GroupedPercentileHistogram(3, -10.0, 10.0, 0.5)
    g.add(np.array([2, 2]), np.array([0.0, 1.0]))
    assert h.counts.dtype == np.int64 and g.counts().dtype == np.int64
    assert h.n == 2 and list(g.counts()) == [0, 0, 2]


def test_a_percentile_on_a_rank_is_that_sample_beside_an_infinite_neighbour():
    """Samples -inf, -inf (NaN: unserved), 1.25 (1.1's bin middle), +inf, +inf (above
    ``hi``). numpy's linear method at ``h = (n - 1) q / 100 = 4 q / 100``: q = 50 falls on
    rank 2 exactly, 1.25, though the next sample is infinite; between two infinities
    (q = 12.5, 87.5) the result is that infinity; between 1.25 and +inf (q = 62.5), +inf.
    No warnings (the interpolation's inf - inf is silenced)."""
    h = PercentileHistogram(-10.0, 10.0, 0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        h.add([np.nan, 50.0, 1.1, np.nan, 60.0])
        got = h.percentiles([0, 12.5, 50, 62.5, 87.5, 100])
    np.testing.assert_array_equal(got, [-np.inf, -np.inf, 1.25, np.inf, np.inf, np.inf])


def test_keys_of_many_groups_are_wide_enough_for_the_last_group():
    """200,000 groups x 14,002 slots (bins of 0.01 over [-60, 80), and the two outside) is
    beyond int32: samples of the last group and of group 3, the groups given as int32,
    are counted in their groups, at their bins."""
    g = GroupedPercentileHistogram(200_000, -60.0, 80.0, 0.01)
    g.add(np.array([199_999, 3], np.int32), np.array([0.0, 1.0]))
    counts = g.counts()
    assert counts[199_999] == 1 and counts[3] == 1 and counts.sum() == 2
    got = g.percentiles([50])
    assert got[199_999, 0] == pytest.approx(0.0, abs=0.005 + 1e-9)
    assert got[3, 0] == pytest.approx(1.0, abs=0.005 + 1e-9)


def test_keys_in_their_documented_form_count_in_their_group_and_slot():
    """``add_keys`` takes ``group * (n_bins + 2) + slot``: 20 bins of 0.5 over [-5, 5), 22
    slots a group. Group 1's slot 3 is the bin [-4.0, -3.5) (middle -3.75); group 2's
    slot 21, twice, is above the bins (+inf)."""
    g = GroupedPercentileHistogram(3, -5.0, 5.0, 0.5)
    g.add_keys(np.array([1 * 22 + 3, 2 * 22 + 21, 2 * 22 + 21]))
    np.testing.assert_array_equal(g.counts(), [0, 1, 2])
    got = g.percentiles([50])[:, 0]
    assert np.isnan(got[0]) and got[1] == -3.75 and got[2] == np.inf


def test_pending_keys_stay_within_the_table_or_min_pending():
    """The pending buffer of new keys is compacted once it holds more than the table (or
    ``MIN_PENDING``): added one sample at a time, it never grows past that."""
    g = GroupedPercentileHistogram(3, -5.0, 5.0, 0.5)
    g.MIN_PENDING = 10
    rng = np.random.default_rng(4)
    for _ in range(100):
        g.add(rng.integers(0, 3, 1), rng.normal(0.0, 2.0, 1))
        pending = sum(k.size for k in g._pending)
        assert pending <= max(g._keys.size, g.MIN_PENDING)
    assert g.counts().sum() == 100
