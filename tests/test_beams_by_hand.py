"""Active-beam selectors over several satellites, by hand and by brute force.

The greedy selector is re-run here as its docstring states it, one satellite and one
candidate beam at a time with the objective summed UT by UT (no arrays shared with the
module); the hopping cycle, cell counts and the dark-beam fallback with hand values.
"""

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.sim.beams.active import (
    cell_counts,
    hopping_slot,
    illumination_fraction,
    restrict_to_lit,
    select_all,
    select_demand,
    select_greedy_sum_rate,
    validate_pattern,
)


def _objective(snr, lit):
    """Sum over lit beams of the mean log2(1 + SINR) of the UTs each serves (noise 1,
    the other lit beams interfere); a UT with no power on any lit beam is not served."""
    per_beam = {}
    for row in snr:
        s = {b: row[b] for b in sorted(lit)}
        b = max(s, key=lambda m: (s[m], -m))
        if s[b] > 0.0:
            rate = np.log2(1.0 + s[b] / (sum(s.values()) - s[b] + 1.0))
            per_beam.setdefault(b, []).append(rate)
    return sum(np.mean(v) for v in per_beam.values())


def _greedy(snr, n_rf):
    """Greedy by the docstring: light the beam that most raises the objective (lowest
    beam on a tie), while it rises, at most ``n_rf`` beams."""
    lit, current = set(), 0.0
    for _ in range(min(n_rf, snr.shape[1])):
        scores = {b: _objective(snr, lit | {b}) for b in range(snr.shape[1]) if b not in lit}
        b = max(scores, key=lambda m: (scores[m], -m))
        if not scores[b] > current:
            break
        lit.add(b)
        current = scores[b]
    return lit


@pytest.mark.parametrize("seed", range(4))
def test_greedy_over_several_satellites_is_the_greedy_of_each_by_hand(seed):
    """Three satellites with their own UTs (NaN: not served by that satellite), n_rf 3:
    each satellite's lit beams are the hand greedy's, however many steps each takes."""
    rng = np.random.default_rng(seed)
    n_sat, n_ut, n_beam, n_rf = 3, 9, 6, 3
    snr = 10 ** rng.uniform(-1.5, 2.0, (n_sat, n_ut, n_beam))
    snr[rng.uniform(size=(n_sat, n_ut)) < 0.4] = np.nan
    snr[2, :, :] = np.nan
    snr[2, 0, :] = [50.0, 50.0, 0.0, 0.0, 0.0, 0.0]  # one UT: one beam, the second only hurts
    lit = select_greedy_sum_rate(snr, n_rf)
    for s in range(n_sat):
        assert set(np.flatnonzero(lit[s])) == _greedy(np.nan_to_num(snr[s]), n_rf), s
    assert np.flatnonzero(lit[2]).tolist() == [0]


def test_demand_per_satellite_with_uncounted_uts():
    """UTs with satellite or beam -1 are not counted. Satellite 0's cells hold 2, 1, 3
    UTs, satellite 1's 0, 4, 0: with 2 chains satellite 0 lights beams 0 and 2, satellite
    1 beam 1 only (empty cells stay dark)."""
    sat = np.array([0, 0, 0, 0, 0, 0, 1, 1, 1, 1, -1, 1, 0])
    beam = np.array([0, 0, 1, 2, 2, 2, 1, 1, 1, 1, 2, -1, -1])
    counts = cell_counts(sat, beam, 2, 3)
    np.testing.assert_array_equal(counts, [[2, 1, 3], [0, 4, 0]])
    np.testing.assert_array_equal(
        select_demand(counts, 2), [[True, False, True], [False, True, False]]
    )


def test_hopping_slot_before_the_first_cycle_and_with_one_dwell_duration():
    """The cycle repeats backwards too: t = -0.5 s in a 3.5 s cycle (1, 2, 0.5 s) is at
    3.0 s, the third dwell; one duration for every dwell (0.25 s, 4 dwells): t = 0.6 s is
    in the third (0.5 to 0.75 s), t = 1.0 s starts the next cycle."""
    np.testing.assert_array_equal(hopping_slot([-0.5, -3.0], [1.0, 2.0, 0.5], 3), [2, 0])
    np.testing.assert_array_equal(hopping_slot([0.6, 0.99, 1.0], 0.25, 4), [2, 3, 0])


def test_illumination_fraction_of_windows_shorter_than_a_dwell_and_across_cycles():
    """Two dwells, 0.4 s then 0.6 s (cycle 1 s); beam 0 lit in the first, beam 1 in the
    second, beam 2 in both. [0.1, 0.3): inside dwell 0. [0.3, 0.5): 0.1 s of each.
    [2.2, 4.9): 2.7 s = beam 0 lit 0.2 + 0.4 + 0.4 = 1.0 s, beam 1 1.7 s."""
    pattern = np.array([[True, False, True], [False, True, True]])
    dwell = [0.4, 0.6]
    np.testing.assert_allclose(illumination_fraction(0.1, 0.3, pattern, dwell), [1, 0, 1])
    np.testing.assert_allclose(illumination_fraction(0.3, 0.5, pattern, dwell), [0.5, 0.5, 1])
    np.testing.assert_allclose(
        illumination_fraction(2.2, 4.9, pattern, dwell), [1.0 / 2.7, 1.7 / 2.7, 1.0], rtol=1e-12
    )
    with pytest.raises(ConfigError, match=r"illumination window \[1\.0, 1\.0\) is empty"):
        illumination_fraction(1.0, 1.0, pattern, dwell)
    with pytest.raises(ConfigError, match=r"dwell_s = \[0\.4, -0\.6\]; use durations > 0 s"):
        illumination_fraction(0.0, 1.0, pattern, [0.4, -0.6])


def test_a_pattern_without_rows_or_of_one_axis_is_refused():
    for bad in (np.zeros((0, 3), bool), np.ones(3, bool)):
        with pytest.raises(ConfigError, match="one row per dwell"):
            validate_pattern(bad, 2)


def test_the_dark_fallback_looks_at_every_satellite():
    """UT 0's best beam is satellite 1's beam 0 (dark); UT 1's best is satellite 0's beam 1
    (lit). Under "wait" UT 0 gets no candidate at all, UT 1 keeps its lit beams only."""
    snr = np.array([[[3.0, 4.0], [9.0, 1.0]], [[2.0, 8.0], [7.0, np.nan]]])
    lit = np.array([[True, True], [False, True]])
    out, dark = restrict_to_lit(snr, lit, "neighbour")
    np.testing.assert_array_equal(dark, [True, False])
    np.testing.assert_array_equal(out[0], [[3.0, 4.0], [np.nan, 1.0]])
    out, dark = restrict_to_lit(snr, lit, "wait")
    assert np.isnan(out[0]).all()
    np.testing.assert_array_equal(out[1], [[2.0, 8.0], [np.nan, np.nan]])


def test_greedy_counts_the_noise_of_unit_power():
    """UT A sees beam 0 at SNR 3 and beam 1 at 0.5, UT B beam 1 at 0.3 (linear). Beam 0
    alone: log2(4) = 2 bit/s/Hz. Adding beam 1 for B: A falls to log2(1 + 3 / 1.5) =
    1.585, B gets log2(1 + 0.3 / 4) = 0.104: 1.689 + ... < 2, so beam 1 stays dark (with a
    noise of 2 it would raise the sum: 1.379 + 0.638 > 1.585)."""
    snr = np.array([[[3.0, 0.5], [0.0, 0.3]]])
    np.testing.assert_array_equal(select_greedy_sum_rate(snr, 2), [[True, False]])
    assert _objective(snr[0], {0, 1}) < _objective(snr[0], {0}) == 2.0


def test_demand_breaks_ties_by_beam_id_over_a_large_codebook():
    """60 beams with counts 0 to 2, many tied: the 15 lit beams are the first 15 in the
    order (most UTs, then lowest beam_id), computed with Python's sort."""
    rng = np.random.default_rng(3)
    counts = rng.integers(0, 3, (2, 60))
    lit = select_demand(counts, 15)
    for s in range(2):
        order = sorted(range(60), key=lambda b: (-counts[s, b], b))[:15]
        expected = [b for b in sorted(order) if counts[s, b] > 0]
        assert np.flatnonzero(lit[s]).tolist() == expected


def test_a_time_just_before_a_cycle_start_is_in_the_last_dwell():
    """t = -1e-20 s: its phase in the 3.5 s cycle rounds to 3.5 s itself; it belongs to the
    last dwell of the previous cycle, not to a dwell past the pattern."""
    np.testing.assert_array_equal(hopping_slot([-1e-20], [1.0, 2.0, 0.5], 3), [2])


def test_messages_name_what_is_allowed():
    with pytest.raises(
        ConfigError, match=r"n_rf = 3 RF chains; use 'demand' or 'hopping', or fewer beams$"
    ):
        select_all(1, 4, 3)
    with pytest.raises(
        ConfigError, match=r"use a boolean \(n_dwell, n_beam\) table, one row per dwell$"
    ):
        validate_pattern(np.ones(3, bool), 2)


def test_the_dark_fallback_skips_unseen_beams_before_the_best():
    """UT 0 does not see satellite 0's beam 0 (NaN); its best, satellite 1's beam 1, is
    dark: it is a UT with a dark best beam."""
    snr = np.array([[[np.nan, 4.0], [2.0, 9.0]]])
    lit = np.array([[True, True], [True, False]])
    out, dark = restrict_to_lit(snr, lit)  # the default fallback: a lit neighbour
    np.testing.assert_array_equal(dark, [True])
    np.testing.assert_array_equal(out[0], [[np.nan, 4.0], [2.0, np.nan]])
