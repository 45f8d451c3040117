"""Tests of leolink.sim.mobility.models against independent formulas (haversine, bearing,
spherical coordinates written out here, numerical derivatives)."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.constants import EARTH_RADIUS_M as R
from leolink.errors import ConfigError, LeolinkError
from leolink.io.tracks import TrackFileError, read_track_csv
from leolink.placement import (
    geodetic_to_roi_points,
    place_grid,
    place_random,
    roi_points_to_geodetic,
)
from leolink.sim.mobility.models import (
    SPEED_PRESETS_M_S,
    ConstantVelocity,
    Static,
    Track,
    UTState,
    Waypoints,
    concat_states,
)

DATA = Path(__file__).parent / "data"
TRACKS = Path(__file__).parents[1] / "configs" / "examples" / "tracks"

# Positions are ~6.4e6 m, so float64 rounding is ~1e-9 m; 1 mm is a million times that and
# a thousand times smaller than one second of pedestrian motion.
ONE_MM = 1e-3
# Central difference with h = 1 s on |pos| ~ 6.4e6 m: rounding ~1e-9 m/s, truncation
# h^2 |jerk|/6 <= (250 m/s)^3 / R^2 / 6 ~ 1e-7 m/s. 1e-5 m/s is far below any speed tested.
VEL_TOL_M_S = 1e-5
# Second difference with h = 10 s: rounding 4e-9 m / 100 s^2 ~ 4e-11 m/s^2; the centripetal
# term of a pedestrian is 3e-7 m/s^2, so 1e-9 m/s^2 still sees it.
ACC_TOL_M_S2 = 1e-9


def ecef(lat, lon, alt=0.0):
    """Spherical coordinates written out independently of leolink.geometry."""
    r = R + np.asarray(alt)
    return np.stack(
        [r * np.cos(lat) * np.cos(lon), r * np.cos(lat) * np.sin(lon), r * np.sin(lat)], axis=-1
    )


def haversine_m(lat1, lon1, lat2, lon2, radius_m=R):
    """Great-circle distance, haversine formula."""
    a = (
        np.sin((lat2 - lat1) / 2) ** 2
        + np.cos(lat1) * np.cos(lat2) * np.sin((lon2 - lon1) / 2) ** 2
    )
    return 2 * radius_m * np.arcsin(np.sqrt(a))


def bearing_rad(lat1, lon1, lat2, lon2):
    """Initial great-circle bearing from point 1 to point 2, from north clockwise."""
    y = np.sin(lon2 - lon1) * np.cos(lat2)
    x = np.cos(lat1) * np.sin(lat2) - np.sin(lat1) * np.cos(lat2) * np.cos(lon2 - lon1)
    return np.mod(np.arctan2(y, x), 2 * np.pi)


def angle_diff(a, b):
    """Wrapped difference of two angles [rad]."""
    return np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))


# --- Static -------------------------------------------------------------------------------


def test_static_has_fixed_position_and_zero_velocity():
    lat, lon, alt = np.radians([10.0, -45.0]), np.radians([20.0, 170.0]), np.array([0.0, 500.0])
    pop = Static(lat, lon, alt)
    s0, s1 = pop.state(0.0), pop.state(1234.5)
    np.testing.assert_allclose(s0.pos_m, ecef(lat, lon, alt), atol=ONE_MM)
    np.testing.assert_array_equal(s0.pos_m, s1.pos_m)
    assert not s1.vel_m_s.any() and not s1.acc_m_s2.any()
    assert s1.vel_m_s.shape == (2, 3) and s1.lat_rad.shape == (2,)


def test_models_that_say_they_do_not_move_do_not_move():
    """``moves = False`` lets the simulator run no motion process for a population (its
    first state holds): it must be said by exactly the models whose states never change."""
    from leolink.sim.mobility.models import OnWgs84

    lat, lon = np.radians([10.0, -45.0]), np.radians([20.0, 170.0])
    models = [
        Static(lat, lon, [0.0, 500.0]),
        ConstantVelocity(lat, lon, 0.0, np.radians([90.0, 200.0]), "pedestrian"),
        Waypoints([TRACK_A, TRACK_B]),
    ]
    times = np.linspace(-600.0, 600.0, 7)
    for model in [*models, *(OnWgs84(m) for m in models)]:
        first = model.state(float(times[0]))
        still = all(
            np.array_equal(value, getattr(model.state(float(t)), name))
            for t in times[1:]
            for name, value in vars(first).items()
        )
        assert getattr(model, "moves", True) is not still, model


# --- ConstantVelocity ---------------------------------------------------------------------

lat_st = st.floats(np.radians(-80), np.radians(80))
ang_st = st.floats(-np.pi, np.pi)


@settings(max_examples=60, deadline=None)
@given(
    lat=lat_st,
    lon=ang_st,
    heading=ang_st,
    speed=st.floats(0.0, 300.0),
    alt=st.floats(0.0, 12_000.0),
    t=st.floats(-3600.0, 3600.0),
)
def test_constant_velocity_kinematics(lat, lon, heading, speed, alt, t):
    pop = ConstantVelocity(lat, lon, alt, heading, speed, t0_s=0.0)
    s = pop.state(t)
    # Distance along the circle of radius R + alt (speed is |vel|; see the class docstring).
    d = haversine_m(lat, lon, s.lat_rad, s.lon_rad, radius_m=R + alt)
    assert d == pytest.approx(speed * abs(t), abs=ONE_MM)
    np.testing.assert_allclose(s.pos_m, ecef(s.lat_rad, s.lon_rad, alt), atol=ONE_MM)
    assert np.linalg.norm(s.vel_m_s) == pytest.approx(speed, abs=1e-9)
    radial = s.pos_m / np.linalg.norm(s.pos_m)
    assert abs(np.sum(s.vel_m_s * radial)) < 1e-9 * max(speed, 1.0)
    h = 1.0
    num_vel = (pop.state(t + h).pos_m - pop.state(t - h).pos_m) / (2 * h)
    np.testing.assert_allclose(s.vel_m_s, num_vel, atol=VEL_TOL_M_S)
    h = 10.0
    num_acc = (pop.state(t + h).pos_m - 2 * s.pos_m + pop.state(t - h).pos_m) / h**2
    np.testing.assert_allclose(s.acc_m_s2, num_acc, atol=ACC_TOL_M_S2)


@pytest.mark.usefixtures("compiled_and_numpy")  # great_circle_state both ways
def test_constant_velocity_starts_along_heading_and_uses_presets():
    lat, lon = np.radians([30.0, -60.0]), np.radians([0.0, 100.0])
    heading = np.radians([90.0, 200.0])
    pop = ConstantVelocity(lat, lon, 0.0, heading, "car", t0_s=100.0)
    s = pop.state(101.0)  # 30 m after t0
    np.testing.assert_allclose(bearing_rad(lat, lon, s.lat_rad, s.lon_rad), heading, atol=1e-6)
    np.testing.assert_allclose(haversine_m(lat, lon, s.lat_rad, s.lon_rad), 30.0, atol=ONE_MM)
    # centripetal acceleration v^2 / R towards the centre
    np.testing.assert_allclose(np.linalg.norm(s.acc_m_s2, axis=1), 30.0**2 / R, rtol=1e-9)
    assert SPEED_PRESETS_M_S == {
        "static": 0,
        "pedestrian": 1.4,
        "car": 30,
        "train": 100,
        "ship": 10,
        "aircraft": 250,
    }
    with pytest.raises(ConfigError, match="speed preset 'rocket' is unknown; use one of"):
        ConstantVelocity(0.0, 0.0, 0.0, 0.0, "rocket")
    with pytest.raises(ConfigError, match="speed_m_s"):
        ConstantVelocity(0.0, 0.0, 0.0, 0.0, -1.0)


@pytest.mark.usefixtures("compiled_and_numpy")  # great_circle_state both ways
def test_constant_velocity_goes_around_the_world():
    speed = 250.0
    period_s = 2 * np.pi * R / speed
    pop = ConstantVelocity(0.3, 1.0, 0.0, 0.7, speed)
    np.testing.assert_allclose(pop.state(period_s).pos_m, pop.state(0.0).pos_m, atol=1e-3)
    half = pop.state(period_s / 2).pos_m
    np.testing.assert_allclose(half, -pop.state(0.0).pos_m, atol=1e-3)  # antipode


# --- Waypoints ----------------------------------------------------------------------------


def make_track(lat_deg, lon_deg, alt_m, time_s, ut_id="x"):
    return Track(
        np.asarray(time_s, float),
        np.radians(lat_deg),
        np.radians(lon_deg),
        np.asarray(alt_m, float),
        ut_id=ut_id,
    )


TRACK_A = make_track(
    [40.0, 40.1, 40.1, 39.9],
    [-3.0, -3.0, -2.8, -2.9],
    [0, 0, 100, 100],
    [0.0, 600.0, 1500.0, 2000.0],
    "a",
)
TRACK_B = make_track([-20.0, -20.5], [150.0, 151.0], [10_000, 10_000], [300.0, 700.0], "b")
TRACK_C = make_track([5.0], [5.0], [3.0], [50.0], "c")  # one point: always there


def test_waypoints_pass_through_waypoints_at_their_times():
    pop = Waypoints([TRACK_A, TRACK_B])
    for tr, i in ((TRACK_A, 0), (TRACK_B, 1)):
        for t, la, lo, al in zip(tr.time_s, tr.lat_rad, tr.lon_rad, tr.alt_m, strict=True):
            s = pop.state(t)
            np.testing.assert_allclose(s.pos_m[i], ecef(la, lo, al), atol=ONE_MM)
            assert s.alt_m[i] == pytest.approx(al)


def test_waypoints_segment_speed_is_length_over_duration():
    pop = Waypoints([TRACK_A, TRACK_B])
    for seg, tr, i in ((0, TRACK_A, 0), (0, TRACK_B, 1)):
        a, b = seg, seg + 1
        length = haversine_m(
            tr.lat_rad[a], tr.lon_rad[a], tr.lat_rad[b], tr.lon_rad[b], radius_m=R + tr.alt_m[a]
        )
        expected = length / (tr.time_s[b] - tr.time_s[a])
        for f in (0.0, 0.3, 0.9):
            t = tr.time_s[a] + f * (tr.time_s[b] - tr.time_s[a])
            assert np.linalg.norm(pop.state(t).vel_m_s[i]) == pytest.approx(expected, rel=1e-9)


def test_waypoints_mid_time_is_the_great_circle_midpoint():
    pop = Waypoints([TRACK_B])
    ua, ub = (
        ecef(TRACK_B.lat_rad[0], TRACK_B.lon_rad[0]),
        ecef(TRACK_B.lat_rad[1], TRACK_B.lon_rad[1]),
    )
    mid = (ua + ub) / np.linalg.norm(ua + ub) * (R + 10_000)
    np.testing.assert_allclose(pop.state(500.0).pos_m[0], mid, atol=ONE_MM)


@pytest.mark.parametrize("t", [123.0, 900.0, 1499.0, 1700.0])  # inside segments, some climb
def test_waypoints_velocity_and_acceleration_are_derivatives(t):
    pop = Waypoints([TRACK_A])
    s = pop.state(t)
    h = 1.0
    num_vel = (pop.state(t + h).pos_m - pop.state(t - h).pos_m) / (2 * h)
    np.testing.assert_allclose(s.vel_m_s, num_vel, atol=VEL_TOL_M_S)
    num_acc = (pop.state(t + h).pos_m - 2 * s.pos_m + pop.state(t - h).pos_m) / h**2
    # h = 1 s (segments are short): rounding 4e-9 m / 1 s^2; keep 1e-7 m/s^2 < 2 w h' ~ 1e-5
    np.testing.assert_allclose(s.acc_m_s2, num_acc, atol=1e-7)


def test_waypoints_hold_end_points_outside_the_track():
    pop = Waypoints([TRACK_A, TRACK_B, TRACK_C])
    for t, idx in ((-10.0, [0, 0, 0]), (2500.0, [-1, -1, -1]), (2000.0, [-1, -1, 0])):
        s = pop.state(t)
        for i, tr in enumerate((TRACK_A, TRACK_B, TRACK_C)):
            k = idx[i]
            np.testing.assert_allclose(
                s.pos_m[i], ecef(tr.lat_rad[k], tr.lon_rad[k], tr.alt_m[k]), atol=ONE_MM
            )
    s = pop.state(2500.0)
    assert not s.vel_m_s.any() and not s.acc_m_s2.any()
    assert not pop.state(100.0).vel_m_s[1:].any()  # b not started, c a single point
    np.testing.assert_array_equal(pop.time_span_s, [[0, 2000], [300, 700], [50, 50]])


def test_waypoints_vectorized_equals_one_ut_at_a_time():
    rng = np.random.default_rng(7)
    tracks = []
    for i in range(12):
        n = int(rng.integers(1, 9))
        t = np.cumsum(rng.uniform(1.0, 100.0, n)) + rng.uniform(-200, 200)
        tracks.append(
            make_track(
                rng.uniform(-60, 60) + np.cumsum(rng.normal(0, 0.1, n)),
                rng.uniform(-180, 180) + np.cumsum(rng.normal(0, 0.1, n)),
                rng.uniform(0, 1000, n),
                t,
                str(i),
            )
        )
    pop = Waypoints(tracks)
    singles = [Waypoints([tr]) for tr in tracks]
    for t in np.concatenate([rng.uniform(-300, 1200, 20), tracks[3].time_s]):
        s = pop.state(t)
        for i, one in enumerate(singles):
            si = one.state(t)
            for f in ("pos_m", "vel_m_s", "acc_m_s2", "lat_rad", "lon_rad", "alt_m"):
                np.testing.assert_array_equal(getattr(s, f)[i], getattr(si, f)[0])


def test_track_validation():
    with pytest.raises(ConfigError, match="increase strictly"):
        make_track([0, 1], [0, 1], [0, 0], [5.0, 5.0])
    with pytest.raises(ConfigError, match="finite"):
        make_track([0, np.nan], [0, 1], [0, 0], [0.0, 1.0])
    with pytest.raises(ConfigError, match="antipodal"):
        Waypoints([make_track([10, -10], [20, -160], [0, 0], [0.0, 1.0])])


# --- CSV ----------------------------------------------------------------------------------


def test_read_track_csv_two_interleaved_uts():
    tracks = read_track_csv(DATA / "mobility_two_uts.csv")
    assert [t.ut_id for t in tracks] == ["walker", "boat"]
    np.testing.assert_array_equal(tracks[0].time_s, [0, 600, 1200])
    np.testing.assert_allclose(np.degrees(tracks[0].lat_rad), [40.0, 40.005, 40.005])
    np.testing.assert_array_equal(tracks[1].alt_m, [0, 0])
    pop = Waypoints(read_track_csv(DATA / "mobility_two_uts.csv"))
    # boat: 0.1 deg of longitude at 36 deg N in 100 s
    expected = haversine_m(*np.radians([36.0, -5.0, 36.0, -4.9])) / 100.0
    assert np.linalg.norm(pop.state(50.0).vel_m_s[1]) == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize(("name", "speed_m_s"), [("ship.csv", 10.0), ("car.csv", 30.0)])
def test_example_tracks(name, speed_m_s):
    tracks = read_track_csv(TRACKS / name)
    assert len(tracks) == 1 and 30 <= tracks[0].time_s.size <= 60
    pop = Waypoints(tracks)
    t0, t1 = pop.time_span_s[0]
    speeds = [np.linalg.norm(pop.state(t).vel_m_s[0]) for t in np.linspace(t0, t1, 50)[:-1]]
    # fixes are rounded to 1e-7 deg (1 cm); made at sea-level distance (car: R+689 m is 0.01 %)
    np.testing.assert_allclose(speeds, speed_m_s, rtol=2e-3)


def write(tmp_path, text):
    path = tmp_path / "track.csv"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("time_s,lat_deg,lon_deg\n0,1,2\n", r"track.csv: line 1: missing column\(s\) 'alt_m'"),
        (
            "# c\ntime_s,lat_deg,lon_deg,alt_m\n0,1,2,0\n0,1,2,0\n",
            r"line 4, column 'time_s': 0.0 s is not after 0.0 s \(line 3\)",
        ),
        (
            "time_s,lat_deg,lon_deg,alt_m\n0,91,2,0\n",
            r"line 2, column 'lat_deg': 91.0 is out of \[-90, 90\]",
        ),
        (
            "time_s,lat_deg,lon_deg,alt_m\n0,1,2,0\n1,1,east,0\n",
            r"line 3, column 'lon_deg': not a finite number",
        ),
        ("time_s,lat_deg,lon_deg,alt_m\n0,1,2\n", r"line 2: 3 fields, expected 4"),
        ("time_s,lat_deg,lon_deg,alt_m\n0,1,2,nan\n", r"column 'alt_m': not a finite"),
        ("# only a comment\n\n", r"empty track file"),
        ("time_s,lat_deg,lon_deg,alt_m\n", r"no data rows after the header \(line 1\)"),
    ],
)
def test_read_track_csv_errors(tmp_path, text, match):
    with pytest.raises(TrackFileError, match=match):
        read_track_csv(write(tmp_path, text))


def test_read_track_csv_per_ut_time_order_and_missing_file(tmp_path):
    text = "time_s,ut,lat_deg,lon_deg,alt_m\n0,a,1,2,0\n5,b,1,2,0\n3,a,1,2,0\n2,b,1,2,0\n"
    with pytest.raises(TrackFileError, match=r"line 5, .* of ut 'b'"):
        read_track_csv(write(tmp_path, text))
    with pytest.raises(LeolinkError, match="track file '.*nowhere.csv' does not exist"):
        read_track_csv(tmp_path / "nowhere.csv")


# --- placement ----------------------------------------------------------------------------

RX_M, RY_M = 534.1e3, 170.5e3  # the paper's ROI (Table 1)


def test_place_random_inside_ellipse_and_uniform():
    rng = np.random.default_rng(1)
    n = 200_000
    x, y = place_random(n, RX_M, RY_M, rng)
    q = (x / RX_M) ** 2 + (y / RY_M) ** 2
    assert np.all(q <= 1.0)
    # For uniform points in an ellipse E[x^2] = rx^2/4, so the mean has std rx/(2 sqrt(n)).
    assert abs(x.mean()) < 5 * RX_M / (2 * np.sqrt(n))
    assert abs(y.mean()) < 5 * RY_M / (2 * np.sqrt(n))
    # Area uniformity: a quarter of the points in the half-size ellipse (binomial, 5 sigma).
    assert abs(np.mean(q <= 0.25) - 0.25) < 5 * np.sqrt(0.25 * 0.75 / n)


def test_place_grid_points_inside_and_regular():
    x, y = place_grid(21, 7, RX_M, RY_M)
    assert np.all((x / RX_M) ** 2 + (y / RY_M) ** 2 <= 1.0)
    assert np.any((x == 0) & (y == 0))  # odd counts: the centre is a cell centre
    np.testing.assert_allclose(np.diff(np.unique(x)), 2 * RX_M / 21)
    np.testing.assert_allclose(np.diff(np.unique(y)), 2 * RY_M / 7)
    # brute force count: cells whose centre is inside
    xs = (np.arange(21) + 0.5) / 21 * 2 - 1
    ys = (np.arange(7) + 0.5) / 7 * 2 - 1
    assert x.size == sum(a * a + b * b <= 1 for a in xs for b in ys)


@settings(max_examples=80, deadline=None)
@given(x=st.floats(-2e6, 2e6), y=st.floats(-2e6, 2e6), lat_c=lat_st, lon_c=ang_st, heading=ang_st)
def test_roi_round_trip(x, y, lat_c, lon_c, heading):
    lat, lon = roi_points_to_geodetic(x, y, lat_c, lon_c, heading)
    x2, y2 = geodetic_to_roi_points(lat, lon, lat_c, lon_c, heading)
    assert x2 == pytest.approx(x, abs=ONE_MM) and y2 == pytest.approx(y, abs=ONE_MM)
    # Central projection: the arc from the centre is R atan(rho / R).
    d = haversine_m(lat_c, lon_c, lat, lon)
    assert d == pytest.approx(R * np.arctan(np.hypot(x, y) / R), abs=ONE_MM)


@pytest.mark.parametrize("heading_deg", [0.0, 37.0, 90.0, 200.0, 315.0])
def test_roi_axes_point_along_heading_and_to_its_left(heading_deg):
    lat_c, lon_c, h = np.radians(48.0), np.radians(11.0), np.radians(heading_deg)
    lat, lon = roi_points_to_geodetic(
        np.array([1000.0, 0.0]), np.array([0.0, 1000.0]), lat_c, lon_c, h
    )
    az = bearing_rad(lat_c, lon_c, lat, lon)
    # x > 0 ahead; y > 0 to the left (e_y = u_c x e_x, right-handed with z up). The points
    # lie on the great circles through the centre tangent to e_x, e_y: exact bearings.
    assert abs(angle_diff(az[0], h)) < 1e-6
    assert abs(angle_diff(az[1], h - np.pi / 2)) < 1e-6


def test_concat_states():
    a = Static([0.1, 0.2], [0.3, 0.4]).state(0.0)
    b = ConstantVelocity(0.5, 0.6, 0.0, 0.0, 10.0).state(5.0)
    c = concat_states([a, b])
    assert isinstance(c, UTState) and c.n_ut == 3 and c.pos_m.shape == (3, 3)
    np.testing.assert_array_equal(c.vel_m_s[2], b.vel_m_s[0])
    np.testing.assert_array_equal(c.lat_rad[:2], a.lat_rad)


# --- many times in one call (sim/motion.py's blocks) --------------------------------------
UT_FIELDS = ("pos_m", "vel_m_s", "acc_m_s2", "lat_rad", "lon_rad", "alt_m")


def _block_models():
    rng = np.random.default_rng(11)
    n = 257
    lat, lon = rng.uniform(-1.5, 1.5, n), rng.uniform(-np.pi, np.pi, n)
    moving = ConstantVelocity(lat, lon, rng.uniform(0.0, 12e3, n), rng.uniform(-np.pi, np.pi, n),
                              rng.uniform(0.0, 300.0, n), t0_s=-7.3)  # fmt: skip
    return {"static": Static(lat, lon, rng.uniform(0.0, 100.0, n)), "great circle": moving}


@pytest.mark.parametrize("name", ["static", "great circle"])
def test_states_of_many_times_are_the_states_time_after_time_bit_for_bit(name):
    """``states(times)`` is documented as ``state`` at each time (the simulator's outputs
    must not depend on which is called): equal bits, for times of 1/30 s steps around the
    model's start (before and after it) and a day later."""
    model = _block_models()[name]
    times = np.concatenate([np.arange(-37, 27) / 30.0 + 59.9, [86400.0, -7.3]])
    block = model.states(times)
    for j, t in enumerate(times):
        one = model.state(float(t))
        for f in UT_FIELDS:
            got, expected = getattr(block, f)[j], getattr(one, f)
            assert got.shape == expected.shape and np.array_equal(got, expected), (f, t)


def test_motion_blocks_take_a_wrapped_models_own_states():
    """OnWgs84 hands unknown attributes to the sphere model it wraps; a block of its UTs
    must still be on the ellipsoid (its ``state``), not the wrapped model's ``states``."""
    from leolink.sim.mobility.models import OnWgs84
    from leolink.sim.motion import MotionBlocks

    sphere = _block_models()["great circle"]
    wgs84 = OnWgs84(sphere)
    times = np.arange(5) * 10.0

    def no_satellites(t_s):
        return (np.zeros((len(t_s), 0, 3)),) * 3

    both = [("sphere", sphere), ("wgs84", wgs84)]
    block = MotionBlocks(no_satellites, both, times, 0, 2 * sphere.n_ut).block_of(0)
    for j, t in enumerate(times):
        for f in UT_FIELDS:
            expected = np.concatenate([getattr(m.state(t), f) for _, m in both])
            assert np.array_equal(getattr(block, "ut_" + f)[j], expected), (f, t)
    assert not np.allclose(wgs84.state(10.0).pos_m, sphere.state(10.0).pos_m, atol=1e3)


def test_motion_blocks_are_longer_for_fewer_uts_within_the_state_budget():
    """A block aims at BLOCK_UT_EPOCHS = 64,000 UT-epochs (each block's vectorized calls
    cost the same few microseconds whatever their size): 64 epochs of 1,000 UTs, 640 of
    100, never fewer than 64 epochs nor more than 1,024, and never more than 4 Mi float
    states (9 a satellite, 12 a UT per epoch): 105 epochs of 4,399 satellites and 10 UTs,
    3 of 100,000 UTs."""
    from leolink.sim import motion

    def n_block(n_sat, n_ut, n_epoch=5000):
        return motion.MotionBlocks(None, [], np.arange(n_epoch) * 1.0, n_sat, n_ut).n_block

    # The behaviour the constants are for: a block's states (9 floats a satellite, 12 a
    # UT, per epoch) never exceed 32 MiB.
    for n_sat in (1, 66, 4399, 30_000):
        for n_ut in (1, 257, 10_000, 100_000):
            k = n_block(n_sat, n_ut)
            assert k >= 1 and (k == 1 or (9 * n_sat + 12 * n_ut) * k * 8 <= 32 << 20)
    assert [n_block(1, n) for n in (1, 10, 62, 100, 999, 1000, 5000)] == [
        1024, 1024, 1024, 640, 64, 64, 64]  # fmt: skip
    assert n_block(4399, 10) == (1 << 22) // (9 * 4399 + 12 * 10) == 105
    assert n_block(4399, 1000) == 64 and n_block(1, 100_000) == 3

    def no_satellites(t_s):
        return (np.zeros((len(t_s), 0, 3)),) * 3

    ut = _block_models()["great circle"]  # 257 UTs: blocks of 64,000 // 257 = 249 epochs
    blocks = motion.MotionBlocks(no_satellites, [("ut", ut)], np.arange(600.0), 0, ut.n_ut)
    spans = {(b.k0, b.k1) for b in map(blocks.block_of, range(600))}
    assert spans == {(0, 249), (249, 498), (498, 600)}


def test_motion_blocks_are_c_contiguous_whatever_the_models_layout():
    """A static population's states are broadcast views; the block's arrays must still be
    C-contiguous, the layout of stacked per-epoch states: with other strides the engine's
    reductions (einsum over the 3 axes) give other last bits (the TLE example's
    elevations moved by 1 ulp)."""
    from leolink.sim.motion import MotionBlocks

    def no_satellites(t_s):
        return (np.zeros((len(t_s), 0, 3)),) * 3

    static = _block_models()["static"]
    block = MotionBlocks(no_satellites, [("s", static)], np.arange(7.0), 0, static.n_ut).block_of(0)
    for f in UT_FIELDS:
        arr = getattr(block, "ut_" + f)
        assert arr.flags.c_contiguous and arr.strides[-1] == 8, f
