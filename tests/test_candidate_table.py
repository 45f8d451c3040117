"""leolink.sim.candidates.table.Candidates: slot lookups against a loop over each row."""

import contextlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.sim.candidates.table import Candidates

PATHS = ["compiled", "numpy"]


@contextlib.contextmanager
def _path(name, table):
    """Within: ``table``'s lookups take the path ``name`` (the compiled loops or numpy, as
    ``LEOLINK_JIT=0``)."""
    import leolink.compiled

    saved = leolink.compiled.use
    leolink.compiled.use = (lambda n: False) if name == "numpy" else saved
    try:
        yield
    finally:
        leolink.compiled.use = saved


def _table(rng, n_ut, n_slot, n_cell):
    """Rows of distinct cells in random slots, -1 in the unused ones."""
    cell = np.full((n_ut, n_slot), -1, np.int64)
    for i in range(n_ut):
        k = rng.integers(0, min(n_slot, n_cell) + 1)
        cell[i, rng.permutation(n_slot)[:k]] = rng.choice(n_cell, k, replace=False)
    return Candidates(cell, rng.normal(size=(n_ut, n_slot)))


def _slot_loop(table, cells):
    out = []
    for row, c in zip(table.cell, cells, strict=True):
        where = [j for j, x in enumerate(row) if c >= 0 and x == c]
        out.append(where[0] if where else -1)
    return np.array(out, np.int64)


@pytest.mark.parametrize("path", PATHS)
@settings(max_examples=150, deadline=None)
@given(
    n_ut=st.integers(1, 40),
    n_slot=st.integers(0, 12),
    n_more=st.integers(0, 2),
    seed=st.integers(0, 2**32 - 1),
)
def test_slot_of_finds_each_rows_cell(path, n_ut, n_slot, n_more, seed):
    """Cells present, absent, -1 (which unused slots also hold) and other negatives; one
    array or several searched at once."""
    rng = np.random.default_rng(seed)
    table = _table(rng, n_ut, n_slot, n_cell=15)
    queries = [rng.integers(-2, 18, n_ut) for _ in range(1 + n_more)]
    with _path(path, table):
        got = table.slot_of(*queries)
    got = got if n_more else (got,)
    assert len(got) == 1 + n_more
    for q, slots in zip(queries, got, strict=True):
        assert slots.dtype == np.int64
        np.testing.assert_array_equal(slots, _slot_loop(table, q))
        hit = slots >= 0
        np.testing.assert_array_equal(table.value_at(q)[hit], table.snr_db[hit, slots[hit]])
        assert np.isnan(table.value_at(q)[~hit]).all()


def _best_loop(table):
    """Best finite-or-+inf cell of each row, ties to the lowest cell id; -1/NaN if none."""
    cells, values = [], []
    for row_cell, row_snr in zip(table.cell, table.snr_db, strict=True):
        ok = [(v, -c) for c, v in zip(row_cell, row_snr, strict=True) if c >= 0 and v > -np.inf]
        v, c = max(ok) if ok else (np.nan, 1)
        cells.append(-c)
        values.append(v)
    return np.array(cells, np.int64), np.array(values)


@pytest.mark.parametrize("path", PATHS)
@settings(max_examples=150, deadline=None)
@given(
    n_ut=st.integers(1, 30),
    n_slot=st.sampled_from([0, 1, 1, 2, 3, 7]),  # one slot per UT: the best cell only
    seed=st.integers(0, 2**32 - 1),
)
def test_best_and_at_against_a_loop_over_each_row(path, n_ut, n_slot, seed):
    """NaN, -inf (a null) and +inf SNRs, ties; ``at`` of every slot and of -1."""
    rng = np.random.default_rng(seed)
    table = _table(rng, n_ut, n_slot, n_cell=15)
    specials = rng.choice([np.nan, -np.inf, np.inf, 1.5, -0.0], table.snr_db.shape)
    table.snr_db[:] = np.where(rng.random(table.snr_db.shape) < 0.4, specials, table.snr_db)
    table.snr_db[table.cell < 0] = np.nan  # unused slots
    with _path(path, table):
        cell, value = table.best()
    want_cell, want_value = _best_loop(table)
    assert cell.dtype == np.int64
    np.testing.assert_array_equal(cell, want_cell)
    np.testing.assert_array_equal(value, want_value)
    for slot in [*(np.full(n_ut, j) for j in range(n_slot)), np.full(n_ut, -1)]:
        slot = np.where(rng.random(n_ut) < 0.3, -1, slot)
        want = np.array([table.snr_db[i, j] if j >= 0 else np.nan for i, j in enumerate(slot)])
        with _path(path, table):
            got = table.at(slot)
        np.testing.assert_array_equal(got, want)


def test_a_query_of_another_length_broadcasts_over_the_rows():
    """A one-cell query broadcasts over the rows as numpy's comparison does."""
    cell = np.array([[3, 4], [4, 5], [6, 4]], np.int64)
    table = Candidates(cell, np.zeros(cell.shape))
    np.testing.assert_array_equal(table.slot_of(np.array([4])), np.array([1, 0, 1]))


@settings(max_examples=100, deadline=None)
@given(n_ut=st.integers(1, 12), n_entry=st.integers(0, 40), sort=st.booleans(),
       seed=st.integers(0, 2**32 - 1))  # fmt: skip
def test_from_entries_puts_each_uts_entries_in_its_row_in_order(n_ut, n_entry, sort, seed):
    """Entries sorted by UT (as the search gives them) or in any order: row ``i`` holds
    UT ``i``'s entries in the order given, -1/NaN after them (a loop over the entries)."""
    rng = np.random.default_rng(seed)
    ut = rng.integers(0, n_ut, n_entry)
    if sort:
        ut = np.sort(ut)
    cell = rng.permutation(10 * n_entry + 1)[:n_entry].astype(np.int64)  # distinct
    snr = rng.normal(size=n_entry)
    table = Candidates.from_entries(n_ut, ut, cell, snr)
    rows = [[(c, v) for u, c, v in zip(ut, cell, snr, strict=True) if u == i] for i in range(n_ut)]
    assert table.n_slot == max([len(r) for r in rows], default=0)
    for i, row in enumerate(rows):
        want_cell = [c for c, _ in row] + [-1] * (table.n_slot - len(row))
        want_snr = [v for _, v in row] + [np.nan] * (table.n_slot - len(row))
        np.testing.assert_array_equal(table.cell[i], want_cell)
        np.testing.assert_array_equal(table.snr_db[i], want_snr)
