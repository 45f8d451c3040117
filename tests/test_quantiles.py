"""leolink.sim.quantiles against numpy.median and numpy.percentile, bit for bit."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.sim.quantiles import median, percentile_of_sorted

# Finite values with repeats, signed zeros, subnormals and huge ones (the two middle
# values' sum may overflow, as numpy's does).
VALUES = st.lists(
    st.one_of(
        st.floats(allow_nan=False, allow_infinity=False),
        st.floats(-1e3, 1e3),
        st.sampled_from([0.0, -0.0, 1.0, 5e-324]),
    ),
    min_size=1,
    max_size=40,
)


def _same_bits(got, expected):
    assert type(got) is float
    assert np.array_equal(got, expected, equal_nan=True)
    assert np.signbit(got) == np.signbit(expected)


@settings(max_examples=300, deadline=None)
@given(VALUES)
def test_median_is_numpys(values):
    with np.errstate(all="ignore"):
        expected = np.median(np.array(values))
        _same_bits(median(values), expected)


@settings(max_examples=300, deadline=None)
@given(VALUES, st.one_of(st.sampled_from([0.0, 10.0, 50.0, 90.0, 100.0]), st.floats(0, 100)))
def test_percentile_of_sorted_is_numpys(values, q_percent):
    """Ranks below and above one half between two values (numpy's lerp computes those
    from different ends), on the rank, at 0 and at 100. (No -0.0: which of two equal
    zeros numpy's partition puts last is its own choice.)"""
    s = np.sort(np.array(values) + 0.0)
    with np.errstate(all="ignore"):
        expected = np.percentile(s, q_percent)
    _same_bits(percentile_of_sorted(s, q_percent), expected)


@pytest.mark.parametrize("values", [[-0.0], [-1.0, -0.0], [-2.0, -1.0, -0.0], [-0.0, 3.0]])
@pytest.mark.parametrize("q_percent", [0.0, 10.0, 50.0, 90.0, 100.0])
def test_percentile_of_sorted_gives_numpys_signed_zeros(values, q_percent):
    s = np.array(values)
    _same_bits(percentile_of_sorted(s, q_percent), np.percentile(s, q_percent))


def test_a_run_of_dwells_gives_numpys_statistics():
    """time_of_stay's median and deciles on real-shaped dwells (an even and an odd count)."""
    from leolink.sim.handover.kpi import time_of_stay

    for n in (7, 8):
        start = np.arange(n, dtype=float) * 3.0
        dur = np.linspace(0.5, 40.0, n) ** 1.3
        dwells = {
            "ut": np.zeros(n, np.int64),
            "beam": np.arange(n),
            "satellite": np.arange(n),
            "start_s": start,
            "end_s": start + dur,
            "censored_start": np.zeros(n, bool),
            "censored_end": np.zeros(n, bool),
        }
        got = time_of_stay(dwells, "beam")
        done = got["durations_s"]
        assert got["median_s"] == np.median(done)
        assert got["p10_s"] == np.percentile(done, 10)
        assert got["p90_s"] == np.percentile(done, 90)
