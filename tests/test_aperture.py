"""Tests of leolink.antenna.aperture (TR 38.811 Sec. 6.4.1 circular aperture)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.antenna.aperture import (
    aperture_ka,
    circular_aperture_gain_db,
    circular_aperture_pattern_lin,
    half_power_beamwidth_rad,
)
from leolink.constants import SPEED_OF_LIGHT_M_S

# Airy-pattern constants (uniform circular aperture, Balanis "Antenna Theory"):
FIRST_NULL_U = 3.8317  # first zero of J1
FIRST_SIDELOBE_U = 5.1356
FIRST_SIDELOBE_DB = -17.57
HALF_POWER_U = 1.6163
PRINTED_4_DIGITS = 1e-4
KA_BAND_KA = np.pi * 0.5 * 20e9 / SPEED_OF_LIGHT_M_S  # TR 38.821 Set-1: 0.5 m at 20 GHz
# Midpoint nodes for the aperture integral. The integrand is symmetric about t = pi/2, so the
# half-period integral is half a full-period one of a smooth 2 pi-periodic function, where the
# midpoint rule converges exponentially: 4096 nodes give < 1e-10 for k a sin(theta) <= ~1000.
N_QUAD = 4096


def _aperture_integral_pattern(theta_rad, ka):
    """|far field|^2 of a uniform disk by direct integration over the aperture, normalized.

    E(theta) ~ integral over the disk of exp(i k x sin theta) dA; with the chord
    2 sqrt(a^2 - x^2) and x = a sin t the integral is a^2 int 2 cos^2 t exp(i u sin t) dt,
    u = k a sin theta, over t in [-pi/2, pi/2] (no Bessel function involved).
    """
    t = (np.arange(N_QUAD) + 0.5) * np.pi / N_QUAD - 0.5 * np.pi  # midpoint nodes
    u = ka * np.sin(np.asarray(theta_rad, dtype=float))[..., None]
    integral = np.sum(2.0 * np.cos(t) ** 2 * np.exp(1j * u * np.sin(t)), axis=-1) * np.pi / N_QUAD
    return np.abs(integral) ** 2 / np.pi**2  # / (area / a^2)^2


def test_pattern_equals_direct_aperture_integration():
    theta = np.radians(np.linspace(0.0, 15.0, 3001))  # main lobe and ~20 side lobes
    for ka in (KA_BAND_KA, 41.9, 5.0):
        np.testing.assert_allclose(
            circular_aperture_pattern_lin(theta, ka),
            _aperture_integral_pattern(theta, ka),
            atol=1e-10,
        )


def test_airy_landmarks():
    ka = 100.0
    theta = np.arcsin(np.array([HALF_POWER_U, FIRST_NULL_U, FIRST_SIDELOBE_U]) / ka)
    g = circular_aperture_pattern_lin(theta, ka)
    assert g[0] == pytest.approx(0.5, abs=PRINTED_4_DIGITS)
    assert g[1] < 1e-8
    assert 10 * np.log10(g[2]) == pytest.approx(FIRST_SIDELOBE_DB, abs=0.01)


def test_boresight_small_angles_and_back():
    ka = KA_BAND_KA
    assert circular_aperture_pattern_lin(0.0, ka) == 1.0
    # Either side of the switch to the series (|u| = 1e-4) the pattern equals the direct
    # aperture integral (exact to ~1e-15 at such small u), so the two branches join.
    u = np.array([0.5e-4, 0.99e-4, 1.01e-4, 2e-4])
    theta = np.arcsin(u / ka)
    np.testing.assert_allclose(
        circular_aperture_pattern_lin(theta, ka),
        _aperture_integral_pattern(theta, ka),
        rtol=0.0,
        atol=1e-13,
    )
    assert circular_aperture_pattern_lin(np.radians(120.0), ka) == 0.0  # behind: not defined
    np.testing.assert_allclose(
        circular_aperture_pattern_lin(np.radians([-3.0, 3.0]), ka),
        circular_aperture_pattern_lin(np.radians(3.0), ka),
    )


@settings(max_examples=200, deadline=None)
@given(theta_deg=st.floats(0.0, 90.0), ka=st.floats(1.0, 2000.0))
def test_pattern_is_bounded(theta_deg, ka):
    g = circular_aperture_pattern_lin(np.radians(theta_deg), ka)
    assert 0.0 <= g <= 1.0 + 1e-15


def test_gain_db_and_beam_edge_tr38821_ka():
    # Set-1 LEO-600 Ka: 38.5 dBi, 0.5 m at 20 GHz; -3.01 dB at half the half-power beamwidth.
    half = 0.5 * half_power_beamwidth_rad(20e9, 0.5)
    g = circular_aperture_gain_db(np.array([0.0, half]), 20e9, 0.5, 38.5)
    assert g[0] == 38.5
    assert g[1] == pytest.approx(38.5 - 10 * np.log10(2.0), abs=1e-6)
    assert np.degrees(2 * half) == pytest.approx(1.7676, abs=PRINTED_4_DIGITS)
    assert circular_aperture_gain_db(np.arcsin(FIRST_NULL_U / KA_BAND_KA * 1.0), 20e9, 0.5, 0) < -60


def test_ka_uses_the_diameter():
    # k a = pi D f / c with a = D / 2: 0.5 m at 20 GHz gives 104.79.
    assert aperture_ka(20e9, 0.5) == pytest.approx(2 * np.pi * 20e9 / SPEED_OF_LIGHT_M_S * 0.25)
    assert aperture_ka(20e9, 0.5) == pytest.approx(104.79, abs=0.01)
