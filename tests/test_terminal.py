"""Tests of leolink.antenna.terminal: UPA, leaky wave, metasurface, factory."""

from types import SimpleNamespace

import numpy as np
import pytest

from leolink.antenna.array import explicit_gain, steering_vector
from leolink.antenna.panel import pointing_offsets
from leolink.antenna.terminal import (
    Isotropic,
    LeakyWave,
    Metasurface,
    UPATerminal,
    leaky_wave_gain_lin,
    leaky_wave_peak_gain_lin,
)
from leolink.config import parse_config
from leolink.errors import ConfigError

PAPER_ROUNDING_DB = 0.05  # the paper prints one decimal


def test_upa_terminal_reproduces_paper_27_6_db():
    # N + 1/K = 576 + 0.1 -> 27.605 dB (Sec. 4.1 and 5)
    g = UPATerminal(24, 24, rician_k=10).gain_db(np.radians([20.0, 45.0, 90.0]))
    np.testing.assert_allclose(g, 27.6, atol=PAPER_ROUNDING_DB)
    assert g[0] == pytest.approx(10 * np.log10(576.1), rel=1e-12)


def test_upa_pointing_error_matches_explicit_steering_vectors():
    # second computation: rotate the satellite direction by 3-D vectors, explicit a^H w
    el, delta, psi = np.radians(35.0), np.radians(2.0), np.radians(60.0)
    v = np.array([np.cos(el), 0.0, np.sin(el)])
    e1 = np.array([-np.sin(el), 0.0, np.cos(el)])
    e2 = np.array([0.0, 1.0, 0.0])
    beam = np.cos(delta) * v + np.sin(delta) * (np.cos(psi) * e1 + np.sin(psi) * e2)
    w = steering_vector(beam[:2], 24, 24)[:, None]
    ref = explicit_gain(v[:2], w, 24, 24)[0] + 1 / 10
    got = UPATerminal(24, 24, 10).gain_db(el, delta, psi)
    assert got == pytest.approx(10 * np.log10(ref), abs=1e-9)
    dux, duy = pointing_offsets(el, delta, psi)
    np.testing.assert_allclose([dux, duy], beam[:2] - v[:2], atol=1e-15)


@pytest.mark.parametrize("alpha", [1e-3, 0.02, 0.05, 0.1, 0.5, 2.0])
def test_leaky_wave_closed_form_matches_explicit_weights(alpha):
    n = np.arange(24)
    w = np.exp(-alpha * n)
    explicit = np.abs(w.sum()) ** 2 / np.sum(w**2)
    paper = (1 - np.exp(-alpha * 24)) * (1 + np.exp(-alpha))
    paper /= (1 + np.exp(-alpha * 24)) * (1 - np.exp(-alpha))
    assert leaky_wave_peak_gain_lin(24, alpha) == pytest.approx(explicit, rel=1e-12)
    assert paper == pytest.approx(explicit, rel=1e-9)
    assert leaky_wave_gain_lin(0.0, 24, alpha) == pytest.approx(explicit, rel=1e-12)
    # off the beam: explicit tapered sum
    du = np.array([0.01, 0.05, 0.3])
    ref = np.abs((w * np.exp(1j * np.pi * n * du[:, None])).sum(-1)) ** 2 / np.sum(w**2)
    np.testing.assert_allclose(leaky_wave_gain_lin(du, 24, alpha), ref, rtol=1e-9)
    g_db = LeakyWave(24, 24, alpha).gain_db(0.8)
    assert g_db == pytest.approx(20 * np.log10(explicit), rel=1e-12)


def test_leaky_wave_limits():
    # alpha -> 0: the UPA (N per dimension); large N: threshold coth(alpha / 2)^2
    assert leaky_wave_peak_gain_lin(24, 1e-9) == pytest.approx(24, rel=1e-6)
    assert LeakyWave(24, 24, 0.0).gain_db(1.0) == pytest.approx(10 * np.log10(576), rel=1e-12)
    alpha = 0.1
    threshold_db = 20 * np.log10(1 / np.tanh(alpha / 2))
    assert LeakyWave(2000, 2000, alpha).gain_db(1.0) == pytest.approx(threshold_db, abs=1e-9)
    assert LeakyWave(24, 24, alpha).gain_db(1.0) < threshold_db
    g = [LeakyWave(24, 24, a).gain_db(1.0) for a in (0.0, 0.01, 0.05, 0.1, 0.3)]
    assert np.all(np.diff(g) < 0)


def test_metasurface_roll_off_sign_and_values():
    """A second derivation: the panel lies flat (normal up); the satellite's direction is
    built as a vector from its azimuth and elevation; the element factor is the power
    pattern cos^q of the angle between the two, found by arccos of their dot product and
    raised to q = 1.2 in linear power (the Kymeta roll-off the paper quotes, Sec. 2.1),
    not the sin(el) form of the code."""
    ms = Metasurface(33.0, 1.2)
    rng = np.random.default_rng(2)
    el, az = rng.uniform(0.01, np.pi / 2, 50), rng.uniform(0.0, 2 * np.pi, 50)
    los = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1)
    scan = np.arccos(los @ np.array([0.0, 0.0, 1.0]))
    expected = 33.0 + 10 * np.log10(np.cos(scan) ** 1.2)
    np.testing.assert_allclose(ms.gain_db(el), expected, atol=1e-9)
    assert np.all(np.diff(ms.gain_db(np.sort(el))) > 0)  # falls towards the horizon
    assert np.isnan(ms.gain_db(-0.1))  # below the horizon: callers mask


def test_isotropic_and_broadcasting():
    assert np.array_equal(Isotropic().gain_db(np.zeros((2, 3))), np.zeros((2, 3)))
    g = UPATerminal(4, 4, 10).gain_db(np.ones((5, 1)), np.zeros((1, 3)))
    assert g.shape == (5, 3)


def test_terminals_from_the_config_tables():
    def terminal(**section):
        cfg = parse_config({"terminal": section, "link": {"rician_k": 10.0}})
        return cfg.terminal.build(SimpleNamespace(rician_k=cfg.link.rician_k))

    assert terminal() == UPATerminal(24, 24, 10.0)
    assert terminal(kind="metasurface") == Metasurface(33.0, 1.2)
    leaky = terminal(kind="leaky_wave", leaky_wave={"n_x": 8, "n_y": 8, "leakage": 0.2})
    assert leaky == LeakyWave(8, 8, 0.2)
    with pytest.raises(ConfigError, match="terminal.kind = 'dish' is not allowed"):
        terminal(kind="dish")
    with pytest.raises(ConfigError, match="terminal.leaky_wave.leakage = -0.1"):
        terminal(kind="leaky_wave", leaky_wave={"leakage": -0.1})
    with pytest.raises(ConfigError, match="terminal.upa.n_x = 24.0 is not allowed"):
        terminal(upa={"n_x": 24.0})  # a float count is refused (strict types)
