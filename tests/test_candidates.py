"""sim.processes.candidate_satellites against a brute-force visibility test.

The candidate set must contain every satellite that some UT sees at or above the
elevation mask (else the controller silently loses it), plus the serving ones; it should
also prune (the engine's (UT x satellite x beam) call is the cost it saves).
"""

import numpy as np
import pytest

from leolink.sim.processes import candidate_satellites

R_M = 6_371_000.0


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _random_shell(rng, n, r_lo_m, r_hi_m):
    return _unit(rng.standard_normal((n, 3))) * rng.uniform(r_lo_m, r_hi_m, (n, 1))


def _uts_around(rng, n, centre, spread_rad, alt_m):
    """UTs scattered up to ``spread_rad`` of Earth-central angle around ``centre``."""
    c = _unit(centre)
    t = _unit(np.cross(c, rng.standard_normal((n, 3))))
    ang = rng.uniform(0.0, spread_rad, (n, 1))
    return (np.cos(ang) * c + np.sin(ang) * t) * (R_M + np.asarray(alt_m).reshape(-1, 1))


def _visible(sat, ut, min_el_rad):
    """Brute force: elevation of every satellite from every UT."""
    d = sat[None, :, :] - ut[:, None, :]
    up = _unit(ut)[:, None, :]
    sin_el = np.sum(d * up, -1) / np.linalg.norm(d, axis=-1)
    return (sin_el >= np.sin(min_el_rad)).any(axis=0)


CASES = [
    # (n_ut, spread_rad, alt_m, min_el_deg)
    (1, 0.0, 0.0, 10.0),
    (50, 0.05, 0.0, 10.0),  # a paper-sized ROI
    (200, 0.3, 0.0, 25.0),  # a continent
    (30, 0.1, 10_000.0, 0.0),  # aircraft, every satellite above the horizon
    (30, 0.1, -400.0, 5.0),  # below the sphere (Dead Sea shore)
    (100, 1.2, 0.0, 40.0),
]


@pytest.mark.parametrize("n_ut, spread, alt_m, min_el_deg", CASES)
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_every_visible_satellite_is_a_candidate(n_ut, spread, alt_m, min_el_deg, seed):
    rng = np.random.default_rng(seed)
    sat = _random_shell(rng, 4000, R_M + 400e3, R_M + 2000e3)
    ut = _uts_around(rng, n_ut, rng.standard_normal(3), spread, alt_m)
    min_el = np.radians(min_el_deg)
    cand = candidate_satellites(sat, ut, min_el, np.array([-1]))
    visible = np.flatnonzero(_visible(sat, ut, min_el))
    assert len(visible) > 0
    missing = np.setdiff1d(visible, cand)
    assert missing.size == 0, f"{missing.size} visible satellites dropped"
    if spread <= 0.1:
        assert len(cand) < 0.25 * len(sat)  # it prunes


def test_cone_is_tight_near_its_edge():
    """Satellites just inside the coverage edge are kept, ones well outside are not: a cone
    half as wide (or twice as wide) fails one of the two."""
    rng = np.random.default_rng(9)
    ut = np.array([[R_M, 0.0, 0.0]])
    min_el = np.radians(10.0)
    r_sat = R_M + 1300e3
    # Earth-central angle of elevation 10 deg at 1300 km: pi/2 - el - asin(R cos el / r).
    edge = np.pi / 2 - min_el - np.arcsin(R_M * np.cos(min_el) / r_sat)
    ang = np.concatenate([edge * rng.uniform(0.9, 0.999, 50), edge * rng.uniform(1.2, 2.0, 50)])
    az = rng.uniform(0, 2 * np.pi, 100)
    sat = r_sat * np.stack([np.cos(ang), np.sin(ang) * np.cos(az), np.sin(ang) * np.sin(az)], -1)
    sat = np.concatenate([sat, _random_shell(rng, 100, r_sat, r_sat)])  # > 64: cone on
    cand = candidate_satellites(sat, ut, min_el, np.array([-1]))
    assert np.isin(np.arange(50), cand).all()
    assert not np.isin(np.arange(50, 100), cand).any()


def test_serving_satellites_are_kept_and_small_sets_are_whole():
    rng = np.random.default_rng(4)
    sat = _random_shell(rng, 500, R_M + 1300e3, R_M + 1300e3)
    ut = _uts_around(rng, 5, np.array([1.0, 0.0, 0.0]), 0.01, 0.0)
    far = int(np.argmin(sat @ np.array([1.0, 0.0, 0.0])))  # on the other side of the Earth
    cand = candidate_satellites(sat, ut, np.radians(10.0), np.array([far, -1]))
    assert far in cand
    few = sat[:64]
    assert np.array_equal(candidate_satellites(few, ut, 0.1, np.array([-1])), np.arange(64))
    # UTs all over the globe: the mean direction means nothing, so every satellite is kept.
    ut_globe = np.array([[R_M, 0, 0], [-R_M, 0, 0]], float)
    assert len(candidate_satellites(sat, ut_globe, 0.1, np.array([-1]))) == len(sat)
