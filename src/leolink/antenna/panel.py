"""The UT panel frame: one frame for the terminal patterns, the engine and pointing errors.

A flat terminal panel lies in the local horizontal plane of the UT: panel ``x`` points
east, ``y`` north and the normal up (ENU of :func:`leolink.geometry.enu_basis`). A
direction ``v`` (unit vector) has panel direction cosines ``(v.x, v.y)``; a terminal
steered at direction ``b`` has gain ``pattern(v - b)`` towards ``v`` (offsets in these
cosines), which is how the engine weighs other satellites' beams and how pointing errors
are applied.
"""

import numpy as np

from leolink.geometry import ecef_to_geodetic, enu_basis

__all__ = ["panel_basis", "panel_direction_cosines", "pointing_offsets", "sky_direction"]


def panel_basis(ut_pos_m, radius_m=None):
    """Rows ``x`` (east), ``y`` (north), normal (up) of flat panels at ``ut_pos_m``.

    Parameters
    ----------
    ut_pos_m : array_like, shape (..., 3)
        UT positions, Earth-centred [m].
    radius_m : float, optional
        Unused for the sphere (the frame depends on the direction only); kept so that
        callers pass the Earth model they use.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    del radius_m
    lat, lon, _ = ecef_to_geodetic(ut_pos_m)
    return enu_basis(lat, lon)


def panel_direction_cosines(basis, unit_vec):
    """Direction cosines ``(v.x, v.y)`` of unit vectors in panel frames.

    Parameters
    ----------
    basis : ndarray, shape (n_ut, 3, 3)
        :func:`panel_basis` of each UT.
    unit_vec : ndarray, shape (n_ut, n_sat, 3)
        Unit vectors UT -> satellite.

    Returns
    -------
    ndarray, shape (n_ut, n_sat, 2)
    """
    return np.einsum("usk,uak->usa", unit_vec, basis[:, :2, :])


def sky_direction(elevation_rad, azimuth_rad):
    """Panel coordinates ``(x, y, z)`` of the direction at (elevation, azimuth from north).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    el, az = np.broadcast_arrays(np.asarray(elevation_rad, float), np.asarray(azimuth_rad, float))
    return np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)


def pointing_offsets(elevation_rad, off_boresight_rad, error_azimuth_rad, azimuth_rad=np.pi / 2):
    """Offsets ``(du_x, du_y)`` = beam - satellite direction of a beam pointed off target.

    The beam misses the satellite direction ``v`` (at ``elevation_rad``, ``azimuth_rad``)
    by the angle ``off_boresight_rad``, towards error azimuth ``psi`` around ``v``
    (0: towards higher elevation, pi/2: to the left of the satellite seen from the UT):
    ``b = cos(d) v + sin(d) (cos(psi) e_el + sin(psi) e_left)``. The default azimuth
    (the satellite due east) puts the panel ``x`` axis towards the satellite.

    Parameters
    ----------
    elevation_rad, off_boresight_rad, error_azimuth_rad, azimuth_rad : array_like
        Satellite elevation and azimuth (from north, clockwise), pointing error and its
        direction [rad]; broadcast.

    Returns
    -------
    du_x, du_y : ndarray, broadcast shape
        Offsets in the panel's direction cosines [-].
    """
    el, d, psi, az = np.broadcast_arrays(
        *(np.asarray(a, float) for a in (elevation_rad, off_boresight_rad, error_azimuth_rad,
                                          azimuth_rad))
    )  # fmt: skip
    sin_el, cos_el, sin_az, cos_az = np.sin(el), np.cos(el), np.sin(az), np.cos(az)
    # Towards higher elevation: (-sin el sin az, -sin el cos az, cos el); left: up x horizon.
    e_el = (-sin_el * sin_az, -sin_el * cos_az)
    e_left = (-cos_az, sin_az)
    v = (cos_el * sin_az, cos_el * cos_az)
    c, s = np.cos(d), np.sin(d)
    du_x = (c - 1.0) * v[0] + s * (np.cos(psi) * e_el[0] + np.sin(psi) * e_left[0])
    du_y = (c - 1.0) * v[1] + s * (np.cos(psi) * e_el[1] + np.sin(psi) * e_left[1])
    return du_x, du_y
