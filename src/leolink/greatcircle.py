"""Motion on a spherical Earth's great circles: where a heading leads, and its velocity.

Ground movers (sim/mobility/models.py) and the ROI's x axis (placement.py) follow great circles
of the sphere of :mod:`leolink.geometry` (R = ``earth.radius_m``). Closed forms of the
spherical triangle (E. Williams, "Aviation Formulary", "Lat/lon given radial and distance").
"""

import numpy as np

from leolink.constants import EARTH_RADIUS_M
from leolink.geometry import enu_basis

__all__ = ["destination_point", "great_circle_velocity"]


def destination_point(lat_rad, lon_rad, heading_rad, distance_m, radius_m=EARTH_RADIUS_M):
    """End point of a great-circle path from a start point, heading and distance.

    Parameters
    ----------
    lat_rad, lon_rad : array_like
        Start point [rad].
    heading_rad : array_like
        Initial heading from north, clockwise [rad].
    distance_m : array_like
        Distance along the sphere surface [m].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    lat_rad, lon_rad : ndarray
        End point [rad]; longitude wrapped to (-pi, pi].
    """
    delta = np.asarray(distance_m, dtype=float) / radius_m
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    sin_lat2 = sl * np.cos(delta) + cl * np.sin(delta) * np.cos(heading_rad)
    lat2 = np.arcsin(np.clip(sin_lat2, -1.0, 1.0))
    dlon = np.arctan2(np.sin(heading_rad) * np.sin(delta) * cl, np.cos(delta) - sl * sin_lat2)
    lon2 = np.angle(np.exp(1j * (np.asarray(lon_rad) + dlon)))
    return lat2, lon2


def great_circle_velocity(lat_rad, lon_rad, heading_rad, speed_m_s):
    """Earth-centred velocity of a ground mover on a great circle (tangent vector).

    Parameters
    ----------
    lat_rad, lon_rad : array_like
        Current position [rad].
    heading_rad : array_like
        Heading from north, clockwise [rad].
    speed_m_s : array_like
        Ground speed [m/s].

    Returns
    -------
    ndarray, shape (..., 3)
        Velocity ``speed (sin(h) east + cos(h) north)`` [m/s].
    """
    basis = enu_basis(lat_rad, lon_rad)
    h = np.asarray(heading_rad, dtype=float)[..., None]
    v = np.asarray(speed_m_s, dtype=float)[..., None]
    return v * (np.sin(h) * basis[..., 0, :] + np.cos(h) * basis[..., 1, :])
