"""UTs spread over the globe, screened by tiles (sim/candidates/tiles.py): each group's cap
holds every satellite one of its UTs sees (brute force, sphere and WGS 84, UTs in the air
and below the surface), and the candidate tables pruned by caps are the exhaustive ones.
"""

from __future__ import annotations

import numpy as np
import pytest

from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.geodesy import wgs84_to_ecef
from leolink.geometry import enu_basis, geodetic_to_ecef
from leolink.sim.candidates import tiles
from leolink.sim.candidates.search import CandidateSearch
from leolink.sim.candidates.tiles import choose_groups, cube_cells, group_cones
from leolink.sim.motion import MotionBlocks

R_M = 6_371_000.0


def _labels(groups, n):
    label = np.empty(n, np.int64)
    for g, members in enumerate(groups):
        label[members] = g
    return label


def _uts(rng, n, earth):
    """UTs uniform over -60..60 deg of latitude, heights -400 m .. 12 km; their
    positions and local up (geodetic on WGS 84, radial on the sphere)."""
    lat = np.arcsin(rng.uniform(np.sin(np.radians(-60)), np.sin(np.radians(60)), n))
    lon = rng.uniform(-np.pi, np.pi, n)
    alt = rng.choice([-400.0, 0.0, 12_000.0], n)
    if earth == "sphere":
        pos = geodetic_to_ecef(lat, lon, alt, radius_m=R_M)
        return pos, None
    return wgs84_to_ecef(lat, lon, alt), enu_basis(lat, lon)[..., 2, :]


def _sky(rng, n):
    """Satellites on shells from 500 to 1,300 km over a 6,378 km sphere."""
    d = rng.standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(6.878e6, 7.678e6, (n, 1))


@pytest.mark.parametrize("earth", ["sphere", "wgs84"])
@pytest.mark.parametrize("min_el_deg", [0.0, 25.0, 40.0])
def test_every_cap_holds_what_its_uts_see(earth, min_el_deg):
    rng = np.random.default_rng(int(min_el_deg) + (earth == "wgs84"))
    pos, up = _uts(rng, 600, earth)
    sat = _sky(rng, 3000)
    groups = choose_groups(pos, len(sat), 0.2)
    assert len(groups) > 10  # spread over the globe: many tiles
    label = _labels(groups, len(pos))
    min_el = np.radians(min_el_deg)
    caps = group_cones(sat, pos, up, min_el, label, len(groups))
    d = sat[None, :, :] - pos[:, None, :]
    normal = pos / np.linalg.norm(pos, axis=1, keepdims=True) if up is None else up
    sin_el = np.einsum("usk,uk->us", d, normal) / np.linalg.norm(d, axis=2)
    seen = sin_el >= np.sin(min_el) - 1e-9
    held = np.zeros_like(seen)
    for g, members in enumerate(groups):
        held[np.ix_(members, caps.of(g))] = True
    assert seen.sum() > 1000
    assert not (seen & ~held).any()
    # and they prune: a UT's cap is a small part of the sky unless the mask is low
    assert held.mean() < {0.0: 0.8, 25.0: 0.3, 40.0: 0.2}[min_el_deg]


def test_the_cap_widens_on_the_ellipsoid(monkeypatch):
    """On WGS 84 the mask is measured from the geodetic up, tilted from the radius by up
    to 0.19 deg (towards the pole): a satellite due north at 40.0 deg geodetic elevation,
    0.19 deg lower measured from the radius, is in the cap; a cap of the radial up loses
    it (without the rounding margin, which would hide it)."""
    monkeypatch.setattr(tiles, "CAP_MARGIN_RAD", 0.0)
    lat, lon = np.array([np.radians(45.0)]), np.array([0.0])
    pos = wgs84_to_ecef(lat, lon, 0.0)
    e, n, up = enu_basis(lat, lon)[0]
    el = np.radians(40.0 + 1e-7)
    d = np.cos(el) * n + np.sin(el) * up
    radial = pos[0] / np.linalg.norm(pos[0])
    assert 39.8 < np.degrees(np.arcsin(d @ radial)) < 39.85  # below the mask from the radius
    sat = pos[0] + 1.8e6 * d  # ~1,200 km up: at the cap's edge
    others = _sky(np.random.default_rng(0), 200)  # on the same shell: the cap is sat's
    others *= np.linalg.norm(sat) / np.linalg.norm(others, axis=1, keepdims=True)
    many = np.concatenate([sat[None, :], others])
    one = np.zeros(1, np.int64)
    assert 0 in group_cones(many, pos, up[None, :], np.radians(40.0), one, 1).sat
    assert 0 not in group_cones(many, pos, None, np.radians(40.0), one, 1).sat


def test_cube_cells_are_the_faces_and_the_angles():
    """Each axis direction is the centre of its face; cells are equal in angle."""
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    cells = cube_cells(axes, 2)
    assert np.array_equal(cells // 4, [0, 1, 2, 3, 4, 5])
    assert np.array_equal(cube_cells(axes, 0), np.zeros(6))
    a = np.radians([-44.0, -1.0, 1.0, 44.0])  # atan(y / x) on the +x face
    v = np.stack([np.cos(a), np.sin(a), np.zeros(4)], axis=1)
    assert np.array_equal(cube_cells(v, 2) % 4 // 2, [0, 0, 1, 1])


def _global_block(earth, n_ut):
    sets = ["run.duration_s=10", f'earth.model="{earth}"']
    for i, share in enumerate((4, 3, 2, 1)):
        sets += [f"population.{i}.placement='random_region'",
                 f"population.{i}.lat_band_deg=[-60.0, 60.0]",
                 f"population.{i}.count={n_ut * share // 10}"]  # fmt: skip
    scen = build_scenario(load_config("configs/constellation.toml", sets))
    n = sum(p.n_ut for _, p in scen.populations)
    mb = MotionBlocks(scen.ephemeris, scen.populations, scen.times_s[:2], scen.ephemeris.n_sat,
                      n).block_of(0)  # fmt: skip
    up = None
    if earth == "wgs84":
        up = enu_basis(mb.ut_lat_rad, mb.ut_lon_rad)[..., 2, :]
    return scen.engine, n, mb, up


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("earth", ["sphere", "wgs84"])
def test_tables_pruned_by_caps_are_the_exhaustive_tables(earth, compiled, monkeypatch):
    """UTs over -60..60 deg: every satellite is in the one cone of all UTs, each tile
    screens only its cap, and the tables, the best cells and the satellites above the
    mask equal those of evaluating every UT with every satellite (compiled loop, and the
    numpy screening per group)."""
    import leolink.compiled

    eng, n_ut, mb, up = _global_block(earth, 300)
    every = [np.arange(mb.sat_pos_m.shape[1])] * 2
    blocks = []
    for prune in (True, False):
        if not compiled:
            monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
        search = CandidateSearch(eng, 3.0, prune)
        blocks.append(search.block(0, mb.ut_pos_m, up, mb.sat_pos_m, mb.sat_vel_m_s, every))
        monkeypatch.undo()
    blk, ref = blocks
    t, r = blk.table, ref.table
    assert np.array_equal(np.sort(t.cell, axis=1), np.sort(r.cell, axis=1))
    order, order_r = np.argsort(t.cell, axis=1), np.argsort(r.cell, axis=1)
    assert np.array_equal(np.take_along_axis(t.snr_db, order, 1),
                          np.take_along_axis(r.snr_db, order_r, 1), equal_nan=True)  # fmt: skip
    assert np.array_equal(blk.n_visible, ref.n_visible)
    assert np.array_equal(blk.best_cell, ref.best_cell)
    assert np.array_equal(blk.best_snr_db, ref.best_snr_db, equal_nan=True)
    assert (blk.n_visible > 0).mean() > 0.9
    assert blk.links.n_pair < 0.02 * ref.links.n_pair  # 4,399 satellites, ~60 above the mask


def test_a_cap_too_narrow_is_seen(monkeypatch):
    """The comparison above can fail: caps a degree too narrow lose satellites that
    some UT sees above the mask (its n_visible) or serve from (its tables)."""
    eng, n_ut, mb, up = _global_block("sphere", 300)
    every = [np.arange(mb.sat_pos_m.shape[1])] * 2
    ref = CandidateSearch(eng, 3.0, False).block(0, mb.ut_pos_m, up, mb.sat_pos_m,
                                                 mb.sat_vel_m_s, every)  # fmt: skip
    monkeypatch.setattr(tiles, "CAP_MARGIN_RAD", -np.radians(1.0))
    blk = CandidateSearch(eng, 3.0, True).block(0, mb.ut_pos_m, up, mb.sat_pos_m,
                                                mb.sat_vel_m_s, every)  # fmt: skip
    assert (blk.n_visible < ref.n_visible).any()


def test_tables_do_not_depend_on_how_many_pairs_are_screened_at_once(monkeypatch):
    """The compiled screening takes a group's UTs a few hundred pairs at a time
    (bounded temporaries): the same tables and diagnostics as in one call."""
    from leolink.sim.candidates import search

    eng, n_ut, mb, up = _global_block("wgs84", 300)
    every = [np.arange(mb.sat_pos_m.shape[1])] * 2
    args = (0, mb.ut_pos_m, up, mb.sat_pos_m, mb.sat_vel_m_s, every)
    ref = CandidateSearch(eng, 3.0, True).block(*args)
    monkeypatch.setattr(search, "SCREEN_PAIRS", 500)
    blk = CandidateSearch(eng, 3.0, True).block(*args)
    assert np.array_equal(blk.table.cell, ref.table.cell)
    assert np.array_equal(blk.table.snr_db, ref.table.snr_db, equal_nan=True)
    assert np.array_equal(blk.n_visible, ref.n_visible)
    assert np.array_equal(blk.links.sat, ref.links.sat)
