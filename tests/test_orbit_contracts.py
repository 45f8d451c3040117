"""leolink.orbit: the contracts that mutation testing found unchecked (docs/testing.md).

Walker patterns with phasing other than 1 and single planes, the fields of the element
sets, the two-body acceleration of TLE states against sgp4's own positions, the defaults
of the frame rotation and of the TLE ephemeris, the error-code shape and the names, the
states of some satellites (the look-ahead's).
"""

from pathlib import Path

import numpy as np
import pytest
from sgp4.api import Satrec

from leolink.constants import GM_EARTH_M3_S2
from leolink.errors import ConfigError
from leolink.orbit import (
    CentralBody,
    Elements,
    Ephemeris,
    circular_state,
    eci_to_ecef,
    pass_over,
    tle_state,
    walker_delta,
)

ISS = (
    "1 25544U 98067A   19343.69339541  .00001764  00000-0  38792-4 0  9991",
    "2 25544  51.6439 211.2001 0007417  17.6667  85.6398 15.50103472202482",
)


def test_walker_12_4_2_by_its_definition():
    """i: T/P/F = 53: 12/4/2: RAAN 90 j deg; argument of latitude 120 k + 60 j deg
    (F * 360 / T = 60 deg per plane), counted by hand."""
    el = walker_delta(12, 4, 2, np.radians(53.0), 1300e3)
    assert np.allclose(np.degrees(el.raan_rad), np.repeat([0, 90, 180, 270], 3))
    hand = [0, 120, 240, 60, 180, 300, 120, 240, 0, 180, 300, 60]
    assert np.allclose(np.degrees(el.arg_lat0_rad), hand)
    assert np.all((el.arg_lat0_rad >= 0) & (el.arg_lat0_rad < 2 * np.pi))
    assert np.array_equal(el.altitude_m, np.full(12, 1300e3))
    assert np.allclose(el.inclination_rad, np.radians(53.0))


@pytest.mark.parametrize(("t", "p", "f"), [(1, 1, 0), (5, 1, 0), (4, 2, 0), (6, 3, 2)])
def test_walker_edge_patterns_are_allowed(t, p, f):
    el = walker_delta(t, p, f, 0.9, 550e3)
    assert el.n_sat == t
    assert len(np.unique(np.round(el.raan_rad, 12))) == p


@pytest.mark.parametrize(("t", "p", "f"), [(0, 1, 0), (6, 0, 0), (7, 2, 0), (6, 3, 3), (6, 3, -1)])
def test_walker_bad_patterns_are_refused(t, p, f):
    with pytest.raises((ConfigError, ZeroDivisionError)):
        walker_delta(t, p, f, 0.9, 550e3)


def test_elements_name_a_field_that_is_not_one_dimensional():
    with pytest.raises(ConfigError, match=r"Elements\.\w+ must be 1-D"):
        Elements(np.zeros((2, 2)), 0.1, 0.2)


def test_tle_acceleration_is_the_second_derivative_of_sgp4_positions():
    """Two-body ``-GM r / |r|^3``: pointing down, and within the J2 bound of sgp4's own
    motion (|a_J2| <= 3 J2 g (R/r)^2 = 0.025 m/s^2 at the ISS)."""
    sat = Satrec.twoline2rv(*ISS)
    h_day = 0.5 / 86400.0
    fr = sat.jdsatepochF + np.array([-h_day, 0.0, h_day])
    pos, _, acc, err = tle_state([sat], np.full(3, sat.jdsatepoch), fr)
    assert not err.any()
    fd = (pos[2, 0] - 2 * pos[1, 0] + pos[0, 0]) / 0.5**2
    assert np.linalg.norm(acc[1, 0] - fd) < 0.03
    assert acc[1, 0] @ pos[1, 0] < 0  # towards the Earth


def test_eci_to_ecef_defaults_start_aligned():
    pos, vel, acc = circular_state(np.array([0.0]), 800e3, 1.0, 0.3, 0.7)
    p2, _, _ = eci_to_ecef(pos, vel, acc, np.array([0.0]))
    np.testing.assert_array_equal(p2, pos)  # gmst0 = 0: the frames coincide at t = 0


def test_ephemeris_defaults_names_and_error_shape():
    el = walker_delta(4, 2, 1, 0.9, 550e3)
    eph = Ephemeris.from_elements(el)
    assert eph.names == ["0", "1", "2", "3"] and not eph.earth_rotation
    pos, vel, acc, err = eph.state(np.array([0.0, 10.0, 20.0]))
    assert err.shape == (3, 4) and pos.shape == (3, 4, 3)
    assert Ephemeris(lambda t: None, 2, False, names=["a", "b"]).names == ["a", "b"]


def test_tle_ephemeris_from_satrec_objects_and_its_defaults():
    sat = Satrec.twoline2rv(*ISS)
    eph = Ephemeris.from_tles([sat], sat.jdsatepoch + sat.jdsatepochF)
    assert eph.earth_rotation and eph.names == ["25544"]
    same = Ephemeris.from_tles([("ISS", *ISS)], sat.jdsatepoch, sat.jdsatepochF)
    assert same.names == ["ISS"]
    a, b = eph(np.array([0.0, 60.0]))[0], same(np.array([0.0, 60.0]))[0]
    # One float JD resolves 40 us (0.3 m of ISS motion); a day off would be 1e6 m.
    np.testing.assert_allclose(a, b, rtol=0, atol=1.0)


def test_tle_rotation_uses_the_given_ut1_minus_utc():
    # skyfield (builtin IERS table, no polar motion) rotates TEME to ITRS at UT1; with its
    # UT1 - UTC of the TLE epoch (-0.172 s on 2019-12-09) leolink agrees to 0.12 m
    # (measured). Without it the gap is 55-83 m, with the sign flipped 110-166 m: 1 m
    # separates them.
    from skyfield import api as skyfield_api
    from skyfield.framelib import itrs

    from leolink.io.tle import read_tle_file

    tles = read_tle_file(Path(__file__).parent / "data" / "geo_iss.tle")
    ts = skyfield_api.load.timescale(builtin=True)
    sat = skyfield_api.EarthSatellite(tles[0][1], tles[0][2], tles[0][0], ts)
    jd, fr = sat.model.jdsatepoch, sat.model.jdsatepochF
    t = np.array([0.0, 300.0, 900.0])
    when = ts.utc(2019, 12, 9, 0, 0, (jd + fr - 2458826.5) * 86400.0 + t)
    ref = sat.at(when).frame_xyz(itrs).m.T
    dut1_s = float(when.dut1[0])
    eph = Ephemeris.from_tles(tles, jd, fr, earth_rotation=True, ut1_minus_utc_s=dut1_s)
    assert np.linalg.norm(eph(t)[0][:, 0] - ref, axis=-1).max() < 1.0


def test_tles_given_as_two_lines_are_named_by_their_index():
    sats = [Satrec.twoline2rv(*ISS), Satrec.twoline2rv(*ISS)]
    jd, fr = sats[0].jdsatepoch, sats[0].jdsatepochF
    eph = Ephemeris.from_tles([ISS, ISS], jd, fr, earth_rotation=False)
    assert eph.names == ["0", "1"]
    assert eph.state(0.0)[3].dtype.kind == "i"  # sgp4's error codes, integers
    e, r_km, _ = sats[1].sgp4(jd, fr + 120.0 / 86400.0)
    assert e == 0
    np.testing.assert_allclose(eph(120.0)[0][0, 1], np.array(r_km) * 1e3, rtol=0, atol=1e-3)


def test_tle_acceleration_is_that_of_the_given_gm():
    # Half the GM: half the two-body pull; sgp4's own motion (the finite difference of its
    # positions) stays that of the Earth, within the J2 bound of 0.025 m/s^2.
    sat = Satrec.twoline2rv(*ISS)
    h_day = 0.5 / 86400.0
    eph = Ephemeris.from_tles([sat], sat.jdsatepoch, sat.jdsatepochF - h_day,
                              earth_rotation=False, gm_m3_s2=GM_EARTH_M3_S2 / 2)  # fmt: skip
    pos, _, acc = eph(np.array([0.0, 0.5, 1.0]))
    fd = (pos[2, 0] - 2 * pos[1, 0] + pos[0, 0]) / 0.5**2
    assert np.linalg.norm(acc[1, 0] - fd / 2) < 0.03


def _sub_satellite_point(el, t_s):
    """Inertial latitude, longitude of the satellite at ``t_s`` and its z velocity."""
    pos, vel, _ = circular_state(np.array([t_s]), el.altitude_m, el.inclination_rad,
                                 el.raan_rad, el.arg_lat0_rad)  # fmt: skip
    p = pos[0, 0]
    return np.arcsin(p[2] / np.linalg.norm(p)), np.arctan2(p[1], p[0]), vel[0, 0, 2]


def test_pass_over_defaults_are_an_ascending_pass_without_earth_rotation():
    # Ten minutes after t = 0 an Earth-fixed point would have turned by 2.5 deg: the
    # default frame is inertial, so the pass is over (lat, lon) of that frame, going north.
    el = pass_over(0.5, 1.2, 600.0, 550e3, 0.9)
    lat, lon, v_z = _sub_satellite_point(el, 600.0)
    assert lat == pytest.approx(0.5, abs=1e-12) and lon == pytest.approx(1.2, abs=1e-12)
    assert v_z > 0.0


def test_pass_over_equatorial_and_at_the_reachable_edge():
    # Inclination 0: the equator only (sin u is undefined, u = 0 by convention).
    lat, lon, _ = _sub_satellite_point(pass_over(0.0, -2.0, 100.0, 550e3, 0.0), 100.0)
    assert lat == pytest.approx(0.0, abs=1e-12) and lon == pytest.approx(-2.0, abs=1e-12)
    # |lat| up to 1e-12 rad beyond the inclination is accepted (degrees rounded through
    # radians): the northernmost and southernmost points, not NaN.
    for sign in (1.0, -1.0):
        el = pass_over(sign * (0.9 + 5e-13), 0.3, 0.0, 550e3, 0.9)
        lat, lon, _ = _sub_satellite_point(el, 0.0)
        assert lat == pytest.approx(sign * 0.9, abs=1e-9) and lon == pytest.approx(0.3, abs=1e-9)


def test_pass_over_retrograde_orbit_reaches_pi_minus_inclination():
    # i = 120 deg reaches |lat| <= 60 deg only.
    with pytest.raises(ConfigError, match="use \\|lat\\| <= 60.000 deg"):
        pass_over(np.radians(70.0), 0.0, 0.0, 550e3, np.radians(120.0))
    lat, _, _ = _sub_satellite_point(pass_over(np.radians(59.0), 0.0, 0.0, 550e3,
                                               np.radians(120.0)), 0.0)  # fmt: skip
    assert np.degrees(lat) == pytest.approx(59.0, abs=1e-9)


def test_pass_over_of_another_body_uses_its_radius_and_gm():
    # Mars (NASA fact sheet: GM = 42,828.37 km^3/s^2, mean radius 3,389.5 km): the orbit
    # built for that body passes over the point at t_pass when propagated with its GM.
    gm, radius = 4.282837e13, 3_389.5e3
    el = pass_over(0.3, -0.4, 900.0, 400e3, 0.8, earth=CentralBody(radius, gm))
    elements = (el.altitude_m, el.inclination_rad, el.raan_rad, el.arg_lat0_rad)
    pos, _, _ = circular_state(np.array([900.0]), *elements, radius_m=radius, gm_m3_s2=gm)
    p = pos[0, 0]
    assert np.linalg.norm(p) == pytest.approx(radius + 400e3, rel=1e-12)
    assert np.arcsin(p[2] / np.linalg.norm(p)) == pytest.approx(0.3, abs=1e-12)
    assert np.arctan2(p[1], p[0]) == pytest.approx(-0.4, abs=1e-12)


def test_ephemeris_of_another_body_with_a_rotation_angle():
    # Circular orbit about Mars: back at its start after 2 pi sqrt(a^3 / GM) (inertial).
    gm, radius, h = 4.282837e13, 3_389.5e3, 400e3
    el = Elements(h, 0.8, 0.3, 0.1)
    period_s = 2 * np.pi * np.sqrt((radius + h) ** 3 / gm)
    eph = Ephemeris.from_elements(el, radius_m=radius, gm_m3_s2=gm)
    pos, _, _, err = eph.state(np.array([0.0, period_s / 2, period_s]))
    np.testing.assert_allclose(pos[2], pos[0], atol=1e-6)
    np.testing.assert_allclose(pos[1], -pos[0], atol=1e-6)  # half a period: opposite
    assert err.dtype.kind == "i" and not err.any()
    # Earth-fixed with a rotation angle gmst0 at t = 0: longitudes lag by gmst0, and the
    # Earth-fixed velocity is the derivative of the Earth-fixed positions.
    fixed = Ephemeris.from_elements(el, earth_rotation=True, radius_m=radius, gm_m3_s2=gm,
                                    gmst0_rad=0.5)  # fmt: skip
    t = np.array([-0.5, 0.0, 0.5])
    pos_f, vel_f, _ = fixed(t)
    lon = np.arctan2(pos[0, 0, 1], pos[0, 0, 0])
    assert np.arctan2(pos_f[1, 0, 1], pos_f[1, 0, 0]) == pytest.approx(lon - 0.5, abs=1e-12)
    # Central difference over 1 s: truncation |x'''| dt^2 / 6 ~ n^2 v / 6 ~ 1e-3 m/s.
    np.testing.assert_allclose(vel_f[1, 0], (pos_f[2, 0] - pos_f[0, 0]) / 1.0, atol=5e-3)


def test_ephemeris_default_rotation_angle_is_zero():
    def propagate(t):
        pos = np.broadcast_to(np.array([7e6, 0.0, 0.0]), (len(t), 1, 3)).copy()
        return pos, np.zeros_like(pos), np.zeros_like(pos), np.zeros((len(t), 1), int)

    pos, _, _ = Ephemeris(propagate, 1, earth_rotation=True)(np.array([0.0]))
    np.testing.assert_array_equal(pos[0, 0], [7e6, 0.0, 0.0])


def test_eci_to_ecef_times_in_float32_are_computed_in_float64():
    # float32 times carry 7 digits: theta = w_E t in float32 is off by ~3e-8 rad (0.2 m).
    pos, vel, acc = circular_state(np.array([5400.0]), 800e3, 1.0, 0.3, 0.7)
    t32 = np.array([5400.0], dtype=np.float32)
    got = eci_to_ecef(pos, vel, acc, t32)
    want = eci_to_ecef(pos, vel, acc, t32.astype(np.float64))
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g, w, rtol=1e-14, atol=1e-9)


def test_float32_elements_and_times_are_computed_in_float64():
    # float32 carries 7 digits (0.5 m on a 7e6 m radius): orbits compute in float64 whatever
    # their inputs are stored in; the float64 result of the same values is the reference.
    from leolink.orbit import angular_rate_rad_s, orbital_speed_m_s

    h32 = np.array([550e3], dtype=np.float32)
    for func in (orbital_speed_m_s, angular_rate_rad_s):
        assert func(h32).dtype == np.float64
        np.testing.assert_allclose(func(h32), func(h32.astype(float)), rtol=1e-15)
    values = [np.array([v], dtype=np.float32) for v in (5400.0, 550e3, 0.9, 0.3, 0.7)]
    got = circular_state(*values)
    want = circular_state(*(v.astype(float) for v in values))
    for g, w in zip(got, want, strict=True):
        assert g.dtype == np.float64
        np.testing.assert_allclose(g, w, rtol=1e-14, atol=1e-9)
    assert Elements(*values[1:]).raan_rad.dtype == np.float64


def test_some_satellites_states_are_their_rows_of_every_satellites():
    """``eph(t, sats)``: circular orbits propagated for those satellites alone (unordered
    ids, one repeated), TLEs sliced, and the believed ephemeris of an error model (its
    draws those of every satellite): each the whole set's rows, in the given order, exactly
    (element-wise the same operations)."""
    from leolink.ephemeris_error import EstimatedEphemeris, RtnError

    t = np.array([0.0, 17.0, 600.5])
    sats = np.array([40, 3, 3, 17])
    circ = Ephemeris.from_elements(walker_delta(48, 6, 1, 0.9, 550e3), earth_rotation=True)
    iss = Satrec.twoline2rv(*ISS)
    tle = Ephemeris.from_tles([("a", *ISS), iss, iss], iss.jdsatepoch, iss.jdsatepochF)
    est = EstimatedEphemeris(circ, RtnError((10.0, 5.0, 2.0), (0, 0, 0), 0.1, 60.0, 3.0, seed=2))
    for eph, ids in ((circ, sats), (tle, np.array([2, 0])), (est, sats)):
        every, some = eph(t), eph(t, ids)
        for a, b in zip(every, some, strict=True):
            assert b.shape == (t.size, ids.size, 3)
            np.testing.assert_array_equal(b, a[:, ids])
    assert not np.array_equal(est(t, sats)[0], circ(t, sats)[0])  # (the error is applied)
    assert circ.propagates_some and not tle.propagates_some
