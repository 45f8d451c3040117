"""leolink.io.summary.stats.DbStats: its compiled loop (leolink._kernels.db_stats_add)
against its numpy code, on the same stream of adds."""

from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import leolink.compiled
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


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_ut=st.integers(1, 9), n_add=st.integers(1, 12))
def test_compiled_db_stats_are_the_numpy_ones(seed, n_ut, n_add):
    """Counts, sums (bit for bit: the same additions in the same order), the pooled
    histogram and the per-UT histogram's table."""
    pytest.importorskip("leolink._kernels")  # (built at install: setup.py)
    compiled, plain = DbStats(n_ut), DbStats(n_ut)
    for ut, v in _stream(seed, n_ut, n_add):
        assert leolink.compiled.use(max(v.size, 1))
        compiled.add(ut, v)
        with mock.patch.object(leolink.compiled, "use", lambda n: False):
            plain.add(ut, v)
    np.testing.assert_array_equal(compiled.count, plain.count)
    np.testing.assert_array_equal(compiled.sum, plain.sum)
    np.testing.assert_array_equal(compiled.pooled.counts, plain.pooled.counts)
    compiled.per_ut._compact()
    plain.per_ut._compact()
    np.testing.assert_array_equal(compiled.per_ut._keys, plain.per_ut._keys)
    np.testing.assert_array_equal(compiled.per_ut._counts, plain.per_ut._counts)
