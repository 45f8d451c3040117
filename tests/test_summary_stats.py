"""leolink.io.summary.stats: DbStats, running_sum and group_fmax against loops over the
same stream of adds (value after value, in order)."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.io.summary.stats import DbStats, epoch_major, group_fmax, running_sum


def _stream(seed, n_ut, n_add):
    """Adds of a few UTs' values: spread over the histograms' range and beyond it, with
    NaN, infinities, bin edges and repeats (the order of a UT's values is the order of
    its running sum)."""
    rng = np.random.default_rng(seed)
    specials = np.array([np.nan, np.inf, -np.inf, -200.0, 200.0, 199.995, 0.0, 0.05, -0.05])
    adds = []
    for _ in range(n_add):
        n = int(rng.integers(0, 60))
        ut = rng.integers(0, n_ut, n)
        v = np.where(rng.random(n) < 0.2, rng.choice(specials, n), rng.normal(5, 40, n))
        adds.append((ut, v))
    return adds


#: Per-UT sums added in one order (DbStats's running sum) and by math.fsum (exact).
SUM_REL = 1e-12


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_ut=st.integers(1, 9), n_add=st.integers(1, 12))
def test_db_stats_count_and_sum_each_uts_finite_values(seed, n_ut, n_add):
    """Counts and sums against a loop over the stream (finite values only); the pooled
    histogram holds every finite value once."""
    stats = DbStats(n_ut)
    values = [[] for _ in range(n_ut)]
    for ut, v in _stream(seed, n_ut, n_add):
        stats.add(ut, v)
        for u, x in zip(ut, v, strict=True):
            if math.isfinite(x):
                values[u].append(x)
    np.testing.assert_array_equal(stats.count, [len(x) for x in values])
    want = [math.fsum(x) for x in values]
    np.testing.assert_allclose(stats.sum, want, rtol=SUM_REL, atol=1e-9)
    assert stats.pooled.counts.sum() == sum(len(x) for x in values)


def _sequential_sum(total, group, values):
    """The running sums value after value, each group's from 0.0 + its total (Python
    floats: the reference rounding)."""
    out = [0.0 + float(t) for t in total]
    for g, v in zip(group.tolist(), values.tolist(), strict=True):
        out[g] += v
    return np.array(out)


def _rows(rng, n_group, n_epoch, epoch_major_layout):
    """Group ids of ``n_epoch`` epochs of ``n_group`` groups: epoch by epoch, or shuffled;
    values whose order of addition shows (large and small, -0.0, NaN)."""
    group = np.tile(np.arange(n_group), n_epoch)
    if not epoch_major_layout:
        group = rng.permutation(group)
    pool = np.array([1e16, 1.0, -1e16, 3.5, -0.0, 0.0, 1e-300, np.nan, -2.25, 7e15])
    return group, rng.choice(pool, group.size) * rng.choice([1.0, 1.0 + 2**-52], group.size)


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_group=st.integers(1, 7),
    n_epoch=st.integers(1, 9),
    layout=st.booleans(),
)
def test_running_sum_and_group_fmax_match_the_loop_in_either_layout(seed, n_group, n_epoch, layout):
    """Epoch-major rows take the column path, shuffled ones the scattered one: both give
    the bits of adding value after value from 0.0 + total (-0.0 totals included), and
    np.fmax.at's maxima (NaN ignored)."""
    rng = np.random.default_rng(seed)
    group, values = _rows(rng, n_group, n_epoch, layout)
    finite = np.nan_to_num(values, nan=1.0)
    total = rng.choice([-0.0, 0.0, 1e16, -3.0], n_group)
    got = running_sum(total, group, finite)
    want = _sequential_sum(total, group, finite)
    np.testing.assert_array_equal(got, want)
    assert (np.signbit(got) == np.signbit(want)).all()
    start = rng.choice([np.nan, -1.0, 5.0], n_group)
    fast, slow = start.copy(), start.copy()
    group_fmax(fast, group, values)
    np.fmax.at(slow, group, values)
    np.testing.assert_array_equal(fast, slow)


def test_epoch_major_is_each_group_once_per_epoch_in_order():
    assert epoch_major(np.tile(np.arange(4), 3), 4)
    assert epoch_major(np.arange(4), 4)
    assert not epoch_major(np.tile([1, 0, 2, 3], 3), 4)  # a reordered epoch
    assert not epoch_major(np.arange(4), 5)  # a partial epoch
    assert not epoch_major(np.zeros(0, int), 4) and not epoch_major(np.arange(3), 0)
    assert not epoch_major(np.r_[np.arange(4), np.arange(4)[::-1]], 4)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_ut=st.integers(1, 6), n_epoch=st.integers(1, 8))
def test_db_stats_sum_of_epoch_major_rows_with_nans_is_the_finite_values_in_order(
    seed, n_ut, n_epoch
):
    """DbStats sums epoch-major rows with non-finite values among them (summed as -0.0)
    to the bits of adding the finite values alone, in order."""
    rng = np.random.default_rng(seed)
    stats, ut_all, v_all = DbStats(n_ut), [], []
    for _ in range(3):
        ut, v = _rows(rng, n_ut, n_epoch, True)
        v[rng.random(v.size) < 0.2] = np.inf
        stats.add(ut, v)
        ut_all.append(ut)
        v_all.append(v)
    ut, v = np.concatenate(ut_all), np.concatenate(v_all)
    ok = np.isfinite(v)
    want = _sequential_sum(np.zeros(n_ut), ut[ok], v[ok])
    np.testing.assert_array_equal(stats.sum, want)
    assert (np.signbit(stats.sum) == np.signbit(want)).all()
    np.testing.assert_array_equal(stats.count, np.bincount(ut[ok], minlength=n_ut))
