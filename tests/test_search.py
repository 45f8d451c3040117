"""Pruning before evaluating: the screening bound and the candidate tables it builds.

The claim of engine/screening.py and sim/candidates/search.py: a pruned pair can never hold a cell
within the policy's window of the UT's best cell, so the pruned tables are the tables of
the exhaustive evaluation, cell for cell and bit for bit. Checked here on the paper's
constellation (4,399 satellites, 1,000 UTs: hundreds of satellites in each epoch's cone)
against ``prune=False``, which evaluates every pair of the cone.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from pydantic import Field

from leolink.antenna.array import ula_gain
from leolink.antenna.panel import oriented_panel_basis
from leolink.antenna.terminal import TERMINALS, UPATerminal
from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.engine import LinkEngine, screening
from leolink.engine.screening import UNCERTAIN, VISIBLE, envelope, screen
from leolink.errors import ConfigError
from leolink.geometry import body_frame, enu_basis
from leolink.registry import Params
from leolink.sim.candidates import search
from leolink.sim.candidates.search import CandidateSearch
from leolink.sim.motion import MotionBlocks
from leolink.sim.processes import candidate_satellites
from scopes import shared_run_scope

CONSTELLATION = "configs/constellation.toml"
N_EPOCH = 2


def _beams(k, lo, hi):
    """``k`` sorted beam cosines from ``lo`` to ``hi`` (one: ``hi``); asymmetric sets
    have a first beam nearest to some ``u`` through its grating lobe."""
    return np.sort(np.linspace(lo, hi, k)) if k > 1 else np.array([hi])


_LO, _HI = st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)


@given(u=st.floats(-1.0, 1.0), n=st.integers(1, 64), k=st.integers(1, 6), lo=_LO, hi=_HI)
@example(u=0.2, n=12, k=5, lo=-0.8, hi=0.8)  # a beam peak: the bound is n itself
@example(u=-0.95, n=12, k=1, lo=0.0, hi=0.9)  # nearest to 0.9 through its grating lobe
@example(u=0.95, n=12, k=2, lo=-0.9, hi=0.3)  # nearest to -0.9 through its grating lobe
@settings(max_examples=300, deadline=None)
def test_envelope_bounds_every_beam_kernel(u, n, k, lo, hi):
    beams = _beams(k, lo, hi)
    exact = max(float(ula_gain(u - b, n)) for b in beams)  # sin^2(n x) / (n sin^2 x)
    assert float(envelope(np.array([u]), beams, n)[0]) >= exact * (1.0 - 1e-12)


@given(u=st.floats(-1.0, 1.0), n=st.integers(1, 64), k=st.integers(1, 6), lo=_LO, hi=_HI)
@example(u=-0.95, n=12, k=1, lo=0.0, hi=0.9)  # nearest to 0.9 through its grating lobe
@example(u=0.95, n=12, k=2, lo=-0.9, hi=0.3)  # nearest to -0.9 through its grating lobe
@example(u=0.0, n=3, k=1, lo=0.0, hi=0.9)  # 0.9 away: the polynomial at its least accurate
@settings(max_examples=300, deadline=None)
def test_envelope_is_the_documented_minimum(u, n, k, lo, hi):
    """Not only above the kernels: ``min(n, 1 / (n sin^2(pi d / 2)))`` with ``d`` the
    distance to the nearest beam modulo 2 (brute force over the shifts -2, 0, 2), within
    the Taylor polynomial's remainder: ``sin x - P_7(x) <= x^9 / 9! <= 1.6e-4`` at
    ``x <= pi / 2``, so ``1 / s^2`` is at most 3.2e-4 above (4e-4 allowed)."""
    beams = _beams(k, lo, hi)
    d = min(abs(u - b + shift) for b in beams for shift in (-2.0, 0.0, 2.0))
    s = np.sin(0.5 * np.pi * min(d, 1.0))
    with np.errstate(divide="ignore", over="ignore"):  # tiny s: 1 / (n s^2) -> inf -> n
        want = min(float(n), 1.0 / (n * s * s))
    got = float(envelope(np.array([u]), beams, n)[0])
    assert want * (1.0 - 1e-12) <= got <= want * (1.0 + 4e-4)


def test_envelope_on_a_beam_is_n_without_a_warning():
    """On a beam (``s = 0``: 1 / 0) and 1e-155 off it (``n s^2`` subnormal: 1 / it
    overflows) the envelope is ``n``, silently, as documented (screened every epoch)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = envelope(np.array([0.0, 1e-155, -1e-155]), np.array([0.0]), 12)
    assert np.array_equal(got, [12.0, 12.0, 12.0])


@pytest.fixture(scope=shared_run_scope)  # per test under mutmut (tests/scopes.py)
def block():
    scen = build_scenario(load_config(CONSTELLATION, ["run.duration_s=10"]))
    n_ut = sum(p.n_ut for _, p in scen.populations)
    mb = MotionBlocks(scen.ephemeris, scen.populations, scen.times_s[:N_EPOCH],
                      scen.ephemeris.n_sat, n_ut).block_of(0)  # fmt: skip
    none = np.zeros(0, np.int64)
    cones = [
        candidate_satellites(
            mb.sat_pos_m[i], mb.ut_pos_m[i], scen.min_elevation_rad, none
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
    assert code.dtype == np.int8  # as documented: one byte per pair of the grid
    b, e = bound.reshape(-1)[links.visible], best[links.visible]
    assert (b >= e).all()
    # Tight where it matters: the best pair of a UT is bounded within 3 dB.
    assert np.median(b / e) < 30.0 and (b / e).min() < 1.0 + 1e-3


def _variant(eng, kind):
    """The constellation's engine (per-population UPAs, a fixed loss) or one with another
    terminal / atmosphere: each path of the bound's ``G_rx / L_atm`` factor."""
    from leolink.antenna.terminal import Metasurface
    from leolink.link.atmosphere import AtmosphereTable

    if kind == "groups":
        return eng
    terminal = Metasurface() if "metasurface" in kind else UPATerminal(24, 24, 10.0)
    atm = eng.atmosphere
    if "table" in kind:  # 0.3 dB at zenith, growing as 1 / sin(el): depends on it
        atm = AtmosphereTable(lambda el: 0.3 / np.sin(np.maximum(el, 0.05)))
    return LinkEngine(eng.codebook, terminal, eng.params, atm, eng.colors)


@pytest.mark.parametrize("kind", ["groups", "upa", "upa_table", "metasurface_table"])
def test_screening_bound_is_the_product_of_the_envelopes(block, kind):
    """The bound of each pair is what engine/screening.py says, recomputed here from the
    positions: the engine's ``K / rho^2 x G_rx / L_atm`` of the pair (its exact evaluation)
    times ``E_x(u_x) E_y(u_y)`` at the direction cosines ``u = (ut - sat) . axis / rho``
    of the satellite's body frame, times the two slacks (1 + 1e-6 each, ``BOUND_SLACK``
    and the one of the dB gain). A bound only looser (wrong cosines: the envelope's
    maximum ``n``) still bounds every beam; this sees it."""
    eng, n_ut, mb, cones = block
    eng = _variant(eng, kind)
    cone = cones[0]
    sat_pos, sat_vel = mb.sat_pos_m[0][cone], mb.sat_vel_m_s[0][cone]
    axes = body_frame(sat_pos, sat_vel)
    code, bound = screen(eng, mb.ut_pos_m[0], sat_pos, axes)
    ut, sat = np.nonzero(np.ones(code.shape, bool))
    links = eng.evaluate_pairs(mb.ut_pos_m[0], sat_pos, sat_vel, ut, sat)
    rel = mb.ut_pos_m[0][:, None, :] - sat_pos[None, :, :]
    rho = np.linalg.norm(rel, axis=2)
    ux = np.einsum("usk,sk->us", rel, axes[:, 0]) / rho
    uy = np.einsum("usk,sk->us", rel, axes[:, 1]) / rho
    cb = eng.codebook
    env = envelope(ux, eng.beam_ux, cb.n_sub_x) * envelope(uy, eng.beam_uy, cb.n_sub_y)
    want = env * links.path_lin.reshape(code.shape) * (1.0 + screening.BOUND_SLACK) ** 2
    on = code > 0
    assert on.sum() > 10_000 and np.allclose(bound[on], want[on], rtol=1e-9, atol=0.0)
    assert (env[on] < 0.5 * cb.n_sub_x * cb.n_sub_y).mean() > 0.9  # most pairs off-beam


def _tables(eng, n_ut, mb, cones, window_db, prune, floor_db=-np.inf):
    blk = CandidateSearch(eng, window_db, prune, floor_db).block(
        0, mb.ut_pos_m, None, mb.sat_pos_m, mb.sat_vel_m_s, cones
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


def test_find_pairs_finds_each_evaluated_pair_and_no_other(block):
    eng, n_ut, mb, cones = block
    _, _, full = _tables(eng, n_ut, mb, cones, 3.0, prune=True)
    rng = np.random.default_rng(3)
    # a random part of the pairs (in their order): rows of none, one and several
    keep = np.flatnonzero(rng.random(full.links.n_pair) < 0.3)
    blk = dataclasses.replace(full, links=full.links.take(keep))
    links = blk.links
    index = {(int(u), int(s)): i for i, (u, s) in enumerate(zip(links.ut, links.sat, strict=True))}
    count = np.bincount(links.ut, minlength=blk.n_visible.size)
    assert min((count == c).sum() for c in (0, 1, 2)) > 100  # rows of none, one, several
    rows = np.concatenate([links.ut, rng.integers(0, blk.n_visible.size, 5000)])
    sats = np.concatenate([links.sat, rng.integers(-1, mb.sat_pos_m.shape[1] + 2, 5000)])
    want = [index.get((int(r), int(s)), -1) for r, s in zip(rows, sats, strict=True)]
    assert np.array_equal(blk.find_pairs(rows, sats), want)
    assert (np.asarray(want[links.n_pair :]) == -1).mean() > 0.5  # most random pairs absent


@pytest.mark.parametrize("floor_db", [-10.0, 5.0])
def test_tables_with_a_floor_are_the_exhaustive_cells_at_or_above_it(block, floor_db):
    """The trigger policies' tables (window inf, floor = the service threshold): every
    cell of every visible satellite whose SNR is at least the floor, and nothing else;
    the diagnostics are those of the search without a floor."""
    eng, n_ut, mb, cones = block
    cells, snr, blk = _tables(eng, n_ut, mb, cones, np.inf, True, floor_db)
    cells_all, snr_all, ref = _tables(eng, n_ut, mb, cones, np.inf, False)
    keep = snr_all >= floor_db
    assert 0 < keep.sum() < 0.2 * keep.size  # most visible cells are below the floor
    assert np.array_equal(cells, cells_all[:, keep]) and np.array_equal(snr, snr_all[keep])
    assert np.array_equal(blk.n_visible, ref.n_visible)
    assert np.array_equal(blk.best_cell, ref.best_cell)
    assert np.array_equal(blk.best_snr_db, ref.best_snr_db, equal_nan=True)
    assert blk.links.n_pair < 0.5 * ref.links.n_pair


def test_a_bound_too_low_is_seen(block, monkeypatch):
    """The comparison above can fail: a bound 3 dB too low prunes pairs that matter."""
    eng, n_ut, mb, cones = block
    monkeypatch.setattr(screening, "BOUND_SLACK", -0.5)
    cells, _, _ = _tables(eng, n_ut, mb, cones, 3.0, prune=True)
    monkeypatch.undo()
    cells_ref, _, _ = _tables(eng, n_ut, mb, cones, 3.0, prune=False)
    assert cells.shape != cells_ref.shape or not np.array_equal(cells, cells_ref)


def test_screening_of_elevation_dependent_gains_on_the_ellipsoid():
    """The per-pair factor (a metasurface terminal's gain falls with the elevation) and
    the local up of WGS 84 (up to 0.19 deg from the radial one): visibility agrees with
    the engine's exact evaluation from the same up, the bound is above every beam and
    tight at the best pair of a UT, and pairs below the mask keep the bound -1."""
    from leolink.geometry import enu_basis

    over = ["run.duration_s=10", 'terminal.kind="metasurface"', 'earth.model="wgs84"']
    scen = build_scenario(load_config(CONSTELLATION, over))
    n_ut = sum(p.n_ut for _, p in scen.populations)
    mb = MotionBlocks(scen.ephemeris, scen.populations, scen.times_s[:1],
                      scen.ephemeris.n_sat, n_ut).block_of(0)  # fmt: skip
    every = slice(None, None, 10)  # 100 UTs of the four populations: enough edge pairs
    eng, ut_pos = scen.engine, mb.ut_pos_m[0][every]
    up = enu_basis(mb.ut_lat_rad[0][every], mb.ut_lon_rad[0][every])[..., 2, :]
    # The satellites within ~25 deg of the horizon of the area: the mask's edge is in it.
    cone = candidate_satellites(mb.sat_pos_m[0], ut_pos, 0.0, np.zeros(0, np.int64), up)
    sat_pos, sat_vel = mb.sat_pos_m[0][cone], mb.sat_vel_m_s[0][cone]
    code, bound = screen(eng, ut_pos, sat_pos, body_frame(sat_pos, sat_vel), ut_up=up)
    ut, sat = np.nonzero(np.ones(code.shape, bool))
    links = eng.evaluate_pairs(ut_pos, sat_pos, sat_vel, ut, sat, ut_up=up)
    vis = links.visible.reshape(code.shape)
    assert vis.any() and (~vis).any()
    assert (code[vis] > 0).all() and not (code[~vis] == VISIBLE).any()
    assert (bound[code == 0] == -1.0).all()
    best = links.gain_tx_bm(eng.beam_ix, eng.beam_iy).max(axis=0) * links.path_snr_lin
    b, e = bound.reshape(-1)[links.visible], best[links.visible]
    assert (b >= e).all() and (b / e).min() < 1.0 + 1e-3
    # A pair on the mask's edge (1e-12 rad above it: inside the 1e-9 band of sin(el)) is
    # "uncertain": its bound still carries the terminal's gain at that elevation.
    e_, n_, u_ = enu_basis(mb.ut_lat_rad[0, :1], mb.ut_lon_rad[0, :1])[0]  # UT 0 = ut_pos[0]
    el = eng.params.min_elevation_rad + 1e-12
    edge = ut_pos[:1] + 1.5e6 * (np.cos(el) * n_ + np.sin(el) * u_)
    edge_vel = 7.5e3 * e_[None, :]
    code1, bound1 = screen(eng, ut_pos[:1], edge, body_frame(edge, edge_vel), ut_up=u_[None])
    one = eng.evaluate_pairs(ut_pos[:1], edge, edge_vel, np.zeros(1, int), np.zeros(1, int),
                             ut_up=u_[None])  # fmt: skip
    assert code1[0, 0] == UNCERTAIN and one.visible[0]
    exact = one.gain_tx_bm(eng.beam_ix, eng.beam_iy).max(axis=0) * one.path_snr_lin
    assert bound1[0, 0] >= exact[0]


@pytest.fixture(scope=shared_run_scope)  # as block (tests/scopes.py)
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
    # The bound's terminal factor is the gain at the angle above the panel plane, pair by
    # pair: tilted / flat = G(asin(n . d / |d|)) / G(el), d = satellite - UT (sphere: up
    # is radial), recomputed here from the positions.
    d = sat_pos[None, :, :] - mb.ut_pos_m[0][:, None, :]
    dist = np.linalg.norm(d, axis=2)
    up = mb.ut_pos_m[0] / np.linalg.norm(mb.ut_pos_m[0], axis=1)[:, None]
    sin_p = np.einsum("usk,uk->us", d, normal[0]) / dist
    sin_e = np.einsum("usk,uk->us", d, up) / dist
    gain = scan.terminal.gain_db
    want = 10.0 ** ((gain(np.arcsin(sin_p)) - gain(np.arcsin(sin_e))) / 10.0)
    on = code > 0
    assert on.sum() > 1000 and np.allclose(bound[on] / flat[on], want[on], rtol=1e-9)


def test_pruned_tables_of_tilted_panels_are_the_exhaustive_tables(block, tilted):
    _, n_ut, mb, cones = block
    scan, normal = tilted
    out = []
    for prune in (True, False):
        blk = CandidateSearch(scan, 3.0, prune).block(
            0, mb.ut_pos_m, None, mb.sat_pos_m, mb.sat_vel_m_s, cones, normal
        )
        t = blk.table
        r, s = np.nonzero(t.cell >= 0)
        order = np.lexsort((t.cell[r, s], r))
        out.append((r[order], t.cell[r, s][order], t.snr_db[r, s][order], blk.best_snr_db))
    (r, c, v, b), (r0, c0, v0, b0) = out
    assert np.array_equal(r, r0) and np.array_equal(c, c0) and np.array_equal(v, v0)
    assert np.array_equal(b, b0, equal_nan=True)


@pytest.mark.parametrize("floor_db", [-np.inf, 5.0])
@pytest.mark.parametrize("pairs", [1, 37, 1024])
def test_tables_do_not_depend_on_their_chunks(block, monkeypatch, pairs, floor_db):
    """The tables are built in chunks of whole rows (bounded memory): chunks of one pair
    (every row longer than a chunk), of 37 pairs (cuts inside rows moved to the next row)
    and of 1024 give the tables of one chunk, bit for bit."""
    eng, n_ut, mb, cones = block
    window_db = np.inf if floor_db > -np.inf else 3.0
    cells_ref, snr_ref, ref = _tables(eng, n_ut, mb, cones, window_db, True, floor_db)
    assert ref.links.visible.sum() > 4 * 1024  # several chunks of every size
    monkeypatch.setattr(search, "TABLE_PAIRS", pairs)
    cells, snr, blk = _tables(eng, n_ut, mb, cones, window_db, True, floor_db)
    assert np.array_equal(cells, cells_ref) and np.array_equal(snr, snr_ref, equal_nan=True)
    assert np.array_equal(blk.best_cell, ref.best_cell)
    assert np.array_equal(blk.best_snr_db, ref.best_snr_db, equal_nan=True)
    assert np.array_equal(blk.n_visible, ref.n_visible)


@given(
    rows=st.lists(st.integers(0, 6), max_size=40).map(lambda r: np.sort(np.array(r, int))),
    size=st.integers(1, 12),
)
def test_row_chunks_cut_only_between_rows(rows, size):
    slices = list(search._row_chunks(rows, size))
    assert slices[0][0] == 0 and slices[-1][1] == rows.size
    assert all(a[1] == b[0] for a, b in zip(slices, slices[1:], strict=False))
    for lo, hi in slices:
        assert hi > lo or rows.size == 0
        # at most `size` entries, then the rest of the last one's row
        assert hi - lo <= size or rows[lo + size - 1] == rows[hi - 1]
        if hi < rows.size:
            assert rows[hi - 1] != rows[hi]  # a row is never split


def test_screening_of_per_population_terminals_follows_each_rows_ut(block):
    """Per-population terminals (``TerminalGroups``): 10 dBi, 40 dBi and a metasurface
    (its gain falls with the elevation: the per-pair factor) in one screen of 200 UTs
    taken out of order, each row's UT given by ``ut_id``. The bound of every visible pair
    is above its best beam's SNR evaluated exactly with that UT's own terminal, and
    within 1e-3 of it at the best pair of each population: a row bounded with another
    row's terminal is 30 dB (or 20 dB) off one way or the other."""
    from leolink.antenna.terminal import FixedGain, Metasurface, TerminalGroups

    eng, n_ut, mb, cones = block
    group = np.arange(n_ut) % 3  # UT i has terminal i % 3
    terms = TerminalGroups([FixedGain(10.0), FixedGain(40.0), Metasurface()], group)
    multi = LinkEngine(eng.codebook, terms, eng.params, eng.atmosphere, eng.colors)
    sel = np.random.default_rng(3).permutation(n_ut)[:200]  # rows != UTs
    assert (group[sel] != group[np.arange(200)]).mean() > 0.5
    cone = cones[0]
    sat_pos, sat_vel = mb.sat_pos_m[0][cone], mb.sat_vel_m_s[0][cone]
    ut_pos = mb.ut_pos_m[0][sel]
    code, bound = screen(multi, ut_pos, sat_pos, body_frame(sat_pos, sat_vel), ut_id=sel)
    ut, sat = np.nonzero(np.ones(code.shape, bool))
    links = multi.evaluate_pairs(ut_pos, sat_pos, sat_vel, ut, sat, ut_id=sel)
    vis = links.visible
    # The reference takes each UT's own terminal: 10 / 40 dBi, 33 + 12 log10(sin el).
    g = group[sel][ut]
    el = links.elevation_rad
    expect = np.choose(g, [np.full(el.shape, 10.0), np.full(el.shape, 40.0),
                           33.0 + 12.0 * np.log10(np.abs(np.sin(el)))])  # fmt: skip
    assert np.allclose(np.broadcast_to(links.rx_db, el.shape)[vis], expect[vis], atol=1e-9)
    best = links.gain_tx_bm(multi.beam_ix, multi.beam_iy).max(axis=0) * links.path_snr_lin
    b, e = bound.reshape(-1), best
    assert (code.reshape(-1)[vis] > 0).all() and (b[vis] >= e[vis]).all()
    for k in range(3):  # tight at the best pair of each population
        mine = vis & (g == k)
        assert mine.sum() > 100 and (b[mine] / e[mine]).min() < 1.0 + 1e-3


def test_screening_of_satellites_at_the_zenith(block):
    """Satellites straight above their UTs: ``sin(el)`` from dot products rounds to
    above 1 for 119 of them (by up to 1.1e-14), the terminal's gain and the loss
    are then taken at 90 deg (clipped), not NaN: the bound stays above the exact SNR."""
    from leolink.antenna.terminal import Metasurface

    eng, n_ut, mb, cones = block
    eng = _variant(eng, "metasurface_table")
    rng = np.random.default_rng(11)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    ut_pos, sat_pos = 6371e3 * u, (6371e3 + 1300e3) * u
    sat_vel = np.cross(u, rng.normal(size=(400, 3)))  # orthogonal to the position
    r = np.linalg.norm(ut_pos, axis=1)  # the screening's sin(el), for these inputs only
    rho = np.sqrt(
        r * r + np.einsum("sk,sk->s", sat_pos, sat_pos) - 2 * np.einsum("sk,sk->s", ut_pos, sat_pos)
    )
    assert ((np.einsum("sk,sk->s", ut_pos, sat_pos) / r - r) / rho > 1.0).any()
    code, bound = screen(eng, ut_pos, sat_pos, body_frame(sat_pos, sat_vel))
    pair = np.arange(400)
    links = eng.evaluate_pairs(ut_pos, sat_pos, sat_vel, pair, pair)
    best = links.gain_tx_bm(eng.beam_ix, eng.beam_iy).max(axis=0) * links.path_snr_lin
    b = bound[pair, pair]
    assert (code[pair, pair] == VISIBLE).all() and np.isfinite(b).all() and (b >= best).all()
    assert np.allclose(links.rx_db, Metasurface().gain_db(np.pi / 2), atol=1e-6)
    # The same with a scan-loss UPA lying flat (normal = up): the angle above the panel
    # plane, from the normal's dot product, rounds above 1 too.
    scan = LinkEngine(eng.codebook, UPATerminal(24, 24, 10.0, scan_loss=True), eng.params,
                      eng.atmosphere, eng.colors)  # fmt: skip
    code, bound = screen(scan, ut_pos, sat_pos, body_frame(sat_pos, sat_vel), ut_normal=u)
    links = scan.evaluate_pairs(ut_pos, sat_pos, sat_vel, pair, pair, ut_normal=u)
    best = links.gain_tx_bm(scan.beam_ix, scan.beam_iy).max(axis=0) * links.path_snr_lin
    b = bound[pair, pair]
    assert (code[pair, pair] == VISIBLE).all() and np.isfinite(b).all() and (b >= best).all()


@settings(max_examples=80, deadline=None)
@given(
    k0=st.integers(0, 5), n_k=st.integers(1, 6), n_ut=st.integers(1, 5),
    sizes=st.lists(st.integers(0, 3), min_size=6, max_size=6), same=st.booleans(),
)  # fmt: skip
def test_dense_pairs_are_every_ut_with_every_satellite_of_its_epochs_cone(k0, n_k, n_ut, sizes,
                                                                           same):  # fmt: skip
    """The dense search's pairs (one cone size: built at once; several: epoch by epoch),
    against their definition, pair by pair in order."""
    ks = range(k0, k0 + n_k)
    sizes = [sizes[0]] * 6 if same else sizes
    cones = {k: np.arange(10 * k, 10 * k + sizes[k - k0]) for k in ks}
    rows, sats = search._dense_pairs(ks, n_ut, cones)
    want = [(k * n_ut + u, s) for k in ks for u in range(n_ut) for s in cones[k]]
    assert list(zip(rows.tolist(), sats.tolist(), strict=True)) == want
    assert rows.dtype == sats.dtype == np.int64


#: Width of the steps of the stepped pattern below [rad]: about ten times the difference
#: between the screening's elevation and the engine's (rounding, ~1e-15 rad), so that one
#: pair in ten or so sees another step in the two.
_STEP_RAD = 1e-14


class SteppedConfig(Params):
    smooth_gain: bool = Field(False, description="declare the gain smooth (it is not)")
    give_max: bool = Field(True, description="declare max_gain_db")


class Stepped:
    """A stepped (piecewise constant) pattern: 30 dB on every other elevation step, 0 dB
    on the others: its gain jumps between the screening's elevation and the engine's."""

    elevation_independent = False
    pattern_lin = None

    def __init__(self, smooth_gain=False, give_max=True):
        self.smooth_gain = smooth_gain
        if give_max:
            self.max_gain_db = 30.0

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        el = np.asarray(elevation_rad, float) + 0.0 * np.asarray(off_boresight_rad)
        return np.where(np.floor(el / _STEP_RAD) % 2 == 1, 30.0, 0.0)


@pytest.fixture
def stepped():
    TERMINALS.register("stepped", config=SteppedConfig)(Stepped)
    yield
    TERMINALS.remove("stepped")


@pytest.mark.parametrize("declared_smooth", [False, True])
def test_a_stepped_terminal_is_pruned_exactly_when_it_says_it_is_not_smooth(
    block, stepped, declared_smooth
):
    """The TerminalAntenna contract: a gain that is not smooth, declared so with its
    maximum, is bounded by that maximum and the pruned tables are the exhaustive ones; the
    same pattern declared smooth breaks the pruning (what the contract guards against)."""
    eng, n_ut, mb, cones = block
    terminal = TERMINALS.build("stepped", SteppedConfig(smooth_gain=declared_smooth))
    eng = LinkEngine(eng.codebook, terminal, eng.params, eng.atmosphere, eng.colors)
    cells, snr, blk = _tables(eng, n_ut, mb, cones, 3.0, prune=True)
    cells_ref, snr_ref, ref = _tables(eng, n_ut, mb, cones, 3.0, prune=False)
    same = cells.shape == cells_ref.shape and np.array_equal(cells, cells_ref)
    assert same == (not declared_smooth)
    if not declared_smooth:
        assert np.array_equal(snr, snr_ref)
        assert np.array_equal(blk.best_snr_db, ref.best_snr_db, equal_nan=True)
        assert blk.links.n_pair < ref.links.n_pair  # still pruned (by the 30 dB maximum)


def test_a_stepped_terminal_without_its_maximum_is_refused_at_config_time(stepped):
    sets = ["terminal.kind=stepped", "terminal.stepped.give_max=false"]
    with pytest.raises(ConfigError, match=r"terminal.kind = 'stepped' is not allowed: its gain"):
        build_scenario(load_config("configs/paper.toml", sets))


@pytest.mark.parametrize("floor_db", [-np.inf, -1.0])
@pytest.mark.parametrize("window_db", [0.0, 3.0, np.inf])
def test_compiled_window_gives_the_numpy_windows_entries(window_db, floor_db, monkeypatch):
    """``search.window_entries`` by the compiled loop and by numpy (as ``LEOLINK_JIT=0``):
    the same entries in the same order, the same row bests and best cells, bit for bit
    (the same comparisons of the same values), with rows of one pair and of many, rows
    whose every SNR is NaN, -inf SNRs (a null), exact ties at the best, and a floor (the
    trigger policies': entries below it left out, the best cell still seen)."""
    import leolink.compiled

    rng = np.random.default_rng(43)
    nb, m = 15, 3000
    rows = np.sort(rng.integers(0, 900, m))
    sat = rng.integers(0, 4000, m)
    snr = np.round(rng.normal(0.0, 4.0, (nb, m)), 1)  # rounded: many exact ties
    snr[:, rng.random(m) < 0.1] = np.nan  # pairs below the mask
    snr[rng.random((nb, m)) < 0.01] = -np.inf
    snr[:, rows == rows[0]] = np.nan  # a row with no finite SNR
    got_best, want_best = np.full(900, 7.0), np.full(900, 7.0)
    got_cell, want_cell = np.full(900, -2), np.full(900, -2)
    limits = (window_db, floor_db)
    got = search.window_entries(snr, rows, sat, limits, (got_best, got_cell))
    monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    want = search.window_entries(snr, rows, sat, limits, (want_best, want_cell))
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
    np.testing.assert_array_equal(got_best, want_best)
    np.testing.assert_array_equal(got_cell, want_cell)
    assert np.isnan(want_best[rows[0]]) and (want_best == 7.0).any()  # untouched rows kept
    assert want_cell[rows[0]] == -2 and (want_cell >= 0).sum() > 800
    if floor_db > -np.inf:
        assert want[2].min() >= floor_db and (want_best < floor_db).any()
    else:
        assert want[0].size > (m if window_db > 0 else 900 // 2)


@pytest.mark.parametrize("path_exp", [(8.0, 11.0), (-11.0, -8.0)])  # linear SNRs > 1 or < 1
@pytest.mark.parametrize("window_db", [0.0, 3.0, np.inf])
def test_window_from_kernels_gives_the_window_of_the_snr_matrix(window_db, path_exp):
    """``search.link_window_entries`` (the compiled loop: a linear pre-selection, then the
    dB sums of the few beams near the best) against ``window_entries`` of the full
    ``Links.snr_db_bm`` matrix (the path it replaces, the same dB sums): the same entries
    in the same order and the same row bests, bit for bit, with rows of one pair and of
    many, pairs below the mask (NaN path), nulls (a zero kernel: -inf dB), exact ties
    (equal kernels) and gaps of an ulp or two at the best (within the pre-selection's
    margin, where a dB sum may tie or not)."""
    from leolink.engine.links import Links

    rng = np.random.default_rng(44)
    m, n_rows = 4000, 1500
    kx, ky = rng.uniform(0.0, 12.0, (5, m)), rng.uniform(0.0, 10.0, (3, m))
    kx[1] = np.where(rng.random(m) < 0.3, kx[0], kx[1])  # exact ties between beams
    kx[2] = np.where(rng.random(m) < 0.1, kx[0] * (1.0 + 4e-16), kx[2])  # an ulp or two
    kx[rng.random((5, m)) < 0.02] = 0.0  # nulls
    path = 10.0 ** rng.uniform(*path_exp, m)
    visible = rng.random(m) > 0.1
    rows = np.sort(rng.integers(0, n_rows, m))
    sat = rng.integers(0, 4000, m)
    z = np.zeros(m)
    links = Links(rows, sat, np.zeros((m, 3)), z, z, visible, path, kx, ky, 0.0)
    beams = (np.repeat(np.arange(5), 3), np.tile(np.arange(3), 5))
    for pairs in (slice(0, m), np.flatnonzero(visible)):
        got_best, want_best = np.full(n_rows, 7.0), np.full(n_rows, 7.0)
        r, s = rows[pairs], sat[pairs]
        got = search.link_window_entries(links, pairs, beams, r, s, window_db, got_best)
        snr_bm = links.snr_db_bm(*beams, pairs)
        want = search.window_entries(snr_bm, r, s, window_db, want_best)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)
        np.testing.assert_array_equal(got_best, want_best)
        assert want[0].size > (m * 15 // 2 if window_db == np.inf else n_rows // 2)
        assert np.isneginf(want[2]).any() == (window_db == np.inf)
