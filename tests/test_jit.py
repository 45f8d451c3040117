"""The compiled kernels (engine/kernels.py) against the numpy reference, bit for bit.

The kernels repeat the numpy code's operations in the same order (engine/kernels.py
docstring), so every value must be identical, not close, wherever numpy's transcendental
loops are the C library's (on AVX-512 CPUs numpy takes some from SVML: then within a few
ulp, tests/platform_math.py): the inputs are a real constellation epoch (4,399
satellites, the config's 1,000 UTs) and the pairs include satellites below the horizon,
beam peaks and the other degenerate cases a run meets.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("leolink._kernels")  # (built at install: setup.py)

from leolink import compiled  # noqa: E402
from leolink.antenna.panel import oriented_panel_basis  # noqa: E402
from leolink.antenna.terminal import UPATerminal  # noqa: E402
from leolink.app.scenario import build_scenario  # noqa: E402
from leolink.config import load_config  # noqa: E402
from leolink.engine import SERVE_COLUMNS, SERVE_GEOMETRY_COLUMNS, LinkEngine, jit  # noqa: E402
from leolink.engine.links import pair_geometry  # noqa: E402
from leolink.geometry import body_frame, ecef_to_geodetic, enu_basis  # noqa: E402
from leolink.sim.mobility.models import concat_states  # noqa: E402
from platform_math import ATOL_ANGLE_DB, NUMPY_IS_LIBM, close, same  # noqa: E402

CONSTELLATION = "configs/constellation.toml"
COLUMNS = SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS
_N_THREADS = compiled.n_threads


@pytest.fixture(scope="module")
def epoch():
    """Engine, UT states, satellite states of the constellation at t = 30 s, and pairs:
    every UT with 40 random satellites (most below the horizon) and with the satellite
    nearest its zenith (the links a run serves)."""
    scen = build_scenario(load_config(CONSTELLATION))
    pos, vel, acc = (a[0] for a in scen.ephemeris(np.array([30.0])))
    uts = concat_states([p.state(30.0) for _, p in scen.populations])
    rng = np.random.default_rng(13)
    n_ut = uts.n_ut
    up = uts.pos_m / np.linalg.norm(uts.pos_m, axis=1, keepdims=True)
    zenith = np.argmax(up @ (pos / np.linalg.norm(pos, axis=1, keepdims=True)).T, axis=1)
    ut = np.concatenate([np.repeat(np.arange(n_ut), 40), np.arange(n_ut)])
    sat = np.concatenate([rng.integers(0, len(pos), 40 * n_ut), zenith])
    return scen.engine, uts, pos, vel, acc, ut, sat, rng


@pytest.fixture(params=[None, 3], ids=["threads", "split3"], autouse=True)
def split(request, monkeypatch):
    """Each test as the machine runs it, and with every large call split over 3 threads
    into uneven shares (a row is one thread's: the bits must not change)."""
    if request.param is not None:
        monkeypatch.setattr(compiled, "n_threads", lambda: request.param)
        monkeypatch.setattr(compiled, "SPLIT_MIN_ROWS", 997)
    return request.param


def _numpy(monkeypatch):
    monkeypatch.setattr(compiled, "use", lambda n: False)


def _same(a, b, angle_db=False):
    """Bit for bit where numpy's transcendental loops are the C library's; within a few
    ulp elsewhere (tests/platform_math.py), and ``ATOL_ANGLE_DB`` for values in dB,
    radians or degrees (``angle_db``)."""
    return same(a, b, ATOL_ANGLE_DB if angle_db else 0.0)


def _same_beam(beam, ref, snr_db):
    """Beam choices: equal; where numpy's loops are not the C library's, a choice may differ
    only between beams whose SNRs (``snr_db``, (n_beam, m)) are within the tolerance (a
    near tie, decided by the last bits)."""
    if NUMPY_IS_LIBM:
        return _same(beam, ref)
    cols = np.arange(beam.size)
    return beam.shape == ref.shape and bool(
        close(snr_db[beam, cols], snr_db[ref, cols], atol=ATOL_ANGLE_DB).all()
    )


def _same_column(name, a, b):
    return _same(a, b, angle_db=name.endswith(("_db", "_rad", "_deg", "_db_s")))


@pytest.mark.parametrize("ellipsoid_up", [False, True])
def test_pair_geometry_and_kernels_are_the_numpy_bits(epoch, ellipsoid_up):
    eng, uts, pos, vel, _, ut, sat, _ = epoch
    up = enu_basis(uts.lat_rad, uts.lon_rad)[:, 2, :] if ellipsoid_up else None
    ref = pair_geometry(eng, uts.pos_m, pos, vel, ut, sat, up)
    got = jit.links_arrays(eng, uts.pos_m, pos, body_frame(pos, vel), ut, sat, up)
    names = ("rel", "rho2", "rho", "elevation", "visible", "kx", "ky")
    differ = [n for n, a, b in zip(names, ref, got, strict=True)
              if not _same(a, b, angle_db=n == "elevation")]  # fmt: skip
    assert differ == []
    assert got[4].sum() > 900  # the zenith pairs are visible: the test sees real links


def _turned(enu, tilt_rad=math.pi / 180, turn_rad=math.pi / 9):
    """Local frames whose up is tilted ``tilt_rad`` about east and whose east is then turned
    ``turn_rad`` about that up (rows east, north, up): not the sphere's frame."""

    def rot(v, axis, a):  # Rodrigues, per row
        dot = np.sum(v * axis, axis=-1, keepdims=True)
        return v * np.cos(a) + np.cross(axis, v) * np.sin(a) + axis * dot * (1 - np.cos(a))

    e, n, u = enu[:, 0], enu[:, 1], enu[:, 2]
    n, u = rot(n, e, tilt_rad), rot(u, e, tilt_rad)
    return np.stack([rot(e, u, turn_rad), rot(n, u, turn_rad), u], axis=1)


@pytest.mark.parametrize("given_up", [False, True])
def test_evaluate_pairs_and_snr_db_are_the_numpy_bits(epoch, monkeypatch, given_up):
    """With the sphere's up, and with a given up 1 deg off it (the fused geometry must use
    it: elevations and visibility differ)."""
    eng, uts, pos, vel, _, ut, sat, _ = epoch
    assert compiled.use(ut.size)
    up = _turned(enu_basis(uts.lat_rad, uts.lon_rad))[:, 2] if given_up else None
    links = eng.evaluate_pairs(uts.pos_m, pos, vel, ut, sat, up)
    snr = links.snr_db_bm(eng.beam_ix, eng.beam_iy)
    _numpy(monkeypatch)
    ref = eng.evaluate_pairs(uts.pos_m, pos, vel, ut, sat, up)
    assert _same(links.elevation_rad, ref.elevation_rad, angle_db=True)
    assert _same(links.path_lin, ref.path_lin) and _same(links.kx, ref.kx)
    assert _same(snr, ref.snr_db_bm(eng.beam_ix, eng.beam_iy), angle_db=True)
    assert np.isfinite(snr).sum() > 15 * 900


def _edge_links(links, rng):
    """``links`` (a real epoch's pairs) with the cases the best-beam kernel must decide as
    ``numpy.argmax`` does, each on its own visible pairs: exact ties of the best beams
    (along x, and all 15), near ties (the best x kernel 1 to 4 ulps apart: the dB values
    may tie where the linear ones do not), a NaN kernel, all-zero kernels (-inf dB),
    subnormal kernels, paths outside the kernel's quick range (1e-180, 1e180, 0, inf),
    linear SNRs one subnormal step apart whose dB values are equal (the quick rule would
    take the larger linear one, numpy the first)."""
    kx, ky, path = links.kx.copy(), links.ky.copy(), links.path_lin.copy()
    vis = rng.permutation(np.flatnonzero(links.visible))
    cases = np.array_split(vis[: 13 * (vis.size // 14)], 13)
    kx[:, cases[0]] = kx[:, cases[0]].max(axis=0)  # ties along x
    kx[:, cases[1]] = kx[:, cases[1]].max(axis=0)  # ties of all 15
    ky[:, cases[1]] = ky[:, cases[1]].max(axis=0)
    top = kx[:, cases[2]].max(axis=0)
    for a in range(kx.shape[0]):  # near ties: a few ulps either side of the best
        kx[a, cases[2]] = top + rng.integers(-4, 5, top.size) * np.spacing(top)
    kx[3, cases[3]] = np.nan
    kx[:, cases[4]] = 0.0
    kx[1:, cases[5]] = 1e-310 * rng.random((kx.shape[0] - 1, cases[5].size))
    for c, f in zip(cases[6:10], (1e-180, 1e180, 0.0, np.inf), strict=True):
        path[c] *= f
    ky[:, cases[10]] = 0.0  # with an infinite path: 0 x inf, NaN in every beam
    path[cases[10]] = np.inf
    kx[:, cases[11]] = kx[:, cases[11]].max(axis=0) * (1.0 + 1e-10 * rng.random(5)[:, None])
    c = cases[12]  # x kernels 0 and 1 one ulp apart (the same dB values: the first wins),
    top = 1e-12 * kx[:, c].max(axis=0)  # linear SNRs one subnormal step apart (~1e-317)
    kx[0, c], kx[1, c], kx[2:, c] = top, np.nextafter(top, np.inf), 0.5 * top
    g0, g1 = (top * ky[:, c].max(axis=0), kx[1, c] * ky[:, c].max(axis=0))
    q = (2e6 + 0.5) / g1 * 2.0**-1074  # g1 q half way between two subnormals
    for _ in range(8):
        q = np.nextafter(q, 0.0)
    split = np.full(c.size, np.nan)
    for _ in range(17):  # the path, within 8 ulps, that rounds g0 q and g1 q apart
        hit = np.isnan(split) & (g1 * q > g0 * q)
        split[hit] = q[hit]
        q = np.nextafter(q, np.inf)
    assert np.isfinite(split).sum() > c.size // 2
    path[c] = np.where(np.isnan(split), q, split)
    return dataclasses.replace(links, kx=kx, ky=ky, path_lin=path)


@pytest.mark.parametrize("edges", [False, True], ids=["real", "edges"])
def test_best_beam_is_numpys_argmax(epoch, monkeypatch, edges):
    """``Links.best_beam`` compiled against ``numpy.argmax`` of the dB matrix (the numpy
    path), every pair (most are below the horizon: NaN rows), beam and value; with the
    ties and degenerate values of :func:`_edge_links`."""
    eng, uts, pos, vel, _, ut, sat, rng = epoch
    links = eng.evaluate_pairs(uts.pos_m, pos, vel, ut, sat)
    if edges:
        links = _edge_links(links, rng)
    got = links.best_beam(eng.beam_ix, eng.beam_iy, with_snr_db=True)
    alone, none = links.best_beam(eng.beam_ix, eng.beam_iy)
    with np.errstate(invalid="ignore"):  # -inf + inf: the NaN cases
        snr = links.snr_db_bm(eng.beam_ix, eng.beam_iy)
        _numpy(monkeypatch)
        beam, val = dataclasses.replace(links).best_beam(eng.beam_ix, eng.beam_iy, True)
        ref_alone = dataclasses.replace(links).best_beam(eng.beam_ix, eng.beam_iy)
    assert _same_beam(got[0], beam, snr) and _same(got[1], val, angle_db=True)
    assert _same_beam(alone, beam, snr)
    assert none is None and ref_alone[1] is None and _same(ref_alone[0], beam)
    ref = np.argmax(snr, axis=0)  # the definition, on the compiled matrix as well
    assert _same_beam(beam, ref, snr)
    assert _same(val, snr[ref, np.arange(ref.size)], angle_db=True)
    vis = links.visible
    assert (beam[~vis] == 0).all() and np.isnan(val[~vis]).all() and vis.sum() > 900
    if edges:  # the cases are there: ties resolved to a beam other than the linear argmax
        lin = np.argmax(links.gain_tx_bm(eng.beam_ix, eng.beam_iy), axis=0)
        assert np.isnan(val[vis]).sum() > 50 and (np.isneginf(val[vis])).sum() > 50
        assert (lin[vis] != beam[vis]).sum() > 0


@pytest.mark.parametrize("extras", [False, True, "lit"])
def test_serving_columns_are_the_numpy_bits(epoch, monkeypatch, extras):
    """Every serving column, with and without fading, other-satellite interference and
    given local frames (turned 20 deg from the sphere's: the azimuth must use them), and
    with lit beams (active beams: the numpy path, which the fused kernel must not take);
    rows without a link (pair -1) are NaN in both."""
    eng, uts, pos, vel, acc, ut, sat, rng = epoch
    links = eng.evaluate_pairs(uts.pos_m, pos, vel, ut, sat)
    n = 30_000
    pair = rng.integers(-1, links.n_pair, n)
    beam = rng.integers(0, eng.n_beam, n)
    p = np.maximum(pair, 0)
    args = (uts.vel_m_s[ut[p]], uts.acc_m_s2[ut[p]], vel[sat[p]], acc[sat[p]])
    kw = {"ut_pos_m": uts.pos_m[ut[p]]}
    if extras:
        lat, lon, _ = ecef_to_geodetic(kw["ut_pos_m"])
        kw.update(rx_fading_lin=rng.uniform(0.2, 1.5, n), i_other=rng.uniform(0.0, 0.3, n),
                  ut_enu=_turned(enu_basis(lat, lon)))  # fmt: skip
    if extras == "lit":
        kw["lit"] = rng.random((n, eng.n_beam)) < 0.5
        kw["lit"][np.arange(n), beam] = True  # the serving beam is lit (as a run has it)
    got = eng.serve_pairs(links, pair, beam, *args, **kw)
    _numpy(monkeypatch)
    ref = eng.serve_pairs(links, pair, beam, *args, **kw)
    assert [c for c in COLUMNS if not _same_column(c, got[c], ref[c])] == []
    assert np.isfinite(got["snr_db"]).sum() > 100 and np.isnan(got["snr_db"][pair < 0]).all()


def test_turned_off_by_the_environment(monkeypatch):
    monkeypatch.setenv("LEOLINK_JIT", "0")
    jit.enabled.cache_clear()
    try:
        assert not compiled.use(10**9)
    finally:
        monkeypatch.delenv("LEOLINK_JIT")
        jit.enabled.cache_clear()
    assert compiled.use(10**9)


def test_every_non_empty_call_takes_the_kernels():
    """No size threshold: the extension loads in a millisecond, so a one-pair call (a link
    budget) takes the kernels as a run's calls do, and a run's bits do not depend on how
    its work is cut into calls."""
    assert compiled.use(1) and not compiled.use(0)


def test_the_switch_reaches_every_layer(monkeypatch):
    """``leolink.compiled.use``, replaced (as the tests' numpy path does, as LEOLINK_JIT=0),
    turns off the kernels below the engine too: the codebook's Dirichlet kernels, the
    visibility loop, the summary's histograms and dB statistics."""
    from sgp4.api import Satrec, jday

    from leolink import _kernels, visibility_kernel
    from leolink.antenna.array import dirichlet_kernels
    from leolink.io.summary.stats import DbStats
    from leolink.sim.histograms import PercentileHistogram
    from leolink.visibility import tle_elevations_rad

    def called(*args):
        raise AssertionError("a kernel ran with the kernels off")

    monkeypatch.setattr(compiled, "use", lambda n: False)
    for name in ("dirichlet_kernels", "histogram_slots", "db_stats_add"):
        monkeypatch.setattr(_kernels, name, called)
    monkeypatch.setattr(visibility_kernel, "elevations", called)
    u = np.linspace(-0.1, 0.1, 7)
    assert dirichlet_kernels(u, np.array([-0.05, 0.0, 0.05]), 8, compiled=True).shape == (3, 7)
    iss = Satrec.twoline2rv(
        "1 25544U 98067A   19343.69339541  .00001764  00000-0  38792-4 0  9991",
        "2 25544  51.6439 211.2001 0007417  17.6667  85.6398 15.50103472202482",
    )
    jd, fr = jday(2019, 12, 9, 16, 30, 0.0)
    assert tle_elevations_rad([iss], [0.1], [0.2], 0.0, [jd], [fr]).shape == (1, 1, 1)
    assert PercentileHistogram(-10.0, 10.0, 0.5).slots(np.array([1.0, np.nan])).size == 2
    DbStats(2).add(np.array([0, 1]), np.array([3.0, 4.0]))


def test_tilted_panel_gains_are_the_numpy_bits(epoch, monkeypatch):
    """A scan-loss terminal on tilted panels takes the angle above the panel plane: the
    compiled geometry gives the numpy bits of it (and the tilt changes the gains)."""
    eng, uts, pos, vel, _, ut, sat, rng = epoch
    scan = LinkEngine(eng.codebook, UPATerminal(24, 24, 10.0, scan_loss=True), eng.params,
                      eng.atmosphere, eng.colors)  # fmt: skip
    enu = enu_basis(uts.lat_rad, uts.lon_rad)
    n_ut = len(uts.pos_m)
    normal = oriented_panel_basis(
        enu, rng.uniform(0.0, 1.0, n_ut), rng.uniform(0.0, 2 * np.pi, n_ut)
    )[:, 2, :]
    got = scan.evaluate_pairs(uts.pos_m, pos, vel, ut, sat, ut_normal=normal)
    flat = scan.evaluate_pairs(uts.pos_m, pos, vel, ut, sat)
    _numpy(monkeypatch)
    ref = scan.evaluate_pairs(uts.pos_m, pos, vel, ut, sat, ut_normal=normal)
    assert _same(got.rx_db, ref.rx_db) and _same(got.path_lin, ref.path_lin)
    vis = got.visible
    assert np.abs(got.rx_db[vis] - flat.rx_db[vis]).max() > 1.0


def test_screening_kernel_agrees_with_numpy_on_every_row(epoch, monkeypatch):
    """The compiled screening (split over threads by UT rows) against the numpy one: the
    same codes away from the band edges and the same bounds to rounding (it may round
    differently, jit.py; an unfilled row would hold garbage)."""
    from leolink.engine import screening

    eng, uts, pos, vel, *_ = epoch
    axes = body_frame(pos, vel)
    assert compiled.use(uts.n_ut * len(pos))
    got = screening.screen(eng, uts.pos_m, pos, axes)
    _numpy(monkeypatch)
    ref = screening.screen(eng, uts.pos_m, pos, axes)
    assert (got[0] == ref[0]).mean() > 1 - 1e-6 and (got[0] > 0).sum() > 1000
    both = (got[0] > 0) & (ref[0] > 0)
    np.testing.assert_allclose(got[1][both], ref[1][both], rtol=1e-9)
    assert (got[1][got[0] == 0] == -1.0).all()


def test_thread_count_from_the_environment(monkeypatch):
    from leolink.errors import ConfigError

    n_threads = _N_THREADS  # the real one (the split fixture replaces compiled.n_threads)

    try:
        for value, expected in (("3", 3), (" 1 ", 1)):
            monkeypatch.setenv("LEOLINK_THREADS", value)
            n_threads.cache_clear()
            assert n_threads() == expected
        for bad in ("0", "two", "-2"):
            monkeypatch.setenv("LEOLINK_THREADS", bad)
            n_threads.cache_clear()
            with pytest.raises(ConfigError, match=f"LEOLINK_THREADS = '{bad}' is not allowed"):
                n_threads()
    finally:
        monkeypatch.delenv("LEOLINK_THREADS")
        n_threads.cache_clear()


def test_a_large_runs_bits_do_not_depend_on_its_motion_blocks(monkeypatch):
    """Every non-empty call takes the kernels (``leolink.compiled.use``): 10 UTs of the paper's
    constellation for 200 s in blocks of 105 epochs (its own) or of 64 give the same
    trace, bit for bit. With a threshold of 1,000 pairs (numba's, once) the monitor's calls
    of 640 rows took numpy and those of 1,050 the kernels: on an AVX-512 CPU 14 columns
    differed, by up to 1.4e-14 dB."""
    from leolink.app.run import run
    from leolink.sim import motion

    cfg = load_config(CONSTELLATION, ["population.0.count=10", "run.duration_s=200",
                                      "output.plots.enabled=false"])  # fmt: skip
    cfg = cfg.model_copy(update={"population": cfg.population[:1]})
    own = run(cfg).trace
    monkeypatch.setattr(motion, "MAX_BLOCK_EPOCHS", 64)
    cut = run(cfg).trace
    assert len(own) == 10 * 200 and own.snr_db.notna().sum() > 1000
    assert "leolink.engine.kernels" in sys.modules or not jit.enabled()
    pd.testing.assert_frame_equal(own, cut, check_exact=True)


def test_without_the_extension_a_run_takes_numpy_and_writes_the_same_trace(tmp_path):
    """Where leolink was installed without a C compiler (setup.py: the extension is
    optional) the import of ``leolink._kernels`` fails: a run then takes the numpy path
    everywhere and writes the trace the kernels write (within tests/platform_math.py)."""
    import json
    import subprocess

    sets = ["run.duration_s=20", "population.1.count=17", 'population.1.placement="random"',
            "population.1.x_m=[]", "population.1.y_m=[]"]  # fmt: skip
    code = (
        "import sys, json; {block}"
        "import leolink.app.run, leolink.compiled; "
        "from leolink.config import load_config; "
        f"res = leolink.app.run.run(load_config('configs/paper.toml', {sets!r})); "
        "res.trace.to_parquet(sys.argv[1]); "
        "print(json.dumps([leolink.compiled.enabled(), 'leolink.engine.kernels' in sys.modules]))"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("LEOLINK_JIT",)}
    seen, traces = [], []
    for block in ("sys.modules['leolink._kernels'] = None; ", ""):
        path = tmp_path / f"{len(traces)}.parquet"
        done = subprocess.run([sys.executable, "-c", code.format(block=block), str(path)],
                              capture_output=True, text=True, check=True, env=env)  # fmt: skip
        seen.append(json.loads(done.stdout))
        traces.append(pd.read_parquet(path))
    assert seen == [[False, False], [True, True]]
    plain, fused = traces
    assert len(plain) == 20 * 20 and plain.snr_db.notna().sum() > 300
    assert list(plain.columns) == list(fused.columns)
    for c in plain.columns:
        if plain[c].dtype.kind == "f":
            assert _same_column(c, plain[c].to_numpy(), fused[c].to_numpy()), c
        else:
            assert plain[c].equals(fused[c]), c
