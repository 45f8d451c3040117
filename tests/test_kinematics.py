"""Tests of leolink.kinematics: closed forms against numerical derivatives and brute force.

The orbits are written here by hand (no leolink.orbit): a circular orbit of radius
``r_s`` in the plane spanned by ``e1, e2``, ``x(t) = r_s (cos(wt + u0) e1 + sin(wt + u0) e2)``.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.kinematics import (
    angular_speed_rad_s,
    doppler_hz,
    doppler_rate_hz_s,
    doppler_sat_hz,
    doppler_ut_hz,
    max_angular_speed_rad_s,
    max_doppler_sat_hz,
    max_doppler_sat_small_roi_hz,
    mean_abs_doppler_ut_hz,
    range_rate_m_s,
)

R_M = 6_371_000.0
GM = 3.986004418e14
C = 299_792_458.0
F_HZ = 11.45e9
H_M = 1_300e3
CAR_DOPPLER_HZ = 30.0 * F_HZ / C  # 1.15 kHz: every tolerance below is far smaller

# Central differences with dt = 1e-3 s: truncation rho''' dt^2 / 6 ~ 0.2 m/s^3 * 1e-6 / 6
# ~ 3e-8 m/s; rounding eps * rho / dt ~ 2e-16 * 3e6 / 1e-3 ~ 1e-6 m/s. Times f/c = 38 Hz
# per m/s: < 1e-4 Hz. We allow 1e-3 Hz, 1e6 times below the car's 1.1 kHz.
DT_S = 1e-3
DOPPLER_TOL_HZ = 1e-3
# Doppler rate by central differences of the Doppler (dt = 1e-2 s): rounding
# eps * 3e5 Hz / 1e-2 s ~ 1e-8, truncation f/c rho'''' dt^2 / 6 ~ 1e-5 Hz/s.
DOPPLER_RATE_TOL_HZ_S = 1e-3
ANGULAR_RTOL = 1e-6  # |dl/dt| by central differences, relative


def orbit(t_s, inc_rad, raan_rad, u0_rad, altitude_m=H_M):
    """Circular orbit (pos, vel, acc), written independently of leolink."""
    r_s = R_M + altitude_m
    w = np.sqrt(GM / r_s**3)
    e1 = np.array([np.cos(raan_rad), np.sin(raan_rad), 0.0])
    e2 = np.array(
        [-np.sin(raan_rad) * np.cos(inc_rad), np.cos(raan_rad) * np.cos(inc_rad), np.sin(inc_rad)]
    )
    u = w * np.asarray(t_s, dtype=float)[..., None] + u0_rad
    pos = r_s * (np.cos(u) * e1 + np.sin(u) * e2)
    vel = r_s * w * (-np.sin(u) * e1 + np.cos(u) * e2)
    return pos, vel, -(w**2) * pos


def ground(lat_rad, lon_rad):
    return R_M * np.array(
        [np.cos(lat_rad) * np.cos(lon_rad), np.cos(lat_rad) * np.sin(lon_rad), np.sin(lat_rad)]
    )


def scenario(inc, raan, u0, dlat, dlon, vx, vy, vz, ax):
    """Satellite near the UT: the UT sits up to ~20 deg from the sub-satellite point at t=0."""
    sat = orbit(0.0, inc, raan, u0)[0]
    lat0 = np.arcsin(sat[2] / np.linalg.norm(sat))
    lon0 = np.arctan2(sat[1], sat[0])
    ut0 = ground(lat0 + dlat, lon0 + dlon)
    ut_vel = np.array([vx, vy, vz])
    ut_acc = np.array([ax, 0.0, 0.0])

    def ut(t):
        t = np.asarray(t, dtype=float)[..., None]
        return ut0 + ut_vel * t + 0.5 * ut_acc * t**2, ut_vel + ut_acc * t

    def sat_state(t):
        return orbit(t, inc, raan, u0)

    return sat_state, ut, ut_acc


geometry = dict(
    inc=st.floats(0.0, np.pi),
    raan=st.floats(0.0, 2 * np.pi),
    u0=st.floats(0.0, 2 * np.pi),
    dlat=st.floats(-0.3, 0.3),
    dlon=st.floats(-0.3, 0.3),
    vx=st.floats(-40.0, 40.0),
    vy=st.floats(-40.0, 40.0),
    vz=st.floats(-5.0, 5.0),
    ax=st.floats(-3.0, 3.0),
)


def slant_range(sat_state, ut, t):
    return np.linalg.norm(sat_state(t)[0] - ut(t)[0], axis=-1)


@settings(max_examples=60, deadline=None)
@given(**geometry)
def test_doppler_is_minus_range_rate_numerically(**g):
    sat_state, ut, _ = scenario(**g)
    t = np.array([0.0, 17.0])
    numeric = -(slant_range(sat_state, ut, t + DT_S) - slant_range(sat_state, ut, t - DT_S)) / (
        2 * DT_S
    )
    pos, vel, _ = sat_state(t)
    ut_pos, ut_vel = ut(t)
    total = doppler_hz(pos, vel, ut_pos, ut_vel, F_HZ)
    np.testing.assert_allclose(total, numeric * F_HZ / C, atol=DOPPLER_TOL_HZ, rtol=0)
    # The two parts add up to the total, and the static-UT part is the paper's formula.
    parts = doppler_sat_hz(pos, vel, ut_pos, F_HZ) + doppler_ut_hz(ut_pos, ut_vel, pos, F_HZ)
    np.testing.assert_allclose(parts, total, atol=1e-9, rtol=0)
    np.testing.assert_allclose(range_rate_m_s(pos, vel, ut_pos, ut_vel), -numeric, atol=1e-4)


@settings(max_examples=40, deadline=None)
@given(**geometry)
def test_doppler_rate_matches_numerical_derivative(**g):
    sat_state, ut, ut_acc = scenario(**g)
    dt, t = 1e-2, np.array([0.0, 5.0])

    def dop(tt):
        p, v, _ = sat_state(tt)
        up, uv = ut(tt)
        return doppler_hz(p, v, up, uv, F_HZ)

    numeric = (dop(t + dt) - dop(t - dt)) / (2 * dt)
    p, v, a = sat_state(t)
    up, uv = ut(t)
    rate = doppler_rate_hz_s(p, v, a, up, uv, ut_acc, freq_hz=F_HZ)
    np.testing.assert_allclose(rate, numeric, atol=DOPPLER_RATE_TOL_HZ_S, rtol=0)


@settings(max_examples=40, deadline=None)
@given(**geometry)
def test_angular_speed_is_norm_of_los_derivative(**g):
    sat_state, ut, _ = scenario(**g)
    t = np.array([0.0, 9.0])

    def los(tt):
        d = sat_state(tt)[0] - ut(tt)[0]
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    numeric = np.linalg.norm((los(t + DT_S) - los(t - DT_S)) / (2 * DT_S), axis=-1)
    p, v, _ = sat_state(t)
    up, uv = ut(t)
    np.testing.assert_allclose(angular_speed_rad_s(p, v, up, uv), numeric, rtol=ANGULAR_RTOL)


def test_paper_angular_speed_form_for_static_ut():
    # Eq. (doppler_ang): sqrt(1 - <v/|v|, l>^2) |v| / rho, l from sat to UT.
    rng = np.random.default_rng(3)
    pos, vel, _ = orbit(rng.uniform(0, 3000, 50), 0.93, 0.2, 0.1)
    ut = ground(0.3, 0.4)
    d = ut - pos
    rho = np.linalg.norm(d, axis=-1)
    cosang = np.sum(vel * d, -1) / (np.linalg.norm(vel, axis=-1) * rho)
    paper = np.sqrt(1 - cosang**2) * np.linalg.norm(vel, axis=-1) / rho
    np.testing.assert_allclose(angular_speed_rad_s(pos, vel, ut), paper, rtol=1e-9)


def test_sign_conventions():
    # Satellite overhead moving towards +x, UT ahead of it (at +x): approaching -> positive.
    sat, vel = np.array([0.0, 0.0, 1e6]), np.array([7e3, 0.0, 0.0])
    ut = np.array([5e5, 0.0, 0.0])
    assert doppler_sat_hz(sat, vel, ut, F_HZ) > 0
    # UT driving towards the satellite's ground track point: positive.
    assert doppler_ut_hz(ut, np.array([-30.0, 0.0, 0.0]), sat, F_HZ) > 0


def roi_ground_points(rx_m, ry_m, sat_pos, sat_vel, n=4001):
    """ROI ellipse boundary and interior mapped to the ground, paper's projection."""
    u_z = sat_pos / np.linalg.norm(sat_pos)
    u_x = sat_vel - np.dot(sat_vel, u_z) * u_z
    u_x /= np.linalg.norm(u_x)
    u_y = np.cross(u_z, u_x)
    th = np.linspace(-np.pi, np.pi, n)
    scale = np.concatenate([np.ones(n), np.sqrt(np.linspace(0, 1, 41)).repeat(n)[: 40 * n]])
    th_all = np.tile(th, 41)[: len(scale)]
    x = rx_m * scale * np.cos(th_all)
    y = ry_m * scale * np.sin(th_all)
    p = R_M * u_z + x[:, None] * u_x + y[:, None] * u_y
    return R_M * p / np.sqrt(R_M**2 + x**2 + y**2)[:, None]


RX_M, RY_M = 534.1e3, 170.5e3  # paper's Table


def test_max_doppler_closed_form_vs_brute_force_over_roi():
    pos, vel, _ = orbit(0.0, np.radians(53), 0.3, 0.7)
    pts = roi_ground_points(RX_M, RY_M, pos, vel)
    brute = np.max(np.abs(doppler_sat_hz(pos, vel, pts, F_HZ)))
    closed = max_doppler_sat_hz(RX_M, H_M, F_HZ)
    # The tip (Rx, 0) is on the sampled boundary (theta = 0): agreement to rounding.
    assert closed == pytest.approx(brute, rel=1e-9)
    assert 100e3 < closed < 200e3  # 102.8 kHz at 11.45 GHz
    # The paper's shortcut R_x v / h overestimates by ~10 % here (errata).
    short = max_doppler_sat_small_roi_hz(RX_M, H_M, F_HZ)
    assert short / closed - 1 > 0.05
    # ... and converges for R_x << h.
    assert max_doppler_sat_small_roi_hz(1e3, H_M, F_HZ) == pytest.approx(
        max_doppler_sat_hz(1e3, H_M, F_HZ), rel=1e-5
    )


def test_max_angular_speed_is_at_nadir_and_equals_v_over_h():
    pos, vel, _ = orbit(0.0, np.radians(53), 1.0, 2.0)
    pts = roi_ground_points(RX_M, RY_M, pos, vel, n=401)
    nadir = R_M * pos / np.linalg.norm(pos)
    brute = max(np.max(angular_speed_rad_s(pos, vel, pts)), angular_speed_rad_s(pos, vel, nadir))
    v = np.sqrt(GM / (R_M + H_M))
    assert max_angular_speed_rad_s(H_M) == pytest.approx(v / H_M, rel=1e-12)
    assert angular_speed_rad_s(pos, vel, nadir) == pytest.approx(v / H_M, rel=1e-9)
    assert brute == pytest.approx(max_angular_speed_rad_s(H_M), rel=1e-9)


def test_mean_abs_ut_doppler_is_half_not_sixth():
    # Uniform directions on S2 (normalized Gaussians): E|<v_u, v>| = |v_u| / 2.
    rng = np.random.default_rng(11)
    d = rng.standard_normal((1_000_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    v_u = np.array([30.0, 0.0, 0.0])
    samples = np.abs(d @ v_u) * F_HZ / C
    se = samples.std() / np.sqrt(len(samples))
    expected = mean_abs_doppler_ut_hz(30.0, F_HZ)
    assert abs(samples.mean() - expected) < 5 * se
    paper = 30.0 / 6 * F_HZ / C
    assert abs(samples.mean() - paper) > 1000 * se


def test_defaults_are_a_static_unaccelerated_ut():
    """``ut_vel_m_s`` and ``ut_acc_m_s2`` default to zero (a static UT, uniform motion)."""
    rng = np.random.default_rng(8)
    sat, vel, acc = rng.normal(size=3) * 7e6, rng.normal(size=3) * 7e3, rng.normal(size=3)
    ut, ut_vel = rng.normal(size=3) * 6.4e6, rng.normal(size=3) * 30.0
    zero = np.zeros(3)
    assert range_rate_m_s(sat, vel, ut) == range_rate_m_s(sat, vel, ut, zero)
    assert doppler_rate_hz_s(sat, vel, acc, ut, ut_vel, freq_hz=F_HZ) == doppler_rate_hz_s(
        sat, vel, acc, ut, ut_vel, zero, freq_hz=F_HZ
    )
    assert angular_speed_rad_s(sat, vel, ut) == angular_speed_rad_s(sat, vel, ut, zero)


# Mars (NASA Mars fact sheet: GM = 42,828.37 km^3/s^2, volumetric mean radius 3,389.5 km):
# a body other than the default Earth, so that a dropped radius or GM argument shows.
MARS_GM_M3_S2, MARS_R_M = 4.282837e13, 3_389.5e3


def test_roi_maxima_use_the_given_body_radius_and_gm():
    # Brute force over the along-track arc of a hand-built circular orbit: satellite at
    # (R + h) e_z moving along e_x at the circular speed sqrt(GM / (R + h)); the ROI tip
    # x = R_x is the ground point at central angle atan(R_x / R) (gnomonic projection).
    h_m, rx_m = 400e3, 300e3
    v_m_s = np.sqrt(MARS_GM_M3_S2 / (MARS_R_M + h_m))
    sat, vel = np.array([0.0, 0.0, MARS_R_M + h_m]), np.array([v_m_s, 0.0, 0.0])
    alpha = np.linspace(0.0, np.arctan(rx_m / MARS_R_M), 2001)
    pts = MARS_R_M * np.stack([np.sin(alpha), np.zeros_like(alpha), np.cos(alpha)], axis=-1)
    los = (pts - sat) / np.linalg.norm(pts - sat, axis=-1, keepdims=True)
    brute_hz = np.max(np.abs(los @ vel)) * F_HZ / C
    body = dict(radius_m=MARS_R_M, gm_m3_s2=MARS_GM_M3_S2)
    assert max_doppler_sat_hz(rx_m, h_m, F_HZ, **body) == pytest.approx(brute_hz, rel=1e-9)
    # R_x in whole metres as int32 (its square overflows int32): float arithmetic inside.
    rx_int = np.array([300_000], dtype=np.int32)
    assert max_doppler_sat_hz(rx_int, h_m, F_HZ, **body)[0] == pytest.approx(brute_hz, rel=1e-9)
    assert max_doppler_sat_small_roi_hz(rx_m, h_m, F_HZ, **body) == pytest.approx(
        rx_m * v_m_s / h_m * F_HZ / C, rel=1e-12
    )
    # At nadir the line of sight is orthogonal to the velocity: |dl/dt| = v / h.
    assert max_angular_speed_rad_s(h_m, **body) == pytest.approx(v_m_s / h_m, rel=1e-12)
    assert angular_speed_rad_s(sat, vel, pts[0]) == pytest.approx(v_m_s / h_m, rel=1e-12)


def test_link_kinematics_line_of_sight_that_does_not_turn_has_zero_angular_speed():
    # Relative velocity along the line of sight (a satellite rising straight at the UT,
    # or a UT moving with the satellite): |v_perp| = 0, so the angular speed is 0 up to
    # the rounding of |v|^2 - rho'^2 (~eps |v|^2 = 1e-8 m^2/s^2: 1e-10 rad/s at 1,000 km).
    from leolink.kinematics import link_kinematics

    los = np.array([[3e5, -4e5, 8e5], [1e6, 0.0, 0.0]])
    sat_vel = np.array([-7e3 * los[0] / np.linalg.norm(los[0]), [0.0, 7.5e3, 0.0]])
    ut_vel = np.array([[0.0, 0.0, 0.0], [0.0, 7.5e3, 0.0]])
    got = link_kinematics(los, sat_vel, ut_vel, np.zeros((2, 3)), F_HZ)
    np.testing.assert_allclose(got["angular_speed_rad_s"], 0.0, atol=1e-9)
    # The approaching satellite: Doppler +v f / c, all of it the satellite's.
    assert got["doppler_hz"][0] == pytest.approx(7e3 * F_HZ / C, rel=1e-12)
    assert got["doppler_sat_hz"][0] == pytest.approx(7e3 * F_HZ / C, rel=1e-12)


@pytest.mark.parametrize(
    "name", ["max_doppler rx", "max_doppler altitude", "mean_abs_doppler_ut speed"]
)
def test_float32_inputs_are_computed_in_float64(name):
    # float32 carries 7 digits (0.1 Hz on a 100 kHz Doppler): the closed forms compute in
    # float64 whatever their inputs are stored in; the values are exactly representable
    # in float32, so the float64 result of the same values is the reference.
    func, value = {
        "max_doppler rx": (lambda a: max_doppler_sat_hz(a, H_M, F_HZ), RX_M),
        "max_doppler altitude": (lambda a: max_doppler_sat_hz(RX_M, a, F_HZ), H_M),
        "mean_abs_doppler_ut speed": (lambda a: mean_abs_doppler_ut_hz(a, F_HZ), 27.3),
    }[name]
    x32 = np.array([value], dtype=np.float32)
    got = func(x32)
    assert got.dtype == np.float64
    np.testing.assert_allclose(got, func(x32.astype(np.float64)), rtol=1e-14)
