"""Sharing a beam's time: shares sum to 1 per beam, round robin is equal, proportional fair
behaves as theory says (equal time for constant rates, multiuser-diversity gain H_n with
Rayleigh fading)."""

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.sim.beams.scheduler import (
    beam_groups,
    delivered_rate,
    proportional_fair,
    round_robin_share,
    round_robin_slots,
    slot_shares,
)


def _random_groups(rng, n_ut=200, n_sat=3, n_beam=15):
    sat = rng.integers(-1, n_sat, n_ut)
    beam = np.where(sat >= 0, rng.integers(0, n_beam, n_ut), -1)
    return beam_groups(sat, beam, n_beam), n_sat * n_beam


def test_group_sizes_match_counting_by_hand():
    rng = np.random.default_rng(0)
    sat = rng.integers(-1, 3, 300)
    beam = np.where(sat >= 0, rng.integers(0, 15, 300), -1)
    group, n_sharing = beam_groups(sat, beam, 15)
    for k in range(300):
        same = [j for j in range(300) if sat[j] == sat[k] and beam[j] == beam[k]]
        assert n_sharing[k] == (len(same) if sat[k] >= 0 else 0)
        assert group[k] == (sat[k] * 15 + beam[k] if sat[k] >= 0 else -1)


def _sum_per_group(share, group, n_group):
    ok = group >= 0
    return np.bincount(group[ok], weights=share[ok], minlength=n_group)


def test_round_robin_shares_are_equal_and_sum_to_one_per_beam():
    rng = np.random.default_rng(1)
    (group, n_sharing), n_group = _random_groups(rng)
    share = round_robin_share(group)
    occupied = np.bincount(group[group >= 0], minlength=n_group) > 0
    np.testing.assert_allclose(_sum_per_group(share, group, n_group)[occupied], 1.0)
    np.testing.assert_allclose(share[group >= 0], 1.0 / n_sharing[group >= 0])
    assert np.all(share[group < 0] == 0)


def test_round_robin_slots_serve_each_ut_once_per_round_and_newcomers_first():
    rng = np.random.default_rng(2)
    (group, n_sharing), n_group = _random_groups(rng, n_ut=60, n_sat=1, n_beam=4)
    last = np.full(group.size, -np.inf)
    n = np.bincount(group[group >= 0], minlength=n_group)
    lcm = int(np.lcm.reduce(n[n > 0]))
    schedule, share, last = round_robin_slots(group, n_group, lcm * 2, last)
    np.testing.assert_allclose(share[group >= 0], 1.0 / n_sharing[group >= 0])
    np.testing.assert_allclose(_sum_per_group(share, group, n_group)[n > 0], 1.0)
    # a UT joining group g is served in the next slot (never served there before)
    g = int(group[group >= 0][0])
    group2 = np.append(group, g)
    last2 = np.append(last, -np.inf)
    schedule2, _, _ = round_robin_slots(group2, n_group, 1, last2)
    assert schedule2[0, g] == group.size


@pytest.mark.parametrize("n_slots", [1, 7, 50])
def test_proportional_fair_shares_sum_to_one_per_beam(n_slots):
    rng = np.random.default_rng(3)
    (group, _), n_group = _random_groups(rng)
    rate = rng.exponential(size=(n_slots, group.size))
    schedule, share, avg = proportional_fair(group, n_group, rate, np.zeros(group.size), 100.0)
    occupied = np.bincount(group[group >= 0], minlength=n_group) > 0
    np.testing.assert_allclose(_sum_per_group(share, group, n_group)[occupied], 1.0)
    assert np.all(share[group < 0] == 0) and np.all(schedule[:, ~occupied] == -1)
    # each slot a beam serves one of its own UTs
    ok = schedule >= 0
    assert np.all(group[schedule[ok]] == np.nonzero(ok)[1])


def _one_beam_pf(rate, t_c_slots):
    n_ut = rate.shape[1]
    group = np.zeros(n_ut, int)
    return proportional_fair(group, 1, rate, np.zeros(n_ut), t_c_slots)


def test_proportional_fair_gives_equal_time_for_equal_rates():
    schedule, share, _ = _one_beam_pf(np.full((1000, 5), 2.0), 50.0)
    np.testing.assert_allclose(share, 0.2, atol=1e-3)


def test_proportional_fair_gives_equal_time_for_constant_unequal_rates():
    # PF maximizes sum log(x_k r_k) s.t. sum x_k = 1: x_k = 1/n whatever the r_k; a
    # max-rate scheduler would give all the time to the 8 bit/s/Hz UT.
    rate = np.tile([0.5, 1.0, 2.0, 8.0], (4000, 1))
    _, share, _ = _one_beam_pf(rate, 100.0)
    np.testing.assert_allclose(share, 0.25, atol=2e-3)


def test_proportional_fair_multiuser_diversity_gain_with_rayleigh_fading():
    # Rates proportional to an Exp(1) power (Rayleigh amplitude), unequal means m_k. With
    # a long window PF serves the UT with the largest E_k (the r/R ratios are scale-free),
    # so each UT gets 1/n of the time and m_k H_n / n of throughput, H_n = sum 1/i
    # (Holtzman, "Asymptotic analysis of proportional fair algorithm", PIMRC 2001;
    # Viswanath, Tse, Laroia 2002). Round robin gets m_k / n.
    rng = np.random.default_rng(4)
    n, n_slots = 4, 30_000
    mean = np.array([1.0, 2.0, 5.0, 10.0])
    rate = mean * rng.exponential(size=(n_slots, n))
    schedule, share, _ = _one_beam_pf(rate, 500.0)
    h_n = sum(1 / i for i in range(1, n + 1))
    # Monte Carlo and the finite window (t_c = 500 slots) move the shares by <= 0.002 and
    # the throughputs by <= 1.5 % over 5 seeds; the tolerances are 5 and 3 times that,
    # well inside the effects they guard (a max-rate scheduler gives shares 0 / 1; no
    # diversity gain would leave the throughput at 1 / H_4 = 48 % of the expectation).
    np.testing.assert_allclose(share, 1 / n, atol=0.01)
    thr = delivered_rate(schedule, rate)
    np.testing.assert_allclose(thr / (mean * h_n / n), 1.0, atol=0.04)
    assert np.all(thr > 1.8 * mean / n)  # round robin's expected throughput is m_k / n


def test_delivered_rate_matches_a_loop_over_slots():
    rng = np.random.default_rng(5)
    (group, _), n_group = _random_groups(rng, n_ut=40, n_sat=1, n_beam=5)
    rate = rng.uniform(size=(9, group.size))
    schedule, share, _ = proportional_fair(group, n_group, rate, np.ones(group.size), 10.0)
    ref = np.zeros(group.size)
    for s in range(9):
        for g in range(n_group):
            if schedule[s, g] >= 0:
                ref[schedule[s, g]] += rate[s, schedule[s, g]] / 9
    np.testing.assert_allclose(delivered_rate(schedule, rate), ref)
    np.testing.assert_allclose(slot_shares(schedule, group.size), share)


def test_proportional_fair_window_error():
    with pytest.raises(ConfigError, match=r"t_c_slots = 0.5 is not allowed"):
        proportional_fair(np.zeros(2, int), 1, np.ones((1, 2)), np.zeros(2), 0.5)


# --- Written from a mutation run's reach (issue 45, docs/testing.md): the registered
# schedulers, the state they carry over epochs, and the recurrences by hand.


def test_proportional_fair_average_is_the_exponential_window_in_closed_form():
    """A UT alone in its beam is served every slot: ``R_n = r (1 - (1 - 1/t_c)^n)`` from
    ``R_0 = 0``, and ``R_0 (1 - 1/t_c)^n`` more from a non-zero start; a UT of another
    beam that has no rate decays as ``R_0 (1 - 1/t_c)^n``."""
    t_c, n, r = 7.0, 12, 3.0
    group = np.array([0, 1])
    rate = np.tile([r, 0.0], (n, 1))
    _, share, avg = proportional_fair(group, 2, rate, np.array([0.5, 2.0]), t_c)
    decay = (1 - 1 / t_c) ** n
    np.testing.assert_allclose(avg, [r * (1 - decay) + 0.5 * decay, 2.0 * decay], rtol=1e-12)
    assert share.tolist() == [1.0, 1.0]  # each alone in its beam (a zero rate is still served)


def test_proportional_fair_slot_by_slot_by_hand_with_ties_to_the_lower_id():
    """Two UTs of one beam, rates 1 and 2, t_c = 2 (R <- R/2 + r/2 when served). Slot 0:
    both new (metric inf), the lower id wins; R = (0.5, 0). Slot 1: UT 1 is new; R =
    (0.25, 1). Slot 2: 1/0.25 = 4 > 2/1: UT 0; R = (0.625, 0.5)."""
    schedule, share, avg = proportional_fair(np.array([0, 0]), 1, np.tile([1.0, 2.0], (3, 1)),
                                             np.zeros(2), 2.0)  # fmt: skip
    assert schedule[:, 0].tolist() == [0, 1, 0]
    np.testing.assert_allclose(avg, [0.625, 0.5], rtol=1e-15)
    np.testing.assert_allclose(share, [2 / 3, 1 / 3])
    # a UT without a rate is never "new first": the other one is served every slot
    schedule, _, _ = proportional_fair(np.array([0, 0]), 1, np.tile([0.0, 2.0], (3, 1)),
                                       np.zeros(2), 2.0)  # fmt: skip
    assert schedule[:, 0].tolist() == [1, 1, 1]


def test_proportional_fair_scheduler_carries_its_average_over_epochs():
    """The registered scheduler keeps R_k between epochs: the second epoch continues the
    recurrence of the first (by hand, as above: slots UT1, UT0, UT1), it does not restart."""
    from leolink.sim.beams.scheduler import SCHEDULERS

    pf = SCHEDULERS.build("proportional_fair", {"slots_per_epoch": 3, "t_c_slots": 2.0})
    assert pf.shares
    group, rate = np.array([0, 0]), np.array([1.0, 2.0])
    first, share1 = pf.schedule(group, 1, rate)
    second, share2 = pf.schedule(group, 1, rate)
    assert first[:, 0].tolist() == [0, 1, 0] and second[:, 0].tolist() == [1, 0, 1]
    np.testing.assert_allclose(share2, [1 / 3, 2 / 3])
    np.testing.assert_allclose(pf.avg_rate, [0.328125, 1.3125], rtol=1e-15)
    # a UT without a link (NaN) has rate 0; a new UT count restarts the averages
    _, share = pf.schedule(np.array([0, 0, -1]), 1, np.array([np.nan, 2.0, 1.0]))
    assert share.tolist() == [0.0, 1.0, 0.0] and pf.avg_rate.size == 3


def test_round_robin_scheduler_serves_rank_s_mod_n_in_slot_s():
    """Groups of 3 (UTs 1, 4, 7) and 2 (UTs 0, 5): 3 slots; slot s serves the member of
    rank s mod n by ut_id. UTs 2, 3, 6 are unserved."""
    from leolink.sim.beams.scheduler import SCHEDULERS

    rr = SCHEDULERS.build("round_robin", {})
    group = np.array([1, 0, -1, -1, 0, 1, -1, 0])
    schedule, share = rr.schedule(group, 3, np.ones(8))
    assert schedule.tolist() == [[1, 0, -1], [4, 5, -1], [7, 0, -1]]
    np.testing.assert_allclose(share, [1 / 2, 1 / 3, 0, 0, 1 / 3, 1 / 2, 0, 1 / 3])
    schedule, share = rr.schedule(np.full(3, -1), 2, np.ones(3))
    assert schedule.tolist() == [[-1, -1]] and share.tolist() == [0.0, 0.0, 0.0]


def test_no_sharing_scheduler_shares_nothing():
    from leolink.sim.beams.scheduler import SCHEDULERS

    none = SCHEDULERS.build("none", {})
    assert none.shares is False
    with pytest.raises(NotImplementedError, match="^scheduler 'none' shares nothing$"):
        none.schedule(np.zeros(2, int), 1, np.ones(2))


def test_round_robin_slots_number_from_the_last_finite_slot_by_hand():
    """One group: UT 0 last served at slot 5, UT 1 never, UT 2 at slot 3, UT 3 at 3 too.
    Slots are numbered from 6: UT 1 (never) at 6, then UTs 2 and 3 (tie: the lower id) at
    7 and 8, then UT 0 at 9."""
    last = np.array([5.0, -np.inf, 3.0, 3.0])
    schedule, share, last = round_robin_slots(np.zeros(4, int), 1, 4, last)
    assert schedule[:, 0].tolist() == [1, 2, 3, 0]
    assert last.tolist() == [9.0, 6.0, 7.0, 8.0] and share.tolist() == [0.25] * 4


def test_beam_groups_need_both_a_satellite_and_a_beam():
    group, n_sharing = beam_groups([2, 2, -1, 2], [1, -1, 1, 1], n_beam=4)
    assert group.tolist() == [9, -1, -1, 9] and n_sharing.tolist() == [2, 0, 0, 2]


def test_delivered_rate_of_a_rate_per_ut_is_its_share_of_it():
    schedule = np.array([[0, 2], [1, 2], [0, -1]])
    np.testing.assert_allclose(delivered_rate(schedule, [3.0, 6.0, 9.0]), [2.0, 2.0, 6.0])


def test_beam_groups_with_nobody_or_only_group_zero_served():
    group, n_sharing = beam_groups([-1, -1], [-1, -1], n_beam=3)
    assert group.tolist() == [-1, -1] and n_sharing.tolist() == [0, 0]
    group, n_sharing = beam_groups([0, -1, 0], [0, -1, 0], n_beam=3)
    assert group.tolist() == [0, -1, 0] and n_sharing.tolist() == [2, 0, 2]


def test_round_robin_slots_of_a_fresh_start_are_numbered_from_zero():
    _, _, last = round_robin_slots(np.zeros(3, int), 1, 3, np.full(3, -np.inf))
    assert last.tolist() == [0.0, 1.0, 2.0]
    _, _, last = round_robin_slots(np.zeros(2, int), 1, 1, np.array([0.0, -np.inf]))
    assert last.tolist() == [0.0, 1.0]  # after slot 0, slot 1


def test_proportional_fair_window_of_one_slot_and_new_uts_without_a_rate():
    """t_c = 1 (the smallest window) is allowed: R is the rate of the last slot served, 0
    otherwise. A new UT (R = 0) without a rate is not first in line: a UT with a rate and
    any finite metric goes before it; with no rate anywhere the lower id is served."""
    _, _, avg = proportional_fair(np.array([0, 0]), 1, np.array([[3.0, 5.0]]), np.zeros(2), 1.0)
    assert avg.tolist() == [3.0, 0.0]
    schedule, _, _ = proportional_fair(np.array([0, 0]), 1, np.array([[0.0, 2.0]]),
                                       np.array([0.0, 4.0]), 10.0)  # fmt: skip
    assert schedule.tolist() == [[1]]  # metric 2 / 4 = 0.5 beats the new UT's 0
    schedule, _, _ = proportional_fair(np.array([0, 0]), 1, np.array([[0.0, 0.0]]),
                                       np.array([0.0, 1.0]), 10.0)  # fmt: skip
    assert schedule.tolist() == [[0]]  # both metrics 0: the lower id


def test_proportional_fair_defaults_are_its_configs():
    from leolink.sim.beams.scheduler import ProportionalFair, ProportionalFairConfig

    pf, cfg = ProportionalFair(), ProportionalFairConfig()
    assert (pf.n_slots, pf.t_c_slots) == (cfg.slots_per_epoch, cfg.t_c_slots) == (10, 100.0)
