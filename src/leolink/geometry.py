"""Frames and angles on a spherical Earth: ECEF, ENU, satellite body frame, ROI plane.

All functions are pure numpy and broadcast; vectors carry xyz on the last axis ``(..., 3)``.
Positions are in one Earth-centred frame (ECI or ECEF); nothing here depends on which.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO satellite
   communications", Sec. 3.1 (ROI parametrization).
"""

import numpy as np

import leolink.compiled
from leolink.constants import EARTH_RADIUS_M

__all__ = [
    "azimuth_deg",
    "azimuth_in_frame_deg",
    "azimuth_on_sphere_deg",
    "azimuth_of_deg",
    "body_frame",
    "direction_cosines",
    "earth_central_angle_rad",
    "ecef_to_geodetic",
    "elevation_from_nadir_rad",
    "enu_basis",
    "geodetic_to_ecef",
    "ground_to_roi",
    "look_angles",
    "nadir_angle_rad",
    "ray_to_ground",
    "roi_to_ground",
    "slant_range_from_elevation_m",
]


def _dot(a, b):
    """Dot product over the last axis."""
    return np.sum(np.asarray(a) * np.asarray(b), axis=-1)


def _unit(v):
    """Vector divided by its norm (last axis)."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def geodetic_to_ecef(lat_rad, lon_rad, alt_m=0.0, radius_m=EARTH_RADIUS_M):
    """Spherical latitude, longitude, altitude to Earth-centred Cartesian coordinates.

    Parameters
    ----------
    lat_rad, lon_rad : array_like, broadcastable shape (...)
        Latitude and longitude [rad].
    alt_m : array_like, broadcastable shape (...)
        Height above the sphere [m].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    ndarray, shape (..., 3)
        Position [m].
    """
    lat, lon, alt = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (lat_rad, lon_rad, alt_m))
    )
    r = radius_m + alt
    return np.stack(
        [r * np.cos(lat) * np.cos(lon), r * np.cos(lat) * np.sin(lon), r * np.sin(lat)], axis=-1
    )


def ecef_to_geodetic(pos_m, radius_m=EARTH_RADIUS_M):
    """Inverse of :func:`geodetic_to_ecef` (spherical Earth).

    Parameters
    ----------
    pos_m : array_like, shape (..., 3)
        Position [m].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    lat_rad, lon_rad, alt_m : ndarray, shape (...)
        Latitude in [-pi/2, pi/2], longitude in (-pi, pi] [rad]; height [m].
    """
    p = np.asarray(pos_m, dtype=float)
    rho = np.hypot(p[..., 0], p[..., 1])
    lat = np.arctan2(p[..., 2], rho)
    lon = np.arctan2(p[..., 1], p[..., 0])
    alt = np.hypot(rho, p[..., 2]) - radius_m
    return lat, lon, alt


def enu_basis(lat_rad, lon_rad):
    """Local east, north, up unit vectors of the sphere.

    Parameters
    ----------
    lat_rad, lon_rad : array_like, broadcastable shape (...)
        Latitude and longitude [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Rows east, north, up (Earth-centred components).
    """
    lat, lon = np.broadcast_arrays(np.asarray(lat_rad, float), np.asarray(lon_rad, float))
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    east = np.stack([-so, co, np.zeros_like(lat)], axis=-1)
    north = np.stack([-sl * co, -sl * so, cl], axis=-1)
    up = np.stack([cl * co, cl * so, sl], axis=-1)
    return np.stack([east, north, up], axis=-2)


def body_frame(sat_pos_m, sat_vel_m_s):
    """Satellite body frame: x along-track, z radial (up), y = z x x.

    ``u_z = r/|r|``; ``u_x`` is the unit part of ``v`` orthogonal to ``u_z``. With the
    velocity of an Earth-fixed frame (Earth rotation on), x follows the ground track:
    a yaw-steered satellite, whose beams stay aligned with the track it draws on the ground.
    ``u_y = u_z x u_x`` (right-handed). The paper (Sec. 3.1) takes ``u_x = v/|v|`` and
    ``u_y = u_x x u_sat``, the opposite sign of y (see docs/errata.md).

    Parameters
    ----------
    sat_pos_m : array_like, shape (..., 3)
        Satellite position [m].
    sat_vel_m_s : array_like, shape (..., 3)
        Satellite velocity in the same frame [m/s].

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Rows ``u_x, u_y, u_z``; ``frame @ d`` expresses ``d`` in the body frame.
    """
    # Few satellites, every epoch: written for little per-call overhead (np.cross and
    # np.linalg.norm cost more in dispatch than in arithmetic on such small arrays).
    r, v = np.broadcast_arrays(np.asarray(sat_pos_m, float), np.asarray(sat_vel_m_s, float))
    frame = np.empty(r.shape[:-1] + (3, 3))
    u_x, u_y, u_z = frame[..., 0, :], frame[..., 1, :], frame[..., 2, :]
    np.divide(r, np.sqrt(np.einsum("...k,...k->...", r, r))[..., None], out=u_z)
    t = v - np.einsum("...k,...k->...", v, u_z)[..., None] * u_z
    np.divide(t, np.sqrt(np.einsum("...k,...k->...", t, t))[..., None], out=u_x)
    for i, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):  # u_y = u_z x u_x
        u_y[..., i] = u_z[..., j] * u_x[..., k] - u_z[..., k] * u_x[..., j]
    return frame


def look_angles(ut_pos_m, sat_pos_m):
    """Elevation, azimuth and slant range of a satellite seen from a ground point.

    The local vertical is that of the sphere (radial direction of ``ut_pos_m``).

    Parameters
    ----------
    ut_pos_m : array_like, shape (..., 3)
        User terminal position [m].
    sat_pos_m : array_like, shape (..., 3)
        Satellite position, same frame [m].

    Returns
    -------
    elevation_rad : ndarray, shape (...)
        Elevation above the local horizontal [rad], in [-pi/2, pi/2].
    azimuth_rad : ndarray, shape (...)
        Azimuth from north, clockwise towards east [rad], in [0, 2 pi).
    slant_range_m : ndarray, shape (...)
        Distance UT-satellite [m].
    """
    ut = np.asarray(ut_pos_m, dtype=float)
    d = np.asarray(sat_pos_m, dtype=float) - ut
    lat, lon, _ = ecef_to_geodetic(ut)
    east, north, up = np.moveaxis(enu_basis(lat, lon), -2, 0)
    slant_range_m = np.linalg.norm(d, axis=-1)
    elevation_rad = np.arcsin(np.clip(_dot(d, up) / slant_range_m, -1.0, 1.0))
    azimuth_rad = np.mod(np.arctan2(_dot(d, east), _dot(d, north)), 2.0 * np.pi)
    return elevation_rad, azimuth_rad, slant_range_m


def azimuth_deg(los, ut_pos_m, ut_enu):
    """Azimuth of each row's link ``los (n, 3)`` (UT -> satellite) [deg], [0, 360), in the
    local frame ``ut_enu (n, 3, 3)`` (rows east, north, up: :func:`azimuth_in_frame_deg`)
    or, without it, the sphere's at ``ut_pos_m (n, 3)`` (:func:`azimuth_on_sphere_deg`)."""
    if ut_enu is not None:
        return azimuth_in_frame_deg(los, ut_enu)
    return azimuth_on_sphere_deg(los, ut_pos_m)


@leolink.compiled.jitable
def azimuth_in_frame_deg(los, enu):
    """``atan2(los . east, los . north)`` [deg], [0, 360), ``enu`` (..., 3, 3) rows east,
    north, up (arrays, or one link's rows in a compiled loop)."""
    e, n = enu[..., 0, :], enu[..., 1, :]
    east = los[..., 0] * e[..., 0] + los[..., 1] * e[..., 1] + los[..., 2] * e[..., 2]
    north = los[..., 0] * n[..., 0] + los[..., 1] * n[..., 1] + los[..., 2] * n[..., 2]
    return azimuth_of_deg(east, north)


@leolink.compiled.jitable
def azimuth_on_sphere_deg(los, pos_m):
    """Azimuth [deg], [0, 360), in the sphere's local frame at ``p = (x, y, z)``:
    ``h^2 = x^2 + y^2``, ``r = |p|``, east ``(-y, x, 0) / h`` and north ``(-z x, -z y,
    h^2) / (h r)``; both components times ``h r > 0`` leave the angle unchanged, so
    ``atan2(r (x l_y - y l_x), h^2 l_z - z (x l_x + y l_y))``: no trigonometry but the
    last arctangent (the same angle as through latitude and longitude, to ~1e-13 deg)."""
    x, y, z = pos_m[..., 0], pos_m[..., 1], pos_m[..., 2]
    lx, ly, lz = los[..., 0], los[..., 1], los[..., 2]
    h2 = x * x + y * y
    east = np.sqrt(h2 + z * z) * (x * ly - y * lx)
    north = h2 * lz - z * (x * lx + y * ly)
    return azimuth_of_deg(east, north)


@leolink.compiled.jitable
def azimuth_of_deg(east, north):
    """Azimuth [deg] in [0, 360) of the horizontal components (east, north) (any common
    positive scale): ``atan2(east, north)`` wrapped. A direction a rounding west of north
    (``atan2`` ~ -1e-15 deg) is 0, not ``np.mod``'s 360.0."""
    az = np.mod(np.degrees(np.arctan2(east, north)), 360.0)
    return leolink.compiled.select(az < 360.0, az, 0.0)


def slant_range_from_elevation_m(elevation_rad, altitude_m, radius_m=EARTH_RADIUS_M):
    """Slant range from the elevation angle (law of cosines, triangle centre-UT-satellite).

    ``d = sqrt(R^2 sin^2(el) + h^2 + 2 R h) - R sin(el)``.

    Parameters
    ----------
    elevation_rad : array_like
        Elevation of the satellite seen from the ground [rad].
    altitude_m : array_like
        Satellite height above the sphere [m].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    ndarray, broadcast shape
        Slant range [m].
    """
    s = radius_m * np.sin(elevation_rad)
    h = np.asarray(altitude_m, dtype=float)
    return np.sqrt(s * s + h * h + 2.0 * radius_m * h) - s


def nadir_angle_rad(elevation_rad, altitude_m, radius_m=EARTH_RADIUS_M):
    """Off-nadir angle at the satellite: ``sin(eta) = R cos(el) / (R + h)`` (law of sines).

    Parameters
    ----------
    elevation_rad : array_like
        Elevation seen from the ground [rad].
    altitude_m : array_like
        Satellite height [m].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    ndarray
        Angle between the nadir and the satellite-UT direction [rad].
    """
    return np.arcsin(radius_m * np.cos(elevation_rad) / (radius_m + np.asarray(altitude_m)))


def earth_central_angle_rad(elevation_rad, altitude_m, radius_m=EARTH_RADIUS_M):
    """Earth-central angle between a ground point and a satellite it sees at ``elevation_rad``:
    ``pi / 2 - el - eta``, ``eta`` the off-nadir angle (:func:`nadir_angle_rad`; the angles
    of the triangle centre-UT-satellite, whose angle at the UT is ``pi / 2 + el``).

    Parameters
    ----------
    elevation_rad : array_like
        Elevation above the plane normal to the point's radius [rad].
    altitude_m : array_like
        Satellite height above the point's radius [m].
    radius_m : array_like
        Distance of the point from the Earth's centre [m].

    Returns
    -------
    ndarray
        The angle [rad]; it grows with the satellite's radius and shrinks as the elevation
        or the point's radius grows.
    """
    return np.pi / 2 - elevation_rad - nadir_angle_rad(elevation_rad, altitude_m, radius_m)


def elevation_from_nadir_rad(nadir_rad, altitude_m, radius_m=EARTH_RADIUS_M):
    """Inverse of :func:`nadir_angle_rad`; NaN where the ray misses the Earth.

    Parameters
    ----------
    nadir_rad : array_like
        Off-nadir angle at the satellite [rad].
    altitude_m : array_like
        Satellite height [m].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    ndarray
        Elevation seen from the ground [rad].
    """
    cos_el = (radius_m + np.asarray(altitude_m)) * np.sin(nadir_rad) / radius_m
    with np.errstate(invalid="ignore"):
        return np.where(cos_el <= 1.0, np.arccos(np.minimum(cos_el, 1.0)), np.nan)


def direction_cosines(sat_pos_m, sat_vel_m_s, target_pos_m):
    """Direction cosines ``(u_x, u_y)`` of the satellite-to-target unit vector, body frame.

    Targets on the visible Earth have a negative ``u_z`` component (not returned).

    Parameters
    ----------
    sat_pos_m, sat_vel_m_s : array_like, shape (..., 3)
        Satellite position [m] and velocity [m/s].
    target_pos_m : array_like, shape (..., 3)
        Target position, same frame [m].

    Returns
    -------
    ndarray, shape (..., 2)
        ``(u_x, u_y)`` [-].
    """
    frame = body_frame(sat_pos_m, sat_vel_m_s)
    d = _unit(np.asarray(target_pos_m, dtype=float) - np.asarray(sat_pos_m, dtype=float))
    return np.stack([_dot(frame[..., 0, :], d), _dot(frame[..., 1, :], d)], axis=-1)


def ray_to_ground(sat_pos_m, sat_vel_m_s, u_xy, radius_m=EARTH_RADIUS_M):
    """Ground point hit by the ray leaving the satellite along direction cosines ``u_xy``.

    The ray points Earthwards (``u_z = -sqrt(1 - u_x^2 - u_y^2)``); the first intersection
    with the sphere is returned. Inverse of :func:`direction_cosines` on the visible cap.

    Parameters
    ----------
    sat_pos_m, sat_vel_m_s : array_like, shape (..., 3)
        Satellite position [m] and velocity [m/s].
    u_xy : array_like, shape (..., 2)
        Direction cosines in the body frame [-].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    ndarray, shape (..., 3)
        Ground position [m]; NaN where the ray misses the sphere or ``|u_xy| > 1``.
    """
    frame = body_frame(sat_pos_m, sat_vel_m_s)
    u = np.asarray(u_xy, dtype=float)
    ux, uy = u[..., 0], u[..., 1]
    with np.errstate(invalid="ignore"):
        uz = -np.sqrt(1.0 - ux * ux - uy * uy)
        d = ux[..., None] * frame[..., 0, :] + uy[..., None] * frame[..., 1, :]
        d = d + uz[..., None] * frame[..., 2, :]
        s = np.asarray(sat_pos_m, dtype=float)
        b = _dot(s, d)
        disc = b * b - (_dot(s, s) - radius_m**2)
        t = -b - np.sqrt(disc)  # nearest of the two intersections
        t = np.where((disc >= 0.0) & (t >= 0.0), t, np.nan)
    return s + t[..., None] * d


def roi_to_ground(x_m, y_m, sat_pos_m, sat_vel_m_s, radius_m=EARTH_RADIUS_M):
    """ROI-plane point ``(x, y)`` to the sphere, Sec. 3.1 of [1].

    ``p = R (R u_z + x u_x + y u_y) / sqrt(R^2 + x^2 + y^2)``: the plane tangent to the
    sphere below the satellite is projected from Earth's centre (gnomonic projection;
    the paper calls it stereographic, see docs/errata.md). Axes are those of
    :func:`body_frame` (leolink's ``u_y`` is the paper's ``-u_y``).

    Parameters
    ----------
    x_m, y_m : array_like, shape (...)
        Along-track and cross-track coordinates in the ROI plane [m].
    sat_pos_m, sat_vel_m_s : array_like, shape (..., 3)
        Satellite position [m] and velocity [m/s].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    ndarray, shape (..., 3)
        Ground position [m].
    """
    frame = body_frame(sat_pos_m, sat_vel_m_s)
    x = np.asarray(x_m, dtype=float)[..., None]
    y = np.asarray(y_m, dtype=float)[..., None]
    num = radius_m * frame[..., 2, :] + x * frame[..., 0, :] + y * frame[..., 1, :]
    return radius_m * num / np.sqrt(radius_m**2 + x * x + y * y)


def ground_to_roi(pos_m, sat_pos_m, sat_vel_m_s, radius_m=EARTH_RADIUS_M):
    """Exact inverse of :func:`roi_to_ground`: ``x = R (p.u_x)/(p.u_z)``, ``y = R (p.u_y)/(p.u_z)``.

    Parameters
    ----------
    pos_m : array_like, shape (..., 3)
        Ground position [m] (its norm does not matter: a central projection).
    sat_pos_m, sat_vel_m_s : array_like, shape (..., 3)
        Satellite position [m] and velocity [m/s].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    x_m, y_m : ndarray, shape (...)
        ROI-plane coordinates [m]; NaN on the hemisphere facing away (``p.u_z <= 0``).
    """
    frame = body_frame(sat_pos_m, sat_vel_m_s)
    p = np.asarray(pos_m, dtype=float)
    pz = _dot(p, frame[..., 2, :])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(pz > 0.0, radius_m / pz, np.nan)
    return scale * _dot(p, frame[..., 0, :]), scale * _dot(p, frame[..., 1, :])
