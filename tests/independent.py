"""Independent recomputation of a run's trace, UT by UT, for the trust tests.

Nothing here calls leolink's physics: orbits are built from Napier's rules and rotation
matrices (not the P/Q vectors of ``orbit.circular_state``), TLEs go through ``sgp4``'s
``Satrec`` and skyfield's GMST-1982 (not ``orbit.tle_state``), velocities and
accelerations are central finite differences of positions (not the Coriolis formulas
of ``orbit.eci_to_ecef``), gains are explicit steering-vector sums (not the Dirichlet
closed form of ``antenna.array``) and the link budget uses CODATA constants from scipy.
What is taken from leolink is the *input*: the config and the codebook's beam
directions (the codebook design has its own tests).

Conventions restated here, so that a change of convention in leolink fails a test
rather than being copied: the inertial frame coincides with the Earth-fixed one at
t = 0 (``gmst0 = 0`` for circular orbits); the satellite body frame is x along the
velocity's part orthogonal to the radius, z radial, ``y = z x x``; the ROI plane has
x along the ground track at the centre and ``y = up x x`` (left of the track);
``cross_track`` headings point 90 deg clockwise of the track (to its right).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np
from scipy import constants

C_M_S = constants.c
K_BOLTZMANN_J_K = constants.k
EARTH_ROTATION_RAD_S = 7.2921150e-5  # IERS Conventions (2010), Table 1.1 (omega)

#: Central-difference steps [s]: velocity (error ~ a n^3 h^2 / 6 ~ 1e-7 m/s for LEO) and
#: second derivative of the range (truncation rho'''' h^2 / 12 with rho'''' ~ 3 v^4 / h_sat^3
#: = 4e-3 m/s^4 overhead: 1e-6 m/s^2; round-off eps rho / h^2 = 1e-7 m/s^2 at h = 0.05 s).
H_VEL_S = 0.01
H_ACC_S = 0.05


def rot_z(angle):
    """Active rotation about z by ``angle`` [rad], shape (..., 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack(
        [np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2
    )


def rot_x(angle):
    """Active rotation about x by ``angle`` [rad], shape (..., 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack(
        [np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2
    )


def unit_up(lat_rad, lon_rad):
    lat, lon = np.asarray(lat_rad, float), np.asarray(lon_rad, float)
    return np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)


def east_north(lat_rad, lon_rad):
    lat, lon = np.asarray(lat_rad, float), np.asarray(lon_rad, float)
    east = np.stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)], -1)
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], -1)
    return east, north


def to_earth_fixed(pos_eci, t_s, gmst0_rad=0.0):
    """Inertial -> Earth-fixed: rotate by ``-(gmst0 + w t)`` about z. pos (n_t, ..., 3)."""
    theta = gmst0_rad + EARTH_ROTATION_RAD_S * np.asarray(t_s, float)
    r = rot_z(-theta)  # (n_t, 3, 3)
    return np.einsum("tij,t...j->t...i", r, pos_eci)


# --- orbits -------------------------------------------------------------------------------
@dataclass
class PassOrbit:
    """A circular orbit through the zenith of (lat, lon) at ``t_pass_s``, built by rotating
    the position at the pass about the orbit normal (heading from Clairaut's relation
    ``cos i = cos(lat) sin(psi)``), not from orbital elements."""

    lat_rad: float
    lon_rad: float
    t_pass_s: float
    a_m: float
    inc_rad: float
    ascending: bool
    gm: float
    rotation: bool

    def eci(self, t_s):
        t = np.atleast_1d(np.asarray(t_s, float))
        lon_i = self.lon_rad + (EARTH_ROTATION_RAD_S * self.t_pass_s if self.rotation else 0.0)
        up = unit_up(self.lat_rad, lon_i)
        east, north = east_north(self.lat_rad, lon_i)
        sin_psi = math.cos(self.inc_rad) / math.cos(self.lat_rad)
        cos_psi = math.sqrt(max(0.0, 1.0 - sin_psi**2)) * (1.0 if self.ascending else -1.0)
        d = sin_psi * east + cos_psi * north
        n = math.sqrt(self.gm / self.a_m**3)
        ang = n * (t - self.t_pass_s)
        return self.a_m * (np.cos(ang)[:, None] * up + np.sin(ang)[:, None] * d)[:, None, :]

    def __call__(self, t_s):
        """Positions (n_t, 1, 3) in the run's frame."""
        p = self.eci(t_s)
        return to_earth_fixed(p, np.atleast_1d(t_s)) if self.rotation else p


@dataclass
class WalkerOrbits:
    """Walker delta i: T/P/F by its definition (RAAN 2 pi j / P, argument of latitude
    2 pi k / S + 2 pi F j / T), each orbit as Rz(RAAN) Rx(i) Rz(u) applied to (a, 0, 0)."""

    n_planes: int
    per_plane: int
    phasing: int
    a_m: float
    inc_rad: float
    gm: float
    rotation: bool

    def __call__(self, t_s):
        t = np.atleast_1d(np.asarray(t_s, float))
        total = self.n_planes * self.per_plane
        j = np.repeat(np.arange(self.n_planes), self.per_plane)
        k = np.tile(np.arange(self.per_plane), self.n_planes)
        raan = 2 * np.pi * j / self.n_planes
        u0 = 2 * np.pi * k / self.per_plane + 2 * np.pi * self.phasing * j / total
        n = math.sqrt(self.gm / self.a_m**3)
        u = u0[None, :] + n * t[:, None]  # (n_t, n_sat)
        m = rot_z(raan)[None] @ rot_x(np.full(total, self.inc_rad))[None] @ rot_z(u)
        pos = m[..., :, 0] * self.a_m  # Rz(u) (a, 0, 0) = a (cos u, sin u, 0)
        return to_earth_fixed(pos, t) if self.rotation else pos


@dataclass
class TleOrbit:
    """sgp4's ``Satrec`` in TEME, rotated to the Earth-fixed frame by skyfield's GMST 1982
    of UT1 = UTC + ``dut1_s``."""

    line1: str
    line2: str
    epoch_utc: datetime
    rotation: bool
    dut1_s: float = 0.0

    def state(self, t_s):
        from sgp4.api import Satrec
        from skyfield.sgp4lib import theta_GMST1982

        sat = Satrec.twoline2rv(self.line1, self.line2)
        t = np.atleast_1d(np.asarray(t_s, float))
        # Whole and fractional days kept apart: a single float64 JD (~2.4e6) is only
        # resolved to 40 us, which would spoil a 10 ms finite difference.
        day, sec = divmod(self.epoch_utc.astimezone(UTC).timestamp(), 86400.0)
        whole = np.full(t.shape, 2440587.5 + day)  # the Unix epoch is JD 2440587.5
        frac = (sec + t) / 86400.0
        err, r_km, v_km_s = sat.sgp4_array(whole, frac)
        assert not np.any(err), err
        pos = np.asarray(r_km)[:, None, :] * 1e3
        vel = np.asarray(v_km_s)[:, None, :] * 1e3
        if not self.rotation:
            return pos, vel
        theta, theta_dot_rad_day = theta_GMST1982(whole, frac + self.dut1_s / 86400.0)
        r = rot_z(-np.asarray(theta))
        pos = np.einsum("tij,t...j->t...i", r, pos)
        # v_PEF = R v_TEME - w x r_PEF (Vallado, AIAA 2006-6753, Appendix C).
        w = np.zeros((len(t), 1, 3))
        w[..., 2] = np.asarray(theta_dot_rad_day)[:, None] / 86400.0
        return pos, np.einsum("tij,t...j->t...i", r, vel) - np.cross(w, pos)

    def __call__(self, t_s):
        return self.state(t_s)[0]

    def vel(self, t_s):
        """sgp4's own velocity, rotated. It is not the derivative of sgp4's position: the
        two differ by ~1 cm/s for the ISS TLE (measured), so the run's Doppler (which uses
        it) is compared with it, and with the range's finite difference only to 2 cm/s."""
        return self.state(t_s)[1]


def velocity(orbit, t_s):
    """Velocity [m/s], shape of ``orbit(t_s)``: the orbit's own (TLE) or the central
    difference of its positions."""
    if hasattr(orbit, "vel"):
        return orbit.vel(t_s)
    t = np.atleast_1d(np.asarray(t_s, float))
    return (orbit(t + H_VEL_S) - orbit(t - H_VEL_S)) / (2 * H_VEL_S)


# --- UTs ------------------------------------------------------------------------------------
@dataclass
class GreatCircleUT:
    """A UT from (lat0, lon0) at height ``alt_m`` moving at ``speed_m_s`` along the great
    circle of initial heading ``heading_rad`` (from north, clockwise)."""

    lat0_rad: float
    lon0_rad: float
    alt_m: float
    heading_rad: float
    speed_m_s: float
    radius_m: float
    t0_s: float = 0.0

    def __call__(self, t_s):
        t = np.atleast_1d(np.asarray(t_s, float))
        up0 = unit_up(self.lat0_rad, self.lon0_rad)
        east, north = east_north(self.lat0_rad, self.lon0_rad)
        e0 = math.sin(self.heading_rad) * east + math.cos(self.heading_rad) * north
        r = self.radius_m + self.alt_m
        phi = self.speed_m_s * (t - self.t0_s) / r
        return r * (np.cos(phi)[:, None] * up0 + np.sin(phi)[:, None] * e0)


def roi_frame(lat_rad, lon_rad, track_dir):
    """Unit up, x (along ``track_dir`` made horizontal) and y = up x x at the ROI centre."""
    up = unit_up(lat_rad, lon_rad)
    x = track_dir - (track_dir @ up) * up
    x = x / np.linalg.norm(x)
    return up, x, np.cross(up, x)


def roi_point(x_m, y_m, up, ex, ey, radius_m):
    """Central projection of the ROI-plane point (Sec. 3.1): R (R up + x ex + y ey) / |.|."""
    p = radius_m * up + x_m * ex + y_m * ey
    return radius_m * p / np.linalg.norm(p)


def heading_of(direction, lat_rad, lon_rad):
    """Azimuth from north, clockwise [rad], of a horizontal direction at (lat, lon)."""
    east, north = east_north(lat_rad, lon_rad)
    return math.atan2(float(direction @ east), float(direction @ north))


# --- antennas and link ------------------------------------------------------------------------
def upa_steering(u_x, u_y, n_x, n_y):
    """Half-wavelength UPA steering vectors exp(j pi (m u_x + n u_y)), shape (..., n_x n_y)."""
    m = np.arange(n_x)[:, None]
    n = np.arange(n_y)[None, :]
    ph = np.pi * (np.asarray(u_x)[..., None, None] * m + np.asarray(u_y)[..., None, None] * n)
    return np.exp(1j * ph).reshape(*np.shape(u_x), n_x * n_y)


def beam_gains_lin(u_xy_dir, u_xy_beams, n_x, n_y):
    """|a(u)^H f_b|^2 / ||f_b||^2 for every direction and beam, f_b = a(u_b): the explicit
    product over the n_x n_y elements of one subarray. u_xy_dir (n, 2), beams (n_b, 2)."""
    a = upa_steering(u_xy_dir[:, 0], u_xy_dir[:, 1], n_x, n_y)  # (n, N)
    f = upa_steering(u_xy_beams[:, 0], u_xy_beams[:, 1], n_x, n_y)  # (n_b, N)
    return np.abs(a.conj() @ f.T) ** 2 / (n_x * n_y)


def body_cosines(sat_pos, sat_vel, target):
    """Direction cosines (u_x, u_y) of ``target`` in the body frame, rows (n, 2)."""
    z = sat_pos / np.linalg.norm(sat_pos, axis=-1, keepdims=True)
    x = sat_vel - np.sum(sat_vel * z, -1, keepdims=True) * z
    x = x / np.linalg.norm(x, axis=-1, keepdims=True)
    y = np.cross(z, x)
    d = target - sat_pos
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return np.stack([np.sum(d * x, -1), np.sum(d * y, -1)], -1)


def elevation_rad(ut_pos, sat_pos):
    d = sat_pos - ut_pos
    up = ut_pos / np.linalg.norm(ut_pos, axis=-1, keepdims=True)
    return np.arcsin(np.sum(d * up, -1) / np.linalg.norm(d, axis=-1))


def fspl_p525_db(distance_m, freq_hz):
    """ITU-R P.525-4 Eq. (4): 32.45 + 20 log f[MHz] + 20 log d[km] (32.45 printed as 32.4;
    the exact constant 20 log10(4 pi 1e9 / c) = 32.4478)."""
    return (
        20 * np.log10(4 * np.pi * 1e9 / C_M_S)
        + 20 * np.log10(freq_hz / 1e6)
        + 20 * np.log10(distance_m / 1e3)
    )


def noise_dbw(noise_temp_dbk, bandwidth_hz):
    return 10 * np.log10(K_BOLTZMANN_J_K * bandwidth_hz) + noise_temp_dbk
