"""leolink.sim.candidates.Candidates: slot lookups against a loop over each row."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.sim.candidates import Candidates


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


@settings(max_examples=150, deadline=None)
@given(
    n_ut=st.integers(1, 40),
    n_slot=st.integers(0, 12),
    n_more=st.integers(0, 2),
    seed=st.integers(0, 2**32 - 1),
)
def test_slot_of_finds_each_rows_cell(n_ut, n_slot, n_more, seed):
    """Cells present, absent, -1 (which unused slots also hold) and other negatives; one
    array or several searched at once."""
    rng = np.random.default_rng(seed)
    table = _table(rng, n_ut, n_slot, n_cell=15)
    queries = [rng.integers(-2, 18, n_ut) for _ in range(1 + n_more)]
    got = table.slot_of(*queries)
    got = got if n_more else (got,)
    assert len(got) == 1 + n_more
    for q, slots in zip(queries, got, strict=True):
        assert slots.dtype == np.int64
        np.testing.assert_array_equal(slots, _slot_loop(table, q))
        hit = slots >= 0
        np.testing.assert_array_equal(table.value_at(q)[hit], table.snr_db[hit, slots[hit]])
        assert np.isnan(table.value_at(q)[~hit]).all()
