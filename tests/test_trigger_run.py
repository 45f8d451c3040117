"""Trigger policies on sparse per-UT tables behave exactly as on one dense axis of all cells.

The reference is the dense driver of :mod:`leolink.sim.handover.decisions` (every cell of every
satellite, NaN where not measured, one layer-3 filter per cell), the representation the
TS 38.331 bookkeeping was written for; the run's tables list only the visible
satellites, in shuffled slots, with satellites entering and leaving.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from leolink.sim.candidates.table import Candidates
from leolink.sim.handover.decisions import ConditionalHandover, TriggerPolicy
from leolink.sim.handover.local_axis import LocalAxis
from leolink.sim.handover.measurements import L3Filter, L3State, l3_update
from leolink.sim.handover.trigger_run import TriggerRun
from leolink.sim.handover.triggers import A3, A4, A5, Epoch

N_SAT, N_BEAM, MIN_SNR_DB, DT_S = 6, 3, -10.0, 1.0


@pytest.mark.usefixtures("compiled_and_numpy")
def test_local_axis_finds_each_satellites_slot_as_a_scan_of_its_row():
    # Ragged rows (an empty one too); queries present, absent, negative and above every id:
    # the slot found (binary search per row compiled, one search over all rows in numpy)
    # is the one a plain scan of the row finds.
    rng = np.random.default_rng(44)
    ut = rng.integers(0, 40, 600)
    sat = rng.integers(0, 90, 600)
    axis = LocalAxis.union(41, 1, ut, sat)
    rows = rng.integers(0, 41, 3000)
    picked = axis.sats[rows, rng.integers(0, axis.n_local, rows.size)]
    query = np.where(rng.random(rows.size) < 0.5, picked, rng.integers(-3, 120, rows.size))
    got = axis._slot(rows, query)
    pairs = zip(rows, query, strict=True)
    hits = [np.flatnonzero((axis.sats[r] == q) & (q >= 0)) for r, q in pairs]
    want = [h[0] if h.size else -1 for h in hits]
    np.testing.assert_array_equal(got, want)
    assert 0.3 < np.mean(got >= 0) < 0.7


@pytest.mark.usefixtures("compiled_and_numpy")
def test_local_axis_maps_cells_both_ways_and_carries_values_by_satellite():
    axis = LocalAxis.union(2, N_BEAM, [0, 0, 1, 0], [4, 1, 2, 4])
    np.testing.assert_array_equal(axis.sats, [[1, 4], [2, -1]])
    # no satellite (none given, or only -1): no slot at all
    for ut, sat in (([], []), ([0, 2], [-1, -1])):
        assert LocalAxis.union(3, N_BEAM, ut, sat).sats.shape == (3, 0)
    # global cell 4 * 3 + 2 = 14 is local cell 1 * 3 + 2 = 5 of UT 0; UT 1 has no sat 4
    np.testing.assert_array_equal(axis.local_cell([14, 14]), [5, -1])
    np.testing.assert_array_equal(axis.global_cell([5, 1]), [14, 7])
    new = LocalAxis.union(2, N_BEAM, [0, 0, 1], [0, 4, 2])  # sat 1 left UT 0, sat 0 came
    per_sat = np.array([[10.0, 40.0], [20.0, -1.0]])
    np.testing.assert_array_equal(
        axis.remap(new, per_sat, np.nan), [[np.nan, 40.0], [20.0, np.nan]]
    )
    per_cell = np.arange(12.0).reshape(2, 6)
    got = axis.remap(new, per_cell, -1.0)
    np.testing.assert_array_equal(got[0], [-1, -1, -1, 3, 4, 5])  # sat 4's beams follow it
    np.testing.assert_array_equal(got[1, :3], [6, 7, 8])


@pytest.mark.parametrize("share", [0.03, 0.6])  # mostly the fill (carried value by value)
def test_local_axis_carries_sparse_and_dense_arrays_as_a_lookup_by_satellite(share):
    """``remap`` of per-cell, per-satellite and vector arrays (NaN or False fill, a few of
    their values set or most of them) against a lookup of each new slot's satellite in
    the old row: its values where it was there, the fill where not."""
    from leolink.sim.handover import local_axis

    rng = np.random.default_rng(45)
    n_ut, nb = 30, 3
    axis = LocalAxis.union(n_ut, nb, rng.integers(0, n_ut, 600), rng.integers(0, 40, 600))
    new = LocalAxis.union(n_ut, nb, rng.integers(0, n_ut, 600), rng.integers(20, 60, 600))
    set_ = rng.random((n_ut, axis.n_cand, 3)) < share
    arrays = [
        (np.where(set_[..., 0], rng.normal(size=set_.shape[:2]), np.nan), np.nan),
        (set_[..., 1], False),
        (np.where(set_[:, : axis.n_local, 2], 1.5, np.nan), np.nan),  # per satellite
        (np.where(set_[..., :1], rng.normal(size=set_.shape), np.nan), np.nan),  # (x, y, z)
    ]
    assert (np.mean(set_) < local_axis.SPARSE_SHARE) == (share < 0.1)
    n_kept = 0  # values carried, not the fill
    for values, fill in arrays:
        got = axis.remap(new, values, fill)
        unit = nb if values.shape[1] == axis.n_cand else 1
        want = np.full((n_ut, new.n_local * unit) + values.shape[2:], fill, values.dtype)
        for u in range(n_ut):
            for slot, sat in enumerate(new.sats[u]):
                old = np.flatnonzero((axis.sats[u] == sat) & (sat >= 0))
                if old.size:
                    want[u, slot * unit : (slot + 1) * unit] = values[
                        u, old[0] * unit : (old[0] + 1) * unit
                    ]
        np.testing.assert_array_equal(got, want)
        assert got.dtype == values.dtype
        n_kept += np.count_nonzero(want if fill is False else ~np.isnan(want))
    assert n_kept > 30


@pytest.mark.usefixtures("compiled_and_numpy")
def test_local_axis_values_put_each_cell_at_its_local_cell_and_leave_out_the_others():
    axis = LocalAxis.union(2, 2, [0, 0, 1], [3, 7, 5])  # sats [[3, 7], [5, -1]], 2 beams
    # UT 0: sat 3 beam 0, sat 5 beam 1 (not on its axis), sat 7 beam 1; UT 1: sat 5 beam 0
    table = Candidates(np.array([[6, 11, 15], [10, -1, -1]]),
                       np.array([[1.0, 2.0, 3.0], [4.0, np.nan, np.nan]]))  # fmt: skip
    np.testing.assert_array_equal(
        axis.values(table), [[1.0, np.nan, np.nan, 3.0], [4.0, np.nan, np.nan, np.nan]]
    )
    assert axis.values(table, fill=0.0)[1].tolist() == [4.0, 0.0, 0.0, 0.0]
    # one slot a UT (the flat table's entries are then its rows), an integer fill: UT 0's
    # sat 7 beam 1 at its local cell 3, UT 1's sat 5 beam 0 at 0, the values kept as floats
    one = Candidates(np.array([[15], [10]]), np.array([[2.5], [4.5]]))
    np.testing.assert_array_equal(axis.values(one, fill=0), [[0, 0, 0, 2.5], [4.5, 0, 0, 0]])


def _walks(seed, n_t=80, n_ut=12):
    """Dense SNR (n_t, n_ut, n_sat * n_beam): random walks, whole satellites unseen (NaN)
    for stretches, so satellites leave and re-enter the tables."""
    rng = np.random.default_rng(seed)
    snr = 5.0 + np.cumsum(rng.normal(0.0, 1.5, (n_t, n_ut, N_SAT * N_BEAM)), axis=0) / 2
    seen = np.ones((n_t, n_ut, N_SAT), bool)
    for _ in range(40):
        t0, ut, sat = rng.integers(0, n_t), rng.integers(0, n_ut), rng.integers(0, N_SAT)
        seen[t0 : t0 + rng.integers(1, 12), ut, sat] = False
    snr[~np.repeat(seen, N_BEAM, axis=2)] = np.nan
    return snr


def _sparse(dense, rng):
    """The table of the seen satellites' cells, slots shuffled per UT."""
    ut, cell = np.nonzero(np.isfinite(dense))
    order = rng.permutation(ut.size)
    return Candidates.from_entries(dense.shape[0], ut[order], cell[order], dense[ut, cell][order])


def _dense_run(policy, snr, l3):
    """Reference: the policy on the dense axis, executing every target at once."""
    n_t, n_ut, n_cand = snr.shape
    state, filt = policy.initial_state(n_ut, n_cand, N_BEAM), L3State.initial(n_ut, n_cand)
    serving, path = np.full(n_ut, -1), []
    for k in range(n_t):
        usable = snr[k] >= MIN_SNR_DB
        # Only detected cells (at or above the threshold) are measured and filtered.
        filt, meas = l3_update(filt, k * DT_S, np.where(usable, snr[k], np.nan), l3)
        dec, state = policy.decide(Epoch(k * DT_S, serving, meas), state, N_BEAM)
        best = np.argmax(np.where(usable, snr[k], -np.inf), axis=1)
        best = np.where(usable.any(axis=1), best, -1)
        ok = usable[np.arange(n_ut), np.maximum(serving, 0)] & (serving >= 0)
        serving = np.where(ok, np.where(dec.target >= 0, dec.target, serving), best)
        path.append(serving.copy())
    return np.array(path)


def _sparse_run(policy, snr, l3, seed=0):
    engine = SimpleNamespace(n_beam=N_BEAM, codebook=SimpleNamespace(u_xy=np.zeros((N_BEAM, 2))))
    run = TriggerRun(policy, l3, engine, MIN_SNR_DB, 6.371e6, None, DT_S, 100.0)
    rng = np.random.default_rng(seed)
    serving, path = np.full(snr.shape[1], -1), []
    for k in range(snr.shape[0]):
        table = _sparse(snr[k], rng)
        serving = run.target(k * DT_S, table, serving, None, None, None)
        serving = np.where(np.isfinite(table.masked(MIN_SNR_DB).value_at(serving)), serving, -1)
        path.append(serving.copy())
    return np.array(path)


POLICIES = {
    "a3_cell": lambda: TriggerPolicy(A3(1.0, 0.5, 2.0)),
    "a3_satellite": lambda: TriggerPolicy(A3(0.0, 1.0, 3.0), level="satellite"),
    "a4": lambda: TriggerPolicy(A4(6.0, 1.0, 2.0)),
    "a5": lambda: TriggerPolicy(A5(4.0, 6.0, 0.5, 1.0)),
    "cho": lambda: ConditionalHandover(A3(-1.0, 0.0, 1.0), [A3(1.0, 0.5, 2.0)], 2, 1.0),
}


@pytest.mark.parametrize("name", sorted(POLICIES))
@pytest.mark.parametrize("k", [0, 4])
def test_sparse_tables_choose_exactly_as_the_dense_axis(name, k):
    l3 = L3Filter(k, 1.0)
    for seed in range(3):
        snr = _walks(seed)
        dense = _dense_run(POLICIES[name](), snr, l3)
        sparse = _sparse_run(POLICIES[name](), snr, l3, seed)
        np.testing.assert_array_equal(sparse, dense)
        assert (np.diff(dense, axis=0) != 0).sum() > 10  # the walks do hand over


def test_a_satellite_missing_from_one_table_keeps_its_prepared_cell():
    """CHO, prepare A3(-3 dB, TTT 3 s), execute A3(+2 dB). Cell 0 serves from t = 0 (the
    first assignment; conditions run from t = 1 s), so cell 3 (satellite 1) is prepared
    at t = 4 s; at t = 5 s its satellite is missing from the table (not measured: the
    prepare condition's leaving run starts, 3 s to go); at t = 6 s it is back 3 dB above
    the serving cell: still prepared (TS 38.331 5.5.4.1: it leaves only after the leaving
    condition held for TTT), so the UT executes at once. Forgetting the satellite with its
    table would restart preparation and hand over at t = 9 s instead."""
    snr = np.full((12, 1, 6), np.nan)
    snr[:, 0, 0] = 5.0  # the serving cell, satellite 0
    snr[:5, 0, 3] = 4.0
    snr[6:, 0, 3] = 8.0
    policy = lambda: ConditionalHandover(A3(-3.0, 0.0, 3.0), [A3(2.0, 0.0, 0.0)])  # noqa: E731
    path = _sparse_run(policy(), snr, L3Filter(0, 1.0))[:, 0]
    assert list(path) == [0] * 6 + [3] * 6
    np.testing.assert_array_equal(path, _dense_run(policy(), snr, L3Filter(0, 1.0))[:, 0])


def test_a_cell_below_the_service_threshold_never_triggers_on_its_filtered_past():
    """Cell 3 is 8 dB above the serving cell for two epochs, then falls to -20 dB (below
    the -10 dB service threshold). Its layer-3 value (fc8, a = 1/4) is still 1 dB at
    t = 3 s, above the serving cell's 0 dB, but a cell that cannot serve is no candidate:
    no handover, and the run of its entering condition lapses."""
    snr = np.full((5, 1, 6), np.nan)
    snr[:, 0, 0] = 0.0
    snr[1:3, 0, 3] = 8.0
    snr[3:, 0, 3] = -20.0
    path = _sparse_run(TriggerPolicy(A3(0.0, 0.0, 2.0)), snr, L3Filter(8, 1.0))[:, 0]
    assert list(path) == [0] * 5
    snr[3:, 0, 3] = 8.0  # the same cell, still serving: triggers after TTT (t = 1 + 2 s)
    path = _sparse_run(TriggerPolicy(A3(0.0, 0.0, 2.0)), snr, L3Filter(8, 1.0))[:, 0]
    assert list(path) == [0, 0, 0, 3, 3]


def test_a_cell_detected_again_restarts_its_filter():
    """Cell 3 is unseen at t = 0 (the first assignment goes to cell 0, 5 dB), -20 dB at
    t = 1 s (below the -10 dB threshold: not detected), 8 dB from t = 2 s. A3(+2 dB, TTT
    0), fc8 (a = 1/4). Undetected, the cell's filter restarts: at t = 2 s F = 8 > 5 + 2
    and the UT hands over at once. Filtering the undetected -20 dB would give F = 0.75 x
    (-20) + 0.25 x 8 = -13 dB at t = 2 s, -7.75, -3.8, -0.9 dB after: no handover."""
    snr = np.full((6, 1, 6), np.nan)
    snr[:, 0, 0] = 5.0
    snr[:, 0, 3] = 8.0
    snr[0, 0, 3], snr[1, 0, 3] = np.nan, -20.0
    path = _sparse_run(TriggerPolicy(A3(2.0, 0.0, 0.0)), snr, L3Filter(8, 1.0))[:, 0]
    assert list(path) == [0, 0, 3, 3, 3, 3]
    np.testing.assert_array_equal(path, _dense_run(TriggerPolicy(A3(2.0, 0.0, 0.0)), snr,
                                                   L3Filter(8, 1.0))[:, 0])  # fmt: skip
