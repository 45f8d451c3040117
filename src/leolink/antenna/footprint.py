"""Beam footprints: the -3 dB contour of a DFT beam, in direction cosines and on the ground.

A DFT beam of an ``n_x x n_y`` half-wavelength subarray has the separable normalized gain
``g(du) = D(du_x, n_x) D(du_y, n_y) / (n_x n_y)`` (:func:`leolink.antenna.array.upa_gain`),
``D`` the Dirichlet kernel. Inside the main lobe (``|du_x| < 2/n_x``, ``|du_y| < 2/n_y``)
each factor falls monotonically from 1 to 0, so along every ray ``du = r (cos t, sin t)``
from the boresight the product crosses the half-power level exactly once. The contour is
found by bisection on ``r`` for all ``t`` at once (vectorized, no root-finder per point),
then each point is sent to the ground with :func:`leolink.geometry.ray_to_ground`.

Along an axis the half-power half-width solves ``sin^2(n x) / (n sin x)^2 = 1/2`` with
``x = pi du / 2``; for large ``n`` it tends to ``du = 0.8859 / n`` (the textbook
``sin(z)/z = 1/sqrt(2)`` at ``z = 1.3916``), which the tests use as an independent check.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO satellite
   communications", Sec. 2.2 (steering vectors) and 3.2 (DFT codebook).
.. [2] C. A. Balanis, "Antenna Theory", 4th ed., Wiley, 2016, Sec. 6.3 (uniform linear
   array, half-power beamwidth from ``sin(z)/z``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from leolink.antenna.array import upa_gain
from leolink.constants import EARTH_RADIUS_M
from leolink.geometry import ecef_to_geodetic, ray_to_ground

__all__ = [
    "HALF_POWER",
    "beam_contour_u",
    "beam_footprints_ground",
    "half_power_halfwidth_u",
]

HALF_POWER = 0.5  # -3.0103 dB: the "-3 dB" contour is the exact half-power one
_BISECTIONS = 60  # the bracket [0, 2/n] shrinks below 1e-18 in direction cosine


def _relative_gain(du_x, du_y, n_x, n_y):
    """Normalized gain in [0, 1] of a DFT beam at offset (du_x, du_y)."""
    return upa_gain(du_x, du_y, n_x, n_y) / (n_x * n_y)


def half_power_halfwidth_u(n):
    """Half-power half-width of an ``n``-element half-wavelength ULA beam [direction cosine].

    Parameters
    ----------
    n : int or array_like of int
        Elements.

    Returns
    -------
    ndarray
        ``du > 0`` with ``ula_gain(du, n) = n / 2``; ``inf`` for ``n = 1`` (isotropic).
    """
    n = np.asarray(n)
    theta = np.zeros(n.shape)  # ray along x
    with np.errstate(divide="ignore"):
        return _bisect_radius(theta, n, np.ones_like(n))


def _bisect_radius(theta_rad, n_x, n_y):
    """Radius of the half-power crossing along ``du = r (cos t, sin t)``, by bisection."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    with np.errstate(divide="ignore"):
        # First null along the ray: the product is 0 where either factor is.
        r_hi = np.minimum(2.0 / (n_x * np.abs(c)), 2.0 / (n_y * np.abs(s)))
    if np.any(n_x * n_y == 1):
        return np.where(n_x * n_y == 1, np.inf, _bisect_finite(c, s, n_x, n_y, r_hi))
    return _bisect_finite(c, s, n_x, n_y, r_hi)


def _bisect_finite(c, s, n_x, n_y, r_hi):
    lo, hi = np.zeros_like(r_hi), np.where(np.isfinite(r_hi), r_hi, 2.0)
    for _ in range(_BISECTIONS):  # fixed count: every ray converges together
        mid = 0.5 * (lo + hi)
        above = _relative_gain(mid * c, mid * s, n_x, n_y) > HALF_POWER
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    return 0.5 * (lo + hi)


def beam_contour_u(beam_u_xy, n_x, n_y, n_points=72):
    """Half-power (-3.01 dB) contour of DFT beams in direction-cosine space.

    Parameters
    ----------
    beam_u_xy : array_like, shape (n_beam, 2)
        Beam boresights ``(u_x, u_y)`` in the satellite body frame [-].
    n_x, n_y : int
        Elements of the subarray that forms each beam (``n_sub_x, n_sub_y``), both >= 2.
    n_points : int
        Points on each contour (angles evenly spaced around the boresight).

    Returns
    -------
    ndarray, shape (n_beam, n_points, 2)
        Contour points ``(u_x, u_y)`` [-], counter-clockwise in the (u_x, u_y) plane.
        Points with ``u_x^2 + u_y^2 > 1`` (outside visible space) are kept; they map to NaN
        on the ground.
    """
    offset = _contour_offset(int(n_x), int(n_y), int(n_points))
    return np.asarray(beam_u_xy, float).reshape(-1, 1, 2) + offset[None, :, :]


@lru_cache(maxsize=8)
def _contour_offset(n_x, n_y, n_points):
    """The contour about its boresight, ``(n_points, 2)`` [-]: the same for every beam of a
    codebook, so an animation's frames bisect it once (read-only, shared by the calls)."""
    theta = np.linspace(0.0, 2.0 * np.pi, n_points, endpoint=False)
    r = _bisect_radius(theta, np.asarray(n_x), np.asarray(n_y))  # (n_points,)
    offset = np.stack([r * np.cos(theta), r * np.sin(theta)], axis=-1)
    offset.flags.writeable = False
    return offset


def beam_footprints_ground(
    sat_pos_m, sat_vel_m_s, beam_u_xy, n_x, n_y, n_points=72, radius_m=EARTH_RADIUS_M
):
    """Half-power footprints of every beam of every satellite on the spherical Earth.

    Parameters
    ----------
    sat_pos_m, sat_vel_m_s : array_like, shape (n_sat, 3)
        Satellite positions [m] and velocities [m/s] in one Earth-centred frame; the
        velocity defines the body frame (:func:`leolink.geometry.body_frame`), so give the
        Earth-fixed one when the positions are Earth-fixed.
    beam_u_xy : array_like, shape (n_beam, 2)
        Beam boresights in the body frame [-], the same codebook on every satellite.
    n_x, n_y : int
        Subarray elements that form each beam.
    n_points : int
        Points per contour.
    radius_m : float
        Earth radius [m].

    Returns
    -------
    lat_deg, lon_deg : ndarray, shape (n_sat, n_beam, n_points)
        Contour on the ground [deg]; NaN where the contour ray misses the Earth.
        Longitudes are in (-180, 180]; a ring that crosses the antimeridian jumps there.
    """
    u = beam_contour_u(beam_u_xy, n_x, n_y, n_points)  # (n_beam, n_points, 2)
    pos = np.asarray(sat_pos_m, float).reshape(-1, 1, 1, 3)
    vel = np.asarray(sat_vel_m_s, float).reshape(-1, 1, 1, 3)
    ground = ray_to_ground(pos, vel, u[None], radius_m)  # (n_sat, n_beam, n_points, 3)
    lat, lon, _ = ecef_to_geodetic(ground, radius_m)
    return np.degrees(lat), np.degrees(lon)
