"""The geometry and state a trigger run hands its policies, checked through the decisions.

Each scenario places the satellites by hand (an elevation, a nadir point at a chosen Earth
central angle, a beam's ground centre by the law of sines) so that the correct inputs
cause a handover at one known epoch; wrong elevations, nadir points, reference locations
or cell offsets move or prevent it. The runs are driven as the simulator drives them
(:class:`~leolink.sim.handover.trigger_run.TriggerRun`, sparse candidate tables, the
serving cell fed back every epoch).
"""

from types import SimpleNamespace

import numpy as np
import pytest

from leolink.sim.candidates.table import Candidates
from leolink.sim.handover.decisions import (
    ConditionalHandover,
    GatedTriggerPolicy,
    TriggerPolicy,
)
from leolink.sim.handover.measurements import L3Filter
from leolink.sim.handover.trigger_run import TriggerRun
from leolink.sim.handover.triggers import A2, A3, A4
from leolink.sim.handover.triggers_ntn import D1, D2, Elevation

R_M, H_M, MIN_SNR_DB, N_BEAM = 6.371e6, 600e3, -10.0, 2
NO_FILTER = L3Filter(0, 1.0)


def _engine(u_xy=None, cells_m=None):
    u_xy = np.zeros((N_BEAM, 2)) if u_xy is None else np.asarray(u_xy, float)
    return SimpleNamespace(n_beam=N_BEAM, codebook=SimpleNamespace(u_xy=u_xy),
                           steering=SimpleNamespace(cells_m=cells_m))  # fmt: skip


def _table(snr):
    """Candidates of ``snr (n_ut, n_cell)`` [dB], NaN = not in the table."""
    ut, cell = np.nonzero(np.isfinite(snr))
    return Candidates.from_entries(snr.shape[0], ut, cell, snr[ut, cell])


def _path(run, snr, ut_pos, sat_pos, sat_vel=None, ut_up=None, serving=None):
    """Serving cell of every UT at every epoch (1 s apart): the run's target fed back."""
    n_t, n_ut = snr.shape[:2]
    serving = np.full(n_ut, -1) if serving is None else np.asarray(serving)
    path = []
    for k in range(n_t):
        table = _table(snr[k])
        vel = np.zeros_like(sat_pos[k]) if sat_vel is None else sat_vel[k]
        up = None if ut_up is None else ut_up
        serving = run.target(float(k), table, serving, ut_pos, sat_pos[k], vel, up)
        serving = np.where(np.isfinite(table.masked(MIN_SNR_DB).value_at(serving)), serving, -1)
        path.append(serving.copy())
    return np.array(path)


def _run(policy, engine=None):
    return TriggerRun(policy, NO_FILTER, engine or _engine(), MIN_SNR_DB, R_M, None, 1.0, 100.0)


def _ground(angle_rad, axis=1):
    """The point of the sphere at Earth central angle ``angle_rad`` from (R, 0, 0), in the
    x-y plane (``axis`` 1) or the x-z plane (2) [m]."""
    p = np.zeros(3)
    p[0], p[axis] = R_M * np.cos(angle_rad), R_M * np.sin(angle_rad)
    return p


def _chord_m(angle_rad):
    return 2.0 * R_M * np.sin(angle_rad / 2.0)


# -- elevation ------------------------------------------------------------------------------
EL0_DEG = [50.0, 40.0, 31.0, 29.0, 20.0]  # the serving satellite sets
EL1_DEG = [20.0, 30.0, 39.0, 41.0, 50.0]  # the candidate rises


def _elevation_scene(up):
    """UT at (R, 0, 0) with local up ``up`` (east (0, 1, 0) is orthogonal to it); satellite
    0 and 1 at the elevations above (range 1,000 km, azimuth east and west), satellite 2
    at 80 deg with every beam below the service threshold. SNR: satellite 0 best at first
    (beam 0), satellite 1's beam 1 above its beam 0."""
    ut = np.array([R_M, 0.0, 0.0])
    east = np.array([0.0, 1.0, 0.0])
    sats = []
    for k in range(5):
        row = []
        for el, side in ((EL0_DEG[k], 1.0), (EL1_DEG[k], -1.0), (80.0, 1.0)):
            e = np.radians(el)
            row.append(ut + 1e6 * (np.sin(e) * up + side * np.cos(e) * east))
        sats.append(row)
    snr = np.full((5, 1, 3 * N_BEAM), np.nan)
    snr[:, 0, :] = [10.0, 5.0, 3.0, 6.0, -15.0, -12.0]
    return ut[None], np.array(sats), snr


@pytest.mark.parametrize("tilt_deg", [0.0, 20.0])
def test_elevation_trigger_hands_over_at_the_epoch_the_hand_elevations_cross(tilt_deg):
    """Elevation(serving below 30 deg, candidate above 40 deg), TTT 0, satellite level.
    The hand elevations cross both thresholds first at t = 3 s (29 and 41 deg): the UT
    goes to satellite 1's best beam (cell 3). Satellite 2, at 80 deg, never serves: no
    beam of it is detected. With a local up tilted 20 deg from the radial (``ut_up``, as
    on WGS 84), elevations from the radial would be asin(sin(el) cos 20 deg): 38.1 deg
    for the candidate at t = 3 s, no handover before t = 4 s."""
    t = np.radians(tilt_deg)
    up = np.array([np.cos(t), 0.0, np.sin(t)])
    ut, sats, snr = _elevation_scene(up)
    policy = TriggerPolicy(Elevation(np.radians(30.0), np.radians(40.0)))
    ut_up = None if tilt_deg == 0.0 else up[None]
    path = _path(_run(policy), snr, ut, sats, ut_up=ut_up)[:, 0]
    assert list(path) == [0, 0, 0, 3, 3]


def test_elevation_trigger_sees_each_ut_from_its_own_place():
    """Two UTs: UT 0 at (R, 0, 0) with the scene above, UT 1 at (0, R, 0) with the same
    elevations about its own up (the scene turned 90 deg about z, satellites renumbered
    3, 4, 5, cells 6 to 11). Each hands over at t = 3 s to its own rising satellite."""
    ut0, sats0, snr0 = _elevation_scene(np.array([1.0, 0.0, 0.0]))
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    sats = np.concatenate([sats0, sats0 @ turn.T], axis=1)
    snr = np.full((5, 2, 6 * N_BEAM), np.nan)
    snr[:, 0, :6], snr[:, 1, 6:] = snr0[:, 0], snr0[:, 0]
    ut = np.vstack([ut0, ut0 @ turn.T])
    policy = TriggerPolicy(Elevation(np.radians(30.0), np.radians(40.0)))
    path = _path(_run(policy), snr, ut, sats)
    assert list(path[:, 0]) == [0, 0, 0, 3, 3]
    assert list(path[:, 1]) == [6, 6, 6, 9, 9]


def test_elevation_trigger_on_cells_chooses_the_same_satellite():
    """The same trigger deciding cells: both beams of a satellite share its elevation
    (a tie: any beam of satellite 1), and the handover is at t = 3 s as on satellites."""
    ut, sats, snr = _elevation_scene(np.array([1.0, 0.0, 0.0]))
    policy = TriggerPolicy(Elevation(np.radians(30.0), np.radians(40.0)), level="cell")
    path = _path(_run(policy), snr, ut, sats)[:, 0]
    assert list(path[:3]) == [0, 0, 0]
    assert list(path[3:] // N_BEAM) == [1, 1]


# -- D2: the satellites' nadir points ---------------------------------------------------------
def test_d2_hands_over_when_the_nadir_chords_cross_their_thresholds():
    """UT 0 at (R, 0, 0). Satellite 1 (serving: best SNR) has its nadir at central angles
    0.05, 0.10, 0.15, 0.20 rad (+y side), satellite 0 at 0.25, 0.20, 0.15, 0.10 rad (-y):
    chords 318, 637, 955, 1273 km and 1590, 1273, 955, 637 km. D2(1,000 km, 1,000 km)
    enters first at t = 3 s (1273 > 1000, 637 < 1000): satellite 0's best beam, cell 1.
    Satellite 2, straight above the UT, has no detected beam: never a target. UT 1 sees
    satellite 1 alone and stays."""
    a1, a0 = [0.05, 0.10, 0.15, 0.20], [0.25, 0.20, 0.15, 0.10]
    scale = (R_M + H_M) / R_M
    sats = np.array([[_ground(-a0[k]) * scale, _ground(a1[k]) * scale, _ground(0.0) * scale]
                     for k in range(4)])  # fmt: skip
    ut = np.array([_ground(0.0), _ground(0.3, axis=2)])
    snr = np.full((4, 2, 3 * N_BEAM), np.nan)
    snr[:, 0, :] = [2.0, 4.0, 9.0, 6.0, -20.0, -11.0]
    snr[:, 1, 2:4] = [5.0, 7.0]
    assert _chord_m(0.20) > 1e6 > _chord_m(0.15)
    # D1 on beams, deciding satellites, reads each satellite's nadir too (one reference
    # per satellite, leolink's decision): the same epoch.
    for level, trigger in (("satellite", D2), ("cell", D2), ("satellite", D1)):
        policy = TriggerPolicy(trigger(1e6, 1e6), level=level)
        path = _path(_run(policy), snr, ut, sats)
        # on cells both beams of satellite 0 share its nadir: either beam
        assert list(path[:, 0] // N_BEAM) == [1, 1, 1, 0], level
        assert list(path[:, 0]) == [2, 2, 2, 1] or level == "cell"
        assert list(path[:, 1]) == [3, 3, 3, 3], level


def test_d2_with_no_satellite_in_any_table_keeps_every_ut_unserved():
    """An epoch whose tables are empty (no satellite on any UT's axis) leaves every UT
    without a cell; the next epoch's first assignment is the best cell."""
    sats = np.array([[_ground(0.0) * 1.1, _ground(0.1) * 1.1]] * 2)
    snr = np.full((2, 1, 2 * N_BEAM), np.nan)
    snr[1, 0, :] = [1.0, 3.0, 2.0, 0.0]
    path = _path(_run(TriggerPolicy(D2(1e6, 1e6))), snr, _ground(0.0)[None], sats)
    assert list(path[:, 0]) == [-1, 1]


# -- D1: the beams' ground centres, Earth-fixed cells, configured points ----------------------
def test_d1_hands_over_between_the_beams_of_one_satellite_at_their_ground_centres():
    """One satellite at (R + h, 0, 0) flying +y (body x = +y); beam 1 at u = (0.3, 0)
    meets the ground at Earth central angle gamma = asin((R + h) / R sin(theta)) - theta,
    theta = asin(0.3) (law of sines in the triangle centre, satellite, ground point).
    The UT stands there: D1(threshold1 = threshold2 = half the chord to the nadir) hands
    it from beam 0 (the nadir, best SNR) to beam 1 at the first evaluated epoch."""
    theta = np.arcsin(0.3)
    gamma = np.arcsin((R_M + H_M) / R_M * np.sin(theta)) - theta
    ut = _ground(gamma)[None]
    sats = np.array([[[R_M + H_M, 0.0, 0.0]]] * 3)
    vel = np.array([[[0.0, 7.5e3, 0.0]]] * 3)
    half = 0.5 * _chord_m(gamma)
    snr = np.full((3, 1, N_BEAM), np.nan)
    snr[:, 0, :] = [8.0, 5.0]
    run = _run(TriggerPolicy(D1(half, half)), _engine(u_xy=[[0.0, 0.0], [0.3, 0.0]]))
    path = _path(run, snr, ut, sats, sat_vel=vel)[:, 0]
    assert list(path) == [0, 1, 1]
    # the UT halfway between the centres: both conditions fail, no handover
    run = _run(TriggerPolicy(D1(half, half)), _engine(u_xy=[[0.0, 0.0], [0.3, 0.0]]))
    path = _path(run, snr, _ground(gamma / 2)[None], sats, sat_vel=vel)[:, 0]
    assert list(path) == [0, 0, 0]


def test_d1_beam_centres_on_the_runs_own_sphere_for_every_ut():
    """The same geometry on a sphere of radius 6,400 km (the run's radius, not a default
    one), with a second UT at the nadir, which stays on beam 0."""
    r_m = 6.4e6
    theta = np.arcsin(0.3)
    gamma = np.arcsin((r_m + H_M) / r_m * np.sin(theta)) - theta
    ut = np.array([[r_m * np.cos(gamma), r_m * np.sin(gamma), 0.0], [r_m, 0.0, 0.0]])
    sats = np.array([[[r_m + H_M, 0.0, 0.0]]] * 3)
    vel = np.array([[[0.0, 7.5e3, 0.0]]] * 3)
    half = r_m * np.sin(gamma / 2.0)  # half the chord to the nadir
    snr = np.full((3, 2, N_BEAM), np.nan)
    snr[:, :, :] = [8.0, 5.0]
    engine = _engine(u_xy=[[0.0, 0.0], [0.3, 0.0]])
    # threshold2 5 km: on a 6,371 km sphere the ray meets the ground ~30 km off the UT
    run = TriggerRun(TriggerPolicy(D1(half, 5e3)), NO_FILTER, engine, MIN_SNR_DB, r_m, None,
                     1.0, 100.0)  # fmt: skip
    path = _path(run, snr, ut, sats, sat_vel=vel)
    assert list(path[:, 0]) == [0, 1, 1] and list(path[:, 1]) == [0, 0, 0]


@pytest.mark.parametrize("rows,sat", [(1, 1), (2, 0)])
def test_d1_on_earth_fixed_cells_reads_each_satellites_cell_of_each_beam(rows, sat):
    """D1 on the Earth-fixed cells (``reference = "cell"``): beam 0's cell 0.2 rad from
    the UT (chord 1,273 km), beam 1's cell at the UT; D1(1,000 km, 500 km). Satellite
    ``sat`` alone, serving on beam 0 (best SNR): the UT goes to beam 1. One row of cells
    is every satellite's; with a row per satellite, the other satellite's cells are the
    reverse (they would keep the UT on beam 0)."""
    near, far = _ground(0.0), _ground(0.2)
    cells = np.array([[far, near], [near, far]])[:rows]
    sats = np.array([[_ground(0.1) * 1.1, _ground(0.1) * 1.1]] * 3)
    snr = np.full((3, 1, 2 * N_BEAM), np.nan)
    snr[:, 0, sat * N_BEAM : (sat + 1) * N_BEAM] = [8.0, 5.0]
    run = _run(TriggerPolicy(D1(1e6, 5e5, reference="cell")), _engine(cells_m=cells))
    path = _path(run, snr, _ground(0.0)[None], sats)[:, 0]
    assert list(path) == [sat * N_BEAM, sat * N_BEAM + 1, sat * N_BEAM + 1]


def test_d1_on_points_per_satellite_ignores_the_points_of_single_beams():
    """D1 on configured points, deciding satellites: satellite 0's point 0.2 rad from the
    UT (1,273 km), satellite 1's 0.05 rad (318 km); satellite 2 has a point for its beam 0
    only (at the UT), which a satellite-level run has no use for (one reference per
    satellite: its entries without a beam). D1(1,000 km, 500 km): from satellite 0 to
    satellite 1's best beam (cell 3), never to satellite 2."""
    policy = TriggerPolicy(D1(1e6, 5e5, reference="points"), level="satellite")
    run = _run(policy)
    run.reference_points = ((0, None, _ground(0.2)), (1, None, _ground(0.05)),
                            (2, 0, _ground(0.0)))  # fmt: skip
    sats = np.array([[_ground(0.1) * 1.1] * 3] * 3)
    snr = np.full((3, 1, 3 * N_BEAM), np.nan)
    snr[:, 0, :] = [9.0, 4.0, 3.0, 5.0, 7.0, 6.0]
    path = _path(run, snr, _ground(0.0)[None], sats)[:, 0]
    assert list(path) == [0, 3, 3]


# -- cell offsets (Ocn) -------------------------------------------------------------------------
def test_cell_offsets_by_satellite_and_by_beam_with_the_later_entry_winning():
    """A3(0 dB), no filter, serving cell 0 (sat 0 beam 0, 10 dB, Ocp -2 dB: 8 dB). Offsets:
    satellite 1 all beams +3 dB, then its beam 1 -5 dB (the later entry wins), cell 0
    -2 dB. Mn + Ocn: cell 1 8.5 (no offset), cell 2 6 + 3 = 9, cell 3 12 - 5 = 7. Cells 1
    and 2 are above 8: the UT goes to the higher, cell 2 (9 dB), and stays (cell 1's 8.5
    is below cell 2's 9)."""
    run = _run(TriggerPolicy(A3(0.0, 0.0, 0.0)))
    run.cell_offsets = ((1, None, 3.0), (1, 1, -5.0), (0, 0, -2.0))
    snr = np.full((3, 1, 2 * N_BEAM), np.nan)
    snr[:, 0, :] = [10.0, 8.5, 6.0, 12.0]
    sats = np.zeros((3, 2, 3))
    path = _path(run, snr, _ground(0.0)[None], sats, serving=[0])[:, 0]
    assert path[-1] == 2 and set(path) <= {0, 2}


# -- state carried across a satellite's absence ---------------------------------------------
# (the execution conditions; the elevation one holds for both satellites, overhead, and
# makes the cell-level policy keep its state per cell of a satellite axis)
GAP_UNITS = {
    "satellite": ("satellite", False),
    "cell": ("cell", False),
    "cell-of-satellite-axis": ("cell", True),
}


@pytest.mark.parametrize("unit", sorted(GAP_UNITS))
@pytest.mark.parametrize("serving_sat", [0, 1])
def test_a_triggered_but_unprepared_satellite_keeps_its_state_through_a_gap(serving_sat, unit):
    """CHO on satellites: prepare A3(-3 dB, TTT 2 s), preparation delay 2 s, execute
    A3(+2 dB, TTT 0). Serving satellite 0 at 5 dB; satellite 1 at 9 dB from t = 1 s, absent
    from the table at t = 4 s only. Its prepare condition enters at t = 1 s and triggers at
    t = 3 s; the gap starts the leaving run (2 s to go), which lapses at t = 5 s, when
    the satellite is back and, triggered for 2 s, becomes prepared and executes at once.
    A satellite forgotten with its table at t = 4 s would restart at t = 5 s: triggered at
    7 s, prepared and executed at t = 9 s. The same with the roles of the satellites
    swapped (satellite 0 the candidate). The same by cells (the candidate's best beam,
    cell ``c``): on an axis of cells (one a slot), and, with an elevation condition added
    to the execution (both satellites overhead: it holds), on an axis of satellites with
    the state per cell."""
    level, gated = GAP_UNITS[unit]
    execute = [A3(2.0, 0.0, 0.0)] + ([Elevation(np.pi / 2, 0.0)] if gated else [])
    policy = ConditionalHandover(A3(-3.0, 0.0, 2.0), execute, 8, 2.0, level=level)
    s, c = 2 * serving_sat, 2 * (1 - serving_sat)  # the cells of the two satellites
    snr = np.full((10, 1, 2 * N_BEAM), np.nan)
    snr[:, 0, s : s + 2] = [5.0, 1.0]
    snr[1:, 0, c : c + 2] = [9.0, 8.0]
    snr[4, 0, c : c + 2] = np.nan
    sats = np.zeros((10, 2, 3))
    sats[:, :, 0], sats[:, :, 1] = R_M + H_M, [1e5, -1e5]  # above (R, 0, 0), 100 km apart
    path = _path(_run(policy), snr, _ground(0.0)[None], sats)[:, 0]
    assert list(path) == [s] * 5 + [c] * 5


@pytest.mark.parametrize("serving_sat", [0, 1])
def test_a_satellite_triggered_before_a_two_epoch_gap_is_prepared_in_it(serving_sat):
    """CHO on satellites: prepare A3(-3 dB, TTT 3 s), preparation delay 2 s, execute
    A3(+2 dB). The candidate satellite (9 dB against 5 dB) from t = 1 s, absent at t = 5
    and 6 s: triggered at t = 4 s, its leaving run starts at t = 5 s (3 s to go, it lapses
    at t = 7 s, when the satellite is back), prepared at t = 6 s, executed at t = 7 s.
    In the second epoch of the gap its filter has restarted: only the trigger's state
    keeps the satellite. Forgotten there, it would trigger again at t = 10 s and be
    prepared after the horizon (no handover)."""
    policy = ConditionalHandover(A3(-3.0, 0.0, 3.0), [A3(2.0, 0.0, 0.0)], 8, 2.0,
                                 level="satellite")  # fmt: skip
    s, c = 2 * serving_sat, 2 * (1 - serving_sat)
    snr = np.full((12, 1, 2 * N_BEAM), np.nan)
    snr[:, 0, s : s + 2] = [5.0, 1.0]
    snr[1:, 0, c : c + 2] = [9.0, 8.0]
    snr[5:7, 0, c : c + 2] = np.nan
    path = _path(_run(policy), snr, _ground(0.0)[None], np.zeros((12, 2, 3)))[:, 0]
    assert list(path) == [s] * 7 + [c] * 5


def test_the_filter_of_a_lone_satellites_beams_runs_on_across_epochs():
    """One satellite, A3(+2 dB) between its beams, fc8 with a 1 s reference period
    (a = 1/4). Beam 0 serves at 5 dB; beam 1 is at 0 dB at t = 0, 10 dB after: its
    filtered value 0, 2.5, 4.375, 5.78, 6.84, 7.63 dB exceeds 5 + 2 first at t = 5 s.
    (A filter restarted every epoch would hand over at t = 1 s.)"""
    snr = np.full((7, 1, N_BEAM), np.nan)
    snr[:, 0, 0] = 5.0
    snr[:, 0, 1] = [0.0] + [10.0] * 6
    run = TriggerRun(TriggerPolicy(A3(2.0, 0.0, 0.0)), L3Filter(8, 1.0), _engine(), MIN_SNR_DB,
                     R_M, None, 1.0, 100.0)  # fmt: skip
    path = _path(run, snr, _ground(0.0)[None], np.zeros((7, 1, 3)))[:, 0]
    assert list(path) == [0] * 5 + [1] * 2


def test_the_a2_gate_of_a2a4_holds_its_time_to_trigger_across_epochs():
    """A4(6 dB) measured while A2(3 dB, TTT 2 s) holds. The serving cell is at 5 dB, then
    2 dB from t = 2 s: A2 enters at t = 2 s and triggers at t = 4 s, when the neighbour
    (satellite 1, 8 dB all along) is measured and hands the UT over at once."""
    policy = GatedTriggerPolicy(A2(3.0, 0.0, 2.0), A4(6.0, 0.0, 0.0))
    snr = np.full((6, 1, 2 * N_BEAM), np.nan)
    snr[:, 0, 0] = [5.0, 5.0, 2.0, 2.0, 2.0, 2.0]
    snr[:, 0, 2] = 8.0
    path = _path(_run(policy), snr, _ground(0.0)[None], np.zeros((6, 2, 3)), serving=[0])[:, 0]
    assert list(path) == [0] * 4 + [2] * 2


def test_a_cell_exactly_at_the_service_threshold_is_detected():
    """The service threshold is inclusive (a cell at or above it is detected): A4(-11 dB)
    hands the UT from cell 0 (5 dB, serving from before t = 0) to cell 2, at exactly the
    -10 dB threshold, at the first epoch; at -10.01 dB it is never measured."""
    for level, expected in ((MIN_SNR_DB, 2), (MIN_SNR_DB - 0.01, 0)):
        snr = np.full((1, 1, 2 * N_BEAM), np.nan)
        snr[:, 0, 0], snr[:, 0, 2] = 5.0, level
        run = _run(TriggerPolicy(A4(-11.0, 0.0, 0.0)))
        path = _path(run, snr, _ground(0.0)[None], np.zeros((1, 2, 3)), serving=[0])[:, 0]
        assert list(path) == [expected], level
