"""The satellite array's Dirichlet kernels: precision, bounds, call sizes, warnings.

Written from the survivors of a mutation run (docs/testing.md). References: explicit
steering-vector sums ``|sum_k e^{i pi k du}|^2 / n`` (no closed form), the float64
computation of the same float32 values, and the bound ``n`` of a normalized gain.
"""

import warnings

import numpy as np
import pytest

from leolink.antenna.array import dirichlet_coefficients, dirichlet_kernels, ula_gain

RNG = np.random.default_rng(1616)


def _explicit_ula(du, n):
    k = np.arange(n)
    return np.abs(np.exp(1j * np.pi * np.multiply.outer(du, k)).sum(axis=-1)) ** 2 / n


def test_kernels_of_float32_directions_are_the_float64_kernels_of_the_same_values():
    # float32 keeps 7 digits: computed in float32 the kernels would be 1e-7 off.
    u = RNG.uniform(-1, 1, 64).astype(np.float32)
    beams = np.linspace(-0.8, 0.8, 5)
    ref = _explicit_ula(u.astype(float)[None, :] - beams[:, None], 12)
    np.testing.assert_allclose(dirichlet_kernels(u, beams, 12), ref, rtol=1e-9, atol=1e-12)
    du = RNG.uniform(-2, 2, 64).astype(np.float32)
    np.testing.assert_allclose(ula_gain(du, 12), _explicit_ula(du.astype(float), 12),
                               rtol=1e-10, atol=1e-12)  # fmt: skip
    b32 = beams.astype(np.float32)
    np.testing.assert_array_equal(dirichlet_coefficients(b32, 12),
                                  dirichlet_coefficients(b32.astype(float), 12))  # fmt: skip


def test_a_direction_has_the_same_kernel_bits_whatever_the_call_size():
    u = RNG.uniform(-1, 1, 33)
    beams = np.linspace(-0.9, 0.9, 7)
    whole = dirichlet_kernels(u, beams, 16)
    for size in (1, 2, 3):
        for start in range(0, 33 - size, 5):
            part = dirichlet_kernels(u[start : start + size], beams, 16)
            assert part.shape == (7, size)
            np.testing.assert_array_equal(part, whole[:, start : start + size])
    ref = _explicit_ula(u[None, :] - beams[:, None], 16)
    np.testing.assert_allclose(whole, ref, rtol=1e-9, atol=1e-12)


def test_kernels_never_exceed_n_next_to_the_peaks():
    # Just outside the recomputed band (|sin| >= 5e-6) the angle-addition formula rounds
    # above n for small n (measured: 5 of 10,000 directions for n = 2, 8 for n = 3).
    beams = RNG.uniform(-1, 1, 50)
    off = (2 / np.pi) * RNG.choice([-1, 1], (50, 200)) * RNG.uniform(5e-6, 3e-5, (50, 200))
    u = (beams[:, None] + off).ravel()
    for n in (2, 3, 4):
        g = dirichlet_kernels(u, beams, n)
        assert g.max() <= n
        np.testing.assert_allclose(g, np.minimum(_explicit_ula(u[None, :] - beams[:, None], n),
                                                 n), rtol=1e-8)  # fmt: skip


def test_kernels_at_the_beam_and_grating_lobes_are_n_without_a_warning():
    beams = np.array([-0.5, 0.0, 0.25, 0.5])
    u = np.array([-0.5, 0.0, 0.25, 0.5, 1.5])  # on each beam; 1.5 = grating lobe of -0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = dirichlet_kernels(u, beams, 8)
        g_ula = ula_gain(np.array([0.0, 2.0, -2.0, 4.0]), 8)
    np.testing.assert_allclose(np.diag(g[:, :4]), 8.0, rtol=1e-12)
    assert g[0, 4] == 8.0
    np.testing.assert_allclose(g_ula, 8.0, rtol=0)


#: The compiled loop and the numpy path compute the same angle subtraction (subtracted_gain),
#: one with scalars, one broadcast: they may round differently (LLVM, SVML), and the
#: denominator ``sin(x - b)`` cancels, ~1e-16 / |sin| of relative error, down to the
#: recomputed band |sin| < 5e-6 (2e-11 at most for n = 72).
PATHS_REL = 1e-10
PATHS_ABS_OF_PEAK = 1e-12


@pytest.mark.parametrize(("n", "k"), [(10, 9), (12, 9), (24, 17), (72, 64)])
def test_compiled_loop_and_numpy_product_agree(n, k, monkeypatch):
    """The kernels by the compiled loop (leolink.compiled on) and by the numpy product
    (off): random directions, the beams' peaks and grating lobes and their neighbours (the
    recomputed entries), within PATHS_REL (PATHS_ABS_OF_PEAK of n at the nulls); and both
    against the explicit steering-vector sums on every 25th direction (the paths share
    their coefficients, so their agreement alone would not see a wrong one)."""
    import leolink.compiled

    beams = np.linspace(-0.7, 0.7, k)
    peaks = np.concatenate([beams, beams + 2.0 / n, beams - 2.0])
    u = np.concatenate([RNG.uniform(-1, 1, 20_003), peaks, np.nextafter(peaks, 2.0),
                        peaks + 1e-7])  # fmt: skip
    u = u[np.abs(u) <= 1.0]
    got = dirichlet_kernels(u, beams, n)
    monkeypatch.setattr(leolink.compiled, "use", lambda size: False)
    want = dirichlet_kernels(u, beams, n)
    np.testing.assert_allclose(got, want, rtol=PATHS_REL, atol=PATHS_ABS_OF_PEAK * n)
    some = slice(None, None, 25)
    ref = _explicit_ula(u[None, some] - beams[:, None], n)
    for kernels in (got, want):
        np.testing.assert_allclose(kernels[:, some], ref, rtol=1e-9, atol=1e-12 * n)
    assert (want == n).sum() >= beams.size  # the peaks were met (and recomputed)
    assert (want > 1.0).sum() > 1000  # main lobes met, not only the nulls
