"""User-terminal (UT) motion models: every UT's state at a time ``t``, all UTs at once.

A motion model holds ``n_ut`` terminals; its ``state(t_s)`` returns a :class:`UTState`
for all of them (vectorized; no Python loop over UTs). Frame: Earth-centred, Earth-fixed,
spherical Earth of radius ``EARTH_RADIUS_M`` (the inertial frame when Earth rotation is
off). Models: :class:`Static`, :class:`ConstantVelocity` (great circles) and
:class:`Waypoints` (time-stamped tracks: configured waypoints, recorded CSV/GPX files).
How config populations become these objects: :mod:`leolink.sim.mobility.populations`.
"""

from dataclasses import dataclass

import numpy as np

from leolink import compiled
from leolink.constants import EARTH_RADIUS_M
from leolink.errors import ConfigError
from leolink.geometry import ecef_to_geodetic, enu_basis, geodetic_to_ecef
from leolink.greatcircle import great_circle_velocity

__all__ = [
    "SPEED_PRESETS_M_S",
    "ConstantVelocity",
    "OnWgs84",
    "Static",
    "Track",
    "SelectedUTs",
    "UTState",
    "Waypoints",
    "concat_states",
    "resolve_speed_m_s",
    "take_uts",
]

#: Typical ground speeds [m/s], usable by name in configs.
SPEED_PRESETS_M_S = {
    "static": 0.0,
    "pedestrian": 1.4,
    "car": 30.0,
    "train": 100.0,
    "ship": 10.0,
    "aircraft": 250.0,
}


@dataclass(frozen=True)
class UTState:
    """Kinematic state of ``n_ut`` terminals at one time (Earth-fixed frame, sphere).

    Attributes
    ----------
    pos_m, vel_m_s, acc_m_s2 : ndarray, shape (n_ut, 3)
        Position [m], velocity [m/s] and acceleration [m/s^2].
    lat_rad, lon_rad, alt_m : ndarray, shape (n_ut,)
        Spherical latitude, longitude [rad] and height above the sphere [m].
    """

    pos_m: np.ndarray
    vel_m_s: np.ndarray
    acc_m_s2: np.ndarray
    lat_rad: np.ndarray
    lon_rad: np.ndarray
    alt_m: np.ndarray

    @property
    def n_ut(self):
        """Number of terminals."""
        return self.pos_m.shape[0]


def concat_states(states):
    """Stack the states of several populations into one (UT order is kept).

    Parameters
    ----------
    states : sequence of UTState
        States at the same time.

    Returns
    -------
    UTState
        ``n_ut`` is the sum over ``states``.
    """
    states = list(states)
    if not states:
        raise ValueError("concat_states needs at least one UTState")
    fields = ("pos_m", "vel_m_s", "acc_m_s2", "lat_rad", "lon_rad", "alt_m")
    return UTState(*(np.concatenate([getattr(s, f) for s in states], axis=0) for f in fields))


def resolve_speed_m_s(speed):
    """A speed given as a number [m/s] or a preset name of :data:`SPEED_PRESETS_M_S`."""
    if isinstance(speed, str) and speed not in SPEED_PRESETS_M_S:
        names = ", ".join(sorted(SPEED_PRESETS_M_S))
        raise ConfigError(f"speed preset {speed!r} is unknown; use one of {names} or m/s")
    return SPEED_PRESETS_M_S[speed] if isinstance(speed, str) else speed


def _vec(a, n, name):
    """``a`` as a float array broadcast to shape (n,)."""
    try:
        return np.broadcast_to(np.asarray(a, dtype=float), (n,)).copy()
    except ValueError:
        raise ConfigError(f"{name} has shape {np.shape(a)}; expected a scalar or ({n},)") from None


class Static:
    """Terminals that do not move (in the Earth-fixed frame).

    Parameters
    ----------
    lat_rad, lon_rad, alt_m : array_like, shape (n_ut,) or scalar
        Position [rad, rad, m].
    """

    moves = False  # the simulator runs no motion process for these UTs

    def __init__(self, lat_rad, lon_rad, alt_m=0.0):
        n = np.broadcast(np.asarray(lat_rad), np.asarray(lon_rad), np.asarray(alt_m)).size
        self.lat_rad, self.lon_rad = _vec(lat_rad, n, "lat_rad"), _vec(lon_rad, n, "lon_rad")
        self.alt_m = _vec(alt_m, n, "alt_m")
        self._pos_m, self.n_ut = geodetic_to_ecef(self.lat_rad, self.lon_rad, self.alt_m), n

    def state(self, t_s):
        """State at ``t_s`` [s]: fixed position, zero velocity and acceleration."""
        zero = np.zeros((self.n_ut, 3))
        lat, lon, alt = self.lat_rad.copy(), self.lon_rad.copy(), self.alt_m.copy()
        return UTState(self._pos_m.copy(), zero, zero.copy(), lat, lon, alt)

    def states(self, times_s):
        """:meth:`state` at each of ``times_s`` (n_t,): a leading time axis, read-only views."""
        v, zero = (len(times_s), self.n_ut), np.broadcast_to(0.0, (len(times_s), self.n_ut, 3))
        lat, lon, alt = (np.broadcast_to(a, v) for a in (self.lat_rad, self.lon_rad, self.alt_m))
        return UTState(np.broadcast_to(self._pos_m, zero.shape), zero, zero, lat, lon, alt)

    def take(self, index):
        """The UTs ``index`` (:func:`take_uts`)."""
        return Static(self.lat_rad[index], self.lon_rad[index], self.alt_m[index])


class ConstantVelocity:
    """Terminals moving along great circles at constant speed and constant height.

    ``speed_m_s`` is the magnitude of the UT velocity: the great circle of radius
    ``R + alt`` is covered at angular rate ``speed / (R + alt)``, so the distance along
    the sea-level sphere is ``speed t R/(R + alt)`` (0.16 % less for an aircraft at 10 km;
    exact equality for ground UTs). The acceleration is the centripetal term
    ``-speed^2/(R + alt) u_up`` of uniform great-circle motion.

    Parameters
    ----------
    lat0_rad, lon0_rad : array_like, shape (n_ut,)
        Position at ``t0_s`` [rad].
    alt_m : array_like, shape (n_ut,)
        Height above the sphere [m].
    heading_rad : array_like, shape (n_ut,)
        Initial heading from north, clockwise [rad].
    speed_m_s : array_like or str, shape (n_ut,)
        Speed [m/s] (>= 0) or the name of a preset of :data:`SPEED_PRESETS_M_S`.
    t0_s : float
        Time at which the UTs are at ``(lat0, lon0)`` [s].
    radius_m : float
        Earth radius [m].
    """

    def __init__(
        self, lat0_rad, lon0_rad, alt_m, heading_rad, speed_m_s, t0_s=0.0, radius_m=EARTH_RADIUS_M
    ):
        speed_m_s = resolve_speed_m_s(speed_m_s)
        args = [
            np.asarray(a, dtype=float) for a in (lat0_rad, lon0_rad, alt_m, heading_rad, speed_m_s)
        ]
        n = np.broadcast(*args).size
        self.lat0_rad, self.lon0_rad, self.alt_m, self.heading_rad, self.speed_m_s = (
            _vec(a, n, name)
            for a, name in zip(
                args, ("lat0_rad", "lon0_rad", "alt_m", "heading_rad", "speed_m_s"), strict=True
            )
        )
        if np.any(~(self.speed_m_s >= 0.0)):
            raise ConfigError(f"speed_m_s = {speed_m_s!r} is not allowed; use values >= 0")
        self.t0_s, self.radius_m, self.n_ut = float(t0_s), float(radius_m), n
        self._u0 = enu_basis(self.lat0_rad, self.lon0_rad)[..., 2, :]  # up at the start
        self._e0 = great_circle_velocity(self.lat0_rad, self.lon0_rad, self.heading_rad, 1.0)

    def state(self, t_s):
        """State at ``t_s`` [s] (scalar), all UTs at once."""
        at = self.states(np.array([float(t_s)]))
        return UTState(at.pos_m[0], at.vel_m_s[0], at.acc_m_s2[0], at.lat_rad[0], at.lon_rad[0],
                       self.alt_m.copy())  # fmt: skip

    def states(self, times_s):
        """:meth:`state` at each of ``times_s`` (n_t,), a leading time axis: every value by
        :func:`great_circle_state` (in one compiled pass where the loops run)."""
        r_m = self.radius_m + self.alt_m
        # The great circle u(phi) = cos(phi) u0 + sin(phi) e0, phi = distance / r: two
        # trigonometric calls per UT (the simulator moves every UT every epoch).
        phi = self.speed_m_s * (np.asarray(times_s, float)[:, None] - self.t0_s) / r_m
        alt = np.broadcast_to(self.alt_m, phi.shape)
        if compiled.use(phi.size):
            vectors = tuple(np.empty(phi.shape + (3,)) for _ in range(3))
            out = (*vectors, np.empty(phi.shape), np.empty(phi.shape))
            _great_circle_rows(phi, (self._u0, self._e0, r_m, self.speed_m_s), out)
            return UTState(*out, alt)
        pos, vel, acc, lat, lon = great_circle_state(phi, self._u0, self._e0, r_m, self.speed_m_s)
        vectors = (np.stack(v, axis=-1) for v in (pos, vel, acc))
        return UTState(*vectors, lat, lon, alt)

    def take(self, index):
        """The UTs ``index`` (:func:`take_uts`)."""
        rows = (self.lat0_rad, self.lon0_rad, self.alt_m, self.heading_rad, self.speed_m_s)
        return ConstantVelocity(*(a[index] for a in rows), self.t0_s, self.radius_m)


@compiled.jitable
def great_circle_state(phi_rad, u0, e0, r_m, speed_m_s):
    """A mover's state after the arc ``phi`` along its great circle ``u(phi) = cos(phi) u0
    + sin(phi) e0`` (``u0`` the unit up at the start, ``e0`` the unit tangent of the
    heading): position ``r u``, velocity ``v u'(phi)`` and the centripetal acceleration
    ``-(v^2 / r) u`` [m, m/s, m/s^2], each as its (x, y, z) components, then the spherical
    latitude and longitude of ``u`` [rad]. Arrays (``phi`` (..., n); ``u0``, ``e0``
    (n, 3); ``r_m``, ``speed_m_s`` (n,)), or one mover's scalars and 3-vectors in a
    compiled loop (:func:`_great_circle_rows`)."""
    c, s = np.cos(phi_rad), np.sin(phi_rad)
    up = (c * u0[..., 0] + s * e0[..., 0], c * u0[..., 1] + s * e0[..., 1],
          c * u0[..., 2] + s * e0[..., 2])  # fmt: skip
    tangent = (c * e0[..., 0] - s * u0[..., 0], c * e0[..., 1] - s * u0[..., 1],
               c * e0[..., 2] - s * u0[..., 2])  # fmt: skip
    k = -(speed_m_s * speed_m_s / r_m)
    pos = (r_m * up[0], r_m * up[1], r_m * up[2])
    vel = (speed_m_s * tangent[0], speed_m_s * tangent[1], speed_m_s * tangent[2])
    acc = (k * up[0], k * up[1], k * up[2])
    lat = np.arcsin(np.minimum(np.maximum(up[2], -1.0), 1.0))
    return pos, vel, acc, lat, np.arctan2(up[1], up[0])


@compiled.jit
def _great_circle_rows(phi, movers, out):
    """:func:`great_circle_state` of every (time, UT) of ``phi`` (n_t, n_ut) into ``out``
    (pos, vel, acc (n_t, n_ut, 3); lat, lon (n_t, n_ut)); ``movers``: (u0, e0, r_m,
    speed_m_s) of the UTs."""
    u0, e0, r_m, speed = movers
    pos, vel, acc, lat, lon = out
    for t in range(phi.shape[0]):
        for i in range(phi.shape[1]):
            p, v, a, lat[t, i], lon[t, i] = great_circle_state(phi[t, i], u0[i], e0[i],
                                                               r_m[i], speed[i])  # fmt: skip
            for k in range(3):
                pos[t, i, k], vel[t, i, k], acc[t, i, k] = p[k], v[k], a[k]


@dataclass(frozen=True)
class Track:
    """Time-stamped track of one UT (waypoints).

    Attributes
    ----------
    time_s : ndarray, shape (n_point,)
        Strictly increasing times [s].
    lat_rad, lon_rad, alt_m : ndarray, shape (n_point,)
        Waypoints [rad, rad, m].
    ut_id : str
        Label of the UT (the CSV ``ut`` column, or the file name).
    """

    time_s: np.ndarray
    lat_rad: np.ndarray
    lon_rad: np.ndarray
    alt_m: np.ndarray
    ut_id: str = "0"

    def __post_init__(self):
        arrays = [
            np.atleast_1d(np.asarray(a, dtype=float))
            for a in (self.time_s, self.lat_rad, self.lon_rad, self.alt_m)
        ]
        if len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1 or arrays[0].size < 1:
            raise ConfigError(
                f"track {self.ut_id!r}: time, lat, lon, alt must be 1-D arrays of "
                f"one common length >= 1, got shapes {[a.shape for a in arrays]}"
            )
        if not np.all(np.isfinite(np.stack(arrays))):
            raise ConfigError(f"track {self.ut_id!r}: values must be finite (no NaN/inf)")
        if np.any(np.diff(arrays[0]) <= 0.0):
            raise ConfigError(f"track {self.ut_id!r}: time_s must increase strictly")
        for name, a in zip(("time_s", "lat_rad", "lon_rad", "alt_m"), arrays, strict=True):
            object.__setattr__(self, name, a)


class Waypoints:
    """Terminals following their own time-stamped tracks (one :class:`Track` per UT).

    Between two waypoints the UT moves along the great-circle arc (spherical linear
    interpolation of the unit vectors, linear in angle) at constant angular rate, its height
    changing linearly: ``p(t) = (R + h(t)) u(t)``. Velocity and acceleration are the exact
    time derivatives of that motion inside the segment (the segment velocity; the kinks at
    waypoints are not smoothed, the state is right-continuous). Before its first time and
    from its last time on, a UT holds the end point with zero velocity and acceleration.
    Consecutive antipodal waypoints are rejected (the arc is undefined).

    Parameters
    ----------
    tracks : sequence of Track
        One track per UT (``n_ut`` tracks).
    radius_m : float
        Earth radius [m].
    """

    def __init__(self, tracks, radius_m=EARTH_RADIUS_M):
        tracks = list(tracks)
        if not tracks:
            raise ConfigError("Waypoints needs at least one track")
        self.tracks, self.radius_m, self.n_ut = tracks, float(radius_m), len(tracks)
        self.ut_id = [t.ut_id for t in tracks]
        self._n_pt = np.array([t.time_s.size for t in tracks])
        width = max(int(self._n_pt.max()), 2)  # >= 1 segment column even for 1-point tracks

        def padded(field, fill):
            """(n_ut, width) array of a track field, right-padded."""
            return np.array(
                [
                    np.concatenate(
                        [
                            getattr(t, field),
                            np.full(
                                width - t.time_s.size,
                                getattr(t, field)[-1] if fill is None else fill,
                            ),
                        ]
                    )
                    for t in tracks
                ]
            )

        # Times padded with +inf (never reached); points padded by repeating the last one.
        self._time_s, self._alt_m = padded("time_s", np.inf), padded("alt_m", None)
        self._u = enu_basis(padded("lat_rad", None), padded("lon_rad", None))[..., 2, :]
        self._segments()

    def _segments(self):
        """Per-segment angle rate, unit tangent and height rate, (n_ut, width - 1)."""
        ua, ub = self._u[:, :-1], self._u[:, 1:]
        cos_t = np.sum(ua * ub, axis=-1)
        perp = ub - cos_t[..., None] * ua
        sin_t = np.linalg.norm(perp, axis=-1)
        angle = np.arctan2(sin_t, cos_t)
        valid = np.arange(1, self._u.shape[1])[None, :] < self._n_pt[:, None]
        if np.any(valid & (angle > np.pi - 1e-9)):
            raise ConfigError("two consecutive waypoints are antipodal; add a point between")
        dt = np.where(valid, np.diff(np.where(np.isinf(self._time_s), 0.0, self._time_s)), 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            self._tangent = np.where(sin_t[..., None] > 0.0, perp / sin_t[..., None], 0.0)
        self._rate_rad_s = np.where(valid, angle / dt, 0.0)
        self._alt_rate_m_s = np.where(valid, np.diff(self._alt_m, axis=1) / dt, 0.0)

    def _count_reached(self, t_s):
        """Number of waypoints with ``time <= t_s`` per UT: vectorized bisection, (n_ut,)."""
        rows, width = np.arange(self.n_ut), self._time_s.shape[1]
        lo, hi = np.zeros(self.n_ut, dtype=int), np.full(self.n_ut, width)
        for _ in range(width.bit_length()):
            active = lo < hi
            mid = (lo + hi) // 2
            go = self._time_s[rows, np.minimum(mid, width - 1)] <= t_s
            lo = np.where(active & go, mid + 1, lo)
            hi = np.where(active & ~go, mid, hi)
        return lo

    def state(self, t_s):
        """State at ``t_s`` [s] (scalar), all UTs at once."""
        t_s = float(t_s)
        rows, count = np.arange(self.n_ut), self._count_reached(t_s)
        moving = (count >= 1) & (count < self._n_pt)
        k = np.minimum(np.maximum(count - 1, 0), self._n_pt - 1)  # segment start / held point
        ks = np.minimum(k, self._rate_rad_s.shape[1] - 1)
        dt = np.where(moving, t_s - self._time_s[rows, k], 0.0)
        rate = np.where(moving, self._rate_rad_s[rows, ks], 0.0)
        alt_rate = np.where(moving, self._alt_rate_m_s[rows, ks], 0.0)
        u0, tau0 = self._u[rows, k], self._tangent[rows, ks]
        phi = (rate * dt)[:, None]
        u = np.cos(phi) * u0 + np.sin(phi) * tau0  # slerp, linear in angle
        tau = -np.sin(phi) * u0 + np.cos(phi) * tau0
        alt = self._alt_m[rows, k] + alt_rate * dt
        r = (self.radius_m + alt)[:, None]
        # d/dt of (R + h) u:  h' u + (R + h) w tau;  d2/dt2: 2 h' w tau - (R + h) w^2 u.
        vel = alt_rate[:, None] * u + r * rate[:, None] * tau
        acc = 2.0 * (alt_rate * rate)[:, None] * tau - r * (rate**2)[:, None] * u
        lat, lon, _ = ecef_to_geodetic(u)
        return UTState(r * u, vel, acc, lat, lon, alt)

    @property
    def time_span_s(self):
        """First and last waypoint time of every UT, shape (n_ut, 2) [s]."""
        last = self._time_s[np.arange(self.n_ut), self._n_pt - 1]
        return np.stack([self._time_s[:, 0], last], axis=-1)


class OnWgs84:
    """A motion model's UTs carried onto the WGS 84 ellipsoid.

    The wrapped model moves its UTs on the sphere; its latitudes, longitudes and heights
    are taken as geodetic ones: positions are :func:`leolink.geodesy.wgs84_to_ecef`, and
    velocities the exact time derivative of those positions (the sphere's angular rates,
    through :func:`~leolink.geodesy.wgs84_velocity`), so Doppler and range rate agree.
    The ground speed on the ellipsoid is then the configured one scaled by ``(M + h) /
    (R + h)`` northwards and ``(N + h) / (R + h)`` eastwards (within -0.5 % / +0.7 %
    of it for R = 6371 km). The acceleration keeps the model's local east/north/up
    components, which the two Earths share; its curvature term uses R instead of M or N
    (a relative error under 0.7 % of ``v^2 / R``: 1e-6 m/s^2 for a car).

    Parameters
    ----------
    model : motion model on the sphere of radius ``radius_m``.
    radius_m : float, that sphere's radius [m].
    """

    def __init__(self, model, radius_m=EARTH_RADIUS_M):
        self.model, self.radius_m = model, float(radius_m)
        self.n_ut = model.n_ut

    def __getattr__(self, name):  # time_span_s, tracks, ... of the wrapped model
        if name == "model":
            raise AttributeError(name)
        return getattr(self.model, name)

    def take(self, index):
        """The UTs ``index`` (:func:`take_uts`), still on the ellipsoid."""
        return OnWgs84(take_uts(self.model, index), self.radius_m)

    def state(self, t_s):
        """State at ``t_s`` [s]: geodetic positions on WGS 84, all UTs at once."""
        from leolink.geodesy import wgs84_to_ecef, wgs84_velocity

        s = self.model.state(t_s)
        east, north, up = np.moveaxis(enu_basis(s.lat_rad, s.lon_rad), -2, 0)
        r = self.radius_m + s.alt_m
        lat_rate = np.einsum("uk,uk->u", s.vel_m_s, north) / r
        cos_lat = np.cos(s.lat_rad)
        with np.errstate(divide="ignore", invalid="ignore"):
            lon_rate = np.where(
                cos_lat > 1e-12, np.einsum("uk,uk->u", s.vel_m_s, east) / (r * cos_lat), 0.0
            )
        alt_rate = np.einsum("uk,uk->u", s.vel_m_s, up)
        pos = wgs84_to_ecef(s.lat_rad, s.lon_rad, s.alt_m)
        vel = wgs84_velocity(s.lat_rad, s.lon_rad, s.alt_m, lat_rate, lon_rate, alt_rate)
        return UTState(pos, vel, s.acc_m_s2, s.lat_rad, s.lon_rad, s.alt_m)


def _rows(state, index, axis):
    """The UTs ``index`` of a :class:`UTState` (UT axis ``axis``: 1 with a time axis)."""
    fields = ("pos_m", "vel_m_s", "acc_m_s2", "lat_rad", "lon_rad", "alt_m")
    return UTState(*(np.take(getattr(state, f), index, axis=axis) for f in fields))


class SelectedUTs:
    """Some UTs of another motion model: its states, their rows ``index``.

    The fallback of :func:`take_uts` for a model without ``take`` (tracks): it computes
    every UT of ``model``, so it suits small populations.
    """

    def __init__(self, model, index):
        self.model, self.index = model, np.asarray(index, np.int64)
        self.n_ut = int(self.index.size)
        self.moves = getattr(model, "moves", True)

    def state(self, t_s):
        """The selected rows of ``model.state(t_s)``."""
        return _rows(self.model.state(t_s), self.index, 0)


def take_uts(model, index):
    """The UTs ``index`` of a motion model, as a model of ``len(index)`` UTs.

    Parameters
    ----------
    model : motion model (:class:`~leolink.sim.mobility.populations.MotionModel`)
    index : array_like of int, shape (n,)
        Increasing UT indices of ``model`` (may be empty).

    Returns
    -------
    A motion model whose states are the rows ``index`` of ``model``'s: the model's own
    ``take`` where its class has one (static, great circles, WGS 84), computed from the
    selected UTs' parameters only, else :class:`SelectedUTs`. A split run's parts
    (:mod:`leolink.app.split`) hold their UTs this way.
    """
    index = np.asarray(index, np.int64)
    take = getattr(type(model), "take", None)
    return take(model, index) if take is not None else SelectedUTs(model, index)
