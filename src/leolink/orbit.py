"""Satellite ephemerides: circular two-body orbits, Walker-delta, TLEs (sgp4), Earth rotation.

Shapes: states are ``(n_time, n_sat, 3)``. Circular orbits are exact two-body motion on a
sphere (no J2); TLEs go through ``sgp4`` with TEME taken as the inertial frame.
"""

from dataclasses import dataclass, field

import numpy as np

from leolink.constants import EARTH_RADIUS_M, EARTH_ROTATION_RAD_S, GM_EARTH_M3_S2
from leolink.errors import ConfigError

__all__ = [
    "CentralBody",
    "Elements",
    "Ephemeris",
    "angular_rate_rad_s",
    "circular_state",
    "eci_to_ecef",
    "orbital_period_s",
    "orbital_speed_m_s",
    "pass_over",
    "tle_state",
    "walker_delta",
]

SECONDS_PER_DAY = 86_400.0


def orbital_speed_m_s(altitude_m, radius_m=EARTH_RADIUS_M, gm_m3_s2=GM_EARTH_M3_S2):
    """Circular orbital speed ``sqrt(GM / (R + h))`` [m/s], Eq. (1) of the paper."""
    return np.sqrt(gm_m3_s2 / (radius_m + np.asarray(altitude_m, dtype=float)))


def angular_rate_rad_s(altitude_m, radius_m=EARTH_RADIUS_M, gm_m3_s2=GM_EARTH_M3_S2):
    """Circular mean motion ``sqrt(GM / (R + h)^3)`` [rad/s] (the paper's w_sat, after Eq. (1))."""
    a = radius_m + np.asarray(altitude_m, dtype=float)
    return np.sqrt(gm_m3_s2 / a**3)


def orbital_period_s(altitude_m, radius_m=EARTH_RADIUS_M, gm_m3_s2=GM_EARTH_M3_S2):
    """Circular orbital period ``2 pi sqrt((R + h)^3 / GM)`` [s]."""
    return 2.0 * np.pi / angular_rate_rad_s(altitude_m, radius_m, gm_m3_s2)


def _as_1d(x):
    return np.atleast_1d(np.asarray(x, dtype=float))


@dataclass(frozen=True)
class Elements:
    """Circular-orbit elements of ``n_sat`` satellites (1-D arrays, broadcast on creation).

    Attributes
    ----------
    altitude_m : ndarray, shape (n_sat,)
        Height above the sphere [m].
    inclination_rad, raan_rad : ndarray, shape (n_sat,)
        Inclination and right ascension of the ascending node [rad].
    arg_lat0_rad : ndarray, shape (n_sat,)
        Argument of latitude at t = 0 [rad].
    """

    altitude_m: np.ndarray
    inclination_rad: np.ndarray
    raan_rad: np.ndarray
    arg_lat0_rad: np.ndarray | float = field(default=0.0)  # 1-D array after __post_init__

    def __post_init__(self):
        names = ("altitude_m", "inclination_rad", "raan_rad", "arg_lat0_rad")
        arrays = np.broadcast_arrays(*(_as_1d(getattr(self, n)) for n in names))
        for name, arr in zip(names, arrays, strict=True):
            if arr.ndim != 1:
                raise ConfigError(f"Elements.{name} must be 1-D, got shape {arr.shape}")
            object.__setattr__(self, name, arr.copy())

    @property
    def n_sat(self):
        """Number of satellites."""
        return self.altitude_m.shape[0]

    def concat(self, *others):
        """Join element sets; ``a.concat(b, c)`` or ``Elements.concat(a, b, c)``."""
        parts = (self, *others)
        return Elements(
            *(
                np.concatenate([getattr(p, n) for p in parts])
                for n in ("altitude_m", "inclination_rad", "raan_rad", "arg_lat0_rad")
            )
        )


def circular_state(
    t_s,
    altitude_m,
    inclination_rad,
    raan_rad,
    arg_lat0_rad,
    radius_m=EARTH_RADIUS_M,
    gm_m3_s2=GM_EARTH_M3_S2,
):
    """Position, velocity and acceleration of circular two-body orbits, inertial frame.

    ``r = a (cos u P + sin u Q)``, ``u = u0 + n t``, with ``P`` towards the ascending node
    and ``Q = (-sin W cos i, cos W cos i, sin i)``; ``a = -n^2 r``.

    Parameters
    ----------
    t_s : array_like, shape (n_time,) or scalar
        Time since the element epoch [s].
    altitude_m, inclination_rad, raan_rad, arg_lat0_rad : array_like, shape (n_sat,) or scalar
        Circular elements [m, rad].
    radius_m, gm_m3_s2 : float
        Earth radius [m] and gravitational parameter [m^3/s^2].

    Returns
    -------
    pos_m, vel_m_s, acc_m_s2 : ndarray, shape (n_time, n_sat, 3)
    """
    t = _as_1d(t_s)[:, None]
    h, inc, raan, u0 = np.broadcast_arrays(
        *(_as_1d(x) for x in (altitude_m, inclination_rad, raan_rad, arg_lat0_rad))
    )
    a = radius_m + h
    n = np.sqrt(gm_m3_s2 / a**3)
    p_vec = np.stack([np.cos(raan), np.sin(raan), np.zeros_like(raan)], axis=-1)
    q_vec = np.stack([-np.sin(raan) * np.cos(inc), np.cos(raan) * np.cos(inc), np.sin(inc)], -1)
    u = (u0 + n * t)[..., None]  # (n_time, n_sat, 1)
    cos_u, sin_u = np.cos(u), np.sin(u)
    pos = a[:, None] * (cos_u * p_vec + sin_u * q_vec)
    vel = (a * n)[:, None] * (-sin_u * p_vec + cos_u * q_vec)
    acc = -((n * n)[:, None]) * pos
    return pos, vel, acc


def walker_delta(n_total, n_planes, phasing, inclination_rad, altitude_m):
    """Walker-delta constellation ``i: T/P/F``.

    Plane ``j`` has ``RAAN_j = 2 pi j / P``; satellite ``k`` of it has argument of latitude
    ``2 pi k / S + 2 pi F j / T`` with ``S = T / P``. Satellites are ordered plane by plane.

    Parameters
    ----------
    n_total, n_planes, phasing : int
        T (satellites), P (planes), F (phasing, 0 <= F < P).
    inclination_rad : float
        Inclination [rad].
    altitude_m : float
        Height [m].

    Returns
    -------
    Elements
        ``n_sat = T``.
    """
    if n_planes < 1 or n_total < 1 or n_total % n_planes:
        raise ConfigError(
            f"walker: n_total = {n_total!r} must be a positive multiple of n_planes = {n_planes!r}"
        )
    if not 0 <= phasing < n_planes:
        raise ConfigError(f"walker: phasing = {phasing!r} is not allowed; use 0 <= F < {n_planes}")
    per_plane = n_total // n_planes
    j, k = np.divmod(np.arange(n_total), per_plane)
    raan = 2.0 * np.pi * j / n_planes
    arg_lat = 2.0 * np.pi * k / per_plane + 2.0 * np.pi * phasing * j / n_total
    return Elements(altitude_m, inclination_rad, raan, np.mod(arg_lat, 2.0 * np.pi))


@dataclass(frozen=True)
class CentralBody:
    """The body an orbit is flown around: sphere radius [m], GM [m^3/s^2], and whether
    positions are Earth-fixed (``rotation``, angle ``gmst0_rad + w_E t``) or inertial."""

    radius_m: float = EARTH_RADIUS_M
    gm_m3_s2: float = GM_EARTH_M3_S2
    rotation: bool = False
    gmst0_rad: float = 0.0


def pass_over(
    lat_rad,
    lon_rad,
    t_pass_s,
    altitude_m,
    inclination_rad,
    ascending=True,
    earth=None,
):
    """One satellite whose sub-satellite point is ``(lat, lon)`` at ``t_pass_s``.

    ``sin(u) = sin(lat) / sin(i)`` (ascending: ``|u| <= pi/2``, else ``pi - u``); the node
    follows from the longitude. ``earth`` (:class:`CentralBody`, None: the default sphere
    without rotation) gives the radius and GM; with its ``rotation`` the point is the
    ECEF one of :func:`eci_to_ecef` (rotation angle ``gmst0 + w_E t``).

    Raises
    ------
    ConfigError
        If the orbit cannot reach that latitude (``|lat| > min(i, pi - i)``).
    """
    earth = CentralBody() if earth is None else earth
    lat, inc = float(lat_rad), float(inclination_rad)
    max_lat = min(inc, np.pi - inc)
    if abs(lat) > max_lat + 1e-12:
        raise ConfigError(
            f"pass_over: latitude {np.degrees(lat):.3f} deg is not reachable with inclination "
            f"{np.degrees(inc):.3f} deg; use |lat| <= {np.degrees(max_lat):.3f} deg"
        )
    sin_u = np.clip(np.sin(lat) / np.sin(inc), -1.0, 1.0) if np.sin(inc) > 0 else 0.0
    u = np.arcsin(sin_u) if ascending else np.pi - np.arcsin(sin_u)
    lon_eci = float(lon_rad)
    if earth.rotation:
        lon_eci += earth.gmst0_rad + EARTH_ROTATION_RAD_S * t_pass_s
    raan = lon_eci - np.arctan2(np.sin(u) * np.cos(inc), np.cos(u))
    n = angular_rate_rad_s(altitude_m, earth.radius_m, earth.gm_m3_s2)
    arg_lat0 = u - n * t_pass_s
    return Elements(altitude_m, inc, np.mod(raan, 2 * np.pi), np.mod(arg_lat0, 2 * np.pi))


def eci_to_ecef(pos_m, vel_m_s, acc_m_s2, t_s, gmst0_rad=0.0, rotation_rad_s=EARTH_ROTATION_RAD_S):
    """Rotate inertial states into the Earth-fixed frame (rotation angle ``gmst0 + w_E t``).

    ``r' = Rz(-theta) r``, ``v' = Rz(-theta)(v - w x r)``,
    ``a' = Rz(-theta) a - 2 w x v' - w x (w x r')`` (Coriolis and centrifugal terms).

    Parameters
    ----------
    pos_m, vel_m_s, acc_m_s2 : array_like, shape (n_time, ..., 3)
        Inertial states [m, m/s, m/s^2].
    t_s : array_like, shape (n_time,) or scalar
        Times of the leading axis [s].
    gmst0_rad : float
        Rotation angle at t = 0 [rad].
    rotation_rad_s : float
        Earth rotation rate [rad/s].

    Returns
    -------
    pos_m, vel_m_s, acc_m_s2 : ndarray, same shapes, Earth-fixed.
    """
    pos, vel, acc = (np.asarray(x, dtype=float) for x in (pos_m, vel_m_s, acc_m_s2))
    t = np.asarray(t_s, dtype=float)
    t = t.reshape(t.shape + (1,) * (pos.ndim - 1 - t.ndim))
    theta = gmst0_rad + rotation_rad_s * t
    c, s = np.cos(theta), np.sin(theta)

    def rot(v):  # Rz(-theta) v
        return np.stack(
            [c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1], v[..., 2]], -1
        )

    def w_cross(v):  # np.cross((0, 0, w), v), its operations one for one, without its copies
        x, y, z = v[..., 0], v[..., 1], v[..., 2]
        w = rotation_rad_s
        return np.stack([0.0 * z - w * y, w * x - 0.0 * z, 0.0 * y - 0.0 * x], -1)

    pos_f = rot(pos)
    vel_f = rot(vel - w_cross(pos))
    acc_f = rot(acc) - 2.0 * w_cross(vel_f) - w_cross(w_cross(pos_f))
    return pos_f, vel_f, acc_f


def _two_body_acc(pos_m, gm_m3_s2):
    r = np.linalg.norm(pos_m, axis=-1, keepdims=True)
    return -gm_m3_s2 * pos_m / r**3


def tle_state(satrec_array, jd, fr, gm_m3_s2=GM_EARTH_M3_S2):
    """Propagate TLEs with ``sgp4.api.SatrecArray.sgp4`` (TEME taken as inertial).

    Parameters
    ----------
    satrec_array : sgp4.api.SatrecArray or sequence of Satrec
        ``n_sat`` satellites.
    jd, fr : array_like, shape (n_time,)
        Julian date, split in whole and fractional parts [day].
    gm_m3_s2 : float
        For the two-body acceleration ``-GM r / |r|^3`` [m^3/s^2].

    Returns
    -------
    pos_m, vel_m_s, acc_m_s2 : ndarray, shape (n_time, n_sat, 3)
        NaN where sgp4 failed.
    error_code : ndarray of int, shape (n_time, n_sat)
        sgp4 error code, 0 = fine (a mask, not an exception).
    """
    from sgp4.api import SatrecArray

    if not isinstance(satrec_array, SatrecArray):
        satrec_array = SatrecArray(list(satrec_array))
    jd, fr = np.broadcast_arrays(_as_1d(jd), _as_1d(fr))
    err, r_km, v_km_s = satrec_array.sgp4(np.ascontiguousarray(jd), np.ascontiguousarray(fr))
    pos = np.swapaxes(r_km, 0, 1) * 1e3
    vel = np.swapaxes(v_km_s, 0, 1) * 1e3
    err = np.swapaxes(err, 0, 1).astype(int)
    bad = err != 0
    pos[bad], vel[bad] = np.nan, np.nan
    return pos, vel, _two_body_acc(pos, gm_m3_s2), err


class Ephemeris:
    """Callable ephemeris ``eph(t_s) -> (pos_m, vel_m_s, acc_m_s2)``, shapes (n_time, n_sat, 3).

    Build with :meth:`from_elements` or :meth:`from_tles`. The frame is ECEF when
    ``earth_rotation`` is on, inertial otherwise.
    """

    def __init__(self, propagate, n_sat, earth_rotation, gmst0_rad=0.0, names=None, some=None):
        self._propagate = propagate  # t_s (n_time,) -> (pos, vel, acc, err) inertial
        # (t_s, sats) -> the same of the satellites ``sats`` alone; None: all, then taken
        self._propagate_some = some
        self.n_sat = int(n_sat)
        self.earth_rotation = bool(earth_rotation)
        self.gmst0_rad = float(gmst0_rad)
        self.names = list(names) if names is not None else [str(i) for i in range(self.n_sat)]

    @classmethod
    def from_elements(
        cls,
        elements,
        earth_rotation=False,
        radius_m=EARTH_RADIUS_M,
        gm_m3_s2=GM_EARTH_M3_S2,
        gmst0_rad=0.0,
    ):
        """Circular orbits from :class:`Elements` (t = 0 at the element epoch)."""
        e = elements

        def propagate(t, sats=slice(None)):
            elements = (e.altitude_m, e.inclination_rad, e.raan_rad, e.arg_lat0_rad)
            state = circular_state(t, *(x[sats] for x in elements), radius_m, gm_m3_s2)
            return (*state, np.zeros(state[0].shape[:2], dtype=int))

        return cls(propagate, e.n_sat, earth_rotation, gmst0_rad, some=propagate)

    @classmethod
    def from_tles(
        cls,
        tles,
        epoch_jd,
        epoch_fr=0.0,
        earth_rotation=True,
        gm_m3_s2=GM_EARTH_M3_S2,
        ut1_minus_utc_s=0.0,
    ):
        """TLEs (``(name, line1, line2)`` tuples or ``Satrec`` objects) via sgp4.

        ``t_s`` counts from the UTC Julian date ``epoch_jd + epoch_fr`` [day] (TLE epochs
        are UTC). With Earth rotation, the rotation angle at that epoch is GMST82 of
        ``UT1 = UTC + ut1_minus_utc_s`` (sgp4's ``gstime``; TEME -> Earth-fixed, polar
        motion neglected, as skyfield without a polar-motion table).
        """
        from sgp4.api import Satrec, SatrecArray
        from sgp4.propagation import gstime

        sats, names = [], []
        for i, tle in enumerate(tles):
            if isinstance(tle, Satrec):
                sats.append(tle)
                names.append(str(tle.satnum))
            else:
                name, l1, l2 = tle if len(tle) == 3 else ("", *tle)
                sats.append(Satrec.twoline2rv(l1, l2))
                names.append(name or str(i))
        arr = SatrecArray(sats)

        def propagate(t):
            frac = epoch_fr + t / SECONDS_PER_DAY
            return tle_state(arr, np.full_like(t, float(epoch_jd)), frac, gm_m3_s2)

        gmst0 = gstime(float(epoch_jd) + (float(epoch_fr) + ut1_minus_utc_s / SECONDS_PER_DAY))
        return cls(propagate, len(sats), earth_rotation, gmst0, names)

    @property
    def propagates_some(self):
        """Whether ``eph(t, sats)`` propagates those satellites alone (circular orbits),
        not the whole set (then taken)."""
        return self._propagate_some is not None

    def state(self, t_s, sats=None):
        """Like ``__call__`` but also returns the sgp4 error codes, shape (n_time, n_sat)."""
        t = _as_1d(t_s)
        if sats is None:
            pos, vel, acc, err = self._propagate(t)
        elif self._propagate_some is not None:  # circular orbits: those satellites alone
            pos, vel, acc, err = self._propagate_some(t, np.asarray(sats, np.int64))
        else:
            pos, vel, acc, err = (a[:, sats] for a in self._propagate(t))
        if self.earth_rotation:
            pos, vel, acc = eci_to_ecef(pos, vel, acc, t, self.gmst0_rad)
        return pos, vel, acc, err

    def __call__(self, t_s, sats=None):
        """States at times ``t_s`` [s] (1-D or scalar), shapes (n_time, n_sat, 3); with
        ``sats`` (1-D ids), of those satellites alone, (n_time, len(sats), 3): each
        satellite's numbers those of the whole set (element-wise: circular orbits are
        propagated for those satellites only, others sliced)."""
        return self.state(t_s, sats)[:3]
