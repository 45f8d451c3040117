"""Flat-panel scan loss: the element factor ``cos^q`` of the angle off the panel normal.

A phased array's gain towards a direction ``theta`` off the panel normal is the array
factor times the (embedded) element gain pattern. For a flat panel leolink models the
element power pattern as

    g_e(theta) = cos(theta)^q      |theta| < 90 deg,     0 behind the panel,

normalized to 1 on the normal, so a beam steered to ``theta_0`` loses
``L_scan = -10 q log10(cos theta_0)`` dB against broadside (Hannan: array gain = N times
the element gain). ``q = 1`` is the projected-aperture limit of an ideally matched panel
(directivity ~ ``4 pi A cos(theta) / lambda^2``); measured panels roll off faster because
of the active mismatch and the element's own pattern, which ``q > 1`` absorbs.

The default ``q = 1.2`` is the cosine roll-off factor of the Kymeta flat-panel
(metasurface) terminal quoted by the paper [1] (Sec. 2.1: "a 1.2 cosine roll-off factor",
``33 - 1.2 * 10 log10(sin el)`` dB for a panel facing up); leolink applies the same
exponent to the UPA and leaky-wave panels unless the config sets another ``q``.

Angles are those of a panel lying flat (normal = local up) unless a scan angle is given:
``theta = 90 deg - elevation``; in the panel's direction cosines ``sin theta =
sqrt(u_x^2 + u_y^2)``.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO satellite
   communications", Sec. 2.1 (Kymeta terminal, 1.2 cosine roll-off).
.. [2] P. W. Hannan, "The element-gain paradox for a phased-array antenna", IEEE Trans.
   Antennas Propag. 12(4), 1964 (array gain = N x element gain; cos(theta) for a matched
   half-wavelength lattice).
.. [3] R. J. Mailloux, "Phased Array Antenna Handbook", 2nd ed., Artech House 2005
   (element pattern and scan loss of planar arrays).
"""

import numpy as np

from leolink.antenna.array import upa_gain

__all__ = [
    "DEFAULT_SCAN_EXPONENT",
    "element_factor_lin",
    "flat_panel_scan_loss_db",
    "panel_gain_lin",
    "scan_angle_rad",
    "scan_loss_db",
]

#: Default cosine exponent ``q`` (Kymeta roll-off factor quoted in Sec. 2.1 of the paper).
DEFAULT_SCAN_EXPONENT = 1.2


def scan_angle_rad(u_x, u_y):
    """Angle off the panel normal of the direction with panel direction cosines ``(u_x, u_y)``.

    ``arcsin(sqrt(u_x^2 + u_y^2))`` for the front hemisphere (``u_x^2 + u_y^2 <= 1``); NaN
    for the invisible region.
    """
    rho = np.hypot(np.asarray(u_x, dtype=float), np.asarray(u_y, dtype=float))
    with np.errstate(invalid="ignore"):
        return np.where(rho <= 1.0, np.arcsin(np.minimum(rho, 1.0)), np.nan)


def element_factor_lin(scan_rad, exponent=DEFAULT_SCAN_EXPONENT):
    """Element power pattern ``cos(theta)^q`` in front of the panel, 0 behind it.

    Parameters
    ----------
    scan_rad : array_like
        Angle off the panel normal [rad]; ``|theta| >= pi/2`` is behind the panel (0).
    exponent : float or array_like
        Cosine exponent ``q >= 0`` [-].

    Returns
    -------
    ndarray, broadcast shape
        Linear factor in ``[0, 1]``, 1 on the normal.
    """
    theta = np.asarray(scan_rad, dtype=float)
    # Test the angle, not cos > 0: cos(pi/2) is 6e-17 in floating point.
    front = np.abs(theta) < 0.5 * np.pi
    c = np.where(front, np.cos(theta), 1.0)
    return np.where(front, c ** np.asarray(exponent, dtype=float), 0.0)


def scan_loss_db(scan_rad, exponent=DEFAULT_SCAN_EXPONENT):
    """Scan loss ``-10 q log10(cos theta)`` [dB] (positive; ``inf`` at and beyond 90 deg).

    Parameters
    ----------
    scan_rad : array_like
        Steering angle off the panel normal [rad].
    exponent : float or array_like
        Cosine exponent ``q`` [-].

    Returns
    -------
    ndarray
        Loss against broadside [dB], ``>= 0``.
    """
    with np.errstate(divide="ignore"):
        return -10.0 * np.log10(element_factor_lin(scan_rad, exponent))


def flat_panel_scan_loss_db(elevation_rad, exponent=DEFAULT_SCAN_EXPONENT):
    """Scan loss of a panel lying flat towards a satellite at ``elevation_rad``.

    The scan angle is ``pi/2 - el``, so the loss is ``-10 q log10(sin el)`` (the paper's
    metasurface roll-off with the sign of docs/errata.md); ``inf`` for ``el <= 0``.
    """
    return scan_loss_db(0.5 * np.pi - np.asarray(elevation_rad, dtype=float), exponent)


def panel_gain_lin(u_xy, beam_u_xy, n_x, n_y, exponent=DEFAULT_SCAN_EXPONENT):
    """Gain of a half-wavelength ``n_x x n_y`` panel with element factor ``cos^q``.

    ``g_e(theta(u)) * ula(u_x - b_x, n_x) * ula(u_y - b_y, n_y)``: the Dirichlet array
    factor of a DFT beam ``b`` (peak ``n_x n_y``) times the element pattern towards ``u``.

    Parameters
    ----------
    u_xy : array_like, shape (..., 2)
        Directions in the panel's direction cosines [-].
    beam_u_xy : array_like, shape (..., 2), broadcastable
        Beam (steering) directions [-].
    n_x, n_y : int
        Elements along x and y.
    exponent : float
        Cosine exponent ``q`` [-].

    Returns
    -------
    ndarray, broadcast shape without the last axis
        Linear gain; ``n_x n_y cos(theta_0)^q`` at the beam peak ``u = b``.
    """
    u = np.asarray(u_xy, dtype=float)
    b = np.asarray(beam_u_xy, dtype=float)
    af = upa_gain(u[..., 0] - b[..., 0], u[..., 1] - b[..., 1], n_x, n_y)
    return af * element_factor_lin(scan_angle_rad(u[..., 0], u[..., 1]), exponent)
