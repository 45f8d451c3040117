"""Elliptical region of interest (ROI) of one satellite, Sec. 3.1 of [1].

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO satellite
   communications", Sec. 3.1.
"""

from dataclasses import dataclass

import numpy as np

from leolink.constants import EARTH_RADIUS_M

__all__ = [
    "CoverageVerdict",
    "check_coverage",
    "coverage_condition",
    "in_ellipse",
    "roi_semi_axes_m",
]


def _half_spacings_m(n_planes, sats_per_plane, inclination_rad, radius_m):
    """Half grid spacings ``(pi R / N_s, pi R sin(i) / N_p)`` of Sec. 3.1 [m]."""
    dx = np.pi * radius_m / sats_per_plane
    dy = np.pi * radius_m * np.sin(inclination_rad) / n_planes
    return dx, dy


def roi_semi_axes_m(n_planes, sats_per_plane, inclination_rad, radius_m=EARTH_RADIUS_M):
    """ROI semi-axes that just close the coverage gaps, Eq. (13) of [1].

    ``rx = sqrt(2) pi R / N_s``, ``ry = sqrt(2) pi R sin(i) / N_p``.

    Parameters
    ----------
    n_planes : int
        Number of orbital planes N_p.
    sats_per_plane : int
        Satellites per plane N_s.
    inclination_rad : float
        Inclination of the planes theta_op [rad].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    rx_m, ry_m : float
        Along-track and cross-track semi-axes [m]. For the paper's Table (83 x 53 at 53 deg)
        this gives 534.1 x 272.4 km; the Table prints 170.5 km for ry (docs/errata.md).
    """
    dx, dy = _half_spacings_m(n_planes, sats_per_plane, inclination_rad, radius_m)
    return np.sqrt(2.0) * dx, np.sqrt(2.0) * dy


def coverage_condition(
    rx_m, ry_m, n_planes, sats_per_plane, inclination_rad, radius_m=EARTH_RADIUS_M
):
    """Left side of the coverage condition, Eq. (12) of [1]: ``(dx/rx)^2 + (dy/ry)^2``.

    Parameters
    ----------
    rx_m, ry_m : array_like
        ROI semi-axes [m].
    n_planes, sats_per_plane : int
        N_p and N_s.
    inclination_rad : float
        Inclination [rad].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    float or ndarray
        ``<= 1`` means the ellipses leave no gap.
    """
    dx, dy = _half_spacings_m(n_planes, sats_per_plane, inclination_rad, radius_m)
    return (dx / np.asarray(rx_m)) ** 2 + (dy / np.asarray(ry_m)) ** 2


@dataclass(frozen=True)
class CoverageVerdict:
    """Result of :func:`check_coverage`: condition value, yes/no and a readable sentence."""

    value: float
    covers: bool
    message: str


def check_coverage(rx_m, ry_m, n_planes, sats_per_plane, inclination_rad, radius_m=EARTH_RADIUS_M):
    """Say in plain words whether an ROI of ``rx x ry`` covers the whole Earth.

    Returns
    -------
    CoverageVerdict
        ``value`` of :func:`coverage_condition`, ``covers = value <= 1`` and a message giving,
        when there are gaps, the smallest ``ry`` that closes them for this ``rx``.
    """
    value = float(
        coverage_condition(rx_m, ry_m, n_planes, sats_per_plane, inclination_rad, radius_m)
    )
    dx, dy = _half_spacings_m(n_planes, sats_per_plane, inclination_rad, radius_m)
    roi = f"ROI {rx_m / 1e3:.1f} x {ry_m / 1e3:.1f} km"
    if value <= 1.0:
        return CoverageVerdict(value, True, f"{roi} covers the Earth: condition {value:.2f} <= 1")
    if rx_m <= dx:
        fix = f"rx must exceed {dx / 1e3:.1f} km before any ry can close them"
    else:
        ry_min = dy / np.sqrt(1.0 - (dx / rx_m) ** 2)
        fix = f"the smallest ry that closes them for this rx is {ry_min / 1e3:.1f} km"
    return CoverageVerdict(value, False, f"{roi} leaves gaps: condition {value:.2f} > 1; {fix}")


def in_ellipse(x_m, y_m, rx_m, ry_m):
    """Whether ROI-plane points lie inside (or on) the ellipse ``(x/rx)^2 + (y/ry)^2 <= 1``.

    Parameters
    ----------
    x_m, y_m : array_like
        ROI-plane coordinates [m] (NaN counts as outside).
    rx_m, ry_m : float
        Semi-axes [m].

    Returns
    -------
    ndarray of bool, broadcast shape
    """
    return (np.asarray(x_m) / rx_m) ** 2 + (np.asarray(y_m) / ry_m) ** 2 <= 1.0
