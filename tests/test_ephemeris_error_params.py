"""ephemeris_error.py with non-default parameters (survivors of mutmut, issue 45).

An error that grows between updates, a velocity-only error and the update period through
the registry were exercised by no test. The references are independent of the code's
formulas: the velocity error must be the time derivative of the position error (central
finite difference), the position error must vanish at each update instant and its spread
must equal the stated growth times the age (sample standard deviation over many satellites,
within 5 standard errors), a velocity-only error must have the stated spread.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from leolink.ephemeris_error import EPHEMERIS_ERRORS, NoError, RtnConfig, RtnError

N_SAT = 20_000
N_SE = 5.0  # standard errors allowed to a sample standard deviation
GROWTH_M_PER_H = 360.0  # 0.1 m/s along track
PERIOD_S = 100.0


def _se_of_std(sigma, n):
    return sigma / np.sqrt(2.0 * (n - 1))


def test_an_error_that_grows_between_updates():
    model = RtnError((0, 0, 0), (0, 0, 0), 0.0, GROWTH_M_PER_H, PERIOD_S, seed=4)
    assert not model.is_zero
    t = np.array([200.0, 230.0, 260.0, 299.0, 300.0])  # third period, then an update
    dpos, dvel = model.offsets(t, N_SAT)
    rate = GROWTH_M_PER_H / 3600.0
    for i, age in enumerate([0.0, 30.0, 60.0, 99.0]):
        if age == 0.0:
            assert not dpos[i].any()  # exact at the update instant
            continue
        spread = np.std(dpos[i, :, 0])
        assert abs(spread - rate * age) < N_SE * _se_of_std(rate * age, N_SAT)
        assert not dpos[i, :, 1:].any()  # along track only
    assert not dpos[4].any()  # the next update starts from zero again
    # the velocity error is the derivative of the position error inside a period
    h = 1e-3
    up, _ = model.offsets(np.array([230.0 + h]), N_SAT)
    down, _ = model.offsets(np.array([230.0 - h]), N_SAT)
    np.testing.assert_allclose((up[0] - down[0]) / (2 * h), dvel[1], rtol=1e-6, atol=1e-9)


def test_a_velocity_only_error_has_its_spread():
    model = RtnError((0, 0, 0), (0, 0, 0), 0.5, 0.0, None, seed=9)
    assert not model.is_zero
    dpos, dvel = model.offsets(np.array([0.0, 50.0]), N_SAT)
    assert not dpos.any()
    for axis in range(3):
        spread = np.std(dvel[0, :, axis])
        assert abs(spread - 0.5) < N_SE * _se_of_std(0.5, N_SAT)
    np.testing.assert_array_equal(dvel[0], dvel[1])  # one draw per run without updates


def test_the_update_period_reaches_the_model_through_the_registry():
    params = RtnConfig(along_track_m=10.0, update_period_s=PERIOD_S)
    model = EPHEMERIS_ERRORS.build("rtn", params, SimpleNamespace(seed=3))
    dpos, _ = model.offsets(np.array([10.0, 90.0, 110.0]), 5)
    np.testing.assert_array_equal(dpos[0], dpos[1])  # same period: same draw
    assert np.all(dpos[1, :, 0] != dpos[2, :, 0])  # a new along-track draw after the update


@pytest.mark.parametrize("n_sat", [0, 3])
def test_no_error_is_zero_in_the_models_shape(n_sat):
    dpos, dvel = NoError().offsets(np.arange(4.0), n_sat)
    assert dpos.shape == dvel.shape == (4, n_sat, 3)
    assert not dpos.any() and not dvel.any() and dpos is not dvel


class _Circular:
    """Satellites on one circular equatorial orbit (7,000 km, 1.07e-3 rad/s), spread in phase."""

    n_sat = 50
    radius_m, rate_rad_s = 7.0e6, 1.07e-3

    def __call__(self, t_s):
        phase = np.asarray(t_s)[:, None] * self.rate_rad_s + np.linspace(0, 6, self.n_sat)
        c, s, z = np.cos(phase), np.sin(phase), np.zeros_like(phase)
        pos = self.radius_m * np.stack([c, s, z], -1)
        vel = self.radius_m * self.rate_rad_s * np.stack([-s, c, z], -1)
        return pos, vel, -(self.rate_rad_s**2) * pos


def test_the_believed_velocity_follows_the_believed_position():
    """d/dt (believed - true position) = believed - true velocity, up to the turn of the
    along/cross/radial frame (rate x |dpos|): a growing along-track error, 60 s after an
    update."""
    from leolink.ephemeris_error import EstimatedEphemeris

    true = _Circular()
    est = EstimatedEphemeris(true, RtnError((0, 0, 0), (0, 0, 0), 0.0, 3600.0, 1000.0, seed=1))
    h, t = 1e-2, 60.0
    (p_up, _, _), (p_dn, _, _) = est(np.array([t + h])), est(np.array([t - h]))
    (t_up, _, _), (t_dn, _, _) = true(np.array([t + h])), true(np.array([t - h]))
    fd = ((p_up - t_up) - (p_dn - t_dn))[0] / (2 * h)
    pos_b, vel_b, _ = est(np.array([t]))
    pos_t, vel_t, _ = true(np.array([t]))
    turn = true.rate_rad_s * np.linalg.norm(pos_b - pos_t, axis=-1)[0]  # frame rotation
    assert np.all(np.linalg.norm(fd - (vel_b - vel_t)[0], axis=-1) <= turn + 1e-6)
    assert np.linalg.norm((vel_b - vel_t)[0], axis=-1).max() > 10 * turn.max()
