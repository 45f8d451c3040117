"""Tests of leolink.arrays: fast 2-D nonzero, row gathers and unique keys against numpy's own."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.arrays import (
    FLAT_MIN_SIZE,
    any_per_group,
    nonzero_2d,
    reduce_groups,
    take_rows,
    unique_inverse,
)


def _same_as_numpy(a):
    rows, cols = nonzero_2d(a)
    want_rows, want_cols = np.nonzero(a)
    assert rows.dtype == want_rows.dtype and cols.dtype == want_cols.dtype
    np.testing.assert_array_equal(rows, want_rows)
    np.testing.assert_array_equal(cols, want_cols)


@settings(max_examples=200, deadline=None)
@given(
    n_row=st.integers(0, 300),
    n_col=st.integers(0, 40),
    density=st.floats(0.0, 1.0),
    layout=st.sampled_from(["c", "transposed", "strided"]),
    dtype=st.sampled_from([bool, np.int32, float]),
    seed=st.integers(0, 2**32 - 1),
)
def test_nonzero_2d_is_numpys_nonzero(n_row, n_col, density, layout, dtype, seed):
    """Both paths (below and above FLAT_MIN_SIZE entries), any memory layout."""
    rng = np.random.default_rng(seed)
    a = (rng.random((n_row, n_col)) < density).astype(dtype)
    if layout == "transposed":
        a = a.T
    elif layout == "strided":
        a = a[::2, ::-1]
    _same_as_numpy(a)


@pytest.mark.parametrize("shape", [(1000, 16), (13, 37177), (FLAT_MIN_SIZE, 1), (1, FLAT_MIN_SIZE)])
def test_nonzero_2d_on_the_tables_it_was_measured_on(shape):
    a = np.random.default_rng(7).random(shape) < 0.2
    assert a.size >= FLAT_MIN_SIZE  # the flat path
    _same_as_numpy(a)


@pytest.mark.parametrize("shape", [(5,), (2, 3, 4), ()])
def test_nonzero_2d_refuses_other_ranks(shape):
    with pytest.raises(ValueError, match=r"2-D array, not one of shape"):
        nonzero_2d(np.ones(shape, bool))


@settings(max_examples=200, deadline=None)
@given(
    lead=st.lists(st.integers(1, 6), min_size=1, max_size=3),
    trail=st.lists(st.integers(1, 4), min_size=0, max_size=2),
    n_index=st.integers(1, 3),
    n_pick=st.integers(0, 20),
    seed=st.integers(0, 2**32 - 1),
)
def test_take_rows_is_numpys_advanced_indexing(lead, trail, n_index, n_pick, seed):
    """Over one, two or three leading axes, rows repeated, in any order, also of a
    non-contiguous array (a transposed view)."""
    rng = np.random.default_rng(seed)
    shape = (*lead, *trail)
    n_index = min(n_index, len(lead))
    a = rng.normal(size=shape[::-1]).T if rng.random() < 0.5 else rng.normal(size=shape)
    index = [rng.integers(0, size, n_pick) for size in lead[:n_index]]
    got = take_rows(a, *index)
    want = a[tuple(index)]
    assert got.shape == want.shape and got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(0, 300),
    span=st.integers(1, 50),
    ordered=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_unique_inverse_is_numpys_unique(n, span, ordered, seed):
    """``unique_inverse`` against ``np.unique(return_inverse=True)``: sorted keys (its
    linear path, repeats and all) and unsorted ones (numpy's), empty and single keys."""
    keys = np.random.default_rng(seed).integers(-span, span, n)
    if ordered:
        keys = np.sort(keys)
    got_unique, got_inverse = unique_inverse(keys)
    want_unique, want_inverse = np.unique(keys, return_inverse=True)
    np.testing.assert_array_equal(got_unique, want_unique)
    np.testing.assert_array_equal(got_inverse, want_inverse)
    np.testing.assert_array_equal(got_unique[got_inverse], keys)


def test_any_per_group_of_a_satellites_beams():
    """Three beams a satellite: set in the first, last, middle or none of its beams."""
    mask = np.array([[1, 0, 0, 0, 0, 1, 0, 0, 0], [0, 1, 0, 0, 0, 0, 1, 1, 1]], bool)
    np.testing.assert_array_equal(any_per_group(mask, 3), [[1, 1, 0], [1, 0, 1]])
    np.testing.assert_array_equal(any_per_group(mask, 1), mask)
    assert any_per_group(np.zeros((4, 0), bool), 15).shape == (4, 0)


@settings(max_examples=100, deadline=None)
@given(
    lead=st.lists(st.integers(0, 5), min_size=0, max_size=2),
    n_group=st.integers(0, 8),
    size=st.integers(1, 16),
    density=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_any_per_group_is_numpys_any(lead, n_group, size, density, seed):
    mask = np.random.default_rng(seed).random((*lead, n_group * size)) < density
    got = any_per_group(mask, size)
    want = mask.reshape(*lead, n_group, size).any(axis=-1)
    assert got.shape == want.shape and got.dtype == bool
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("ufunc", [np.fmax, np.fmin, np.add])
def test_reduce_groups_is_numpys_reduce_along_the_group(ufunc):
    # NaN and infinities among the values: fmax/fmin ignore NaN, add propagates it
    rng = np.random.default_rng(7)
    x = rng.normal(size=(3, 4, 5 * 3))
    x[rng.random(x.shape) < 0.3] = np.nan
    x[0, 0, :3] = np.nan  # a whole group NaN
    x[1, 2, 4] = np.inf
    x[2, 3, 9] = -np.inf
    got = reduce_groups(ufunc, x, 3)
    want = ufunc.reduce(x.reshape(3, 4, 5, 3), axis=-1)
    assert got.shape == (3, 4, 5)
    np.testing.assert_array_equal(got, want)
