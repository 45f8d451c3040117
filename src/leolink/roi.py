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
    "closest_overhead_pass",
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


#: Instants sampled in the pass window before the golden-section refinement, and how
#: many of them one ephemeris call evaluates (every satellite's state: bounded memory).
_PASS_SAMPLES, _PASS_BLOCK = 97, 8
#: Golden-section steps refining the overhead instant: the bracket (two samples, ~2.5 min
#: for a LEO pass) shrinks 0.618x each, to < 1 ms.
_PASS_REFINE = 36


def _sin_elevation(sat_pos_m, site_pos_m, site_up):
    """sin(elevation) of satellites (..., 3) seen from a site; -2 where unknown (NaN)."""
    d = sat_pos_m - site_pos_m
    s = np.einsum("...k,k->...", d, site_up) / np.linalg.norm(d, axis=-1)
    return np.where(np.isfinite(s), s, -2.0)


def closest_overhead_pass(ephemeris, t0_s, site_pos_m, site_up, gm_m3_s2=3.986004418e14):
    """The satellite highest above a site at ``t0_s``, and the instant of its closest
    approach to the site's zenith on that pass.

    The satellite is the one with the highest elevation at ``t0_s``; its pass is searched
    within ``t0_s +- P / 8`` (``P`` its orbital period from ``|r|`` and ``GM``: the part of
    an orbit in which a LEO satellite seen at ``t0_s`` stays in view), on 97 instants, then
    refined by golden-section search between the neighbours of the best. Used for the ROI
    frame: its x axis follows this satellite's ground track (ascending or descending, as
    its ephemeris says), whatever the length of the run.

    Parameters
    ----------
    ephemeris : callable
        ``ephemeris(t_s (n_t,)) -> (pos_m, vel_m_s, acc_m_s2)``, each (n_t, n_sat, 3).
    t0_s : float
        Reference instant, e.g. the run's first epoch [s].
    site_pos_m, site_up : array_like, shape (3,)
        Site position [m] and unit local vertical, in the ephemeris frame.
    gm_m3_s2 : float
        Gravitational parameter for the period [m^3/s^2].

    Returns
    -------
    sat : int
        Index of the satellite.
    t_s : float
        Instant of its highest elevation on that pass [s].
    pos_m, vel_m_s : ndarray, shape (3,)
        Its state then.
    """
    site, up = np.asarray(site_pos_m, float), np.asarray(site_up, float)
    pos0 = ephemeris(np.array([float(t0_s)]))[0][0]
    k = int(np.argmax(_sin_elevation(pos0, site, up)))
    period_s = 2.0 * np.pi * np.sqrt(np.sum(pos0[k] ** 2) ** 1.5 / gm_m3_s2)
    grid = t0_s + np.linspace(-period_s / 8.0, period_s / 8.0, _PASS_SAMPLES)
    # In blocks of a few instants: an ephemeris call holds every satellite's state.
    s = np.concatenate(
        [
            _sin_elevation(ephemeris(grid[i : i + _PASS_BLOCK])[0][:, k], site, up)
            for i in range(0, len(grid), _PASS_BLOCK)
        ]
    )
    i = int(np.argmax(s))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]

    def sin_el(t):
        return _sin_elevation(ephemeris(np.array([t]))[0][0, k], site, up)

    golden = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = b - golden * (b - a), a + golden * (b - a)
    fc, fd = sin_el(c), sin_el(d)
    for _ in range(_PASS_REFINE):  # the elevation is unimodal near its maximum
        if fc >= fd:  # one new evaluation per step: the other point is reused
            b, d, fd = d, c, fc
            c = b - golden * (b - a)
            fc = sin_el(c)
        else:
            a, c, fc = c, d, fd
            d = a + golden * (b - a)
            fd = sin_el(d)
    t = 0.5 * (a + b)
    pos, vel, _ = ephemeris(np.array([t]))
    return k, float(t), pos[0, k], vel[0, k]
