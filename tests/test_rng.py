"""leolink.rng: the counter-based draws are the distributions they claim to be.

Monte Carlo tolerances are N_SIGMA standard errors of the estimator (false alarm ~6e-7
per check at 5 sigma); distribution tests use Kolmogorov-Smirnov at p > 1e-4.
"""

import numpy as np
import pytest
from scipy import stats

from leolink.rng import complex_normal, mix64, uniform, ut_keys

N = 100_000
N_SIGMA = 5.0
P_MIN = 1e-4
#: SplitMix64's increment, the golden ratio's 64-bit fraction (Steele, Lea and Flood 2014).
GOLDEN = 0x9E3779B97F4A7C15


@pytest.fixture(scope="module")
def keys():
    return ut_keys(20201, N)


def test_keys_are_distinct_and_reproducible(keys):
    assert keys.dtype == np.uint64 and keys.shape == (N,)
    assert len(np.unique(keys)) == N
    assert np.array_equal(keys[:1000], ut_keys(20201, 1000))
    assert not np.array_equal(keys[:10], ut_keys(20202, 10))
    # Key u of n UTs is key u of more UTs: results do not depend on the population size.
    assert np.array_equal(ut_keys(20201, 7), keys[:7])


def test_uniform_is_uniform_on_the_open_interval(keys):
    u = uniform(keys, 3)
    assert ((u > 0.0) & (u < 1.0)).all()
    assert stats.kstest(u, "uniform").pvalue > P_MIN
    # Mean 1/2, variance 1/12.
    assert abs(u.mean() - 0.5) < N_SIGMA * np.sqrt(1 / 12 / N)
    assert abs(u.var() - 1 / 12) < N_SIGMA * np.sqrt(
        1 / 180 / N
    )  # Var of the estimator: (mu4 - s^4) / N


def test_complex_normal_moments(keys):
    """CN(0, 1): E g = 0, E|g|^2 = 1, E g^2 = 0 (circular), Re and Im each N(0, 1/2)."""
    g = complex_normal(keys, 11)
    se = 1 / np.sqrt(N)
    assert abs(g.mean()) < N_SIGMA * se  # |mean| of CN(0, 1/N): Rayleigh tail
    # E|g|^2 = 1; |g|^2 ~ Exp(1) has variance 1.
    assert abs(np.mean(np.abs(g) ** 2) - 1.0) < N_SIGMA * se
    # Circularity: E[g^2] = 0 (real and imaginary parts equal power and uncorrelated).
    assert abs(np.mean(g**2)) < N_SIGMA * se
    assert abs(np.mean(g.real * g.imag)) < N_SIGMA * 0.5 * se
    assert abs(np.var(g.real) - 0.5) < N_SIGMA * np.sqrt(2 * 0.25 / N)
    assert abs(np.var(g.imag) - 0.5) < N_SIGMA * np.sqrt(2 * 0.25 / N)


def test_complex_normal_parts_are_gaussian(keys):
    g = complex_normal(keys, 5)
    scale = np.sqrt(0.5)
    assert stats.kstest(g.real, "norm", args=(0.0, scale)).pvalue > P_MIN
    assert stats.kstest(g.imag, "norm", args=(0.0, scale)).pvalue > P_MIN
    # |g|^2 ~ Exp(1) and the phase is uniform: a circular Gaussian, not just its marginals.
    assert stats.kstest(np.abs(g) ** 2, "expon").pvalue > P_MIN
    assert stats.kstest(np.angle(g), "uniform", args=(-np.pi, 2 * np.pi)).pvalue > P_MIN
    # Fourth moment: E|g|^4 = 2 for CN(0, 1) (Var |g|^2 = 1); non-Gaussian draws miss it.
    assert abs(np.mean(np.abs(g) ** 4) - 2.0) < N_SIGMA * np.sqrt(20.0 / N)  # Var |g|^4 = 20


def test_draws_are_independent_across_epochs_and_uts(keys):
    a, b = complex_normal(keys, 0), complex_normal(keys, 1)
    se = 1 / np.sqrt(N)
    assert abs(np.mean(a * b.conj())) < N_SIGMA * se  # epoch k vs k+1, same UT
    assert abs(np.mean(a[:-1] * a[1:].conj())) < N_SIGMA * se  # neighbouring UTs
    # A UT's sequence over epochs: same statistics as across UTs.
    seq = complex_normal(keys[:1], np.arange(50_000))
    assert stats.kstest(np.abs(seq) ** 2, "expon").pvalue > P_MIN
    assert abs(np.mean(seq[:-1] * seq[1:].conj())) < N_SIGMA / np.sqrt(len(seq))


def test_draw_is_a_pure_function_of_key_and_counter(keys):
    """No hidden state: the same (key, counter) gives the same draw, in any order or chunk."""
    whole = complex_normal(keys[:1000], 42)
    parts = np.concatenate([complex_normal(keys[i : i + 100], 42) for i in range(0, 1000, 100)])
    assert np.array_equal(whole, parts)
    assert np.array_equal(complex_normal(keys[::-1][:5], 42), complex_normal(keys[-5:], 42)[::-1])
    assert not np.array_equal(uniform(keys[:5], 1, stream=0), uniform(keys[:5], 1, stream=1))


def test_the_finalizer_gives_splitmix64s_published_outputs():
    """``mix64`` of the states ``seed + k GOLDEN`` (k = 1, 2, ...) is SplitMix64's output
    sequence: from seed 0 as Vigna's splitmix64.c gives it (prng.di.unimi.it), and from seed
    1234567 as Rosetta Code's task "Pseudo-random numbers/Splitmix64" lists it."""
    published = {
        0: [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F],
        1234567: [6457827717110365317, 3203168211198807973, 9817491932198370423,
                  4593380528125082431, 16408922859458223821],
    }  # fmt: skip
    for seed, outputs in published.items():
        states = [(seed + k * GOLDEN) % 2**64 for k in range(1, len(outputs) + 1)]
        assert mix64(np.array(states, dtype=np.uint64)).tolist() == outputs


@pytest.mark.parametrize(("counter", "stream"), [(0, 0), (0, 1), (3, 0), (3, 1), (1000, 1)])
def test_counter_and_stream_step_the_key_by_splitmix64s_increment(counter, stream):
    """Draw (key, counter c, stream s) finalizes the SplitMix64 state ``key + (2 c + s)
    GOLDEN``, and 0 is the finalizer's fixed point (its xor-shifts and products keep 0): the
    key ``-(2 c + s) GOLDEN`` draws the smallest value, 53 zero bits, which is 2^-54 (half a
    step of 2^-53 above 0: the open interval), and its neighbours' counters do not."""
    key = np.array([-(2 * counter + stream) * GOLDEN % 2**64], dtype=np.uint64)
    assert uniform(key, counter, stream)[0] == 2.0**-54
    assert uniform(key, counter + 1, stream)[0] > 2.0**-53
    assert uniform(key, counter, 1 - stream)[0] > 2.0**-53


def test_a_draws_phase_is_independent_of_the_next_counters_modulus(keys):
    """Modulus and phase have streams of their own: neither is the other's at the next
    counter (Spearman's rank correlation of the phase of counter k with the modulus of k + 1
    and the other way round, within N_SIGMA of its standard error 1 / sqrt(N - 1))."""
    a, b = complex_normal(keys, 4), complex_normal(keys, 5)
    for phase, modulus in ((np.angle(a), np.abs(b)), (np.angle(b), np.abs(a))):
        r = stats.spearmanr(np.mod(phase, 2 * np.pi), modulus).statistic
        assert abs(r) < N_SIGMA / np.sqrt(N - 1)
