"""Active-beam selectors: never more lit beams than RF chains, hopping covers the codebook,
demand lights the covering beams, chains are assigned one per lit beam."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.errors import ConfigError
from leolink.sim.beams.active import (
    assign_chains,
    cell_counts,
    default_hopping_pattern,
    hopping_slot,
    illumination_fraction,
    restrict_to_lit,
    select_all,
    select_demand,
    select_greedy_sum_rate,
    select_hopping,
    validate_pattern,
)


def _lit_ok(lit, n_rf):
    chain = assign_chains(lit, n_rf)
    rows = zip(lit.reshape(-1, lit.shape[-1]), chain.reshape(-1, lit.shape[-1]), strict=True)
    for row_lit, row_chain in rows:
        used = row_chain[row_lit]
        assert row_lit.sum() <= n_rf
        assert len(set(used.tolist())) == used.size and np.all((used >= 0) & (used < n_rf))
        assert np.all(row_chain[~row_lit] == -1)


@settings(max_examples=60, deadline=None)
@given(
    n_beam=st.integers(1, 40),
    n_rf=st.integers(1, 16),
    n_ut=st.integers(0, 80),
    seed=st.integers(0, 2**32 - 1),
)
def test_no_selector_lights_more_beams_than_chains(n_beam, n_rf, n_ut, seed):
    rng = np.random.default_rng(seed)
    n_sat = 3
    sat = rng.integers(-1, n_sat, n_ut)
    best = rng.integers(0, n_beam, n_ut)
    _lit_ok(select_demand(cell_counts(sat, best, n_sat, n_beam), n_rf), n_rf)
    snr = 10 ** rng.uniform(-1, 2, (n_sat, n_ut, n_beam))
    snr[rng.uniform(size=snr.shape[:2]) < 0.3] = np.nan  # UTs not on that satellite
    _lit_ok(select_greedy_sum_rate(snr, n_rf), n_rf)
    pattern = default_hopping_pattern(n_beam, n_rf)
    _lit_ok(select_hopping(rng.uniform(0, 100, 20), pattern, 0.01, n_rf), n_rf)
    if n_beam <= n_rf:
        _lit_ok(select_all(n_sat, n_beam, n_rf), n_rf)


def test_all_refuses_more_beams_than_chains():
    with pytest.raises(ConfigError, match=r"lights 35 beams but the array has n_rf = 15"):
        select_all(1, 35, 15)


def test_assign_chains_refuses_too_many_and_keeps_identity_when_all_lit():
    with pytest.raises(ConfigError, match="16 beams lit at once"):
        assign_chains(np.ones(16, bool), 15)
    np.testing.assert_array_equal(assign_chains(np.ones(15, bool), 15), np.arange(15))
    lit = np.zeros(35, bool)
    lit[[3, 9, 20]] = True
    np.testing.assert_array_equal(assign_chains(lit, 15)[[3, 9, 20]], [0, 1, 2])


@pytest.mark.parametrize("n_beam,n_rf", [(35, 15), (15, 15), (16, 15), (7, 3), (1, 1), (45, 15)])
def test_default_hopping_lights_every_beam_once_per_cycle(n_beam, n_rf):
    pattern = default_hopping_pattern(n_beam, n_rf)
    validate_pattern(pattern, n_rf)
    np.testing.assert_array_equal(pattern.sum(axis=0), 1)
    assert pattern.shape[0] == -(-n_beam // n_rf)  # the fewest dwells that can cover it
    # Sampled at one time inside each dwell of a cycle with unequal dwells: every beam lit.
    dwell_s = np.linspace(0.002, 0.004, pattern.shape[0])
    t_mid = np.cumsum(dwell_s) - 0.5 * dwell_s + 7 * dwell_s.sum()  # the 8th cycle
    lit = select_hopping(t_mid, pattern, dwell_s, n_rf)
    assert np.all(lit.any(axis=0))


def test_hopping_slot_at_dwell_boundaries():
    dwell_s = np.array([1.0, 2.0, 0.5])  # cycle 3.5 s
    t = np.array([0.0, 0.999, 1.0, 2.999, 3.0, 3.49, 3.5, 7.0 + 1.5])
    np.testing.assert_array_equal(hopping_slot(t, dwell_s, 3), [0, 0, 1, 1, 2, 2, 0, 1])


def test_illumination_fraction_matches_brute_force_sampling():
    rng = np.random.default_rng(1)
    pattern = rng.uniform(size=(4, 10)) < 0.4
    dwell_s = np.array([0.013, 0.007, 0.021, 0.01])
    t0, t1 = 0.1234, 1.1234
    t = t0 + (np.arange(200_000) + 0.5) * (t1 - t0) / 200_000  # midpoint rule
    ref = select_hopping(t, pattern, dwell_s, 10).mean(axis=0)
    # Sampling misplaces at most one sample (5e-6 of the window) per dwell edge, and the
    # window holds 1 s / 0.051 s x 4 < 80 edges: |error| <= 4e-4.
    np.testing.assert_allclose(illumination_fraction(t0, t1, pattern, dwell_s), ref, atol=4e-4)
    # A whole number of cycles: each beam's lit share of one cycle, exactly.
    exact = (dwell_s @ pattern) / dwell_s.sum()
    np.testing.assert_allclose(illumination_fraction(0.3, 0.3 + 5 * 0.051, pattern, dwell_s), exact)


def test_validate_pattern_errors():
    with pytest.raises(ConfigError, match=r"dwell 1 lights 3 beams; the array has n_rf = 2"):
        validate_pattern(np.array([[1, 0, 0], [1, 1, 1]], bool), 2)
    with pytest.raises(ConfigError, match="boolean"):
        validate_pattern(np.ones((2, 3)), 2)
    with pytest.raises(ConfigError, match="durations > 0"):
        hopping_slot(0.0, [1.0, 0.0], 2)


def test_demand_lights_the_beams_that_cover_most_uts_ties_to_lower_id():
    # Cells: beam 4 holds 5 UTs, beam 1 holds 3, beams 0, 2, 7 hold 2 each, beam 5 holds 1.
    best = np.array([4] * 5 + [1] * 3 + [7, 7, 2, 2, 0, 0] + [5])
    counts = cell_counts(np.zeros_like(best), best, 1, 9)
    np.testing.assert_array_equal(counts[0], [2, 3, 2, 0, 5, 1, 0, 2, 0])
    lit = select_demand(counts, 4)[0]
    np.testing.assert_array_equal(np.flatnonzero(lit), [0, 1, 2, 4])  # 7 loses the tie
    lit = select_demand(counts, 8)[0]
    np.testing.assert_array_equal(np.flatnonzero(lit), [0, 1, 2, 4, 5, 7])  # empty cells dark


def _objective_by_hand(snr, lit):
    """Delivered sum rate: sum over lit beams of the mean rate of the UTs they serve."""
    per_beam = {}
    for k in range(snr.shape[0]):
        s = {b: snr[k, b] for b in np.flatnonzero(lit)}
        b = max(s, key=lambda m: (s[m], -m))
        rate = np.log2(1 + s[b] / (sum(s.values()) - s[b] + 1))
        per_beam.setdefault(b, []).append(rate)
    return sum(np.mean(v) for v in per_beam.values())


def test_greedy_first_pick_is_the_best_single_beam_and_steps_never_lose():
    rng = np.random.default_rng(6)
    n_ut, n_beam = 12, 6
    snr = 10 ** rng.uniform(-1, 2, (n_ut, n_beam))
    lit1 = select_greedy_sum_rate(snr[None], 1)[0]
    singles = [_objective_by_hand(snr, np.eye(n_beam, dtype=bool)[b]) for b in range(n_beam)]
    assert np.flatnonzero(lit1).tolist() == [int(np.argmax(singles))]
    lit3 = select_greedy_sum_rate(snr[None], 3)[0]
    assert lit3.sum() <= 3 and lit1[lit1].all() and lit3[lit1].all()
    best3 = max(
        _objective_by_hand(snr, np.isin(np.arange(n_beam), c))
        for c in itertools.combinations(range(n_beam), 3)
    )
    assert _objective_by_hand(snr, lit3) <= best3 + 1e-12
    assert _objective_by_hand(snr, lit3) >= max(singles)


def test_greedy_stops_when_another_beam_would_only_interfere():
    # One UT seen equally by two beams: lighting both turns 20 dB of SNR into SINR ~ 0 dB.
    snr = np.array([[[100.0, 100.0, 0.0]]])
    np.testing.assert_array_equal(select_greedy_sum_rate(snr, 3)[0], [True, False, False])


def test_restrict_to_lit_neighbour_or_wait():
    snr_db = np.array(
        [
            [[10.0, 7.0, 3.0]],  # best beam 0 is dark -> neighbour beam 1
            [[1.0, 9.0, 2.0]],  # best beam 1 is lit
            [[np.nan, np.nan, np.nan]],  # sees nothing
        ]
    )
    lit = np.array([[False, True, True]])
    out, best_dark = restrict_to_lit(snr_db, lit, "neighbour")
    np.testing.assert_array_equal(best_dark, [True, False, False])
    assert np.all(np.isnan(out[:, 0, 0])) and out[0, 0, 1] == 7.0
    out, best_dark = restrict_to_lit(snr_db, lit, "wait")
    assert np.all(np.isnan(out[0])) and out[1, 0, 1] == 9.0
    with pytest.raises(ConfigError, match="use one of"):
        restrict_to_lit(snr_db, lit, "steal")
