"""The WGS 84 ellipsoid: geodetic coordinates, Earth-fixed positions and their rates.

leolink's default Earth is the sphere of :mod:`leolink.geometry` (the paper's). With
``earth.model = "wgs84"`` user terminals sit on the WGS 84 ellipsoid: their latitude is
geodetic, their local vertical is the ellipsoid normal and elevations are measured from
the plane tangent to the ellipsoid. The local east/north/up frame at geodetic
``(lat, lon)`` has the same components as the sphere's at spherical ``(lat, lon)``, so
:func:`leolink.geometry.enu_basis` serves both.

Formulas are the exact closed forms (NIMA TR8350.2, Sec. 4): ``N = a / sqrt(1 - e^2
sin^2 lat)``; the inverse is iterated to convergence. Tests check both against pyproj
(PROJ, EPSG:4979 -> EPSG:4978) and skyfield's ``wgs84`` to 1 mm.

References
----------
.. [1] NIMA TR8350.2, "Department of Defense World Geodetic System 1984", 3rd ed., 2000.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "WGS84_A_M",
    "WGS84_E2",
    "WGS84_F",
    "ecef_to_wgs84",
    "radii_of_curvature_m",
    "wgs84_to_ecef",
    "wgs84_velocity",
]

#: Semi-major axis [m] and flattening of WGS 84 (TR8350.2, Table 3.1).
WGS84_A_M = 6_378_137.0
WGS84_F = 1.0 / 298.257223563
#: First eccentricity squared, ``f (2 - f)``.
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
#: Iterations of the inverse: each gains ~3 orders of magnitude; 6 reach 1e-15 rad for
#: heights from -10 km to 40,000 km.
_INVERSE_ITERATIONS = 6


def radii_of_curvature_m(lat_rad):
    """Meridian ``M`` and prime-vertical ``N`` radii of curvature at geodetic latitude [m].

    ``N = a / sqrt(1 - e^2 sin^2 lat)``, ``M = a (1 - e^2) / (1 - e^2 sin^2 lat)^(3/2)``.
    """
    w2 = 1.0 - WGS84_E2 * np.sin(np.asarray(lat_rad, float)) ** 2
    n = WGS84_A_M / np.sqrt(w2)
    return n * (1.0 - WGS84_E2) / w2, n


def wgs84_to_ecef(lat_rad, lon_rad, h_m=0.0):
    """Geodetic latitude, longitude and ellipsoidal height to Earth-fixed Cartesian.

    ``((N + h) cos lat cos lon, (N + h) cos lat sin lon, (N (1 - e^2) + h) sin lat)``.

    Parameters
    ----------
    lat_rad, lon_rad, h_m : array_like, broadcastable shape (...)
        Geodetic latitude, longitude [rad] and height above the ellipsoid [m].

    Returns
    -------
    ndarray, shape (..., 3)
        Position [m].
    """
    lat, lon, h = np.broadcast_arrays(*(np.asarray(a, float) for a in (lat_rad, lon_rad, h_m)))
    _, n = radii_of_curvature_m(lat)
    r_xy = (n + h) * np.cos(lat)
    z = (n * (1.0 - WGS84_E2) + h) * np.sin(lat)
    return np.stack([r_xy * np.cos(lon), r_xy * np.sin(lon), z], axis=-1)


def ecef_to_wgs84(pos_m):
    """Inverse of :func:`wgs84_to_ecef` (fixed-point iteration on the latitude).

    Parameters
    ----------
    pos_m : array_like, shape (..., 3)
        Earth-fixed position [m] (not at the centre).

    Returns
    -------
    lat_rad, lon_rad, h_m : ndarray, shape (...)
    """
    p_m = np.asarray(pos_m, float)
    x, y, z = p_m[..., 0], p_m[..., 1], p_m[..., 2]
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - WGS84_E2))
    for _ in range(_INVERSE_ITERATIONS):
        _, n = radii_of_curvature_m(lat)
        lat = np.arctan2(z + WGS84_E2 * n * np.sin(lat), p)
    _, n = radii_of_curvature_m(lat)
    # Stable at every latitude (no division by cos lat): h = p cos + z sin - a^2 / N.
    h = p * np.cos(lat) + z * np.sin(lat) - WGS84_A_M**2 / n
    return lat, np.arctan2(y, x), h


def wgs84_velocity(lat_rad, lon_rad, h_m, lat_rate_rad_s, lon_rate_rad_s, h_rate_m_s):
    """Earth-fixed velocity of a point moving in geodetic coordinates (exact chain rule).

    ``v = (M + h) lat' n + (N + h) cos(lat) lon' e + h' u`` with ``e, n, u`` the local
    east, north and up unit vectors (the derivative of :func:`wgs84_to_ecef`).

    Parameters
    ----------
    lat_rad, lon_rad, h_m : array_like, shape (...)
    lat_rate_rad_s, lon_rate_rad_s, h_rate_m_s : array_like, shape (...)
        Time derivatives [rad/s, rad/s, m/s].

    Returns
    -------
    ndarray, shape (..., 3)
        Velocity [m/s].
    """
    from leolink.geometry import enu_basis

    lat = np.asarray(lat_rad, float)
    h = np.asarray(h_m, float)
    m, n = radii_of_curvature_m(lat)
    basis = enu_basis(lat, lon_rad)
    v_east = (n + h) * np.cos(lat) * np.asarray(lon_rate_rad_s, float)
    v_north = (m + h) * np.asarray(lat_rate_rad_s, float)
    v_up = np.asarray(h_rate_m_s, float)
    return (
        v_east[..., None] * basis[..., 0, :]
        + v_north[..., None] * basis[..., 1, :]
        + v_up[..., None] * basis[..., 2, :]
    )
