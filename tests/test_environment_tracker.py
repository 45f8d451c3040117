"""The channel of a run's paths (leolink.sim.environment) with hand-placed satellites and
hand-built epochs: which pairs hold a state, each path's terms and losses.

The per-pair physics (TR 38.811 tables) is leolink.link's, tested in test_environment.py;
here the satellites are placed at chosen elevations, so the scintillation of each path
must be the table's value at that elevation, and an :class:`EpochChannel` built by hand
must give each path's loss by satellite id, 0 (or NaN in the trace) without a state.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from leolink.errors import ConfigError
from leolink.link import environment as env
from leolink.sim.candidates.table import Candidates
from leolink.sim.environment import ChannelParams, ChannelTracker, EpochChannel, environment_models

R_M, FREQ_HZ = 6.371e6, 20e9
ENU = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # east, north, up at (R, 0, 0)


def _sat(el_deg, az_deg, range_m=1.2e6):
    """A satellite seen from (R, 0, 0) at elevation / azimuth (from north, towards east)."""
    el, az = np.radians(el_deg), np.radians(az_deg)
    east, north, up = ENU
    los = np.cos(el) * (np.sin(az) * east + np.cos(az) * north) + np.sin(el) * up
    return np.array([R_M, 0.0, 0.0]) + range_m * los


def _pops(*specs):
    return [SimpleNamespace(environment=e, channel=c) for e, c in specs]


def test_pairs_above_the_mask_carry_the_scintillation_of_their_elevation():
    """Two UTs at the same place, population 0 open without scintillation, population 1
    open with it. Satellites 4, 7, 9 at 60, 5 and 30 deg elevation; mask 10 deg: the
    pairs of satellites 4 and 9 hold a state, satellite 7's not. Population 1's paths
    lose TR 38.811's scintillation margin at 60 and 30 deg, population 0's nothing; both
    are line of sight (open)."""
    models = environment_models(
        _pops(("open", None), ("open", ChannelParams(scintillation=True))), FREQ_HZ
    )
    tracker = ChannelTracker(models, [1, 1], np.array([11, 12], np.uint64), np.radians(10.0))
    assert tracker.environment == ("open", "open")
    sat_pos = np.zeros((10, 3))
    sat_pos[[4, 7, 9]] = [_sat(60.0, 20.0), _sat(5.0, 90.0), _sat(30.0, 200.0)]
    ut = np.array([[R_M, 0.0, 0.0]] * 2)
    ch = tracker.step(0, ut, np.array([ENU, ENU]), sat_pos, np.array([4, 7, 9]))
    np.testing.assert_array_equal(ch.has, [[True, False, True]] * 2)
    np.testing.assert_array_equal(ch.sat_id, [[4, -1, 9]] * 2)
    expected = env.scintillation_db(np.array([60.0, 30.0]), FREQ_HZ, None)
    assert np.all(expected > 0.0)
    np.testing.assert_allclose(ch.scintillation_db, np.r_[0.0, 0.0, expected], rtol=1e-9)
    np.testing.assert_allclose(ch.loss_grid(), [[0, 0, 0], [expected[0], 0, expected[1]]],
                               rtol=1e-9)  # fmt: skip
    assert ch.los.all() and not ch.shadow_db.any() and not ch.clutter_db.any()
    with pytest.raises(ValueError, match="epoch 0 after epoch 0: the channel moves forward"):
        tracker.step(0, ut, np.array([ENU, ENU]), sat_pos, np.array([4, 7, 9]))
    ch = tracker.step(1, ut, np.array([ENU, ENU]), sat_pos, np.array([4, 9]))
    np.testing.assert_allclose(ch.loss_db(np.array([[9], [9]])), [[0.0], [expected[1]]], rtol=1e-9)


def test_open_populations_without_scintillation_have_no_channel_and_errors_name_the_population():
    assert environment_models(_pops(("open", None), ("open", ChannelParams())), FREQ_HZ) is None
    models = environment_models(_pops(("open", None), ("urban", None)), FREQ_HZ)
    assert [m.environment for m in models] == ["open", "urban"]
    bad = ChannelParams(scintillation=True)  # below 6 GHz it needs the geomagnetic latitude
    with pytest.raises(ConfigError, match=r"^population\.1\.channel: "):
        environment_models(_pops(("open", None), ("open", bad)), 2e9)


def _epoch(scintillation=True):
    """UT 0 has states with satellites 3 and 9, UT 1 with 7 and 9 (cone 3, 7, 9): pairs in
    row-major order (0, 3), (0, 9), (1, 7), (1, 9)."""
    has = np.array([[True, False, True], [False, True, True]])
    return EpochChannel(
        np.array([3, 7, 9]),
        has,
        np.array([True, False, True, False]),
        np.array([1.0, 2.0, 3.0, 4.0]),
        np.array([0.0, 20.0, 0.0, 40.0]),
        np.array([0.1, 0.2, 0.3, 0.4]) if scintillation else None,
    )


def test_an_epochs_losses_by_satellite_id_by_hand():
    ch = _epoch()
    np.testing.assert_allclose(ch.extra_loss_db, [1.1, 22.2, 3.3, 44.4])
    np.testing.assert_allclose(ch.loss_grid(), [[1.1, 0.0, 22.2], [0.0, 3.3, 44.4]])
    sat = np.array([[9, 3, 7, -1, 5, 0], [9, 3, 7, -1, 5, 0]])
    np.testing.assert_allclose(ch.loss_db(sat), [[22.2, 1.1, 0, 0, 0, 0], [44.4, 0, 3.3, 0, 0, 0]])
    cols = ch.columns(np.array([9, 3]))
    np.testing.assert_array_equal(cols["los"], [0.0, np.nan])
    np.testing.assert_array_equal(cols["shadow_db"], [2.0, np.nan])
    np.testing.assert_array_equal(cols["clutter_db"], [20.0, np.nan])
    np.testing.assert_array_equal(cols["scintillation_db"], [0.2, np.nan])
    np.testing.assert_allclose(cols["extra_loss_db"], [22.2, 0.0])
    np.testing.assert_array_equal(ch.sat_id, [[3, -1, 9], [-1, 7, 9]])
    dense = ch.terms
    np.testing.assert_array_equal(dense.los, [[True, False, False], [False, True, False]])
    np.testing.assert_allclose(dense.extra_loss_db, [[1.1, np.nan, 22.2], [np.nan, 3.3, 44.4]])


def test_an_epoch_without_scintillation_or_without_satellites():
    ch = _epoch(scintillation=False)
    np.testing.assert_allclose(ch.extra_loss_db, [1.0, 22.0, 3.0, 44.0])
    np.testing.assert_array_equal(ch.columns(np.array([3, 7]))["scintillation_db"], [0.0, 0.0])
    empty = EpochChannel(np.zeros(0, np.int64), np.zeros((2, 0), bool), *[np.zeros(0)] * 3)
    np.testing.assert_array_equal(empty.loss_db(np.array([[1, 2], [0, -1]])), np.zeros((2, 2)))
    np.testing.assert_array_equal(empty.columns(np.array([1, -1]))["los"], [np.nan, np.nan])


def test_applying_an_epoch_lowers_each_cell_by_its_paths_loss():
    """Cells of 2 beams: UT 0's cells 6, 7 (satellite 3) and 18 (satellite 9), UT 1's 14
    (satellite 7) and 4 (satellite 2, no state: unchanged)."""
    table = Candidates.from_entries(
        2, np.array([0, 0, 0, 1, 1]), np.array([6, 7, 18, 14, 4]), np.full(5, 10.0)
    )
    out = _epoch().apply(table, 2)
    got = {(u, c): out.snr_db[u, s] for u, s in zip(*np.nonzero(out.cell >= 0), strict=True)
           for c in [out.cell[u, s]]}  # fmt: skip
    assert got == pytest.approx(
        {(0, 6): 8.9, (0, 7): 8.9, (0, 18): -12.2, (1, 14): 6.7, (1, 4): 10.0}
    )


def test_satellites_past_the_cone_and_a_single_pair_have_no_state():
    """Satellite 12 (above every cone id) and satellite 0 (below) have no state; an epoch
    of one pair gives its loss to that pair only."""
    ch = _epoch()
    np.testing.assert_array_equal(
        ch.loss_db(np.array([[12, 0], [12, 9]])), [[0.0, 0.0], [0.0, 44.4]]
    )
    one = EpochChannel(np.array([5]), np.array([[False], [True]]), np.array([False]),
                       np.array([2.0]), np.array([30.0]))  # fmt: skip
    np.testing.assert_array_equal(one.loss_db(np.array([[5], [5]])), [[0.0], [32.0]])
    np.testing.assert_array_equal(one.columns(np.array([5, 5]))["clutter_db"], [np.nan, 30.0])


def test_applying_an_epoch_lowers_cell_0_of_satellite_0():
    """Cell 0 (satellite 0, beam 0) is a cell like any other."""
    ch = EpochChannel(np.array([0, 1]), np.array([[True, True]]), np.array([True, True]),
                      np.array([1.5, 2.5]), np.zeros(2))  # fmt: skip
    table = Candidates.from_entries(1, np.array([0, 0, 0]), np.array([0, 1, 2]), np.full(3, 10.0))
    out = ch.apply(table, 2)
    got = {int(c): float(v) for c, v in zip(out.cell[0], out.snr_db[0], strict=True) if c >= 0}
    assert got == pytest.approx({0: 8.5, 1: 8.5, 2: 7.5})


def test_a_static_ut_under_a_static_satellite_keeps_its_urban_state():
    """Nothing moves between epochs 0 and 1 (no displacement, the same elevation and
    azimuth): the TR 38.811 state of the path is the same, so its LoS state, shadowing
    and clutter are too (any displacement would decorrelate them)."""
    models = environment_models(_pops(("urban", None)), FREQ_HZ)
    tracker = ChannelTracker(models, [3], np.array([5, 6, 7], np.uint64), np.radians(10.0))
    sat_pos = np.array([_sat(40.0, 30.0), _sat(70.0, 250.0)])
    ut = np.array([[R_M, 0.0, 0.0]] * 3)
    enu = np.array([ENU] * 3)
    first = tracker.step(0, ut, enu, sat_pos, np.array([0, 1]))
    second = tracker.step(1, ut, enu, sat_pos, np.array([0, 1]))
    np.testing.assert_array_equal(second.los, first.los)
    np.testing.assert_array_equal(second.shadow_db, first.shadow_db)
    np.testing.assert_array_equal(second.clutter_db, first.clutter_db)
    assert np.any(first.shadow_db != 0.0)


def _edge_states(urban_model, use_loops, monkeypatch):
    """The states of two co-located static UTs after epochs 0 and 1, cone 0 ..
    4: satellites at 40 deg, exactly at the mask, 5e-10 rad below it, 5 deg and 60 deg; by
    the compiled loop or the numpy code."""
    import leolink.compiled
    from leolink.sim.environment import look_angles_rad

    if not use_loops:
        monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    assert leolink.compiled.use(10) == use_loops
    at_mask = _sat(10.0, 120.0)
    mask = float(look_angles_rad(at_mask - [R_M, 0.0, 0.0], ENU)[0])
    sliver = _sat(np.degrees(mask - 5e-10), 300.0)
    sat_pos = np.array([_sat(40.0, 30.0), at_mask, sliver, _sat(5.0, 90.0), _sat(60.0, 210.0)])
    el_sliver = float(look_angles_rad(sliver - [R_M, 0.0, 0.0], ENU)[0])
    # the sliver passes the sine guard (1e-9) and is decided on the angle itself
    assert mask - 1e-9 < el_sliver < mask and np.sin(el_sliver) > np.sin(mask) - 1e-9
    tracker = ChannelTracker(urban_model, [2], np.array([5, 6], np.uint64), mask)
    ut, enu, cone = np.array([[R_M, 0.0, 0.0]] * 2), np.array([ENU] * 2), np.arange(5)
    out = [tracker.step(0, ut, enu, sat_pos, cone)]
    out.append(tracker.states[0])
    out.append(tracker.step(1, ut, enu, sat_pos, cone))
    return out, tracker.states[0]


def test_compiled_loop_keeps_the_numpy_states_at_the_mask_and_in_empty_slots(monkeypatch):
    """A pair exactly at the mask holds a state (``el >= mask``), one 5e-10 rad below it
    and one far below do not, nor do they stop the scan of the later satellites; the
    compiled loop's state is the numpy code's slot by slot (-1 and zeros in empty slots,
    three pairs carried over gaps), its angles where it computes them."""
    models = environment_models(_pops(("urban", None)), FREQ_HZ)
    (first, state0, second), state1 = _edge_states(models, True, monkeypatch)
    for ch in (first, second):
        np.testing.assert_array_equal(ch.has, [[True, True, False, False, True]] * 2)
    monkeypatch.undo()
    (_, want0, _), want1 = _edge_states(models, False, monkeypatch)
    for got, want in ((state0, want0), (state1, want1)):
        np.testing.assert_array_equal(got.sat_id, [[0, 1, -1, -1, 4]] * 2)
        np.testing.assert_array_equal(want.sat_id, got.sat_id)
        for name in ("z_los", "z_sf_los", "z_sf_nlos"):
            np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=1e-12,
                                       atol=0.0, err_msg=name)  # fmt: skip
        g, w = got.elevation_rad, want.elevation_rad
        assert np.isfinite(g[:, [0, 1, 2, 4]]).all()
        np.testing.assert_allclose(g[:, [0, 1, 2, 4]], w[:, [0, 1, 2, 4]], rtol=1e-12)
        # the ray's offsets: of the link vector (compiled) and of the angles (numpy)
        for name in ("ray_east_m", "ray_north_m"):
            g, w = getattr(got, name), getattr(want, name)
            np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-12, err_msg=name)
            assert np.all(g[:, [2, 3]] == 0.0) and np.all(np.abs(g[:, [0, 1, 4]]) > 0.1)
    # nothing moved: the three carried pairs keep their state (a new pair would draw anew)
    for name in ("z_los", "z_sf_los", "z_sf_nlos"):
        np.testing.assert_array_equal(getattr(state1, name), getattr(state0, name))
    assert np.all(state0.z_los[:, [0, 1, 4]] != 0.0)


def _moving_states(models, use_loops, monkeypatch):
    """States after 4 epochs of 3 UTs per population moving 12 m east a second (positions
    near (R, 0, 0), ENU kept), under satellites at 30..75 deg that drift 0.3 deg a second."""
    import leolink.compiled

    monkeypatch.setattr(leolink.compiled, "use", lambda n: use_loops and n >= 1)
    n = 3 * len(models)
    tracker = ChannelTracker(models, [3] * len(models), np.arange(11, 11 + n, dtype=np.uint64),
                             np.radians(20.0))  # fmt: skip
    enu = np.array([ENU] * n)
    for k in range(4):
        sat = np.array([_sat(el + 0.3 * k, az) for el, az in ((30, 10), (50, 140), (75, 260))])
        ut = np.array([[R_M, 12.0 * k + 40.0 * i, 5.0 * i] for i in range(n)])
        tracker.step(k, ut, enu, sat, np.arange(3))
    monkeypatch.undo()
    return tracker.states


def test_compiled_loop_steps_each_field_with_its_own_correlation_distance(monkeypatch):
    """Moving UTs: the compiled loop's three driving variables are the numpy code's, with
    the defaults (urban: LoS state and NLoS shadowing share 50 m), with three distinct
    distances (rural's 60 / 37 / 120 m, and 20 / 45 / 300 m set) and with the shadowings'
    alike (20 / 45 / 45 m), so each field is stepped with its own distance (a swapped or
    shared one moves the values by ~1e-2, not 1e-12)."""
    params = ChannelParams(los_corr_distance_m=20.0, sf_corr_distance_los_m=45.0,
                           sf_corr_distance_nlos_m=300.0)  # fmt: skip
    # both shadowings' distances equal, the LoS state's not: the NLoS shadowing keeps its own
    shadowing_alike = ChannelParams(los_corr_distance_m=20.0, sf_corr_distance_los_m=45.0,
                                    sf_corr_distance_nlos_m=45.0)  # fmt: skip
    pops = _pops(("urban", None), ("rural", None), ("suburban", params),
                 ("dense_urban", shadowing_alike))  # fmt: skip
    models = environment_models(pops, FREQ_HZ)
    got = _moving_states(models, True, monkeypatch)
    want = _moving_states(models, False, monkeypatch)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g.sat_id, w.sat_id)
        assert (g.sat_id >= 0).all()
        for name in ("z_los", "z_sf_los", "z_sf_nlos"):
            np.testing.assert_allclose(getattr(g, name), getattr(w, name), rtol=0, atol=1e-9,
                                       err_msg=name)  # fmt: skip
