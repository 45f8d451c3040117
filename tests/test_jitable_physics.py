"""The ``@compiled.jitable`` physics functions, called directly (as Python: the same source
numba compiles), where their callers' tests left mutants alive.

Written for issue 45's mutation scores of those functions (``tools/mutation_scores.py
--jitable``). The numpy path never calls ``kernels_of_direction``, ``beam_snr_db``,
``_pair_db`` or ``_screen_pair``, so no numpy test reaches them; the look angles and
azimuths were reached only in frames with zero components. References: the array factor
as an explicit sum of steering phases, decibels of powers of ten, a line of sight built on
a 1-2-2 (rho = 3) triangle whose direction cosines are exact fractions, and lines of sight
built at a known elevation and azimuth in the textbook local frame of a sphere (turned
about its up for a frame with no zero component).
"""

import math

import numpy as np
import pytest

from leolink.antenna.array import dirichlet_coefficients, kernels_of_direction
from leolink.engine.links import _pair_db, beam_snr_db
from leolink.engine.screening import SIN_EL_BAND, _screen_pair
from leolink.geometry import azimuth_in_frame_deg, azimuth_of_deg, azimuth_on_sphere_deg
from leolink.sim.environment import look_angles_rad
from leolink.sim.mobility.models import great_circle_state


def _array_factor(du, n):
    """``|sum_k exp(i pi k du)|^2 / n``: an n-element half-wavelength ULA off its beam by
    ``du``, summed element by element."""
    return abs(sum(np.exp(1j * np.pi * k * du) for k in range(n))) ** 2 / n


def test_kernels_of_one_direction_are_the_array_factor_against_each_beam():
    n, u = 8, 0.3
    # On the beam (the cancelling case, n), on its grating lobe (u - 2), and three others.
    beam_u = np.array([-0.5, u, 0.05, u - 2.0, 0.9])
    out = np.full((beam_u.size, 3), np.nan)
    kernels_of_direction(u, (beam_u, dirichlet_coefficients(beam_u, n), float(n)), out, 1)
    expected = [_array_factor(u - b, n) for b in beam_u]
    assert out[1, 1] == pytest.approx(n, rel=1e-12) and out[3, 1] == pytest.approx(n, rel=1e-12)
    np.testing.assert_allclose(out[:, 1], expected, rtol=1e-9, atol=1e-12 * n)
    assert np.isnan(out[:, [0, 2]]).all()  # only column p is written


def _kernels():
    """Kernel rows of 4 pairs, powers of ten (exact decibels), every entry different."""
    kx = np.array([[1e1, 1e2, 1e3, 1e4], [1e5, 1e6, 1e7, 1e8], [1e-1, 1e-2, 1e-3, 1e-4]])
    ky = np.array([[1e-5, 1e-6, 1e-7, 1e-8], [1e9, 1e10, 1e11, 1e12]])
    path = np.array([1e13, 1e14, 1e15, 1e16])
    return kx, ky, path


def test_beam_snr_is_the_decibels_of_the_product_of_its_kernels_and_the_path():
    kx, ky, path = _kernels()
    # pair 2, kernel rows 1 (x) and 0 (y): 10 log10(1e7 * 1e-7 * 1e15) = 150 dB
    assert beam_snr_db(kx, ky, path, 2, 1, 0) == pytest.approx(150.0, abs=1e-9)
    # pair 1, rows 2 and 1: 10 log10(1e-2 * 1e10 * 1e14) = 220 dB
    assert beam_snr_db(kx, ky, path, 1, 2, 1) == pytest.approx(220.0, abs=1e-9)


def test_pair_decibels_are_each_kernel_row_and_the_path_in_db():
    kx, ky, path = _kernels()
    lx, ly = np.full(3, np.nan), np.full(2, np.nan)
    path_db = _pair_db(kx, ky, path, 3, lx, ly)
    assert path_db == pytest.approx(160.0, abs=1e-9)
    np.testing.assert_allclose(lx, [40.0, 80.0, -40.0], atol=1e-9)
    np.testing.assert_allclose(ly, [-80.0, 120.0], atol=1e-9)


#: One UT and one satellite on a 1-2-2 triangle: UT -> satellite (2, 2, 1) * 100 km (rho
#: = 300 km exactly), the UT's up (2, 1, 2) / 3 (sin el = (4 + 2 + 2) / 9 = 8/9) and the
#: satellite's body axes, rows x = (1, -4, 8) / 9, y = (8, 4, 1) / 9, z = x * y = (-4, 7,
#: 4) / 9 (orthonormal; no zero, no entry repeated within a row or between neighbouring
#: rows at one index, so that any other index changes the result), along which the
#: direction satellite -> UT has cosines u_x = -(2 - 8 + 8) / 27 = -2/27 and u_y = -(16 +
#: 8 + 1) / 27 = -25/27. Row 0 of each array is another UT / satellite.
_UT = np.array([[7.0e6, -1.0e6, 2.0e5], [1.0e3, 2.0e3, 3.0e3]])
_UP = np.array([[0.0, 0.0, 1.0], [2.0 / 3.0, 1.0 / 3.0, 2.0 / 3.0]])
_SAT = np.array([[0.0, 7.5e6, 0.0], [-7.5e6, 0.0, 1.0e5], _UT[1] + [2.0e5, 2.0e5, 1.0e5]])
_AXES = np.array([np.eye(3), np.eye(3)[::-1], np.array([[1, -4, 8], [8, 4, 1], [-4, 7, 4]]) / 9])
_RHO2 = 9.0e10
_SIN_EL, _UX, _UY = 8.0 / 9.0, -2.0 / 27.0, -25.0 / 27.0


def _screen(beam_ux, beam_uy, s_min, n=(16.0, 12.0), scale=2.5):
    lattice = (np.asarray(beam_ux), np.asarray(beam_uy), n[0], n[1], s_min)
    with np.errstate(divide="ignore"):  # on a beam, 1 / 0 -> n: numpy scalars warn, numba not
        return _screen_pair((_UT, _UP, _SAT, _AXES), lattice, scale, 1, 2)


def test_screened_pair_on_its_beams_bounds_by_the_peak_gains_over_rho_squared():
    code, bound, sin_el = _screen([-0.5, _UX, 0.5], [_UY, 0.0], s_min=0.5)
    assert code == 2 and sin_el == pytest.approx(_SIN_EL, rel=1e-14)
    assert bound == pytest.approx(16.0 * 12.0 * 2.5 / _RHO2, rel=1e-12)


def test_screened_pair_off_its_beams_bounds_by_the_sidelobe_envelope():
    # The nearest beams are 0.2 (x) and 0.1 (y) away (the others farther, on either side
    # and through the grating lobe): the envelope 1 / (n sin^2(pi d / 2)) of each axis,
    # which the bound exceeds only by its Taylor sine's error (x^9 / 9!, x <= pi / 10: < 1e-9).
    code, bound, _ = _screen([-0.9, _UX + 0.2, 0.8], [_UY + 0.1, 0.4], s_min=0.5)
    env = [1.0 / (n * math.sin(math.pi * d / 2) ** 2) for n, d in ((16, 0.2), (12, 0.1))]
    expected = env[0] * env[1] * 2.5 / _RHO2
    assert code == 2 and expected <= bound <= expected * (1 + 1e-9)
    # and it bounds the true best beam (the array factors of every beam pair)
    best = max(_array_factor(_UX - bx, 16) for bx in (-0.9, _UX + 0.2, 0.8)) * max(
        _array_factor(_UY - by, 12) for by in (_UY + 0.1, 0.4)
    )
    assert best * 2.5 / _RHO2 <= bound


@pytest.mark.parametrize(
    ("s_min", "code"),
    [(_SIN_EL - 1e-6, 2), (_SIN_EL - 0.5 * SIN_EL_BAND, 1), (_SIN_EL, 1),
     (_SIN_EL + 0.5 * SIN_EL_BAND, 1), (_SIN_EL + 1e-6, 0)],
)  # fmt: skip
def test_screened_pair_is_uncertain_within_the_band_of_the_mask(s_min, code):
    got, bound, sin_el = _screen([_UX], [_UY], s_min=s_min)
    assert got == code and sin_el == pytest.approx(_SIN_EL, rel=1e-14)
    if code == 0:
        assert bound == -1.0  # below the mask: no bound
    else:
        assert bound == pytest.approx(16.0 * 12.0 * 2.5 / _RHO2, rel=1e-12)


def _sphere_frame(lat_deg, lon_deg):
    """Rows east, north, up of a sphere's local frame at (lat, lon): the textbook ENU."""
    la, lo = np.radians(lat_deg), np.radians(lon_deg)
    return np.array([
        [-np.sin(lo), np.cos(lo), 0.0],
        [-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)],
        [np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)],
    ])  # fmt: skip


def _turned(enu, deg):
    """``enu`` turned by ``deg`` about its up (east towards north): rows with no zero
    component, as a tilted or rotated local frame has."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([c * enu[0] + s * enu[1], -s * enu[0] + c * enu[1], enu[2]])


#: (elevation, azimuth) [deg] of the lines of sight: every quadrant, north itself, just
#: west of north, the horizon and below it.
_LOOKS = np.array([(40.0, 0.0), (10.0, 30.0), (75.0, 135.0), (25.0, 200.0), (5.0, 290.0),
                   (60.0, 359.5), (0.0, 90.0), (-20.0, 250.0)])  # fmt: skip


def _los(enu, rho_m=1.2e6):
    """Lines of sight (m, 3) at :data:`_LOOKS` in the frame ``enu``."""
    el, az = np.radians(_LOOKS[:, 0]), np.radians(_LOOKS[:, 1])
    local = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)
    return rho_m * local @ enu


def test_look_angles_are_the_elevation_and_azimuth_the_line_of_sight_was_built_at():
    enu = _turned(_sphere_frame(35.0, 20.0), 25.0)
    assert np.all(enu != 0.0)
    el, az = look_angles_rad(tuple(_los(enu).T), enu[:, :, None])
    np.testing.assert_allclose(np.degrees(el), _LOOKS[:, 0], atol=1e-9)
    # atan2's range (-180, 180]: 200 deg is -160 deg
    np.testing.assert_allclose(np.degrees(az), (_LOOKS[:, 1] + 180.0) % 360.0 - 180.0, atol=1e-9)


def test_a_satellite_at_the_zenith_or_nadir_is_at_plus_or_minus_90_deg_never_nan():
    """|up . los| / |los| rounds above 1 for some frames and ranges: clipped, not NaN (and
    1 - 1 ulp is an arcsine 2.1e-8 rad from 90 deg)."""
    rng = np.random.default_rng(45)
    lat, lon = rng.uniform(-90.0, 90.0, 500), rng.uniform(-180.0, 180.0, 500)
    enu = np.stack([_sphere_frame(a, b) for a, b in zip(lat, lon, strict=True)], axis=-1)
    for sign in (1.0, -1.0):
        los = sign * rng.uniform(5e5, 3e6, 500) * enu[2]
        el, _ = look_angles_rad(tuple(los), enu)
        assert np.all(np.abs(el - sign * np.pi / 2) < 3e-8)  # (NaN fails it)


def _assert_same_azimuth_deg(got, want):
    """Equal azimuths [deg] to 1e-9 deg, on the circle (due north is 0, or a little less
    than 360)."""
    assert np.all((got >= 0.0) & (got < 360.0))
    np.testing.assert_allclose((got - want + 180.0) % 360.0 - 180.0, 0.0, atol=1e-9)


def test_azimuth_in_a_frame_is_the_azimuth_the_line_of_sight_was_built_at():
    enu = _turned(_sphere_frame(-50.0, 130.0), -70.0)
    got = azimuth_in_frame_deg(_los(enu), np.broadcast_to(enu, (len(_LOOKS), 3, 3)))
    _assert_same_azimuth_deg(got, _LOOKS[:, 1])


@pytest.mark.parametrize(("lat", "lon"), [(35.0, 20.0), (-50.0, 130.0), (80.0, -100.0)])
def test_azimuth_on_the_sphere_is_the_one_in_its_local_frame(lat, lon):
    enu = _sphere_frame(lat, lon)
    pos = 6.371e6 * enu[2]
    got = azimuth_on_sphere_deg(_los(enu), np.broadcast_to(pos, (len(_LOOKS), 3)))
    _assert_same_azimuth_deg(got, _LOOKS[:, 1])


def test_due_north_a_rounding_west_is_0_not_360():
    """``np.mod(-5.7e-16, 360.0)`` is 360.0: the azimuth stays in [0, 360) (with a
    frame whose east row is a rounding off, and on the sphere on the prime meridian)."""
    east = np.array([-1e-17, 0.0, -0.0, 1e-17, -1.0, 0.0])
    north = np.array([1.0, 1.0, 1.0, 1.0, 0.0, -1.0])
    np.testing.assert_array_equal(azimuth_of_deg(east, north),
                                  [0.0, 0.0, 0.0, np.degrees(1e-17), 270.0, 180.0])  # fmt: skip
    enu = np.array([[1.0, -1e-17, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    assert azimuth_in_frame_deg(np.array([0.0, 1.0, 0.0]), enu) == 0.0  # east . los = -1e-17
    north_of_prime_meridian = azimuth_on_sphere_deg(np.array([-1.0, -1e-17, 1.0]),
                                                    np.array([6.371e6, 0.0, 0.0]))  # fmt: skip
    assert 0.0 <= north_of_prime_meridian < 360.0


def test_a_mover_through_a_pole_is_at_plus_or_minus_90_deg_never_nan():
    """Movers heading due north (south) from 400 latitudes, each an arc ``phi = 90 deg -
    lat`` (``90 deg + lat``) along: at the pole, where ``cos(phi) sin(lat) + sin(phi)
    cos(lat)`` rounds above 1 for some, the latitude is +-90 deg (the arcsine's 2.1e-8 rad
    at 1 - 1 ulp), not NaN, and the position is the pole's."""
    lat = np.radians(np.linspace(-89.0, 89.0, 400))
    lon = np.radians(np.linspace(-180.0, 180.0, 400))
    u0 = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)
    north = np.stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)], -1)
    r, v = np.full(400, 6.371e6), np.full(400, 250.0)
    for sign, e0 in ((1.0, north), (-1.0, -north)):
        pos, _, _, got, _ = great_circle_state(np.pi / 2 - sign * lat, u0, e0, r, v)
        assert np.all(np.abs(got - sign * np.pi / 2) < 3e-8)  # (NaN fails it)
        np.testing.assert_allclose(pos[2], sign * r, rtol=1e-12)
