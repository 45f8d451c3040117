"""Compiled kernels (``leolink._kernels``, C), optional: the same numbers as the numpy
code they replace.

Every non-empty call takes the kernels when the extension is built (it loads in about a
millisecond: no start-up to repay) and ``LEOLINK_JIT`` is not 0 in the environment; else
the numpy code runs everywhere (:func:`leolink.compiled.use`, the switch of every layer).
So a run's bits do not depend on how its work is cut into calls.

The kernels (:mod:`leolink.engine.kernels`) repeat the numpy code's operations one for
one: a pair gets the same bits from either where numpy's transcendental loops are the C
library's (x86-64 without AVX-512; with AVX-512, a few ulp: :mod:`leolink.engine.kernels`,
``tests/test_jit.py``). The screening kernel
is the exception: it decides which pairs the engine evaluates, never a value that reaches
an output, so it may (and does) round differently; both of its bounds are rigorous.
"""

from __future__ import annotations

import functools

import numpy as np

from leolink.compiled import SPLIT_MIN_ROWS, enabled, n_threads, run_rows

__all__ = ["best_beam", "enabled", "links_arrays", "n_threads", "run_rows"]
__all__ += ["screen_ragged_kernel", "serve_columns", "serve_pairs", "serving_column"]
__all__ += ["SPLIT_MIN_ROWS", "find_pairs"]


def kernels():
    """The compiled kernels (:mod:`leolink.engine.kernels`)."""
    from leolink.engine import kernels as k

    return k


def links_arrays(engine, ut_pos_m, sat_pos_m, axes, ut, sat, ut_up):
    """The geometry and kernels of ``LinkEngine.evaluate_pairs`` by :func:`links_kernel`:
    rel, rho2, rho, elevation, visible, kx, ky."""
    m = ut.shape[0]
    out = (np.empty((m, 3)), np.empty(m), np.empty(m), np.empty(m), np.empty(m, bool),
           np.empty((len(engine.beam_ux), m)), np.empty((len(engine.beam_uy), m)))  # fmt: skip
    sphere = ut_up is None
    r_ut = np.sqrt(np.einsum("uk,uk->u", ut_pos_m, ut_pos_m)) if sphere else np.zeros(0)
    cx, cy = engine.kernel_coefficients
    run_rows(
        kernels().links_kernel, m, np.ascontiguousarray(ut_pos_m, float),
        np.zeros((0, 3)) if sphere else np.asarray(ut_up, float), sphere, r_ut,
        np.ascontiguousarray(sat_pos_m, float), np.ascontiguousarray(axes[:, 0, :]),
        np.ascontiguousarray(axes[:, 1, :]), np.asarray(ut, np.int64), np.asarray(sat, np.int64),
        engine.params.min_elevation_rad,
        engine.beam_ux, cx, engine.codebook.n_sub_x, engine.beam_uy, cy,
        engine.codebook.n_sub_y, *out,
    )  # fmt: skip
    return out


def snr_db_bm(kx, ky, path_snr_lin, beam_ix, beam_iy):
    """``Links.snr_db_bm`` by :func:`snr_kernel`, of the pairs' kernels and path SNR."""
    m = path_snr_lin.shape[0]
    out = np.empty((len(beam_ix), m))
    run_rows(kernels().snr_kernel, m, kx, ky, path_snr_lin, beam_ix, beam_iy, out)
    return out


def best_beam(links, beam_ix, beam_iy, with_snr_db):
    """``Links.best_beam`` by :func:`best_beam_kernel`: the beams, and their SNR [dB] or
    None."""
    m = links.n_pair
    best, best_db = np.empty(m, np.int64), np.empty(m)
    run_rows(kernels().best_beam_kernel, m, links.kx, links.ky, links.path_snr_lin, beam_ix,
             beam_iy, bool(with_snr_db), best, best_db)  # fmt: skip
    return best, (best_db if with_snr_db else None)


def serve_columns(engine, links, pair, served, b, rows, rx, atm):
    """``LinkEngine.serve_pairs`` by :func:`serve_kernel` -> (16, n) columns.

    ``rows``: dict of the rows' arrays (fading, i_other, ut_vel, ut_acc, sat_vel,
    sat_acc, ut_pos, enu or None).
    """
    n = pair.shape[0]
    out = np.empty((16, n))
    enu = rows["enu"]
    run_rows(
        kernels().serve_kernel, n, links.kx, links.ky, links.path_snr_lin, links.rel_m,
        links.slant_range_m, links.elevation_rad, pair, b, served, engine.beam_ix, engine.beam_iy,
        rows["fading"], rows["i_other"], rows["ut_vel"], rows["ut_acc"], rows["sat_vel"],
        rows["sat_acc"], rows["ut_pos"], np.zeros((0, 3, 3)) if enu is None else enu,
        enu is not None, engine.params.freq_hz / 299_792_458.0, engine.params.freq_hz,
        engine.bandwidth_hz, rx, atm, out,
    )  # fmt: skip
    return out


def serve_pairs(engine, links, pr, served, b, rows):
    """``LinkEngine.serve_pairs`` of a full lattice with one colour by :func:`serve_columns`
    (``rows``: its per-row arguments by name, None where not given)."""
    n = pr.shape[0]
    rows = {key: (None if v is None else np.ascontiguousarray(v, float)) for key, v in rows.items()}
    rows["fading"] = np.ones(n) if rows["fading"] is None else rows["fading"]
    i_other = rows["i_other"]
    rows["i_other"] = np.zeros(n) if i_other is None else np.broadcast_to(i_other, (n,))
    if rows["ut_pos"] is None:
        rows["ut_pos"] = np.zeros((n, 3))
    if engine._rx_const is not None:
        rx = np.full(n, engine._rx_const)
    else:
        rx = np.ascontiguousarray(np.broadcast_to(links.rx_db, links.ut.shape)[pr])
    if engine._atm_const is not None:
        atm = np.full(n, engine._atm_const)
    else:
        atm = engine.atmosphere(np.maximum(links.elevation_rad[pr], 0.0))
    out = serve_columns(engine, links, pr, served, b, rows, rx, atm)
    from leolink.engine import SERVE_COLUMNS, SERVE_GEOMETRY_COLUMNS

    return dict(zip(SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS, out, strict=True))


@functools.cache
def screen_ragged_kernel():
    """The compiled screening loop of UTs with their own satellites
    (:func:`leolink.engine.kernels.screen_ragged`)."""
    return kernels().screen_ragged


def serving_column(table, serving, row0, block):
    """``leolink.sim.decide.Decider._with_serving``'s column by its compiled loop: each UT's
    serving cell where its table row lacks it, from the block's evaluated pairs
    (``BlockCandidates``: its beam's SNR as ``snr_kernel`` computes it; -1 and NaN below the
    mask). Returns (cell, snr_db, missing, n_need): ``missing`` the UTs whose pair the
    search left out (the caller evaluates them), ``n_need`` the UTs lacking their cell."""
    from leolink import _kernels

    n, links = table.n_ut, block.links
    cell, snr_db, missing = np.empty(n, np.int64), np.empty(n), np.empty(n, bool)
    n_need, _ = _kernels.serving_column(
        table.cell, np.asarray(serving, np.int64), block.n_beam, row0, block.pair_key,
        block.n_key, links.kx, links.ky, links.path_snr_lin, links.visible, block.beam_ix,
        block.beam_iy, cell, snr_db, missing,
    )  # fmt: skip
    return cell, snr_db, missing, n_need


def find_pairs(pair_key, n_key, rows, sats):
    """``leolink.sim.candidates.search.BlockCandidates.find_pairs`` by its compiled loop: the
    index of each pair ``(rows[i], sats[i])`` in the sorted ``pair_key`` (``row * n_key + sat``),
    -1 where absent."""
    from leolink import _kernels

    rows, sats = np.broadcast_arrays(np.asarray(rows, np.int64), np.asarray(sats, np.int64))
    out = np.empty(rows.shape, np.int64)
    _kernels.find_pairs(pair_key, n_key, rows.reshape(-1), sats.reshape(-1), out.reshape(-1))
    return out
