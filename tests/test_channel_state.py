"""Spatially consistent LoS / shadowing process (leolink.link.channel_state).

Statistical tests compare against TR 38.811 V15.4.0 numbers typed here (Table 6.6.1-1,
Tables 6.6.2-1..3) and against the exponential autocorrelation of TR 38.901 Eq. (7.4-5),
each with a tolerance of 4 standard errors of the estimator.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal, norm

from leolink import rng as lrng
from leolink.link import channel_state as cs

N_SIGMA = 4.0


def run(model, keys, sat_id, el_rad, az_rad, steps_m, epochs, state=None):
    """Advance through a list of epochs; geometry and steps may be per-epoch lists."""
    state = cs.empty_state(len(keys)) if state is None else state
    out = []
    for k, epoch in enumerate(epochs):
        pick = [x[k] if isinstance(x, list) else x for x in (sat_id, el_rad, az_rad, steps_m)]
        state = cs.advance(state, model, keys, *pick, epoch)
        out.append(state)
    return out


def fixed_geometry(n_ut, n_slot, elevation_deg, seed=7):
    sat_id = np.tile(np.arange(n_slot), (n_ut, 1))
    el = np.full((n_ut, n_slot), np.radians(elevation_deg))
    az = np.random.default_rng(seed).uniform(0, 2 * np.pi, (n_ut, n_slot))
    return sat_id, el, az


@pytest.mark.parametrize(
    ("environment", "elevation_deg", "p_los"),
    [
        ("dense_urban", 30.0, 0.398),  # Table 6.6.1-1, tabulated
        ("urban", 35.0, (0.493 + 0.613) / 2),  # interpolated between 30 and 40 deg
        ("rural", 10.0, 0.782),
        ("suburban", 5.0, 0.782),  # clamped to the 10-degree row
    ],
)
def test_los_fraction_equals_table_6_6_1_1_within_binomial_error(environment, elevation_deg, p_los):
    n_ut, n_slot = 4000, 5
    model = cs.environment_model(environment, 11.45e9)
    keys = lrng.ut_keys(11, n_ut)
    sat_id, el, az = fixed_geometry(n_ut, n_slot, elevation_deg)
    step = np.tile([3.0, 4.0], (n_ut, 1))  # 5 m per epoch: stationarity must hold after moving
    for state in run(model, keys, sat_id, el, az, step, [0, 1, 5]):
        los = cs.link_terms(state, model).los
        n = los.size
        assert abs(los.mean() - p_los) < N_SIGMA * np.sqrt(p_los * (1 - p_los) / n)


@pytest.mark.parametrize(
    ("environment", "freq_hz", "elevation_deg", "sigma_los", "sigma_nlos", "cl_nlos"),
    [
        ("dense_urban", 2.0e9, 30.0, 2.9, 12.4, 29.0),  # Table 6.6.2-1, S band
        ("urban", 11.45e9, 50.0, 4.0, 6.0, 34.6),  # Table 6.6.2-2, Ka band
        ("suburban", 11.45e9, 10.0, 1.9, 10.7, 29.5),  # Table 6.6.2-3, Ka band
        ("rural", 2.0e9, 20.0, 1.14, 9.08, 18.17),  # Table 6.6.2-3, S band
    ],
)
def test_shadowing_std_and_clutter_equal_tables_6_6_2(
    environment, freq_hz, elevation_deg, sigma_los, sigma_nlos, cl_nlos
):
    n_ut, n_slot = 4000, 10
    model = cs.environment_model(environment, freq_hz)
    keys = lrng.ut_keys(12, n_ut)
    sat_id, el, az = fixed_geometry(n_ut, n_slot, elevation_deg)
    (state,) = run(model, keys, sat_id, el, az, np.zeros(n_ut), [3])
    t = cs.link_terms(state, model)
    for mask, sigma in ((t.los, sigma_los), (~t.los, sigma_nlos)):
        x = t.shadow_db[mask]
        n = x.size
        assert n > 500
        assert abs(x.mean()) < N_SIGMA * sigma / np.sqrt(n)  # zero-mean
        assert abs(x.std() - sigma) < N_SIGMA * sigma / np.sqrt(2 * n)
    assert np.all(t.clutter_db[t.los] == 0.0)
    assert t.clutter_db[~t.los] == pytest.approx(cl_nlos, abs=1e-9)
    assert np.allclose(t.extra_loss_db, t.shadow_db + t.clutter_db)


def track_states(model, n_ut, step_m, n_epoch, seed=21):
    """Every UT drives straight east ``step_m`` per epoch under a fixed satellite direction."""
    keys = lrng.ut_keys(seed, n_ut)
    sat_id, el, az = fixed_geometry(n_ut, 1, 40.0)
    step = np.tile([step_m, 0.0], (n_ut, 1))
    return run(model, keys, sat_id, el, az, step, list(range(n_epoch)))


@pytest.mark.parametrize("environment", ["urban", "rural"])
def test_shadowing_decorrelates_along_a_straight_track_as_exp_minus_d_over_dcorr(environment):
    model = cs.environment_model(environment, 11.45e9)
    n_ut, step_m = 6000, 6.0
    states = track_states(model, n_ut, step_m, 31)
    for field, d_corr in (
        ("z_sf_los", 37.0),
        ("z_sf_nlos", 50.0 if environment == "urban" else 120.0),
    ):
        z0 = getattr(states[0], field)[:, 0]
        for lag in (1, 5, 15, 30):
            rho = np.exp(-lag * step_m / d_corr)
            r = np.corrcoef(z0, getattr(states[lag], field)[:, 0])[0, 1]
            assert abs(r - rho) < N_SIGMA * (1 - rho**2) / np.sqrt(n_ut) + 1e-3, (field, lag)


def test_shadow_db_follows_the_field_of_the_current_state():
    # Dense urban with a long NLoS distance: while a UT stays NLoS its shadow_db / sigma
    # decorrelates over 120 m, while it stays LoS over 37 m (one field per link state).
    model = cs.environment_model(
        "dense_urban", 11.45e9, cs.ChannelOptions(sf_corr_distance_nlos_m=120.0)
    )
    n_ut, step_m, lag = 8000, 6.0, 10
    states = track_states(model, n_ut, step_m, lag + 1)
    t0, t1 = cs.link_terms(states[0], model), cs.link_terms(states[lag], model)
    sigma = {True: 2.4, False: 14.6}  # Table 6.6.2-1, Ka band, 40 deg
    for los, d_corr in ((True, 37.0), (False, 120.0)):
        same = (t0.los[:, 0] == los) & (t1.los[:, 0] == los)
        rho = np.exp(-lag * step_m / d_corr)
        r = np.corrcoef(t0.shadow_db[same, 0] / sigma[los], t1.shadow_db[same, 0] / sigma[los])
        assert same.sum() > 1500
        assert abs(r[0, 1] - rho) < N_SIGMA * (1 - rho**2) / np.sqrt(same.sum()), los


def test_los_state_decorrelates_as_a_thresholded_exponential_field():
    # Independent model: LoS = {Z < t}, (Z0, ZL) bivariate normal with correlation
    # exp(-d/d_corr), so P(LoS at both) = Phi2(t, t; rho) (TR 38.901 clause 7.6.3.3).
    model = cs.environment_model(
        "dense_urban", 11.45e9, cs.ChannelOptions(los_corr_distance_m=30.0)
    )
    n_ut, step_m = 8000, 4.0
    states = track_states(model, n_ut, step_m, 21)
    p = 0.468  # Table 6.6.1-1, dense urban, 40 deg
    t = norm.ppf(p)
    los0 = cs.link_terms(states[0], model).los[:, 0]
    for lag in (1, 3, 8, 20):
        rho = np.exp(-lag * step_m / 30.0)
        both = multivariate_normal(cov=[[1, rho], [rho, 1]]).cdf([t, t])
        expected = (both - p * p) / (p * (1 - p))
        r = np.corrcoef(los0, cs.link_terms(states[lag], model).los[:, 0])[0, 1]
        assert abs(r - expected) < N_SIGMA / np.sqrt(n_ut), lag


def test_no_motion_no_change_of_state():
    model = cs.environment_model("urban", 11.45e9)
    keys = lrng.ut_keys(3, 50)
    sat_id, el, az = fixed_geometry(50, 4, 55.0)
    states = run(model, keys, sat_id, el, az, np.zeros((50, 2)), [0, 1, 2, 9])
    for s in states[1:]:
        for f in ("z_los", "z_sf_los", "z_sf_nlos"):
            assert np.array_equal(getattr(s, f), getattr(states[0], f))


def brute_force_piercing_point(el, az, h):
    """Explicit ray-plane intersection: UT at origin, unit look vector, plane z = h."""
    d = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)
    t = h / d[..., 2]
    return (t[..., None] * d)[..., :2]


def test_effective_displacement_is_the_shift_of_the_rays_piercing_point():
    g = np.random.default_rng(5)
    n_ut, n_slot, h = 40, 6, 15.0
    el0, el1 = (np.radians(g.uniform(10, 90, (n_ut, n_slot))) for _ in range(2))
    az0, az1 = (g.uniform(0, 2 * np.pi, (n_ut, n_slot)) for _ in range(2))
    step = g.normal(0, 10, (n_ut, 2))
    ut_after = step[:, None, :] + brute_force_piercing_point(el1, az1, h)
    expected = np.linalg.norm(ut_after - brute_force_piercing_point(el0, az0, h), axis=-1)
    got = cs.effective_displacement_m(step, el0, az0, el1, az1, h)
    assert got == pytest.approx(expected, rel=1e-12, abs=1e-9)


def test_ray_offset_of_a_link_vector_is_the_piercing_point_whatever_its_length():
    """The compiled loop passes the link's (east, north, up) in metres, not a unit vector;
    below 10 deg the point is held at its 10-degree place."""
    g = np.random.default_rng(8)
    el, az = np.radians(g.uniform(10, 90, 50)), g.uniform(0, 2 * np.pi, 50)
    want = brute_force_piercing_point(el, az, 15.0)
    for length_m in (1.0, 7.3e6):
        link = [length_m * c for c in cs.direction_enu(el, az)]
        got = np.stack(cs.ray_offset_en_m(*link, 15.0), axis=-1)
        assert got == pytest.approx(want, rel=1e-12, abs=1e-12)
    low = [2.1e6 * c for c in cs.direction_enu(np.full(50, np.radians(3.0)), az)]
    held = brute_force_piercing_point(np.full(50, np.radians(10.0)), az, 15.0)
    assert np.stack(cs.ray_offset_en_m(*low, 15.0), axis=-1) == pytest.approx(held, rel=1e-12)


def test_scalar_ut_step_is_the_mean_square_over_travel_directions():
    el0, el1 = np.radians([[20.0]]), np.radians([[24.0]])
    az0, az1 = np.radians([[100.0]]), np.radians([[93.0]])
    step_m = 12.0
    heading = np.linspace(0, 2 * np.pi, 360, endpoint=False)  # exact for a trig polynomial
    vec = np.stack([step_m * np.sin(heading), step_m * np.cos(heading)], axis=-1)
    d2 = [cs.effective_displacement_m(v[None, :], el0, az0, el1, az1, 20.0)[0, 0] ** 2 for v in vec]
    got = cs.effective_displacement_m(np.array([step_m]), el0, az0, el1, az1, 20.0)[0, 0]
    assert got**2 == pytest.approx(np.mean(d2), rel=1e-12)


def test_static_ut_decorrelates_as_the_satellite_moves_and_not_at_zenith():
    # Zenith pass: the piercing point stays above the UT, 0.2 deg of motion moves it by mm.
    el = np.radians([[89.9]]), np.radians([[90.0]])
    near_zenith = cs.effective_displacement_m(np.zeros(1), el[0], [[0.0]], el[1], [[np.pi]], 15.0)
    assert near_zenith[0, 0] < 0.03
    # Low elevation: 15 / tan(10 deg) - 15 / tan(11 deg) = 85.07 - 77.17 = 7.90 m.
    low = cs.effective_displacement_m(
        np.zeros(1), np.radians([[10.0]]), [[1.0]], np.radians([[11.0]]), [[1.0]], 15.0
    )
    assert low[0, 0] == pytest.approx(7.90, abs=0.01)
    # Below 10 deg the piercing point is held at its 10-degree place (the tables' floor).
    below = cs.effective_displacement_m(
        np.zeros(1), np.radians([[3.0]]), [[1.0]], np.radians([[10.0]]), [[1.0]], 15.0
    )
    assert below[0, 0] == pytest.approx(0.0, abs=1e-12)


def changing_candidates(n_ut, n_epoch, n_sat_total=40, n_slot=8, seed=2):
    """Candidate sets that change from epoch to epoch, with padding, and random geometry."""
    g = np.random.default_rng(seed)
    ids, els, azs, steps = [], [], [], []
    for _ in range(n_epoch):
        sat = np.array([g.choice(n_sat_total, n_slot, replace=False) for _ in range(n_ut)])
        sat[g.random((n_ut, n_slot)) < 0.1] = -1  # empty slots
        ids.append(sat)
        els.append(np.radians(g.uniform(5, 90, (n_ut, n_slot))))
        azs.append(g.uniform(0, 2 * np.pi, (n_ut, n_slot)))
        steps.append(g.normal(0, 8, (n_ut, 2)))
    return ids, els, azs, steps


FIELDS = ("sat_id", "z_los", "z_sf_los", "z_sf_nlos", "elevation_rad", "ray_east_m", "ray_north_m")


def chunked_run(model, keys, data, epochs, bounds):
    parts = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        sub = [[x[a:b] for x in series] for series in data]
        parts.append(run(model, keys[a:b], *sub, epochs)[-1])
    return {f: np.concatenate([getattr(p, f) for p in parts]) for f in FIELDS}


def test_same_states_whatever_the_chunking_of_uts():
    n_ut, epochs = 300, [0, 1, 2, 4, 5, 6, 7, 9, 10, 11]
    model = cs.environment_model("dense_urban", 11.45e9)
    keys = lrng.ut_keys(2024, n_ut)
    data = changing_candidates(n_ut, len(epochs))
    whole = run(model, keys, *data, epochs)[-1]
    for bounds in ([0, 7, 150, 300], [0, 1, 2, 299, 300]):
        parts = chunked_run(model, keys, data, epochs, bounds)
        for f in FIELDS:
            assert np.array_equal(getattr(whole, f), parts[f]), f


@settings(max_examples=20, deadline=None)
@given(split=st.integers(1, 29), seed=st.integers(0, 2**16))
def test_chunking_and_slot_order_do_not_change_any_pair(split, seed):
    n_ut, epochs = 30, [0, 1, 2, 3]
    model = cs.environment_model("suburban", 2e9)
    keys = lrng.ut_keys(seed, n_ut)
    ids, els, azs, steps = changing_candidates(n_ut, len(epochs), n_slot=5, seed=seed)
    whole = run(model, keys, ids, els, azs, steps, epochs)[-1]
    parts = chunked_run(model, keys, (ids, els, azs, steps), epochs, [0, split, n_ut])
    perm = np.random.default_rng(seed).permutation(5)
    shuffled = run(model, keys, *[[x[:, perm] for x in s] for s in (ids, els, azs)], steps, epochs)
    for f in FIELDS:
        assert np.array_equal(getattr(whole, f), parts[f])
        assert np.array_equal(getattr(whole, f)[:, perm], getattr(shuffled[-1], f))


def test_a_pair_that_returns_restarts_from_the_stationary_distribution():
    model = cs.environment_model("urban", 11.45e9)
    keys = lrng.ut_keys(9, 20)
    el, az = np.full((20, 1), np.radians(40.0)), np.zeros((20, 1))
    seen = run(model, keys, np.full((20, 1), 7), el, az, np.zeros(20), [0, 1])[-1]
    gone = cs.advance(seen, model, keys, np.full((20, 1), 8), el, az, np.zeros(20), 2)
    back = cs.advance(gone, model, keys, np.full((20, 1), 7), el, az, np.zeros(20), 3)
    fresh = cs.advance(
        cs.empty_state(20), model, keys, np.full((20, 1), 7), el, az, np.zeros(20), 3
    )
    for f in FIELDS:
        assert np.array_equal(getattr(back, f), getattr(fresh, f))
    assert not np.array_equal(back.z_los, seen.z_los)


def test_seed_and_satellite_select_independent_streams():
    model = cs.environment_model("urban", 11.45e9)
    sat_id, el, az = fixed_geometry(2000, 2, 40.0)
    a = run(model, lrng.ut_keys(1, 2000), sat_id, el, az, np.zeros(2000), [0])[0]
    b = run(model, lrng.ut_keys(2, 2000), sat_id, el, az, np.zeros(2000), [0])[0]
    limit = N_SIGMA / np.sqrt(2000)
    assert abs(np.corrcoef(a.z_los[:, 0], b.z_los[:, 0])[0, 1]) < limit
    assert abs(np.corrcoef(a.z_los[:, 0], a.z_los[:, 1])[0, 1]) < limit
    assert abs(np.corrcoef(a.z_los[:, 0], a.z_sf_los[:, 0])[0, 1]) < limit
    assert abs(np.corrcoef(a.z_los[:, 0], a.z_sf_nlos[:, 0])[0, 1]) < limit
    assert abs(np.corrcoef(a.z_sf_los[:, 0], a.z_sf_nlos[:, 0])[0, 1]) < limit


def test_open_environment_is_always_los_with_zero_loss():
    model = cs.environment_model("open", 11.45e9)
    ids, els, azs, steps = changing_candidates(100, 3)
    state = run(model, lrng.ut_keys(0, 100), ids, els, azs, steps, [0, 1, 2])[-1]
    t = cs.link_terms(state, model)
    valid = state.sat_id >= 0
    assert np.all(t.los == valid)
    for x in (t.shadow_db, t.clutter_db, t.scintillation_db, t.extra_loss_db):
        assert np.all(x[valid] == 0.0) and np.all(np.isnan(x[~valid]))


def test_scintillation_margin_enters_the_extra_loss():
    # 20 GHz, 30 deg: 0.30 dB (Table 6.6.6.2.1-1), on top of shadowing and clutter.
    model = cs.environment_model("urban", 20e9, cs.ChannelOptions(scintillation=True))
    sat_id, el, az = fixed_geometry(200, 3, 30.0)
    (state,) = run(model, lrng.ut_keys(4, 200), sat_id, el, az, np.zeros(200), [0])
    t = cs.link_terms(state, model)
    assert t.scintillation_db == pytest.approx(0.30, abs=1e-6)
    assert np.allclose(t.extra_loss_db - t.shadow_db - t.clutter_db, 0.30, atol=1e-6)


def test_invalid_parameters_and_epoch_order():
    with pytest.raises(cs.ConfigError, match=r"los_corr_distance_m = 0.0 is not allowed"):
        cs.environment_model("urban", 11.45e9, cs.ChannelOptions(los_corr_distance_m=0.0))
    with pytest.raises(cs.ConfigError, match="geomagnetic_latitude_deg is required"):
        cs.environment_model("urban", 2e9, cs.ChannelOptions(scintillation=True))
    model = cs.environment_model("urban", 11.45e9)
    sat_id, el, az = fixed_geometry(3, 1, 40.0)
    (state,) = run(model, lrng.ut_keys(0, 3), sat_id, el, az, np.zeros(3), [5])
    with pytest.raises(ValueError, match="must exceed the state's epoch 5"):
        cs.advance(state, model, lrng.ut_keys(0, 3), sat_id, el, az, np.zeros(3), 5)


def _tracker_epochs(use, monkeypatch):
    """Six epochs of a ChannelTracker over two populations (non-default distances and
    clutter height), UTs moving north, satellites drifting, the cone changing."""
    import leolink.compiled
    from leolink.geometry import enu_basis
    from leolink.sim.environment import ChannelTracker

    if not use:
        monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    n, rs = 120, np.random.default_rng(5)
    models = [cs.environment_model("urban", 20e9),
              cs.environment_model("dense_urban", 2e9, cs.ChannelOptions(
                  clutter_height_m=31.0, los_corr_distance_m=7.0, sf_corr_distance_los_m=11.0,
                  sf_corr_distance_nlos_m=23.0))]  # fmt: skip
    tracker = ChannelTracker(models, [80, 40], lrng.ut_keys(3, n), np.radians(10.0))
    lat0, lon = np.radians(rs.uniform(40, 50, n)), np.radians(rs.uniform(0, 10, n))
    sat = rs.normal(size=(300, 3))
    sat *= 6921e3 / np.linalg.norm(sat, axis=1)[:, None]
    out = []
    for k in range(6):
        lat = lat0 + 2e-6 * k * np.arange(n) / n  # up to ~13 m an epoch
        pos = 6371e3 * np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon),
                                 np.sin(lat)], -1)  # fmt: skip
        cone = np.setdiff1d(np.arange(300), np.arange(k, 300, 7))
        out.append(tracker.step(k, pos, enu_basis(lat, lon), sat + 2e3 * k, cone))
    return out


def test_compiled_tracker_equals_the_numpy_path(monkeypatch):
    """ChannelTracker's compiled loop (look angles, carry, ray shift, innovations, AR(1)
    in one pass) gives the numpy path's pairs and terms to 1e-12 dB, with moving UTs,
    non-default distances and clutter height, and pairs that leave and return."""
    fused = _tracker_epochs(True, monkeypatch)
    plain = _tracker_epochs(False, monkeypatch)
    assert sum(int(e.has.sum()) for e in fused) > 3000
    for a, b in zip(fused, plain, strict=True):
        np.testing.assert_array_equal(a.has, b.has)
        np.testing.assert_array_equal(a.los, b.los)
        for name in ("shadow_db", "clutter_db"):
            np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("z_prev", "distance_m", "w", "expected"),
    [
        (1.0, 37.0 * np.log(2.0), 2.0, 0.5 + np.sqrt(3.0)),  # rho = 1/2: 1/2 + sqrt(3/4) 2
        (-0.8, 37.0 * np.log(2.0), -1.0, -0.4 - np.sqrt(0.75)),
        (1.3, 0.0, 2.0, 1.3),  # no move: rho = 1, the same value
        (1.3, np.inf, -0.6, -0.6),  # a new pair: rho = 0, the innovation alone
    ],
)
def test_ar1_step_is_eq_7_4_5_of_tr_38_901_at_hand_values(z_prev, distance_m, w, expected):
    """``z = rho z_prev + sqrt(1 - rho^2) w``, ``rho = exp(-d / d_corr)``, d_corr = 37 m
    (TR 38.901 Eq. (7.4-5)), at distances where rho is 1/2, 1 and 0."""
    assert cs.ar1_step(z_prev, distance_m, 37.0, w) == pytest.approx(expected, rel=1e-12)


def test_pair_keys_of_one_ut_differ_by_satellite_whatever_its_key():
    """Every UT key is allowed, 0 and all ones included: the pair keys of one UT are
    distinct for its satellites (else two satellites would share their shadowing)."""
    sats = np.arange(64)[None, :]
    for key in (0, 2**64 - 1, 0x00000000FFFFFFFF):
        keys = cs.pair_keys(np.array([key], dtype=np.uint64), sats)
        assert len(np.unique(keys)) == 64


def test_empty_state_has_no_pair_and_the_epoch_before_the_first():
    """(n_ut, 0) arrays of the documented dtypes, epoch -1: any first epoch is allowed."""
    state = cs.empty_state(3)
    assert state.sat_id.shape == (3, 0) and state.sat_id.dtype == np.int64
    for name in ("z_los", "z_sf_los", "z_sf_nlos", "elevation_rad", "ray_east_m", "ray_north_m"):
        value = getattr(state, name)
        assert isinstance(value, np.ndarray), name
        assert value.shape == (3, 0) and value.dtype == np.float64, name
    assert state.epoch == -1


@pytest.mark.parametrize(
    ("environment", "expected"),
    [  # (LoS, SF LoS, SF NLoS correlation distance [m], clutter height [m]): module docstring
        ("dense_urban", (50.0, 37.0, 50.0, 20.0)),
        ("urban", (50.0, 37.0, 50.0, 15.0)),
        ("suburban", (50.0, 37.0, 50.0, 8.0)),
        ("rural", (60.0, 37.0, 120.0, 3.5)),  # TR 38.901 Table 7.6.3.1-2 RMa; 38.811 6.7.2
    ],
)
def test_environment_model_defaults_are_the_trs_correlation_distances(environment, expected):
    m = cs.environment_model(environment, 20e9)
    got = (m.los_corr_distance_m, m.sf_corr_distance_los_m, m.sf_corr_distance_nlos_m,
           m.clutter_height_m)  # fmt: skip
    assert got == expected
    assert (m.band, m.scintillation, m.geomagnetic_latitude_deg) == ("ka", False, None)


def test_environment_model_takes_every_option_given():
    """Values below 1 m are allowed (> 0 only); an explicit band wins over the rule; the
    latitude is kept (S-band scintillation needs it)."""
    options = cs.ChannelOptions(band="ka", scintillation=True, geomagnetic_latitude_deg=30.0,
                                los_corr_distance_m=0.5, sf_corr_distance_los_m=0.25,
                                sf_corr_distance_nlos_m=0.75, clutter_height_m=7.0)  # fmt: skip
    m = cs.environment_model("urban", 2e9, options)
    assert (m.los_corr_distance_m, m.sf_corr_distance_los_m, m.sf_corr_distance_nlos_m) == (
        0.5, 0.25, 0.75)  # fmt: skip
    assert (m.clutter_height_m, m.band, m.freq_hz) == (7.0, "ka", 2e9)
    assert (m.scintillation, m.geomagnetic_latitude_deg) == (True, 30.0)


@pytest.mark.parametrize(
    ("option", "message"),
    [
        ({"sf_corr_distance_los_m": -1.0}, r"^sf_corr_distance_los_m = -1.0 is not allowed"),
        ({"sf_corr_distance_nlos_m": 0.0}, r"^sf_corr_distance_nlos_m = 0.0 is not allowed"),
        ({"clutter_height_m": -2.0}, r"^clutter_height_m = -2.0 is not allowed; use a value >= 0"),
    ],
)
def test_environment_model_names_the_bad_option(option, message):
    with pytest.raises(cs.ConfigError, match=message):
        cs.environment_model("urban", 11.45e9, cs.ChannelOptions(**option))


def test_s_band_scintillation_uses_the_models_latitude():
    """Below 6 GHz the margin is ionospheric and needs the latitude the model was given:
    10 deg (within 20 of the geomagnetic equator) at 2 GHz, 1.1 dB (2 / 4)^-1.5 / sqrt(2)
    = 2.2 dB (clause 6.6.6.1.4)."""
    options = cs.ChannelOptions(scintillation=True, geomagnetic_latitude_deg=10.0)
    model = cs.environment_model("suburban", 2e9, options)
    sat_id, el, az = fixed_geometry(4, 2, 30.0)
    (state,) = run(model, lrng.ut_keys(1, 4), sat_id, el, az, np.zeros(4), [0])
    t = cs.link_terms(state, model)
    np.testing.assert_allclose(t.scintillation_db, 2.2, rtol=1e-12)
    np.testing.assert_allclose(t.extra_loss_db, t.shadow_db + t.clutter_db + t.scintillation_db)


def _one_pair_state(z_los, elevation_deg):
    one = np.array([[z_los]])
    return cs.ChannelState(np.array([[4]]), one, np.array([[1.0]]), np.array([[-1.0]]),
                           np.radians(np.array([[elevation_deg]])), np.zeros((1, 1)),
                           np.zeros((1, 1)), 0)  # fmt: skip


def test_los_is_strictly_below_the_table_probability():
    """``Phi(z_los) < P_LoS``: at dense urban zenith (98.1 %, Table 6.6.1-1; the 90-degree
    row, which no rounding of the angle leaves) the threshold itself is NLoS and the next
    float below it LoS."""
    from scipy.special import ndtri

    model = cs.environment_model("dense_urban", 20e9)
    threshold = ndtri(98.1 / 100.0)
    at = cs.pair_terms(_one_pair_state(threshold, 90.0), model, np.array([0]))
    below = cs.pair_terms(_one_pair_state(np.nextafter(threshold, -np.inf), 90.0), model,
                          np.array([0]))  # fmt: skip
    assert not at.los[0] and below.los[0]


def test_open_pair_terms_are_boolean_los_whatever_z():
    model = cs.environment_model("open", 20e9)
    t = cs.pair_terms(_one_pair_state(50.0, 30.0), model, np.array([0]))
    assert t.los.dtype == bool and t.los[0]
    assert (t.shadow_db[0], t.clutter_db[0], t.extra_loss_db[0]) == (0.0, 0.0, 0.0)


def test_advance_to_no_candidate_and_back():
    """A UT may lose every candidate (all slots -1) and later see a satellite again, which
    then starts afresh; the state keeps the documented dtypes from int32 ids and float32
    angles (its elevations the float64 of the given ones)."""
    model = cs.environment_model("urban", 20e9)
    keys = lrng.ut_keys(2, 2)
    el = np.full((2, 2), 0.5, dtype=np.float32)
    ids = np.array([[3, 9], [3, -1]], dtype=np.int32)
    s0 = cs.advance(cs.empty_state(2), model, keys, ids, el, el, np.zeros(2), 0)
    assert s0.sat_id.dtype == np.int64 and s0.elevation_rad.dtype == np.float64
    assert np.all(s0.elevation_rad == np.float64(np.float32(0.5)))
    s1 = cs.advance(s0, model, keys, np.full((2, 2), -1), el, el, np.zeros(2), 1)
    assert np.all(s1.sat_id == -1) and np.all(s1.z_los == 0.0) and np.all(s1.ray_east_m == 0.0)


@pytest.mark.parametrize(
    ("el_deg", "az_deg", "expected"),
    [
        (0.0, 90.0, (1.0, 0.0, 0.0)),  # horizon, east
        (0.0, 180.0, (0.0, -1.0, 0.0)),  # horizon, south
        (90.0, 37.0, (0.0, 0.0, 1.0)),  # zenith, any azimuth
        (30.0, 0.0, (0.0, np.sqrt(3.0) / 2.0, 0.5)),  # north, sin 30 = 1/2 up
        (60.0, 270.0, (-0.5, 0.0, np.sqrt(3.0) / 2.0)),  # west, cos 60 = 1/2 horizontal
    ],
)
def test_direction_enu_at_known_angles(el_deg, az_deg, expected):
    got = cs.direction_enu(np.radians(el_deg), np.radians(az_deg))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)


def test_direction_enu_is_a_unit_vector_in_double_precision_from_float32_angles():
    el = np.array([0.1, 0.7, 1.3], dtype=np.float32)
    az = np.array([0.3, 2.9, 5.1], dtype=np.float32)
    e, n, u = cs.direction_enu(el, az)
    assert e.dtype == n.dtype == u.dtype == np.float64
    np.testing.assert_allclose(e * e + n * n + u * u, 1.0, rtol=0, atol=4e-16)


def test_innovations_are_sqrt2_times_the_complex_normals_at_counters_2k_and_2k_plus_1():
    """Module docstring: epoch k draws at counters 2k and 2k + 1 (no counter shared between
    epochs), real and imaginary parts scaled to unit variance."""
    keys = lrng.ut_keys(9, 5)
    w = cs.innovations(keys, 3)
    g6, g7 = lrng.complex_normal(keys, 6), lrng.complex_normal(keys, 7)
    np.testing.assert_allclose(w, np.sqrt(2.0) * np.stack([g6.real, g6.imag, g7.real]),
                               rtol=1e-14)  # fmt: skip


def test_pair_keys_view_signed_ids_as_their_uint64_bits():
    """pair_keys of int ids is pair_key of the same 64 bits (-1: all ones): the compiled
    tracker, which hands pair_key uint64 ids, keys the same streams."""
    keys = lrng.ut_keys(1, 2)
    ids = np.array([[5, -1], [123456789, 0]])
    as_uint = np.array([[5, 2**64 - 1], [123456789, 0]], dtype=np.uint64)
    np.testing.assert_array_equal(cs.pair_keys(keys, ids), cs.pair_key(keys[:, None], as_uint))
    np.testing.assert_array_equal(cs.pair_keys(list(map(int, keys)), ids.astype(np.int32)),
                                  cs.pair_keys(keys, ids))  # fmt: skip
