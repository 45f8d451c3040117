"""Steering modes (antenna/steering.py, engine/steered.py): re-steered and quantized beams.

References used: the explicit steering-vector product (antenna/array.py ``explicit_gain``,
no Dirichlet closed form), ``geometry.direction_cosines`` for the cells' directions, and
the classical mean loss of b-bit phase quantization (uniform phase error of width
2 pi / 2^b: mean gain factor sinc^2, e.g. Mailloux, Phased Array Antenna Handbook, 2nd
ed., Sec. 7.2: 3 bits cost ~0.22 dB).
"""

from __future__ import annotations

import numpy as np
import pytest

import leolink
from leolink.antenna.array import explicit_gain, steering_vector, ula_gain
from leolink.antenna.steering import EarthFixed, quantized_gain_lin, steered_cosines
from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.errors import LeolinkError
from leolink.geometry import body_frame, direction_cosines

PAPER = "configs/paper.toml"
EARTH_FIXED = ["satellite_array.steering=earth_fixed"]
# Both sides are double-precision sums of <= 288 unit phasors: ~1e-13 relative apart.
CLOSED_FORM_REL = 1e-9


def _random_beams(rng, m, n_beam):
    u = rng.uniform(-0.6, 0.6, (m, 2))
    v = rng.uniform(-0.6, 0.6, (m, n_beam, 2))
    v[:, 0] = u + rng.normal(0.0, 0.01, (m, 2))  # near a peak, where the gain is large
    return u, v


def test_ideal_array_factor_is_the_dirichlet_closed_form():
    rng = np.random.default_rng(1)
    u, v = _random_beams(rng, 300, 4)
    direct = quantized_gain_lin(u, v, 12, 24, None)
    closed = ula_gain(u[None, :, 0] - v[..., 0].T, 12) * ula_gain(u[None, :, 1] - v[..., 1].T, 24)
    np.testing.assert_allclose(direct, closed, rtol=CLOSED_FORM_REL, atol=1e-9)


@pytest.mark.parametrize("bits", [1, 2, 3, 5])
def test_quantized_array_factor_is_the_steering_vector_product(bits):
    rng = np.random.default_rng(bits)
    u, v = _random_beams(rng, 20, 3)
    step = 2.0 * np.pi / 2**bits
    got = quantized_gain_lin(u, v, 6, 8, bits)
    for p in range(len(u)):
        # Weights: the ideal steering vector's phases rounded to the step (angle mod 2 pi
        # rounds as the raw phase does: 2 pi is a multiple of the step).
        w = steering_vector(v[p], 6, 8).T  # (48, n_beam)
        w = np.exp(1j * step * np.rint(np.angle(w) / step))
        np.testing.assert_allclose(got[:, p], explicit_gain(u[p], w, 6, 8), rtol=1e-9)


@pytest.mark.parametrize("bits", [2, 3, 4])
def test_quantization_costs_the_mean_sinc_squared_loss(bits):
    rng = np.random.default_rng(7)
    n_x, n_y, m = 12, 24, 400
    v = rng.uniform(-0.5, 0.5, (m, 1, 2))  # off-lattice directions: quasi-random errors
    peak = quantized_gain_lin(v[:, 0], v, n_x, n_y, bits)[0]
    c = np.sinc(1.0 / 2**bits)  # E[exp(i e)], e uniform in +-pi / 2^b
    expected = (n_x * n_y) * c**2 + (1.0 - c**2)
    # The mean of 400 directions: the errors are deterministic, not independent, so the
    # tolerance is 0.05 dB, below the 3-bit loss (0.22 dB) it must see.
    assert abs(10 * np.log10(peak.mean() / expected)) < 0.05
    assert peak.max() <= n_x * n_y * (1 + 1e-12)


@pytest.fixture(scope="module")
def pass_scenario():
    return build_scenario(load_config(PAPER, EARTH_FIXED))


def test_cells_are_the_footprint_at_the_reference_instant(pass_scenario):
    scen = pass_scenario
    steer, cb = scen.engine.steering, scen.engine.codebook
    assert isinstance(steer, EarthFixed)
    pos, vel, _ = scen.ephemeris(np.array([60.0]))  # the middle of the 120 s pass
    u = direction_cosines(pos[0, 0], vel[0, 0], steer.cells_m[0])
    np.testing.assert_allclose(u, cb.u_xy, atol=1e-9)
    radius = np.linalg.norm(steer.cells_m[0], axis=-1)
    np.testing.assert_allclose(radius, 6_371_000.0, rtol=1e-12)


def test_re_steered_gain_is_the_explicit_product_towards_the_cell(pass_scenario):
    scen = pass_scenario
    eng, cb, steer = scen.engine, scen.engine.codebook, scen.engine.steering
    rng = np.random.default_rng(3)
    pos, vel, _ = scen.ephemeris(np.array([10.0]))
    cells = steer.cells_m[0]
    ut = cells[rng.integers(0, len(cells), 50)] + rng.normal(0.0, 20e3, (50, 3))
    ut *= 6_371_000.0 / np.linalg.norm(ut, axis=-1, keepdims=True)
    snap = eng.evaluate(ut, pos[0], vel[0])
    v = direction_cosines(pos[0, 0], vel[0, 0], cells)  # (n_beam, 2), brute force
    w = np.concatenate(
        [steering_vector(v[b], cb.n_sub_x, cb.n_sub_y)[:, None] for b in range(cb.n_beam)], 1
    )
    u = direction_cosines(pos[0, 0], vel[0, 0], ut)
    ref = explicit_gain(u, w, cb.n_sub_x, cb.n_sub_y)  # (50, n_beam)
    np.testing.assert_allclose(snap.gain_tx_lin[:, 0, :], ref, rtol=CLOSED_FORM_REL)
    # Not the body-fixed beams: 50 s before overhead the cells are ~350 km behind them.
    body = explicit_gain(u, steering_vector(cb.u_xy, cb.n_sub_x, cb.n_sub_y).T, cb.n_sub_x,
                         cb.n_sub_y)  # fmt: skip
    assert np.abs(10 * np.log10(body.max(1) / ref.max(1))).max() > 1.0


def test_a_cell_outside_the_field_of_regard_has_its_beam_off():
    sat = np.array([[0.0, 0.0, 7_671_000.0]])
    axes = body_frame(sat, np.array([[7e3, 0.0, 0.0]]))
    r = 6_371_000.0
    angles = np.radians([0.0, 10.0, 20.0])  # Earth-central angles of three cells
    cells = r * np.stack([np.sin(angles), 0 * angles, np.cos(angles)], -1)[None]
    v, cos_nadir, sin_el = steered_cosines(cells, sat, axes)
    # Brute force: the nadir angle and elevation of each cell by the law of sines.
    rho = np.linalg.norm(cells[0] - sat[0], axis=-1)
    nadir = np.arcsin(r * np.sin(angles) / rho)
    np.testing.assert_allclose(np.arccos(np.clip(cos_nadir[0], -1, 1)), nadir, atol=1e-7)
    np.testing.assert_allclose(np.arcsin(sin_el[0]), np.pi / 2 - nadir - angles, atol=1e-9)
    np.testing.assert_allclose(v[0, :, 0], np.sin(nadir), atol=1e-12)
    # Off nadir 0, 38.4, 52.3 deg; elevations 90, 41.6, 17.7 deg.
    steer = EarthFixed(cells, np.radians(10.0), np.radians(60.0))
    _, on = steer.beam_cosines(sat, axes, np.array([0]))
    assert on.tolist() == [[True, True, True]]
    _, on = EarthFixed(cells, np.radians(20.0), np.radians(60.0)).beam_cosines(
        sat, axes, np.array([0])
    )
    assert on.tolist() == [[True, True, False]]
    _, on = EarthFixed(cells, np.radians(10.0), np.radians(35.0)).beam_cosines(
        sat, axes, np.array([0])
    )
    assert on.tolist() == [[True, False, False]]


def _ut0(cfg_overrides):
    res = leolink.run(load_config(PAPER, cfg_overrides))
    trace, events = res.trace, res.events
    return trace[trace.ut_id == 0], events[events.ut_id == 0]


def test_paper_pass_ut0_hands_over_four_times_body_fixed_and_never_earth_fixed():
    body, ev_body = _ut0([])
    earth, ev_earth = _ut0(EARTH_FIXED)
    assert (ev_body.kind == "beam_handover").sum() == 4  # the paper's ~30 s per beam
    assert len(ev_earth) == 0 and earth.beam_id.nunique() == 1
    # UT 0 is at the ROI centre, the boresight of its cell: the full subarray gain
    # 10 log10(12 x 24) = 24.59 dB all pass long; body-fixed beams straddle down to 23 dB.
    np.testing.assert_allclose(earth.gain_tx_db, 10 * np.log10(288), atol=1e-9)
    assert body.gain_tx_db.min() < 23.1
    assert (earth.snr_db.to_numpy() >= body.snr_db.to_numpy() - 1e-9).all()


def test_phase_bits_with_body_fixed_beams_lose_the_quantization_loss():
    ideal, _ = _ut0(["run.duration_s=5"])
    q, _ = _ut0(["run.duration_s=5", "satellite_array.phase_bits=3"])
    loss = ideal.gain_tx_db.to_numpy() - q.gain_tx_db.to_numpy()
    assert (loss > 0.0).all() and (loss < 1.0).all()


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("satellite_array.phase_bits=0", r"satellite_array.phase_bits.*0"),
        ("satellite_array.steering=sideways", r"satellite_array.steering.*sideways"),
        (
            "satellite_array.earth_fixed.cell_lat_deg=[42.0]",
            r"cell_lat_deg / cell_lon_deg = \[42.0\] / None.*15 beams",
        ),
    ],
)
def test_bad_steering_settings_are_named(override, message):
    with pytest.raises(LeolinkError, match=message):
        build_scenario(load_config(PAPER, [*EARTH_FIXED, override]))


def test_configured_cells_are_used_by_every_satellite():
    lat = [42.24 + 0.5 * k for k in range(15)]
    lon = [-8.72] * 15
    scen = build_scenario(
        load_config(
            PAPER,
            [
                *EARTH_FIXED,
                f"satellite_array.earth_fixed.cell_lat_deg={lat}",
                f"satellite_array.earth_fixed.cell_lon_deg={lon}",
            ],
        )  # fmt: skip
    )
    cells = scen.engine.steering.cells_m
    assert cells.shape == (1, 15, 3)
    lat_rad = np.arcsin(cells[0, :, 2] / np.linalg.norm(cells[0], axis=-1))
    np.testing.assert_allclose(np.degrees(lat_rad), lat, atol=1e-9)


@pytest.fixture(scope="module")
def constellation_block():
    """Two epochs of the paper's constellation with Earth-fixed beams (cells at t = 5 s)."""
    from leolink.sim.motion import MotionBlocks
    from leolink.sim.processes import candidate_satellites

    over = [
        *EARTH_FIXED,
        "run.duration_s=10",
        "population.0.count=150",
        "population.1.count=50",
        "population.2.count=50",
        "population.3.count=50",
    ]
    scen = build_scenario(load_config("configs/constellation.toml", over))
    n_ut = sum(p.n_ut for _, p in scen.populations)
    mb = MotionBlocks(scen.ephemeris, scen.populations, scen.times_s[:2], scen.ephemeris.n_sat,
                      n_ut).block_of(0)  # fmt: skip
    none = np.zeros(0, np.int64)
    cones = [
        candidate_satellites(
            mb.sat_pos_m[i], mb.ut_pos_m[i], scen.min_elevation_rad, none
        )  # fmt: skip
        for i in range(2)
    ]
    return scen.engine, n_ut, mb, cones


def test_screening_bound_holds_for_re_steered_beams(constellation_block):
    from leolink.engine.screening import screen

    eng, n_ut, mb, cones = constellation_block
    cone = cones[0]
    sat_pos, sat_vel = mb.sat_pos_m[0][cone], mb.sat_vel_m_s[0][cone]
    code, bound = screen(eng, mb.ut_pos_m[0], sat_pos, body_frame(sat_pos, sat_vel), sat_id=cone)
    ut, sat = np.nonzero(np.ones(code.shape, bool))
    links = eng.evaluate_pairs(mb.ut_pos_m[0], sat_pos, sat_vel, ut, sat, sat_id=cone)
    best = links.gain_tx_bm(eng.beam_ix, eng.beam_iy).max(axis=0) * links.path_snr_lin
    b, e = bound.reshape(-1)[links.visible], best[links.visible]
    assert (b >= e).all()
    assert (b / e).min() < 1.0 + 1e-3  # tight where a cell is on a UT


def test_pruned_tables_are_the_exhaustive_tables_with_re_steered_beams(constellation_block):
    from leolink.sim.candidates.search import CandidateSearch

    eng, n_ut, mb, cones = constellation_block
    out = []
    for prune in (True, False):
        blk = CandidateSearch(eng, 3.0, prune).block(
            0, mb.ut_pos_m, None, mb.sat_pos_m, mb.sat_vel_m_s, cones
        )
        t = blk.table
        r, s = np.nonzero(t.cell >= 0)
        order = np.lexsort((t.cell[r, s], r))
        out.append((r[order], t.cell[r, s][order], t.snr_db[r, s][order], blk.links.n_pair))
    (r1, c1, s1, n1), (r2, c2, s2, n2) = out
    assert np.array_equal(r1, r2) and np.array_equal(c1, c2) and np.array_equal(s1, s2)
    assert n1 < 0.2 * n2  # the pruning did prune


# -- the steering modes by hand ------------------------------------------------------------
R_EARTH_M, SAT_R_M = 6_371_000.0, 7_000_000.0
#: A satellite over the north pole, body frame by hand: x, y along the Earth's x, y and z
#: up (radial), as :func:`leolink.geometry.body_frame` gives for a velocity along x.
POLE_AXES = np.eye(3)[None]


def _meridian_cells(angles_deg):
    """Ground cells at Earth central angles ``angles_deg`` from the pole, in the x-z plane."""
    a = np.radians(angles_deg)
    return R_EARTH_M * np.stack([np.sin(a), 0 * a, np.cos(a)], -1)


@pytest.mark.parametrize("bits", [None, 1, 16])
def test_phase_bits_from_1_to_16_are_accepted(bits):
    from leolink.antenna.steering import BodyFixed

    assert BodyFixed(np.zeros((1, 2)), bits).phase_bits == bits
    assert EarthFixed(_meridian_cells([0.0])[None], 0.0, 1.0, bits).phase_bits == bits


@pytest.mark.parametrize("bits", [0, 17])
@pytest.mark.parametrize("mode", ["body_fixed", "earth_fixed"])
def test_phase_bits_outside_1_to_16_are_refused_by_the_modes_themselves(bits, mode):
    """The config's schema bounds them too; a mode built in code checks its own."""
    from leolink.antenna.steering import BodyFixed
    from leolink.errors import ConfigError

    said = (
        f"satellite_array.phase_bits = {bits} is not allowed; use 1 to 16 or leave it out "
        "(ideal phase shifters)"
    )
    with pytest.raises(ConfigError) as raised:
        if mode == "body_fixed":
            BodyFixed(np.zeros((1, 2)), bits)
        else:
            EarthFixed(_meridian_cells([0.0])[None], 0.0, 1.0, bits)
    assert str(raised.value) == said


def test_steered_cosines_are_the_x_and_y_cosines_of_each_cell():
    """Cells 0 and 30 deg from the pole, seen from 7,000 km: nadir (0, 0) and, by the law
    of sines, x = sin(nadir angle), y = 0; two components per beam."""
    sat = np.array([[0.0, 0.0, SAT_R_M]])
    cells = _meridian_cells([0.0, 30.0])[None]
    v, _, _ = steered_cosines(cells, sat, POLE_AXES)
    rho = np.hypot(R_EARTH_M * 0.5, SAT_R_M - R_EARTH_M * np.cos(np.radians(30.0)))
    assert v.shape == (1, 2, 2)
    np.testing.assert_allclose(v[0], [[0.0, 0.0], [R_EARTH_M * 0.5 / rho, 0.0]], atol=1e-15)


def test_a_cell_exactly_at_the_mask_or_the_field_of_regard_keeps_its_beam_on():
    """The nadir cell is seen at exactly 90 deg elevation and 0 deg off nadir (unit vectors
    along z, exact in floats): a 90 deg mask or a 0 deg field of regard keeps it on (the
    limits are inclusive), a 1 deg off-nadir cell is then off."""
    sat = np.array([[0.0, 0.0, SAT_R_M]])
    cells = _meridian_cells([0.0, 1.0])[None]
    _, on = EarthFixed(cells, np.pi / 2, np.pi / 2).beam_cosines(sat, POLE_AXES, np.array([0]))
    assert on.tolist() == [[True, False]]
    _, on = EarthFixed(cells, -np.pi / 2, 0.0).beam_cosines(sat, POLE_AXES, np.array([0]))
    assert on.tolist() == [[True, False]]


def test_cells_per_satellite_follow_the_satellite_id_and_one_row_serves_every_id():
    """Two satellites at the same place over the pole. Per-satellite cells: satellite 1's
    row (cells 80 deg away: below the horizon) is off, satellite 0's (the nadir) on,
    whichever row of the call holds which id. One row of cells: shared by ids 0 and 7."""
    sat, axes = np.array([[0.0, 0.0, SAT_R_M]] * 2), np.repeat(POLE_AXES, 2, 0)
    near, far = _meridian_cells([0.0, 0.5]), _meridian_cells([80.0, 80.5])
    steer = EarthFixed(np.stack([near, far]), 0.0, np.pi / 2)
    _, on = steer.beam_cosines(sat, axes, np.array([1, 0]))
    assert on.tolist() == [[False, False], [True, True]]
    v, on = EarthFixed(near[None], 0.0, np.pi / 2).beam_cosines(sat, axes, np.array([0, 7]))
    assert on.all()
    np.testing.assert_array_equal(v[0], v[1])


def test_the_array_factor_is_exact_beyond_two_chunks():
    """600 directions (more than twice the 256-pair chunk): every one is its Dirichlet
    closed form, none left unwritten."""
    from leolink.antenna.steering import _AF_CHUNK

    rng = np.random.default_rng(11)
    u, v = _random_beams(rng, 600, 2)
    assert len(u) > 2 * _AF_CHUNK
    direct = quantized_gain_lin(u, v, 4, 6, None)
    closed = ula_gain(u[None, :, 0] - v[..., 0].T, 4) * ula_gain(u[None, :, 1] - v[..., 1].T, 6)
    np.testing.assert_allclose(direct, closed, rtol=CLOSED_FORM_REL, atol=1e-9)


def test_earth_fixed_cells_are_the_footprint_at_the_configured_reference_instant():
    """``reference_time_s = 30``: the cells are where the codebook beams meet the ground
    at t = 30 s (not the run's middle, 60 s): the direction cosines of the cells from the
    satellite at 30 s are the codebook's."""
    scen = build_scenario(
        load_config(PAPER, [*EARTH_FIXED, "satellite_array.earth_fixed.reference_time_s=30"])
    )
    cells, cb = scen.engine.steering.cells_m, scen.engine.codebook
    pos, vel, _ = scen.ephemeris(np.array([30.0]))
    np.testing.assert_allclose(direction_cosines(pos[0, 0], vel[0, 0], cells[0]), cb.u_xy,
                               atol=1e-9)  # fmt: skip


def test_earth_fixed_beams_with_phase_bits_lose_gain_at_their_cells():
    """3-bit phases on re-steered beams: at its own cell a beam's gain is at most the ideal
    12 x 24 = 288, and on average the rounding's loss (~0.22 dB, Mailloux) below it (the
    centre beam, at direction (0, 0), has exact phases: no loss)."""
    scen = build_scenario(load_config(PAPER, [*EARTH_FIXED, "satellite_array.phase_bits=3"]))
    eng = scen.engine
    pos, vel, _ = scen.ephemeris(np.array([60.0]))
    cells = eng.steering.cells_m[0]
    gain = eng.evaluate(cells, pos[0], vel[0]).gain_tx_lin[:, 0, :]  # (n_cell, n_beam)
    own = gain[np.arange(len(cells)), np.arange(len(cells))]
    loss_db = 10 * np.log10(288 / own)
    assert (loss_db > -1e-9).all() and 0.1 < loss_db.mean() < 0.5
