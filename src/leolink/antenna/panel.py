"""The UT panel frame: one frame for the terminal patterns, the engine and pointing errors.

A flat terminal panel lies in the local horizontal plane of the UT: panel ``x`` points
east, ``y`` north and the normal up (ENU of :func:`leolink.geometry.enu_basis`). A
direction ``v`` (unit vector) has panel direction cosines ``(v.x, v.y)``; a terminal
steered at direction ``b`` has gain ``pattern(v - b)`` towards ``v`` (offsets in these
cosines), which is how the engine weighs other satellites' beams and how pointing errors
are applied.

A population may turn and tilt its panels (:class:`PanelOrientation`,
:func:`oriented_panel_basis`): the x axis at an azimuth, or along the UT's motion, and the
normal tilted towards it; terminals then see the satellite at its angle above the panel
plane (:func:`panel_elevation_rad`) instead of its elevation.
"""

import numpy as np

from leolink.geometry import ecef_to_geodetic, enu_basis

__all__ = [
    "PanelOrientation",
    "motion_azimuth_rad",
    "oriented_panel_basis",
    "panel_basis",
    "panel_direction_cosines",
    "panel_elevation_rad",
    "pointing_offsets",
    "sky_direction",
]


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


def oriented_panel_basis(enu, tilt_rad, x_azimuth_rad):
    """Panel rows ``x``, ``y``, normal of panels turned and tilted in the local frame.

    The panel's ``x`` axis points at azimuth ``x_azimuth_rad`` (from north, clockwise;
    pi/2 = east, the frame of :func:`panel_basis`), and the normal tilts from local up by
    ``tilt_rad`` towards ``+x``: ``x' = cos(t) h - sin(t) up``, ``n' = sin(t) h + cos(t) up``,
    ``y' = n' x x'`` (right-handed; ``t = 0``, azimuth pi/2 gives east, north, up).

    Parameters
    ----------
    enu : ndarray, shape (n_ut, 3, 3)
        Local east, north, up rows.
    tilt_rad, x_azimuth_rad : array_like, shape (n_ut,) or scalar
        Tilt of the normal [rad] and azimuth of the panel x axis [rad].

    Returns
    -------
    ndarray, shape (n_ut, 3, 3)
    """
    tilt = np.asarray(tilt_rad, float)[..., None]
    az = np.asarray(x_azimuth_rad, float)[..., None]
    east, north, up = enu[:, 0, :], enu[:, 1, :], enu[:, 2, :]
    h = np.sin(az) * east + np.cos(az) * north
    x = np.cos(tilt) * h - np.sin(tilt) * up
    n = np.sin(tilt) * h + np.cos(tilt) * up
    return np.stack([x, np.cross(n, x), n], axis=1)


def motion_azimuth_rad(enu, vel_m_s, fallback_rad):
    """Azimuth of the horizontal velocity [rad] (from north, clockwise); ``fallback_rad``
    where the UT does not move horizontally (a static UT keeps its configured panel)."""
    east = np.einsum("uk,uk->u", vel_m_s, enu[:, 0, :])
    north = np.einsum("uk,uk->u", vel_m_s, enu[:, 1, :])
    moving = np.hypot(east, north) > 1e-9
    return np.where(moving, np.arctan2(east, north), fallback_rad)


def panel_elevation_rad(basis, unit_vec):
    """Angle above the panel plane ``arcsin(v . n)`` of unit vectors UT -> satellite.

    Parameters
    ----------
    basis : ndarray, shape (n_ut, 3, 3)
    unit_vec : ndarray, shape (n_ut, n_sat, 3)

    Returns
    -------
    ndarray, shape (n_ut, n_sat) [rad]; the elevation itself for a panel lying flat.
    """
    s = np.einsum("usk,uk->us", unit_vec, basis[:, 2, :])
    return np.arcsin(np.clip(s, -1.0, 1.0))


class PanelOrientation:
    """Each UT's panel: tilt and x-axis azimuth, or the azimuth of its motion.

    Parameters
    ----------
    tilt_rad : array_like, shape (n_ut,)
    x_azimuth_rad : array_like, shape (n_ut,)
        Fixed azimuth of the panel x axis [rad]; also the fallback of a UT that follows
        its motion but stands still.
    follow_motion : array_like of bool, shape (n_ut,)
        The x axis follows the horizontal velocity (cars, trains, ships, aircraft).
    """

    def __init__(self, tilt_rad, x_azimuth_rad, follow_motion):
        self.tilt_rad = np.asarray(tilt_rad, float)
        self.x_azimuth_rad = np.asarray(x_azimuth_rad, float)
        self.follow_motion = np.asarray(follow_motion, bool)

    def basis(self, enu, vel_m_s):
        """Panel rows (n_ut, 3, 3) of UTs with local frames ``enu`` moving at ``vel_m_s``."""
        az = self.x_azimuth_rad
        if self.follow_motion.any():
            az = np.where(self.follow_motion, motion_azimuth_rad(enu, vel_m_s, az), az)
        return oriented_panel_basis(enu, self.tilt_rad, az)
