"""Tests of leolink.antenna.impairments: pointing misalignment and phase quantization."""

import numpy as np
import pytest

from leolink.antenna.impairments import (
    analog_weights,
    hybrid_weights,
    misalignment_gain_db,
    quantization_loss_db,
)
from leolink.antenna.terminal import LeakyWave, UPATerminal
from leolink.errors import ConfigError


@pytest.mark.parametrize("terminal", [UPATerminal(24, 24, 10), LeakyWave(24, 24, 0.05)])
def test_zero_error_no_loss_and_mean_loss_grows(terminal):
    rng = np.random.default_rng(7)
    stats = misalignment_gain_db(terminal, [0.0, 1.0, 2.0, 3.0, 4.0], 500, rng)
    ideal = terminal.gain_db(np.pi / 2)
    assert stats.mean_db[0] == pytest.approx(ideal, abs=1e-12)
    assert stats.min_db[0] == pytest.approx(ideal, abs=1e-12)
    assert np.all(np.diff(stats.mean_db) < 0)
    assert np.all(stats.min_db <= stats.percentile_db[:, 0] + 1e-12)


def test_upa_minimum_collapses_past_the_first_null():
    # 24 elements at zenith: first null at sin(delta) = 2/24 -> 4.78 deg (Fig. 6b: "critical
    # above 4 deg"). A fixed 3 deg error stays > 20 dB; at 5 deg some azimuth hits the null
    # region and the gain falls to the diffuse floor 1/K = -10 dB.
    rng = np.random.default_rng(8)
    stats = misalignment_gain_db(UPATerminal(24, 24, 10), [3.0, 5.0], 4000, rng)
    assert stats.min_db[0] > 20.0
    assert stats.min_db[1] < 0.0


def test_misalignment_distributions_and_errors():
    rng = np.random.default_rng(9)
    t = UPATerminal(24, 24, 10)
    fixed = misalignment_gain_db(t, [2.0], 2000, rng, distribution="fixed")
    uni = misalignment_gain_db(t, [2.0], 2000, rng, distribution="uniform")
    assert uni.mean_db[0] > fixed.mean_db[0]  # a uniform angle in [0, 2] is smaller
    with pytest.raises(ConfigError, match="distribution = 'cauchy'"):
        misalignment_gain_db(t, [1.0], 10, rng, distribution="cauchy")


def test_quantization_loss_decreases_with_bits_and_hybrid_wins():
    rng = np.random.default_rng(10)
    bits = np.arange(1, 9)
    analog, hybrid = quantization_loss_db(24, 24, bits, 100, rng)
    assert np.all(np.diff(analog) < 0) and np.all(np.diff(hybrid) < 0)
    assert np.all(hybrid[:4] < analog[:4])  # hybrid beats analog at low resolution
    # the half-step digital offset of chain 2 doubles the phase grid: b-bit hybrid behaves
    # like (b+1)-bit analog (10 % covers the Monte Carlo spread of 100 directions)
    np.testing.assert_allclose(hybrid[:5], analog[1:6], rtol=0.1)
    # b = 1 analog: 2 phases, loss = -10 log10((2/pi)^2) = 3.92 dB for uniform phase errors
    assert analog[0] == pytest.approx(3.92, abs=0.3)  # finite-array spread (random directions)
    # b-bit uniform phase error: loss -20 log10(sinc(pi / 2^b)); at b = 8 it is 5e-5 dB
    assert analog[-1] < 1e-3 and hybrid[-1] < 1e-3
    assert analog[2] == pytest.approx(-20 * np.log10(np.sinc(1 / 8)), abs=0.03)


def test_quantized_weights_lie_on_the_grid():
    rng = np.random.default_rng(11)
    ideal = np.exp(1j * rng.uniform(-np.pi, np.pi, 1000))
    step = 2 * np.pi / 8
    q = analog_weights(ideal, 3)
    k = np.angle(q) / step
    np.testing.assert_allclose(k, np.round(k), atol=1e-9)
    assert np.max(np.abs(np.angle(q / ideal))) <= step / 2 + 1e-12
    h = hybrid_weights(ideal, 3)
    assert np.max(np.abs(h)) <= 2 + 1e-12
    # better phase accuracy than one analog shifter of the same resolution
    assert np.max(np.abs(np.angle(h / ideal))) < step / 2
