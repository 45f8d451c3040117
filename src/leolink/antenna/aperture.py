"""Satellite reflector antenna with a circular aperture, 3GPP TR 38.811 Sec. 6.4.1.

The normalized pattern of a uniformly illuminated circular aperture of radius ``a``:

    G(theta) / G_max = 1                                     theta = 0
                     = 4 |J1(k a sin theta) / (k a sin theta)|^2   0 < |theta| <= 90 deg

with ``k = 2 pi f / c`` and ``theta`` the angle off boresight (the beam centre). TR 38.811
gives the pattern only; the peak gain ``G_max`` is a separate parameter, in TR 38.821
Table 6.1.1.1-1 (Set-1: 30 dBi for the 2 m S-band aperture, 38.5 dBi for the 0.5 m Ka-band
aperture). TR 38.821 quotes *aperture diameters*, so ``a = D / 2`` (the half-power
beamwidths of that table, 4.4127 and 1.7647 deg, follow from ``D``, not from ``a = D``).

Beyond 90 deg from boresight TR 38.811 does not define the pattern; leolink returns 0
(nothing radiated backwards), which the engine never needs for a nadir-facing antenna.

References
----------
.. [1] 3GPP TR 38.811 V15.4.0, "Study on New Radio (NR) to support non-terrestrial
   networks", Sec. 6.4.1, "HAPS/Satellite antenna".
.. [2] 3GPP TR 38.821 V16.1.0, Table 6.1.1.1-1 (Set-1 satellite parameters).
.. [3] C. A. Balanis, "Antenna Theory", 4th ed., Wiley 2016, chapter on aperture antennas
   (uniform circular aperture: first null at u = 3.8317, half power at u = 1.6163, first
   side lobe -17.6 dB).
"""

import numpy as np
from scipy.special import j1

from leolink.constants import SPEED_OF_LIGHT_M_S

__all__ = [
    "HALF_POWER_U",
    "aperture_ka",
    "aperture_peak_gain_dbi",
    "circular_aperture_gain_db",
    "circular_aperture_pattern_lin",
    "half_power_beamwidth_rad",
]

#: ``u`` at which ``(2 J1(u) / u)^2 = 1/2`` (root of the half-power equation, 7 digits).
HALF_POWER_U = 1.6163399
# Below this |u| the series (2 J1(u)/u)^2 = 1 - u^2/4 + 5 u^4/192 - ... replaces the quotient
# (truncation error < 3e-18; the quotient itself loses digits as u -> 0).
_U_TINY = 1e-4


def aperture_ka(freq_hz, diameter_m):
    """``k a = pi D f / c``, the pattern's argument scale [rad].

    Parameters
    ----------
    freq_hz : array_like
        Carrier frequency [Hz].
    diameter_m : array_like
        Aperture diameter ``D = 2 a`` [m].

    Returns
    -------
    ndarray
        ``k a`` [-].
    """
    return np.pi * np.asarray(diameter_m, dtype=float) * np.asarray(freq_hz) / SPEED_OF_LIGHT_M_S


def circular_aperture_pattern_lin(theta_rad, ka):
    """Normalized TR 38.811 Sec. 6.4.1 pattern ``4 |J1(ka sin theta) / (ka sin theta)|^2``.

    Parameters
    ----------
    theta_rad : array_like
        Angle off boresight [rad]; the pattern is 0 for ``|theta| > pi/2``.
    ka : array_like
        ``k a`` from :func:`aperture_ka`, broadcastable.

    Returns
    -------
    ndarray, broadcast shape
        Linear gain relative to the peak, in ``[0, 1]`` (1 on boresight).
    """
    theta = np.asarray(theta_rad, dtype=float)
    u = np.asarray(ka, dtype=float) * np.sin(theta)
    tiny = np.abs(u) < _U_TINY
    safe_u = np.where(tiny, 1.0, u)
    g = np.where(tiny, 1.0 - 0.25 * u * u, 4.0 * (j1(safe_u) / safe_u) ** 2)
    return np.where(np.abs(theta) <= 0.5 * np.pi, g, 0.0)


def circular_aperture_gain_db(theta_rad, freq_hz, diameter_m, gain_max_dbi):
    """Satellite antenna gain ``G_max + 10 log10(pattern)`` [dBi] (TR 38.811 Sec. 6.4.1).

    Parameters
    ----------
    theta_rad : array_like, shape (n_ut, n_sat, n_beam) or broadcastable
        Angle between the beam boresight and the direction to the UT [rad].
    freq_hz : float or array_like
        Carrier frequency [Hz].
    diameter_m : float
        Aperture diameter [m] (TR 38.821 Set-1: 2 m S band, 0.5 m Ka band).
    gain_max_dbi : float
        Boresight gain [dBi] (TR 38.821 Set-1: 30 dBi S band, 38.5 dBi Ka band).

    Returns
    -------
    ndarray
        Gain [dBi]; ``-inf`` on the pattern nulls and behind the antenna.
    """
    pattern = circular_aperture_pattern_lin(theta_rad, aperture_ka(freq_hz, diameter_m))
    with np.errstate(divide="ignore"):
        return gain_max_dbi + 10.0 * np.log10(pattern)


def half_power_beamwidth_rad(freq_hz, diameter_m):
    """Full half-power (3 dB) beamwidth ``2 arcsin(1.6163 / (k a))`` of the pattern [rad]."""
    return 2.0 * np.arcsin(HALF_POWER_U / aperture_ka(freq_hz, diameter_m))


def aperture_peak_gain_dbi(freq_hz, diameter_m, efficiency):
    """Peak gain of a circular aperture ``eta (pi D / lambda)^2`` [dBi].

    Only for apertures without a quoted gain: TR 38.821's 38.5 dBi (0.5 m, 20 GHz) and
    30 dBi (2 m, 2 GHz) correspond to efficiencies 0.65 and 0.57.

    Parameters
    ----------
    freq_hz : array_like
        Carrier frequency [Hz].
    diameter_m : array_like
        Aperture diameter [m].
    efficiency : array_like
        Aperture efficiency in (0, 1].

    Returns
    -------
    ndarray
        Peak gain [dBi].
    """
    ka = aperture_ka(freq_hz, diameter_m)
    return 10.0 * np.log10(np.asarray(efficiency, dtype=float) * ka**2)
