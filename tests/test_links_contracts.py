"""engine/links.py contracts: pairs taken and joined, per-UT terminal gains, edges of the
geometry, reuse colours and azimuths, each checked another way.

Written from the survivors of a mutation run (docs/testing.md). References: the pairs
evaluated one at a time and in other orders; each terminal of a ``TerminalGroups`` alone;
satellites exactly at the zenith / nadir of a UT (elevation +-90 deg, where ``|sin el|``
exceeds 1 by an ulp for some UTs) and along / against a tilted panel normal; lines of sight
built at a known azimuth in a local frame made by cross products; the neighbour property
of the reuse colours.
"""

import math
import warnings

import numpy as np
import pytest

from leolink.antenna.terminal import FixedGain, Isotropic, TerminalGroups, UPATerminal
from leolink.app.scenario import codebook_from_config
from leolink.config import load_config
from leolink.engine import LinkEngine, LinkParams, reuse_colors
from leolink.engine.links import (
    _PAIR_FIELDS,
    Links,
    group_constants_db,
    panel_elevation_of_pairs,
    rows_gain_db,
)
from leolink.geometry import azimuth_deg
from leolink.link.atmosphere import FixedLoss

PAPER = "configs/paper.toml"
R = 6_371_000.0
RNG = np.random.default_rng(1616)


def _engine(terminal=None):
    cb = codebook_from_config(load_config(PAPER))
    params = LinkParams(11.45e9, 250e6, 15.0, 0.0, 24.1, math.radians(25.0))
    return LinkEngine(cb, terminal or Isotropic(), params, FixedLoss(0.0))


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _sphere_points(n):
    return R * _unit(RNG.normal(size=(n, 3)))


def _links(eng, n_ut=6, n_sat=3):
    ut = _sphere_points(n_ut)
    sat = 1.2 * _sphere_points(n_sat)
    vel = np.cross(sat, [0.0, 0.0, 1.0])
    iu, js = np.meshgrid(np.arange(n_ut), np.arange(n_sat), indexing="ij")
    return eng.evaluate_pairs(ut, sat, vel, iu.ravel(), js.ravel()), (ut, sat, vel)


def test_take_and_concat_keep_each_pairs_values():
    eng = _engine(TerminalGroups((UPATerminal(4, 4, 10.0, scan_loss=True), Isotropic()),
                                 [0, 1, 0, 1, 1, 0]))  # fmt: skip
    links, _ = _links(eng)
    assert np.ndim(links.rx_db) == 1  # per pair
    idx = np.array([5, 0, 11, 3])
    part = links.take(idx)
    for name in ("ut", "sat", "rel_m", "slant_range_m", "elevation_rad", "path_lin", "rx_db"):
        np.testing.assert_array_equal(getattr(part, name), getattr(links, name)[idx])
    np.testing.assert_array_equal(part.kx, links.kx[:, idx])
    both = Links.concat([links.take(np.arange(0, 7)), links.take(np.arange(7, 18))])
    np.testing.assert_array_equal(both.rx_db, links.rx_db)
    np.testing.assert_array_equal(both.ky, links.ky)


def test_concat_of_constant_terminal_gains():
    eng = _engine(FixedGain(7.5))
    links, _ = _links(eng)
    assert np.ndim(links.rx_db) == 0
    assert np.ndim(links.take(np.array([1, 2])).rx_db) == 0
    same = Links.concat([links.take(np.arange(0, 5)), links.take(np.arange(5, 18))])
    assert np.ndim(same.rx_db) == 0 and same.rx_db == 7.5  # one constant stays one number
    other = links.take(np.arange(5, 18))
    other.rx_db = 2.0  # another part with another constant gain: one value per pair
    mixed = Links.concat([links.take(np.arange(0, 5)), other])
    np.testing.assert_array_equal(mixed.rx_db, [7.5] * 5 + [2.0] * 13)


def test_rows_gain_db_per_ut_terminal_with_and_without_the_constants():
    members = (UPATerminal(4, 4, 10.0, scan_loss=True), FixedGain(3.0), Isotropic())
    groups = TerminalGroups(members, [2, 0, 1, 0, 2])
    ut_id = np.array([0, 1, 1, 3, 2, 4, 1])
    el = np.radians([20.0, 35.0, 60.0, 80.0, 10.0, 45.0, 15.0])
    for constants in (None, group_constants_db(groups)):
        got = rows_gain_db(groups, el, ut_id, constants)
        for p, u in enumerate(ut_id):
            assert got[p] == pytest.approx(
                float(members[groups.group[u]].gain_db(el[p])), abs=1e-12
            )
    assert group_constants_db(groups) == [None, 3.0, 0.0]


def test_elevation_at_the_zenith_and_nadir_and_along_a_tilted_normal():
    eng = _engine()
    ut = _sphere_points(400)
    sat = np.concatenate([ut * 1.2, -ut * 1.2])  # right above, right below (through the Earth)
    vel = np.cross(sat, [0.0, 0.0, 1.0]) + np.array([1.0, 0.0, 0.0])
    iu = np.concatenate([np.arange(400), np.arange(400)])
    for up in (None, _unit(ut)):
        links = eng.evaluate_pairs(ut, sat, vel, iu, np.arange(800), ut_up=up)
        np.testing.assert_allclose(links.elevation_rad[:400], np.pi / 2, atol=3e-8)
        np.testing.assert_allclose(links.elevation_rad[400:], -np.pi / 2, atol=3e-8)
        assert links.visible[:400].all() and not links.visible[400:].any()
    # Tilted normals: a satellite along the normal is 90 deg above the panel plane.
    normal = _unit(_unit(ut) + 0.4 * _unit(RNG.normal(size=(400, 3))))
    rel = np.concatenate([-normal, normal]) * 7e5  # satellite -> UT
    rho = np.linalg.norm(rel, axis=1)
    el = panel_elevation_of_pairs(rel, rho, normal, iu)
    np.testing.assert_allclose(el[:400], np.pi / 2, atol=3e-8)
    np.testing.assert_allclose(el[400:], -np.pi / 2, atol=3e-8)


def test_snr_in_db_of_a_null_kernel_is_minus_inf_without_a_warning():
    ut = _sphere_points(2)
    sat = 1.2 * ut  # at the zenith: visible
    links = _engine().evaluate_pairs(
        ut, sat, np.cross(sat, [0, 0, 1.0]), np.arange(2), np.arange(2)
    )
    links.kx[0, 0] = 0.0  # an exact null of the beam pattern
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        snr = links.snr_db_bm(np.array([0, 1]), np.array([0, 0]))
    assert snr[0, 0] == -np.inf


def test_reuse_colours_of_a_lattice():
    i, j = np.meshgrid(np.arange(6), np.arange(5), indexing="ij")
    ij = np.stack([i.ravel(), j.ravel()], axis=1)
    grid = {(a, b): k for k, (a, b) in enumerate(ij)}
    ones = reuse_colors(ij, 1)
    assert ones.dtype.kind == "i" and (ones == 0).all()
    for n in (3, 4):
        c = reuse_colors(ij, n)
        assert c.dtype.kind == "i" and set(c.tolist()) == set(range(n))
        for (a, b), k in grid.items():  # no edge neighbour shares the colour
            for nb in ((a + 1, b), (a, b + 1)):
                if nb in grid:
                    assert c[k] != c[grid[nb]]
    # 2 x 2 pattern: the colour repeats with period 2 along each axis.
    c4 = reuse_colors(ij, 4)
    assert c4[grid[(0, 0)]] == c4[grid[(2, 0)]] == c4[grid[(0, 2)]] == c4[grid[(4, 4)]]
    with pytest.raises(ValueError, match="reuse_colors = 2 is not allowed; use 1, 3 or 4"):
        reuse_colors(ij, 2)


def _enu(pos):
    up = _unit(pos)
    east = _unit(np.cross([0.0, 0.0, 1.0], up))
    return np.stack([east, np.cross(up, east), up], axis=1)


def _assert_same_angle(got_deg, want_deg):
    assert ((got_deg >= 0.0) & (got_deg <= 360.0)).all()
    np.testing.assert_allclose(np.mod(got_deg - want_deg + 180.0, 360.0) - 180.0, 0.0, atol=1e-9)


def test_azimuth_of_lines_of_sight_in_the_sphere_and_in_a_given_frame():
    n = 8
    pos = _sphere_points(n)
    az = np.array([0.0, 10.0, 89.0, 135.0, 181.0, 250.0, 300.0, 359.0])
    el = np.radians(30.0)
    for enu in (_enu(pos), None):
        frame = _enu(pos) if enu is None else enu
        los = (
            (np.sin(np.radians(az)) * np.cos(el))[:, None] * frame[:, 0]
            + (np.cos(np.radians(az)) * np.cos(el))[:, None] * frame[:, 1]
            + np.sin(el) * frame[:, 2]
        )
        _assert_same_angle(azimuth_deg(los, pos, enu), az)
    # A given frame (here turned 20 deg about up) is the one used, not the sphere's.
    t = np.radians(20.0)
    e, nn, u = _enu(pos)[:, 0], _enu(pos)[:, 1], _enu(pos)[:, 2]
    turned = np.stack([np.cos(t) * e - np.sin(t) * nn, np.sin(t) * e + np.cos(t) * nn, u], axis=1)
    los = np.cos(el) * turned[:, 1] + np.sin(el) * u  # due "north" of the turned frame
    _assert_same_angle(azimuth_deg(los, pos, turned), np.zeros(n))
    _assert_same_angle(azimuth_deg(los, pos, None), np.full(n, 20.0))  # the turned north


def test_best_beam_is_the_largest_linear_snr_and_ties_go_to_the_first_beam():
    """``Links.best_beam`` (the numpy path: fewer pairs than a compiled call takes) against
    every beam's linear SNR ``k_x k_y p`` taken beam by beam: the same beam where the two
    largest differ by 1e-6 or more, its dB value to 1e-9 dB (``log10`` rounding, ~1e-14);
    beam 0 and NaN below the mask; exact ties (equal kernels) go to the lowest beam."""
    eng = _engine()
    cos_el = math.cos(math.radians(60.0))  # UTs under a satellite 600 km up, and its antipode
    ut = R * _unit(np.c_[RNG.uniform(-1, 1, (400, 2)) * 0.03 * cos_el, np.ones(400)])
    sat = np.array([[0.0, 0.0, R + 600e3], [0.0, 0.0, -(R + 600e3)]])
    vel = np.array([[7.5e3, 0.0, 0.0], [7.5e3, 0.0, 0.0]])
    links = eng.evaluate_pairs(ut, sat, vel, np.tile(np.arange(400), 2), np.repeat([0, 1], 400))
    beam, snr_db = links.best_beam(eng.beam_ix, eng.beam_iy, with_snr_db=True)
    lin = np.stack([links.kx[i] * links.ky[j] * links.path_lin for i, j in
                    zip(eng.beam_ix, eng.beam_iy, strict=True)])  # fmt: skip
    top = np.sort(lin, axis=0)
    clear = links.visible & (top[-2] < top[-1] * (1.0 - 1e-6))
    assert links.visible[:400].all() and not links.visible[400:].any() and clear.sum() > 390
    assert (beam[clear] == np.argmax(lin, axis=0)[clear]).all()
    assert np.abs(snr_db[:400] - 10.0 * np.log10(top[-1, :400])).max() < 1e-9
    assert (beam[400:] == 0).all() and np.isnan(snr_db[400:]).all()
    beam_only, none = links.best_beam(eng.beam_ix, eng.beam_iy)
    assert none is None
    np.testing.assert_array_equal(beam_only, beam)
    kx = np.repeat(links.kx.max(axis=0, keepdims=True), links.kx.shape[0], axis=0)
    tied = Links(*(getattr(links, f) for f in _PAIR_FIELDS), kx, links.ky, links.rx_db)
    first = np.argmax(np.where(eng.beam_ix == 0, 1, 0)[:, None] * links.ky[eng.beam_iy], axis=0)
    assert (tied.best_beam(eng.beam_ix, eng.beam_iy)[0][:400] == first[:400]).all()


def test_best_beam_of_equal_linear_snrs_is_the_first_largest_db_sum():
    """Beams 0 and 1 with kernels (1.5 x, 4 y) and (2 x, 3 y), where their products are
    equal: equal linear SNRs, dB sums that round apart one way or the other. ``best_beam``
    is then :meth:`Links.snr_db_bm`'s first largest sum, and its value that sum (a choice
    by the linear SNRs alone would take beam 0 every time)."""
    eng = _engine()
    links, _ = _links(eng, n_ut=100, n_sat=2)
    fields = {f: getattr(links, f) for f in _PAIR_FIELDS}
    vis = np.arange(links.n_pair) % 5 > 0  # a fifth below the mask: beam 0 and NaN
    fields["visible"], fields["path_lin"] = vis, RNG.uniform(1e-3, 1.0, links.n_pair)
    x, y = RNG.uniform(0.02, 2.0, (2, 20 * links.n_pair))  # gains below and above 1
    kx, ky = np.stack([1.5 * x, 2.0 * x]), np.stack([4.0 * y, 3.0 * y])
    equal = kx[0] * ky[0] == kx[1] * ky[1]  # (1.5 x and 3 y may round)
    kx, ky = kx[:, equal][:, : links.n_pair], ky[:, equal][:, : links.n_pair]
    tied = Links(*fields.values(), kx, ky, links.rx_db)
    beams = (np.array([0, 1]), np.array([0, 1]))
    snr = tied.snr_db_bm(*beams)
    want = np.argmax(snr, axis=0)
    assert 0 < want[vis].sum() < vis.sum()  # both beams win somewhere
    beam, best_db = tied.best_beam(*beams, with_snr_db=True)
    np.testing.assert_array_equal(beam, want)
    np.testing.assert_array_equal(best_db, snr.max(axis=0))


@pytest.mark.parametrize("jit_on", [True, False])
@pytest.mark.parametrize("n_ut", [4, 500])
def test_snr_of_some_pairs_is_that_of_the_pairs_taken(n_ut, jit_on, monkeypatch):
    """``snr_db_bm(ix, iy, pairs)`` (no copy of the geometry) against ``take(pairs)`` then
    ``snr_db_bm`` bit for bit, and against the dB sum of each pair's kernels and path
    SNR; the pairs unsorted, repeated, and some below the mask (NaN); the compiled
    kernel and the numpy path whatever the size."""
    import leolink.compiled

    monkeypatch.setattr(leolink.compiled, "use", lambda n: jit_on)
    eng = _engine()
    ut = _sphere_points(n_ut)
    sat = 1.2 * ut[:3]  # at the zenith of the first three UTs
    iu, js = np.meshgrid(np.arange(n_ut), np.arange(3), indexing="ij")
    links = eng.evaluate_pairs(ut, sat, np.cross(sat, [0, 0, 1.0]), iu.ravel(), js.ravel())
    assert 3 <= links.visible.sum() < links.n_pair
    pairs = RNG.integers(0, links.n_pair, 2 * links.n_pair)
    ix, iy = eng.beam_ix, eng.beam_iy
    snr = links.snr_db_bm(ix, iy, pairs)
    np.testing.assert_array_equal(snr, links.take(pairs).snr_db_bm(ix, iy))
    with np.errstate(divide="ignore"):
        want = 10 * np.log10(
            links.kx[ix][:, pairs] * links.ky[iy][:, pairs] * links.path_lin[pairs]
        )
    want[:, ~links.visible[pairs]] = np.nan
    np.testing.assert_allclose(snr, want, rtol=0, atol=1e-11)


#: The compiled pair loop and the numpy geometry round differently (a division for a product
#: by 1 / rho, the kernels near a peak): angles, distances and kernels.
PATHS_REL = 1e-10
PATHS_ANGLE_RAD = 1e-12


@pytest.mark.parametrize("wgs84_up", [False, True])
def test_compiled_pair_geometry_agrees_with_numpy(wgs84_up, monkeypatch):
    """``LinkEngine.evaluate_pairs`` by the compiled loop (engine.links._pair_rows) and by
    the numpy code (as ``LEOLINK_JIT=0``): every geometry field and kernel, with the sphere's
    radial up and with tilted local ups (as WGS 84 normals are), pairs above and below the
    mask."""
    import leolink.compiled

    eng = _engine()
    ut = _sphere_points(300)
    up = _unit(ut + 2e5 * RNG.normal(size=ut.shape)) if wgs84_up else None
    sat = 1.1 * ut[:4]
    iu, js = np.meshgrid(np.arange(300), np.arange(4), indexing="ij")
    # velocities with a z component: every entry of the body axes counts
    args = (ut, sat, np.cross(sat, [0.3, -0.2, 1.0]), iu.ravel(), js.ravel(), up)
    got = eng.evaluate_pairs(*args)
    monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    want = eng.evaluate_pairs(*args)
    assert 4 <= want.visible.sum() < want.n_pair
    np.testing.assert_array_equal(got.visible, want.visible)
    for name in ("rel_m", "slant_range_m", "path_lin", "kx", "ky"):
        want_x = getattr(want, name)
        atol = 1e-12 * np.abs(want_x).max()
        np.testing.assert_allclose(getattr(got, name), want_x, PATHS_REL, atol, err_msg=name)
    # At the zenith the arcsine amplifies an ulp of its argument to ~1e-8 rad: compare sines
    np.testing.assert_allclose(np.sin(got.elevation_rad), np.sin(want.elevation_rad), 0, 1e-15)
    away = np.abs(want.elevation_rad) < np.radians(89.0)
    np.testing.assert_allclose(
        got.elevation_rad[away], want.elevation_rad[away], 0, PATHS_ANGLE_RAD
    )
    _check_pairs_independently(eng, args, (got, want))


def test_a_pair_exactly_at_the_mask_is_visible():
    """``visible`` is ``elevation >= mask`` on both paths: with the mask set to the
    elevation of one pair (as that path evaluates it: the two paths may differ by an ulp),
    that pair is visible, and with the mask 1e-9 rad higher it is not."""
    import dataclasses

    import leolink.compiled

    eng = _engine()
    ut, sat = _sphere_points(40), 1.1 * _sphere_points(3)
    vel = np.cross(sat, [0.3, -0.2, 1.0])
    iu, js = np.meshgrid(np.arange(40), np.arange(3), indexing="ij")
    args = (ut, sat, vel, iu.ravel(), js.ravel())
    for loops in (True, False):
        use = leolink.compiled.use if loops else (lambda n: False)
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(leolink.compiled, "use", use)
            assert leolink.compiled.use(1) == loops
            el = eng.evaluate_pairs(*args).elevation_rad
            p = int(np.argmin(np.abs(el - 0.5)))  # a pair near 29 deg
            for mask, want in ((el[p], True), (el[p] + 1e-9, False)):
                params = dataclasses.replace(eng.params, min_elevation_rad=float(mask))
                at = LinkEngine(eng.codebook, eng.terminal, params, eng.atmosphere)
                assert at.evaluate_pairs(*args).visible[p] == want


def _check_pairs_independently(eng, args, results):
    """Range, elevation and kernels of every pair from tests/independent.py's body frame
    and explicit steering-vector sums: both paths share ``body_frame`` and the kernels'
    coefficients, so their agreement alone would not see a wrong one."""
    import independent as ind

    ut, sat, vel, iu, js, up = args
    d = sat[js] - ut[iu]  # UT -> satellite
    rho = np.linalg.norm(d, axis=1)
    ups = _unit(ut) if up is None else up
    u = ind.body_cosines(sat[js], vel[js], ut[iu])  # (m, 2)
    for links in results:
        np.testing.assert_allclose(links.slant_range_m, rho, rtol=1e-14)
        np.testing.assert_allclose(np.sin(links.elevation_rad),
                                   np.einsum("pk,pk->p", d, ups[iu]) / rho, 0, 1e-14)  # fmt: skip
        lattice = ((eng.beam_ux, eng.codebook.n_sub_x), (eng.beam_uy, eng.codebook.n_sub_y))
        for axis, (beams, n) in enumerate(lattice):
            phase = np.pi * np.multiply.outer(u[None, :, axis] - beams[:, None], np.arange(n))
            explicit = np.abs(np.exp(1j * phase).sum(axis=-1)) ** 2 / n
            kernels = (links.kx, links.ky)[axis]
            np.testing.assert_allclose(kernels, explicit, rtol=1e-9, atol=1e-12 * n)


#: The compiled screening loop and the numpy matrix products round differently: far below
#: the bound's own slack (screening.BOUND_SLACK = 1e-6) and the visibility band (1e-9).
SCREEN_REL = 1e-12


@pytest.mark.parametrize("wgs84_up", [False, True])
def test_compiled_screening_agrees_with_numpy(wgs84_up, monkeypatch):
    """``screening.screen`` by the compiled loop and by the numpy code: the same classes,
    bounds within SCREEN_REL, for satellites above, near and below the mask."""
    import leolink.compiled
    from leolink.engine.screening import screen
    from leolink.geometry import body_frame

    eng = _engine()
    ut = _sphere_points(200)
    up = _unit(ut + 2e5 * RNG.normal(size=ut.shape)) if wgs84_up else None
    sat = 1.1 * _sphere_points(60)
    axes = body_frame(sat, np.cross(sat, [0, 0, 1.0]))
    got = screen(eng, ut, sat, axes, up)
    monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    want = screen(eng, ut, sat, axes, up)
    np.testing.assert_array_equal(got[0], want[0])
    assert 50 < (want[0] > 0).sum() < want[0].size  # above and below the mask
    np.testing.assert_allclose(got[1], want[1], rtol=SCREEN_REL, atol=0)


@pytest.mark.parametrize("loops", [True, False])
def test_ragged_screening_is_the_dense_screening_of_each_pair(loops, monkeypatch):
    """``screening.screen_ragged``: UT ``i`` against its group's satellites only (a group
    without any among them), flat from ``start[i]``, by the compiled loop or by numpy per
    group; each entry is the dense numpy screening's (every UT with every satellite) at
    that UT and satellite."""
    import leolink.compiled
    from leolink.engine.screening import screen, screen_ragged
    from leolink.geometry import body_frame
    from leolink.sim.candidates.tiles import Caps

    eng = _engine()
    ut = _sphere_points(40)
    sat = 1.1 * _sphere_points(12)
    axes = body_frame(sat, np.cross(sat, [0, 0, 1.0]))
    caps = Caps(np.array([0, 3, 5, 7, *range(12)]), np.array([0, 4, 4, 16]),
                RNG.integers(0, 3, len(ut)))  # fmt: skip
    assert set(caps.group) == {0, 1, 2}
    if not loops:
        monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    assert leolink.compiled.use(1) == loops
    code, bound, start = screen_ragged(eng, ut, sat, axes, caps)
    monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    want = screen(eng, ut, sat, axes)
    np.testing.assert_array_equal(np.diff(start), np.array([4, 0, 12])[caps.group])
    u, s = caps.pairs(start, np.arange(start[-1]))
    np.testing.assert_array_equal(code, want[0][u, s])
    assert 0 < (code > 0).sum() < code.size  # above and below the mask
    np.testing.assert_allclose(bound, want[1][u, s], rtol=SCREEN_REL, atol=0)


#: The compiled serving loop and the numpy columns round differently (sums of three
#: products in another order, a logarithm of a product for a sum of logarithms).
SERVE_REL = 1e-12


@pytest.mark.parametrize(("enu", "lit"), [(False, False), (True, False), (False, True)])
def test_compiled_serving_columns_agree_with_numpy(enu, lit, monkeypatch):
    """``LinkEngine.serve_pairs`` by the compiled loop (engine._serve_rows) and by numpy (as
    ``LEOLINK_JIT=0``): every column, moving and accelerating UTs, fading and other
    satellites' interference, unserved rows (NaN), the sphere's frame and given ENU rows
    (turned 20 deg about the up: not the sphere's). With lit beams (the loop sums every
    beam): the numpy columns whatever the switch."""
    import leolink.compiled
    from leolink.geometry import ecef_to_geodetic, enu_basis

    eng = _engine()
    ut = R * _unit([0.0, 0.0, 1.0] + 0.03 * RNG.normal(size=(200, 3)))  # under 4 satellites
    sat = 1.1 * R * _unit([0.0, 0.0, 1.0] + 0.03 * RNG.normal(size=(4, 3)))
    iu, js = np.meshgrid(np.arange(200), np.arange(4), indexing="ij")
    links = eng.evaluate_pairs(ut, sat, np.cross(sat, [0, 0, 1.0]), iu.ravel(), js.ravel())
    n = 300
    pair = np.where(RNG.random(n) < 0.1, -1, RNG.integers(0, links.n_pair, n))
    beam = RNG.integers(0, eng.n_beam, n)
    ut_pos = ut[links.ut[np.maximum(pair, 0)]]
    lat, lon, _ = ecef_to_geodetic(ut_pos)
    frame = enu_basis(lat, lon)
    c, s = np.cos(np.radians(20.0)), np.sin(np.radians(20.0))
    frame[:, 0], frame[:, 1] = c * frame[:, 0] + s * frame[:, 1], c * frame[:, 1] - s * frame[:, 0]
    kw = dict(rx_fading_lin=RNG.uniform(0.5, 2.0, n), i_other=RNG.uniform(0.0, 0.1, n),
              ut_pos_m=ut_pos, ut_enu=frame if enu else None)  # fmt: skip
    if lit:  # half the beams, the serving one among them
        kw["lit"] = RNG.random((n, eng.n_beam)) < 0.5
        kw["lit"][np.arange(n), beam] = True
    args = (links, pair, beam, RNG.normal(size=(n, 3)) * 30.0, RNG.normal(size=(n, 3)),
            RNG.normal(size=(n, 3)) * 7e3, RNG.normal(size=(n, 3)) * 8.0)  # fmt: skip
    got = eng.serve_pairs(*args, **kw)
    monkeypatch.setattr(leolink.compiled, "use", lambda size: False)
    want = eng.serve_pairs(*args, **kw)
    assert list(got) == list(want)
    assert (pair < 0).sum() > 3 and np.isfinite(want["snr_db"]).sum() > 100
    for name in want:
        np.testing.assert_allclose(got[name], want[name], SERVE_REL, 1e-9, err_msg=name)
