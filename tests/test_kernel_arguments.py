"""The compiled kernels refuse arguments that do not fit, rather than reading or writing
outside a buffer (``src/leolink/_kernels.c``: REQUIRE, INDICES, ROWS).

Each case makes a call as leolink makes it (a real epoch of ``configs/paper.toml``, the
wrappers' own arrays), checks that it runs, then spoils one thing a caller could get
wrong: an index one past its array or negative, an array one short, a row range past the
end. The spoiled call must raise ValueError naming what does not fit. Without the check
the kernel reads one element past a buffer, which need not crash: only the exception
shows it.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("leolink._kernels")  # (built at install: setup.py)

from leolink import _kernels, visibility_kernel  # noqa: E402
from leolink.app.scenario import build_scenario  # noqa: E402
from leolink.config import load_config  # noqa: E402
from leolink.engine import jit  # noqa: E402
from leolink.geometry import body_frame  # noqa: E402
from leolink.sim.candidates import table_kernels  # noqa: E402
from leolink.sim.candidates.table import Candidates  # noqa: E402
from leolink.sim.handover.controller import ControllerState  # noqa: E402
from leolink.sim.handover.policies import MaxSnr  # noqa: E402
from leolink.sim.handover.step_kernel import compiled_step  # noqa: E402
from leolink.sim.mobility.models import concat_states  # noqa: E402


@pytest.fixture(scope="module")
def epoch():
    """The paper's pass at t = 30 s: engine, UT states, satellite states, and every UT
    paired with the satellite, evaluated."""
    scen = build_scenario(load_config("configs/paper.toml"))
    pos, vel, acc = (a[0] for a in scen.ephemeris(np.array([30.0])))
    uts = concat_states([p.state(30.0) for _, p in scen.populations])
    ut = np.arange(uts.n_ut, dtype=np.int64)
    sat = np.zeros(uts.n_ut, np.int64)
    links = scen.engine.evaluate_pairs(uts.pos_m, pos, vel, ut, sat)
    assert links.visible.all()  # the paper's UTs see the satellite: real links
    return scen.engine, uts, pos, vel, acc, ut, sat, links


def _spoiled(a, at, value):
    a = np.array(a, copy=True)
    a[at] = value
    return a


def _links(epoch, spoil):
    eng, uts, pos, vel, _, ut, sat, _ = epoch
    ut, sat = spoil(ut, sat)
    return jit.links_arrays(eng, uts.pos_m, pos, body_frame(pos, vel), ut, sat, None)


def _snr(epoch, spoil):
    eng, *_, links = epoch
    ix, iy = spoil(eng.beam_ix, eng.beam_iy)
    return jit.snr_db_bm(links.kx, links.ky, links.path_snr_lin, ix, iy)


def _best(epoch, spoil):
    eng, *_, links = epoch
    ix, iy = spoil(eng.beam_ix, eng.beam_iy)
    return jit.best_beam(links, ix, iy, True)


def _serve(epoch, spoil):
    eng, uts, pos, vel, acc, ut, sat, links = epoch
    n = links.n_pair
    pair, beam = spoil(np.arange(n, dtype=np.int64), np.arange(n, dtype=np.int64))
    rows = {"fading": np.ones(n), "i_other": np.zeros(n), "ut_vel": uts.vel_m_s[ut],
            "ut_acc": uts.acc_m_s2[ut], "sat_vel": vel[sat], "sat_acc": acc[sat],
            "ut_pos": uts.pos_m[ut], "enu": None}  # fmt: skip
    rows = {k: v if v is None else np.ascontiguousarray(v) for k, v in rows.items()}
    rx, atm = np.zeros(n), np.zeros(n)
    return jit.serve_columns(eng, links, pair, np.ones(n, bool), beam, rows, rx, atm)


def _elevations(epoch, t0):
    _, uts, pos, *_ = epoch
    r = np.ascontiguousarray(pos.T)  # one satellite, one time
    normal = uts.pos_m / np.linalg.norm(uts.pos_m, axis=1, keepdims=True)
    out = np.empty((uts.n_ut, 1, 2))
    visibility_kernel.elevations(r, uts.pos_m, normal, out, t0, 0, uts.n_ut)
    return out


def _step(n_state):
    table = Candidates.dense(np.array([[10.0, 12.0], [9.0, 3.0], [np.nan, 5.0]]))
    state = ControllerState.initial(n_state)
    target = np.array([1, 0, 1])
    return compiled_step(0.0, table, state, MaxSnr(), target, 0.0, 0.0, 2)


def _window(n_best):
    snr_bm = np.array([[3.0, 9.0, 1.0], [4.0, 2.0, 8.0]])  # (n_beam, m)
    rows, sat = np.array([0, 0, 1]), np.array([4, 7, 4])
    return table_kernels.window_entries(snr_bm, rows, sat, 2, 3.0, np.empty(n_best))


def _db_stats(ut):
    values, count, total = np.array([1.0, 2.0, np.nan]), np.zeros(3, np.int64), np.zeros(3)
    pooled, keys = np.zeros(12, np.int64), np.empty(3, np.int64)
    bins = (0.0, 1.0, 10.0, 10)
    return _kernels.db_stats_add(ut, values, count, total, pooled, *bins, *bins, keys)


def _values_at(slot):
    out = np.empty(2)
    table_kernels.values_at(np.array([[1.0, 2.0], [3.0, 4.0]]), slot, out)
    return out


def _swap(i, value):
    """A spoiler of the first (i = 0) or second (i = 1) index array at its last entry."""

    def spoil(a, b):
        pair = [a, b]
        pair[i] = _spoiled(pair[i], -1, value)
        return pair

    return spoil


def _same(a, b):
    return a, b


N_UT = 7  # the paper config's UT count

CASES = {
    "links: a satellite one past the last": (_links, _same, _swap(1, 1), "sat[6] = 1 is outside"),
    "links: a negative UT": (_links, _same, _swap(0, -1), "ut[6] = -1 is outside"),
    "snr: an x beam past the kernels": (_snr, _same, _swap(0, 5), "ix[14] = 5 is outside"),
    "best beam: a y beam past the kernels": (_best, _same, _swap(1, 3), "iy[14] = 3 is outside"),
    "serve: a pair past the links": (_serve, _same, _swap(0, N_UT), "pair[6] = 7 is outside"),
    "serve: a beam past the codebook": (_serve, _same, _swap(1, 15), "beam[6] = 15 is outside"),
    "elevations: a time past the output": (_elevations, 1, 2, "t0 + n_t <= out.n[2]"),
    "step: a state one UT short": (_step, 3, 2, "a[q].n[0] == n"),
    "window: rows past the best": (_window, 2, 1, "rows[2] = 1 is outside"),
    "db stats: a UT past the counts": (_db_stats, np.array([0, 2, 1]), np.array([0, 3, 1]),
                                       "ut[1] = 3 is outside"),
    "values at: a slot past the row": (_values_at, np.array([1, -1]), np.array([1, 2]),
                                       "< snr.n[1]"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(CASES))
def test_a_spoiled_argument_raises(epoch, case):
    call, good, bad, message = CASES[case]
    run = (lambda arg: call(epoch, arg)) if call in (_links, _snr, _best, _serve, _elevations) \
        else call  # fmt: skip
    run(good)
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("+", r"\+")):
        run(bad)


@pytest.mark.parametrize("lo, hi", [(0, N_UT + 1), (-1, 2), (2, 1)])
def test_rows_outside_the_arrays_raise(epoch, lo, hi):
    eng, *_, links = epoch
    out = np.empty((eng.n_beam, links.n_pair))
    args = (links.kx, links.ky, links.path_snr_lin, eng.beam_ix, eng.beam_iy, out)
    _kernels.snr_kernel(*args, 0, links.n_pair)
    with pytest.raises(ValueError, match=r"snr_kernel: the arguments must satisfy 0 <= \(lo\)"):
        _kernels.snr_kernel(*args, lo, hi)


def test_shapes_that_disagree_raise(epoch):
    """An output one column short of the pairs, and a Dirichlet output one beam short."""
    eng, *_, links = epoch
    short = np.empty((eng.n_beam, links.n_pair - 1))
    with pytest.raises(ValueError, match=r"out\.n\[1\] >= hi"):
        _kernels.snr_kernel(links.kx, links.ky, links.path_snr_lin, eng.beam_ix, eng.beam_iy,
                            short, 0, links.n_pair)  # fmt: skip
    u = np.array([0.1, -0.2])
    beam_u = np.array([-0.5, 0.0, 0.5])
    from leolink.antenna.array import dirichlet_kernels

    good = dirichlet_kernels(u, beam_u, 8, compiled=True)
    assert good.shape == (3, 2) and np.isfinite(good).all()
    from leolink.antenna.array import dirichlet_coefficients, dirichlet_trig

    trig, coef = dirichlet_trig(u, 8), dirichlet_coefficients(beam_u, 8)
    with pytest.raises(ValueError, match=r"out\.n\[0\] == beam_u\.n\[0\]"):
        _kernels.dirichlet_kernels(u, trig, beam_u, coef, 8.0, 1e-6, 1e-12, np.empty((2, 2)))
