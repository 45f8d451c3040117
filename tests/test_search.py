"""Pruning before evaluating: the screening bound and the candidate tables it builds.

The claim of engine/screening.py and sim/search.py: a pruned pair can never hold a cell
within the policy's window of the UT's best cell, so the pruned tables are the tables of
the exhaustive evaluation, cell for cell and bit for bit. Checked here on the paper's
constellation (4,399 satellites, 1,000 UTs: hundreds of satellites in each epoch's cone)
against ``prune=False``, which evaluates every pair of the cone.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from leolink.antenna.array import ula_gain
from leolink.antenna.panel import oriented_panel_basis
from leolink.antenna.terminal import UPATerminal
from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.engine import LinkEngine, screening
from leolink.engine.screening import UNCERTAIN, VISIBLE, envelope, screen
from leolink.geometry import body_frame, enu_basis
from leolink.sim.motion import MotionBlocks
from leolink.sim.processes import candidate_satellites
from leolink.sim.search import CandidateSearch

CONSTELLATION = "configs/constellation.toml"
N_EPOCH = 2


@given(u=st.floats(-1.0, 1.0), n=st.integers(1, 64), k=st.integers(1, 6))
@example(u=0.2, n=12, k=5)  # a beam peak: the bound is n itself
@example(u=-0.95, n=12, k=1)  # nearest to the beam at 0.9 through its grating lobe (at -1.1)
@settings(max_examples=300, deadline=None)
def test_envelope_bounds_every_beam_kernel(u, n, k):
    beams = np.linspace(-0.8, 0.8, k) if k > 1 else np.array([0.9])
    exact = max(float(ula_gain(u - b, n)) for b in beams)  # sin^2(n x) / (n sin^2 x)
    assert float(envelope(np.array([u]), beams, n)[0]) >= exact * (1.0 - 1e-12)


@pytest.fixture(scope="module")
def block():
    scen = build_scenario(load_config(CONSTELLATION, ["run.duration_s=10"]))
    n_ut = sum(p.n_ut for _, p in scen.populations)
    mb = MotionBlocks(scen.ephemeris, scen.populations, scen.times_s[:N_EPOCH],
                      scen.ephemeris.n_sat, n_ut).block_of(0)  # fmt: skip
    none = np.zeros(0, np.int64)
    cones = [
        candidate_satellites(
            mb.sat_pos_m[i], mb.ut_pos_m[i], scen.min_elevation_rad, none, scen.radius_m
        )  # fmt: skip
        for i in range(N_EPOCH)
    ]
    return scen.engine, n_ut, mb, cones


def test_screening_bound_is_above_every_beam_and_visibility_agrees(block):
    eng, n_ut, mb, cones = block
    cone = cones[0]
    sat_pos, sat_vel = mb.sat_pos_m[0][cone], mb.sat_vel_m_s[0][cone]
    code, bound = screen(eng, mb.ut_pos_m[0], sat_pos, body_frame(sat_pos, sat_vel))
    ut, sat = np.nonzero(np.ones(code.shape, bool))
    links = eng.evaluate_pairs(mb.ut_pos_m[0], sat_pos, sat_vel, ut, sat)
    best = links.gain_tx_bm(eng.beam_ix, eng.beam_iy).max(axis=0) * links.path_snr_lin
    vis = links.visible.reshape(code.shape)
    assert (code[vis] > 0).all() and not (code[~vis] == VISIBLE).any()
    assert (code == UNCERTAIN).sum() <= 10  # the band is 1e-9 of sin(elevation) wide
    b, e = bound.reshape(-1)[links.visible], best[links.visible]
    assert (b >= e).all()
    # Tight where it matters: the best pair of a UT is bounded within 3 dB.
    assert np.median(b / e) < 30.0 and (b / e).min() < 1.0 + 1e-3


def _tables(eng, n_ut, mb, cones, window_db, prune):
    blk = CandidateSearch(eng, window_db, prune).block(
        0, n_ut, mb.ut_pos_m, None, mb.sat_pos_m, mb.sat_vel_m_s, cones
    )
    t = blk.table
    r, s = np.nonzero(t.cell >= 0)
    order = np.lexsort((t.cell[r, s], r))
    cells = np.stack([r[order], t.cell[r, s][order]])
    return cells, t.snr_db[r, s][order], blk


@pytest.mark.parametrize("window_db", [0.0, 3.0])
def test_pruned_tables_are_the_exhaustive_tables(block, window_db):
    eng, n_ut, mb, cones = block
    assert min(len(c) for c in cones) > 100  # the pruning has work to do
    cells, snr, blk = _tables(eng, n_ut, mb, cones, window_db, prune=True)
    cells_ref, snr_ref, ref = _tables(eng, n_ut, mb, cones, window_db, prune=False)
    assert np.array_equal(cells, cells_ref) and np.array_equal(snr, snr_ref)
    assert np.array_equal(blk.n_visible, ref.n_visible)
    assert np.array_equal(blk.best_cell, ref.best_cell)
    assert np.array_equal(blk.best_snr_db, ref.best_snr_db, equal_nan=True)
    # The pruning evaluated few of the cone's pairs: ~60 satellites above 40 deg per UT.
    assert blk.links.n_pair < 0.1 * ref.links.n_pair
    assert (blk.n_visible > 20).mean() > 0.9
    if window_db > 0.0:  # some UTs have neighbours within 3 dB
        assert (np.bincount(cells[0], minlength=2 * n_ut) > 1).mean() > 0.3


def test_a_bound_too_low_is_seen(block, monkeypatch):
    """The comparison above can fail: a bound 3 dB too low prunes pairs that matter."""
    eng, n_ut, mb, cones = block
    monkeypatch.setattr(screening, "BOUND_SLACK", -0.5)
    cells, _, _ = _tables(eng, n_ut, mb, cones, 3.0, prune=True)
    monkeypatch.undo()
    cells_ref, _, _ = _tables(eng, n_ut, mb, cones, 3.0, prune=False)
    assert cells.shape != cells_ref.shape or not np.array_equal(cells, cells_ref)


@pytest.fixture(scope="module")
def tilted(block):
    """The constellation's engine with a scan-loss UPA (its gain depends on the angle above
    the panel), and panels tilted up to 60 deg towards random azimuths."""
    eng, n_ut, mb, cones = block
    scan = LinkEngine(eng.codebook, UPATerminal(24, 24, 10.0, scan_loss=True), eng.params,
                      eng.atmosphere, eng.colors)  # fmt: skip
    rng = np.random.default_rng(5)
    tilt, az = rng.uniform(0.0, np.radians(60.0), n_ut), rng.uniform(0.0, 2 * np.pi, n_ut)
    normal = np.stack(
        [oriented_panel_basis(enu_basis(mb.ut_lat_rad[i], mb.ut_lon_rad[i]), tilt, az)[:, 2]
         for i in range(N_EPOCH)]
    )  # fmt: skip
    return scan, normal


def test_screening_bound_holds_for_tilted_panels(block, tilted):
    """The bound takes the gain at the angle above the panel plane: above every beam of the
    tilted panels, while the flat panels' bound falls below some of them."""
    _, n_ut, mb, cones = block
    scan, normal = tilted
    cone = cones[0]
    sat_pos, sat_vel = mb.sat_pos_m[0][cone], mb.sat_vel_m_s[0][cone]
    axes = body_frame(sat_pos, sat_vel)
    code, bound = screen(scan, mb.ut_pos_m[0], sat_pos, axes, ut_normal=normal[0])
    _, flat = screen(scan, mb.ut_pos_m[0], sat_pos, axes)
    ut, sat = np.nonzero(np.ones(code.shape, bool))
    links = scan.evaluate_pairs(mb.ut_pos_m[0], sat_pos, sat_vel, ut, sat, ut_normal=normal[0])
    best = links.gain_tx_bm(scan.beam_ix, scan.beam_iy).max(axis=0) * links.path_snr_lin
    vis = links.visible
    assert (bound.reshape(-1)[vis] >= best[vis]).all()
    assert (flat.reshape(-1)[vis] < best[vis]).sum() > 100


def test_pruned_tables_of_tilted_panels_are_the_exhaustive_tables(block, tilted):
    _, n_ut, mb, cones = block
    scan, normal = tilted
    out = []
    for prune in (True, False):
        blk = CandidateSearch(scan, 3.0, prune).block(
            0, n_ut, mb.ut_pos_m, None, mb.sat_pos_m, mb.sat_vel_m_s, cones, normal
        )
        t = blk.table
        r, s = np.nonzero(t.cell >= 0)
        order = np.lexsort((t.cell[r, s], r))
        out.append((r[order], t.cell[r, s][order], t.snr_db[r, s][order], blk.best_snr_db))
    (r, c, v, b), (r0, c0, v0, b0) = out
    assert np.array_equal(r, r0) and np.array_equal(c, c0) and np.array_equal(v, v0)
    assert np.array_equal(b, b0, equal_nan=True)
