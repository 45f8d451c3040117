"""leolink.orbit: the contracts that mutation testing found unchecked (docs/testing.md).

Walker patterns with phasing other than 1 and single planes, the fields of the element
sets, the two-body acceleration of TLE states against sgp4's own positions, the defaults
of the frame rotation and of the TLE ephemeris, the error-code shape and the names.
"""

import numpy as np
import pytest
from sgp4.api import Satrec

from leolink.errors import ConfigError
from leolink.orbit import (
    Elements,
    Ephemeris,
    circular_state,
    eci_to_ecef,
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
