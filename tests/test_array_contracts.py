"""leolink.antenna.array: contracts that mutation testing found unchecked (docs/testing.md).

The steering vector's phase convention (Eq. (14) has ``e^{-i ...}``; x-major element
order), the explicit gain with non-uniform weights, long inputs across the chunk size,
and the error texts of the hybrid structure.
"""

import numpy as np
import pytest

from leolink.antenna.array import (
    _CHUNK,
    HybridArray,
    beam_gain_lin,
    explicit_gain,
    steering_vector,
)
from leolink.errors import ConfigError


def test_steering_vector_phase_convention_and_element_order():
    u = np.array([0.3, -0.45])
    a = steering_vector(u, 3, 4)
    # Element n = i_x * n_y + i_y has phase -pi (i_x u_x + i_y u_y) (Eq. (14)'s sign).
    for ix in range(3):
        for iy in range(4):
            want = np.exp(-1j * np.pi * (ix * u[0] + iy * u[1]))
            assert a[ix * 4 + iy] == pytest.approx(want, abs=1e-15)


def test_explicit_gain_normalizes_by_the_weights_power():
    """Tapered (non-unit-modulus) weights: |a^H f|^2 / ||f||^2 written out."""
    rng = np.random.default_rng(2)
    f = rng.uniform(0.2, 2.0, (12, 2)) * np.exp(1j * rng.uniform(0, 6.3, (12, 2)))
    u = rng.uniform(-1, 1, (5, 2))
    a = np.exp(-1j * np.pi * (np.repeat(np.arange(3), 4)[None] * u[:, :1]
                              + np.tile(np.arange(4), 3)[None] * u[:, 1:]))  # fmt: skip
    want = np.abs(a.conj() @ f) ** 2 / (np.abs(f) ** 2).sum(axis=0)
    np.testing.assert_allclose(explicit_gain(u, f, 3, 4), want, rtol=1e-12)


def test_beam_gains_of_more_directions_than_one_chunk():
    rng = np.random.default_rng(5)
    u = rng.uniform(-1, 1, (2 * _CHUNK + 37, 2))
    beams = rng.uniform(-0.5, 0.5, (4, 2))
    g = beam_gain_lin(u, beams, 6, 5)
    want = np.array([explicit_gain(u, steering_vector(b, 6, 5)[:, None], 6, 5)[:, 0]
                     for b in beams]).T  # fmt: skip
    np.testing.assert_allclose(g, want, rtol=1e-9, atol=1e-12)


def test_hybrid_array_errors_name_the_key_and_what_is_allowed():
    with pytest.raises(ConfigError, match=r"antenna\.n_rf_y = 0 .*>= 1 \(a positive count\)"):
        HybridArray(60, 72, 5, 0)
    with pytest.raises(ConfigError, match=r"antenna\.n_rf_y = 5 does not divide antenna\.n_y = 72"):
        HybridArray(60, 72, 5, 5)
    HybridArray(1, 1, 1, 1)  # the smallest array is allowed


def test_precoder_refuses_a_beam_count_other_than_the_rf_chains():
    arr = HybridArray(4, 6, 2, 3)
    with pytest.raises(
        ConfigError, match=r"precoder got 5 beams; the array has n_rf = 6 RF chains"
    ):
        arr.precoder(np.zeros((5, 2)))
