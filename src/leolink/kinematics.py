"""Doppler shift, Doppler rate and angular speed of the UT-satellite line of sight.

Sec. 2.2.2 ("Satellite angular speed and Doppler effects") of [1]: Eq. (7), Eq. (8) and
its small-ROI shortcut Eq. (9), and the UT Doppler paragraph (unnumbered).
Positions, velocities and accelerations are given in one Earth-centred frame (ECI or
ECEF, consistently) as arrays ``(..., 3)``; every function broadcasts, callers add
axes (``sat_pos_m[:, None, :, :]``). Doppler is first order in ``v / c`` (classical).

Sign convention: positive Doppler = the received frequency is higher = the range is
shrinking. ``doppler_hz = doppler_sat_hz + doppler_ut_hz = -(f/c) d(range)/dt``.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
"""

import numpy as np

import leolink.compiled
from leolink.constants import EARTH_RADIUS_M, GM_EARTH_M3_S2, SPEED_OF_LIGHT_M_S
from leolink.orbit import orbital_speed_m_s

__all__ = [
    "angular_speed_rad_s",
    "doppler_hz",
    "doppler_rate_hz_s",
    "doppler_sat_hz",
    "doppler_ut_hz",
    "KINEMATICS_TERMS",
    "kinematics_terms",
    "link_kinematics",
    "max_angular_speed_rad_s",
    "max_doppler_sat_hz",
    "max_doppler_sat_small_roi_hz",
    "mean_abs_doppler_ut_hz",
    "range_rate_m_s",
    "propagation_delay_s",
    "delay_rate_from_doppler_s_s",
]


def _kinematics(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s=0.0, rel_acc_m_s2=0.0, freq_hz=1.0):
    """:func:`link_kinematics` of positions and states that broadcast, ``(..., 3)``."""
    los, v_sat, v_ut, acc = np.broadcast_arrays(
        np.asarray(sat_pos_m, dtype=float) - np.asarray(ut_pos_m, dtype=float),
        np.asarray(sat_vel_m_s, dtype=float),
        np.asarray(ut_vel_m_s, dtype=float),
        np.asarray(rel_acc_m_s2, dtype=float),
    )
    return link_kinematics(los, v_sat, v_ut, acc, freq_hz)


def doppler_sat_hz(sat_pos_m, sat_vel_m_s, ut_pos_m, freq_hz):
    """Doppler shift due to the satellite's motion, Eq. (7) of [1].

    ``Delta f_sat = <v_sat, (x_u - x_sat) / ||x_u - x_sat||> f / c``
    (positive when the satellite moves towards the UT).

    Parameters
    ----------
    sat_pos_m, sat_vel_m_s : array_like, shape (..., 3)
        Satellite position [m] and velocity [m/s].
    ut_pos_m : array_like, shape (..., 3)
        UT position [m].
    freq_hz : float or array_like
        Carrier frequency [Hz].

    Returns
    -------
    ndarray, shape (...)
        Doppler shift [Hz].
    """
    return _kinematics(sat_pos_m, sat_vel_m_s, ut_pos_m, freq_hz=freq_hz)["doppler_sat_hz"]


def doppler_ut_hz(ut_pos_m, ut_vel_m_s, sat_pos_m, freq_hz):
    """Doppler shift due to the UT's motion, Sec. 2.2 of [1].

    ``Delta f_u = <v_u, (x_sat - x_u) / ||x_sat - x_u||> f / c`` (positive when the UT
    moves towards the satellite). Shapes as in :func:`doppler_sat_hz`.
    """
    return _kinematics(sat_pos_m, 0.0, ut_pos_m, ut_vel_m_s, freq_hz=freq_hz)["doppler_ut_hz"]


def range_rate_m_s(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s=0.0):
    """Time derivative of the slant range ``rho' = <v_sat - v_u, l>`` [m/s], shape (...).

    ``l`` is the unit vector UT -> satellite; positive when the range grows.
    """
    return _kinematics(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s)["range_rate_m_s"]


def propagation_delay_s(slant_range_m):
    """One-way propagation delay over a slant range, ``d / c`` [s] (free space).

    Parameters
    ----------
    slant_range_m : array_like [m]

    Returns
    -------
    ndarray [s], the shape of the input.
    """
    return np.asarray(slant_range_m, float) / SPEED_OF_LIGHT_M_S


def delay_rate_from_doppler_s_s(doppler_hz, freq_hz):
    """Rate of the one-way delay ``rho' / c`` [s/s] from the total Doppler of the same link:
    :func:`doppler_hz` is ``-(f / c) rho'``, so ``rho' / c = -Delta f / f``.

    Parameters
    ----------
    doppler_hz : array_like [Hz], total Doppler shift (satellite and UT motion).
    freq_hz : float [Hz], carrier frequency.
    """
    return -np.asarray(doppler_hz, float) / freq_hz


def doppler_hz(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s, freq_hz):
    """Total Doppler shift ``Delta f_sat + Delta f_u = -(f/c) d(range)/dt`` [Hz], shape (...).

    Shapes as in :func:`doppler_sat_hz`; ``ut_vel_m_s`` (..., 3) [m/s] (0 for a static UT).
    """
    return _kinematics(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s, freq_hz=freq_hz)["doppler_hz"]


def doppler_rate_hz_s(
    sat_pos_m, sat_vel_m_s, sat_acc_m_s2, ut_pos_m, ut_vel_m_s, ut_acc_m_s2=0.0, *, freq_hz
):
    """Time derivative of the total Doppler, ``-(f/c) d^2(range)/dt^2`` [Hz/s].

    Exact: with ``r = x_sat - x_u``, ``v = v_sat - v_u``, ``a = a_sat - a_u`` and
    ``rho = |r|``, ``rho'' = (|v|^2 + <r, a> - rho'^2) / rho``.

    Parameters
    ----------
    sat_pos_m, sat_vel_m_s, sat_acc_m_s2 : array_like, shape (..., 3)
        Satellite state [m], [m/s], [m/s^2].
    ut_pos_m, ut_vel_m_s : array_like, shape (..., 3)
        UT position [m] and velocity [m/s].
    ut_acc_m_s2 : array_like, shape (..., 3), optional
        UT acceleration [m/s^2] (0: uniform motion; in ECEF a static UT has none).
    freq_hz : float or array_like, keyword-only
        Carrier frequency [Hz].

    Returns
    -------
    ndarray, shape (...)
        Doppler rate [Hz/s].
    """
    acc = np.asarray(sat_acc_m_s2, dtype=float) - np.asarray(ut_acc_m_s2, dtype=float)
    kin = _kinematics(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s, acc, freq_hz)
    return kin["doppler_rate_hz_s"]


def angular_speed_rad_s(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s=0.0):
    """Angular speed of the line of sight seen from the UT, ``|dl/dt|`` [rad/s].

    ``w_rel = |v_rel - <v_rel, l> l| / rho`` with ``v_rel = v_sat - v_u``. For a static
    UT this is the paper's Eq. (7),
    ``sqrt(1 - <v_sat/|v_sat|, l>^2) |v_sat| / rho``; a moving UT adds its own motion.

    Parameters
    ----------
    sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s : array_like, shape (..., 3)
        As in :func:`doppler_hz`.

    Returns
    -------
    ndarray, shape (...)
        Angular speed [rad/s], >= 0.
    """
    return _kinematics(sat_pos_m, sat_vel_m_s, ut_pos_m, ut_vel_m_s)["angular_speed_rad_s"]


def link_kinematics(los_m, sat_vel_m_s, ut_vel_m_s, rel_acc_m_s2, freq_hz):
    """Doppler (both parts), its rate, the range rate and the angular speed of many links.

    :func:`kinematics_terms` by name (the functions above call it).

    Parameters
    ----------
    los_m : ndarray, shape (..., 3)
        UT -> satellite vector [m].
    sat_vel_m_s, ut_vel_m_s : ndarray, shape (..., 3)
        Velocities [m/s].
    rel_acc_m_s2 : ndarray, shape (..., 3)
        Satellite minus UT acceleration [m/s^2].
    freq_hz : float
        Carrier frequency [Hz].

    Returns
    -------
    dict of ndarray, shape (...)
        ``doppler_sat_hz, doppler_ut_hz, doppler_hz, doppler_rate_hz_s, range_rate_m_s,
        angular_speed_rad_s``.
    """
    terms = kinematics_terms(los_m, sat_vel_m_s, ut_vel_m_s, rel_acc_m_s2, freq_hz)
    return dict(zip(KINEMATICS_TERMS, terms, strict=True))


#: The names of :func:`kinematics_terms`' values, in order.
KINEMATICS_TERMS = ("doppler_sat_hz", "doppler_ut_hz", "doppler_hz", "doppler_rate_hz_s",
                    "range_rate_m_s", "angular_speed_rad_s")  # fmt: skip


@leolink.compiled.jitable
def _dot(a, b):
    """``a . b`` over the last axis (3): arrays, or a compiled loop's rows."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


@leolink.compiled.jitable
def _norm2_of_difference(a, b):
    """``|a - b|^2`` over the last axis (3), without a temporary ``a - b``."""
    d0, d1, d2 = a[..., 0] - b[..., 0], a[..., 1] - b[..., 1], a[..., 2] - b[..., 2]
    return d0 * d0 + d1 * d1 + d2 * d2


@leolink.compiled.jitable
def kinematics_terms(los_m, sat_vel_m_s, ut_vel_m_s, rel_acc_m_s2, freq_hz):
    """The one place of the line of sight's kinematics (:data:`KINEMATICS_TERMS`, in order).

    With the unit vector ``l = los / rho`` UT -> satellite: ``rho' = <v_sat, l> - <v_u,
    l>``; Doppler Eq. (7) of [1] and the UT's, ``-(f/c) <v_sat, l>`` and ``(f/c) <v_u,
    l>``, their sum ``-(f/c) rho'``; its rate ``-(f/c) rho''`` with ``rho'' = (|v|^2 +
    <r, a> - rho'^2) / rho`` (``v = v_sat - v_u``, ``a`` the relative acceleration); the
    angular speed ``|v_perp| / rho`` with ``|v_perp|^2 = |v|^2 - rho'^2``. Arrays
    ``(..., 3)`` (values of shape (...)), or one link's rows in a compiled loop.
    """
    rho = np.sqrt(_dot(los_m, los_m))
    k = freq_hz / SPEED_OF_LIGHT_M_S
    v_sat = _dot(sat_vel_m_s, los_m) / rho
    v_ut = _dot(ut_vel_m_s, los_m) / rho
    v2 = _norm2_of_difference(sat_vel_m_s, ut_vel_m_s)
    rho_dot = v_sat - v_ut
    rho_ddot = (v2 + _dot(los_m, rel_acc_m_s2) - rho_dot**2) / rho
    angular = np.sqrt(np.maximum(v2 - rho_dot**2, 0.0)) / rho
    return -k * v_sat, k * v_ut, -k * rho_dot, -k * rho_ddot, rho_dot, angular


def max_doppler_sat_hz(rx_m, altitude_m, freq_hz, radius_m=EARTH_RADIUS_M, gm_m3_s2=GM_EARTH_M3_S2):
    """Maximum ``|Delta f_sat|`` over the ROI, Eq. (8) of [1].

    Reached at the along-track tip of the ROI, the ground point
    ``R (R u_z + R_x u_x) / sqrt(R^2 + R_x^2)`` (gnomonic projection of ``x = R_x``),
    at Earth-central angle ``alpha`` with ``tan(alpha) = R_x / R``::

        R R_x / sqrt(R^2 + R_x^2) v_sat / sqrt(R^2 + (R+h)^2 - 2 R^2 (R+h) / sqrt(R^2 + R_x^2)) f/c

    Parameters
    ----------
    rx_m : array_like
        Along-track ROI semi-axis [m] (the paper's Table: 534.1 km).
    altitude_m : array_like
        Satellite altitude [m].
    freq_hz : float or array_like
        Carrier frequency [Hz].
    radius_m, gm_m3_s2 : float
        Earth radius [m] and GM [m^3/s^2].

    Returns
    -------
    ndarray
        Maximum Doppler magnitude [Hz].
    """
    rx = np.asarray(rx_m, dtype=float)
    r_sat = radius_m + np.asarray(altitude_m, dtype=float)
    q = np.sqrt(radius_m**2 + rx**2)
    along_m = radius_m * rx / q
    rho_m = np.sqrt(radius_m**2 + r_sat**2 - 2.0 * radius_m**2 * r_sat / q)
    v = orbital_speed_m_s(altitude_m, radius_m, gm_m3_s2)
    return along_m / rho_m * v * freq_hz / SPEED_OF_LIGHT_M_S


def max_doppler_sat_small_roi_hz(
    rx_m, altitude_m, freq_hz, radius_m=EARTH_RADIUS_M, gm_m3_s2=GM_EARTH_M3_S2
):
    """The paper's shortcut ``R_x v_sat / h f / c``, Eq. (9) [Hz].

    Valid only when ``R_x << h`` (the paper states ``R_x << R_earth``, which is not
    enough: with the paper's ROI it overestimates by ~10 %, see docs/errata.md).
    """
    v = orbital_speed_m_s(altitude_m, radius_m, gm_m3_s2)
    return np.asarray(rx_m, dtype=float) * v / altitude_m * freq_hz / SPEED_OF_LIGHT_M_S


def max_angular_speed_rad_s(altitude_m, radius_m=EARTH_RADIUS_M, gm_m3_s2=GM_EARTH_M3_S2):
    """Maximum angular speed seen by a static UT, ``v_sat / h`` [rad/s], Eq. (8).

    Reached at the sub-satellite point (nadir), where the velocity is orthogonal to the
    line of sight and the range is shortest.
    """
    return orbital_speed_m_s(altitude_m, radius_m, gm_m3_s2) / np.asarray(altitude_m, float)


def mean_abs_doppler_ut_hz(speed_m_s, freq_hz):
    """Mean ``|Delta f_u|`` for a direction uniform on the sphere: ``v_u f / (2 c)`` [Hz].

    ``E|cos(theta)| = 1/2`` for ``cos(theta)`` uniform on ``[-1, 1]``. The paper writes
    ``v_u / 6 f / c`` (Sec. 2.2), which is wrong (docs/errata.md).
    """
    return 0.5 * np.asarray(speed_m_s, dtype=float) * freq_hz / SPEED_OF_LIGHT_M_S
