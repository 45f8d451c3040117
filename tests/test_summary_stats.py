"""leolink.io.summary.stats.DbStats against a loop over the same stream of adds."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.io.summary.stats import DbStats


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
