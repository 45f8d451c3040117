"""Which (UT, satellite) pairs can matter: visibility and an upper bound of the best beam.

Before the engine evaluates every beam of a pair, :func:`screen` classifies each pair of a
UT x satellite grid from dot products alone (one matrix product per quantity, no
per-pair trigonometry but one sine per axis):

- visibility: ``sin(el) = (up . (sat - ut)) / rho`` against ``sin(min_elevation)``; pairs
  within ``SIN_EL_BAND`` of the mask are *uncertain* and must be evaluated exactly (the
  engine decides with ``arcsin``; the dot products differ from its value by ~1e-15);
- an upper bound of the SNR of **every** beam of the pair (linear):
  ``K / rho^2 x G_rx / L_atm x E_x(u_x) x E_y(u_y)``.

The beams' gain is ``k_x(u_x - b_x) k_y(u_y - b_y)`` (two Dirichlet kernels, paper Sec.
3.2), and a Dirichlet kernel of ``n`` elements is bounded by its envelope,

    k(du, n) = sin^2(n pi du / 2) / (n sin^2(pi du / 2)) <= min(n, 1 / (n sin^2(pi d / 2))),

with ``d`` the distance from ``du`` to the nearest multiple of 2 (the kernel has period 2).
The envelope decreases in ``d`` on ``[0, 1]``, so the largest kernel over the codebook's
distinct beam cosines is bounded by the envelope at the distance to the nearest one:
``E(u) = env(min_b d(u - b))``. No beam of a pair can beat ``bound``; a pair whose bound is
below the best SNR already found for its UT cannot hold the best beam.

The bound uses the screening geometry, which differs from the engine's by rounding only
(~1e-15 relative); ``BOUND_SLACK`` (1e-6, i.e. 4e-6 dB) covers it, and it covers the
terminal gain and the atmospheric loss evaluated at the screening elevation provided they
change by less than 1e-6 dB per 1e-12 rad (every registered model: they are smooth). A
terminal that declares its gain not smooth is bounded by its maximum gain instead
(:func:`leolink.antenna.terminal.pruning_terminal`, the TerminalAntenna protocol).
"""

from __future__ import annotations

import numpy as np

from leolink import compiled
from leolink.antenna.terminal import pruning_terminal
from leolink.arrays import nonzero_2d
from leolink.engine.links import group_constants_db, rows_gain_db
from leolink.engine.steered import steered_bound_lin

__all__ = ["BOUND_SLACK", "SIN_EL_BAND", "UNCERTAIN", "VISIBLE", "envelope", "screen"]
__all__ += ["screen_ragged"]

#: Relative margin of the SNR upper bound over rounding (and the gain models' smoothness).
BOUND_SLACK = 1e-6
#: Half-width of the band of ``sin(elevation)`` around the mask where visibility is decided
#: by the engine's exact evaluation (the screening's error is ~1e-15).
SIN_EL_BAND = 1e-9
#: Pair classes of :func:`screen` (0: below the mask).
UNCERTAIN, VISIBLE = 1, 2


def envelope(u, beam_u, n):
    """Upper bound of ``max_b dirichlet(u - b, n)`` over the beam cosines ``beam_u``.

    :func:`_envelope` (which the compiled screening loop calls on scalars), without numpy's
    warning where the bound is ``n`` (``1 / 0``).

    Parameters
    ----------
    u : float or ndarray
        Direction cosines [-], any shape.
    beam_u : ndarray, shape (k,)
        Distinct beam cosines, sorted.
    n : int or float
        Elements along the axis.

    Returns
    -------
    float or ndarray, shape of ``u``
        ``min(n, 1 / (n sin^2(pi d / 2)))``, ``d`` the distance to the nearest beam
        modulo 2 (so the grating lobes at ``|u - b| = 2`` are counted), with the sine
        replaced by a polynomial below it (the bound only grows).
    """
    with np.errstate(divide="ignore", over="ignore"):
        return _envelope(u, beam_u, n)


@compiled.jitable
def _envelope(u, beam_u, n):
    """:func:`envelope`'s formula, arithmetic and ufuncs only (arrays and scalars alike)."""
    d = np.abs(u - beam_u[0])
    for b in beam_u[1:]:
        d = np.minimum(d, np.abs(u - b))
    # Modulo 2: the farthest beam is the nearest one through the grating lobe.
    d = np.minimum(d, 2.0 - np.maximum(u - beam_u[0], beam_u[-1] - u))
    x = (0.5 * np.pi) * np.minimum(np.maximum(d, 0.0), 1.0)
    # sin x from below, by its Taylor polynomial to x^7 (an alternating series: the partial
    # sum after a negative term is below sin x on [0, pi]): the bound only grows.
    x2 = x * x
    s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)))
    return np.minimum(np.float64(n), 1.0 / (n * s * s))  # tiny s: 1 / (n s^2) -> inf -> n


def screen(engine, ut_pos_m, sat_pos_m, sat_axes, ut_up=None, ut_id=None, ut_normal=None,
           sat_id=None):  # fmt: skip
    """Classify every pair of the UT x satellite grid and bound its best beam's SNR.

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    ut_pos_m : ndarray, shape (n_u, 3)
    sat_pos_m : ndarray, shape (n_s, 3)
    sat_axes : ndarray, shape (n_s, 3, 3)
        Body frames of the satellites (:func:`leolink.geometry.body_frame`).
    ut_up : ndarray, shape (n_u, 3), optional
        Local up of each UT (WGS 84); None: the sphere's radial up.
    ut_id : ndarray of int, shape (n_u,), optional
        The UT of each row (per-population terminals); None: row = UT.
    ut_normal : ndarray, shape (n_u, 3), optional
        Panel normal of each row (tilted panels): an elevation-dependent terminal gain is
        bounded at the screening angle above the panel plane, as the engine evaluates it.
    sat_id : ndarray of int, shape (n_s,), optional
        Global id of each satellite (re-steered beams, :mod:`leolink.engine.steered`,
        whose bound is per satellite); None: row = id.

    Returns
    -------
    code : ndarray of int8, shape (n_u, n_s)
        0 below the mask, :data:`UNCERTAIN`, :data:`VISIBLE`.
    bound : ndarray, shape (n_u, n_s)
        Upper bound of every beam's linear SNR where ``code > 0``, -1 elsewhere.
    """

    ut_id = np.arange(len(ut_pos_m)) if ut_id is None else ut_id
    rx = _rx_bound(engine.terminal)
    factor = _ut_factor(engine, rx, ut_id)
    known = np.where(np.isnan(factor), 1.0, factor)
    if engine.steering is None and compiled.use(ut_pos_m.shape[0] * sat_pos_m.shape[0]):
        code, bound, sin_el = _screen_compiled(engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, known)
    else:
        code, bound, sin_el = _screen_numpy(
            engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, known, sat_id
        )
    rows = np.flatnonzero(np.isnan(factor))
    if rows.size:  # UTs whose gain or loss depends on the elevation: per pair
        r, s = nonzero_2d(code[rows] > 0)
        pairs = (rows[r], s)
        bound[pairs] *= _elevation_factor(engine, rx, ut_pos_m, sat_pos_m, sin_el[pairs], pairs,
                                          ut_id, ut_normal)  # fmt: skip
    return code, bound


def screen_ragged(engine, ut_pos_m, sat_pos_m, sat_axes, caps, ut_up=None, ut_id=None,
                  ut_normal=None):  # fmt: skip
    """:func:`screen` of groups of UTs, each against its own satellites, flat, in one call
    of the compiled loop.

    UT ``i`` of group ``g = caps.group[i]`` is screened against the satellites
    ``caps.sat[caps.start[g] : caps.start[g + 1]]`` (rows of ``sat_pos_m`` and
    ``sat_axes``), in that order, at ``start[i] : start[i + 1]`` of the flat outputs. The
    caller runs it where :func:`leolink.compiled.use` and the beams are not re-steered
    (else :func:`screen` per group).

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    ut_pos_m : ndarray, shape (n_u, 3)
    sat_pos_m : ndarray, shape (n_s, 3)
    sat_axes : ndarray, shape (n_s, 3, 3)
    caps : leolink.sim.candidates.tiles.Caps
        The groups' satellites: ``sat`` (flat), ``start`` (n_group + 1,), ``group`` (n_u,).
    ut_up, ut_id, ut_normal : as for :func:`screen`

    Returns
    -------
    code : ndarray of int8, shape (m,)
    bound : ndarray, shape (m,)
    start : ndarray of int, shape (n_u + 1,)
        Each UT's first pair.
    """
    n_u = len(ut_pos_m)
    ut_id = np.arange(n_u) if ut_id is None else ut_id
    rx = _rx_bound(engine.terminal)
    factor = _ut_factor(engine, rx, ut_id)
    size = np.diff(caps.start)[caps.group]
    start = np.zeros(n_u + 1, np.int64)
    np.cumsum(size, out=start[1:])
    known = np.where(np.isnan(factor), 1.0, factor)
    pos, axes = sat_pos_m[caps.sat], sat_axes[caps.sat]  # each cap's satellites in a row
    layout = (caps.start, caps.group, start)
    if engine.steering is None and compiled.use(int(start[-1])):
        code, bound, sin_el = _ragged_compiled(engine, ut_pos_m, pos, axes, ut_up, known, layout)
    else:
        code, bound, sin_el = _ragged_numpy(engine, ut_pos_m, (pos, axes, caps.sat), ut_up, known,
                                            layout)  # fmt: skip
    rows = np.isnan(factor)
    if rows.any():  # UTs whose gain or loss depends on the elevation: per pair
        p = np.flatnonzero(np.repeat(rows, size) & (code > 0))
        pairs = caps.pairs(start, p)
        bound[p] *= _elevation_factor(engine, rx, ut_pos_m, sat_pos_m, sin_el[p], pairs, ut_id,
                                      ut_normal)  # fmt: skip
    return code, bound, start


def _elevation_factor(engine, rx, ut_pos_m, sat_pos_m, sin_el, pairs, ut_id, ut_normal):
    """:func:`_pair_factor` of the pairs ``(ut row, satellite row)`` whose screening
    elevations are ``sin_el``, with the panel's angle where the UTs have normals."""
    r, s = pairs
    sin_rx = None
    if ut_normal is not None:  # the gain sees the angle above the panel plane
        d = sat_pos_m[s] - ut_pos_m[r]
        sin_rx = np.einsum("pk,pk->p", d, ut_normal[r]) / np.linalg.norm(d, axis=1)
    return _pair_factor(engine, rx, sin_el, ut_id[r], sin_rx)


def _screen_numpy(engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, ut_factor, sat_id=None):
    """:func:`screen` in numpy (matrix products): code, bound, sin(elevation)."""
    cb = engine.codebook
    r_ut2 = np.einsum("uk,uk->u", ut_pos_m, ut_pos_m)
    g = ut_pos_m @ sat_pos_m.T
    rho2 = (r_ut2[:, None] + np.einsum("sk,sk->s", sat_pos_m, sat_pos_m)[None, :]) - 2.0 * g
    rho = np.sqrt(rho2)
    if ut_up is None:
        r_ut = np.sqrt(r_ut2)[:, None]
        sin_el = (g / r_ut - r_ut) / rho
    else:
        up_ut = np.einsum("uk,uk->u", ut_up, ut_pos_m)
        sin_el = (ut_up @ sat_pos_m.T - up_ut[:, None]) / rho
    s_min = np.sin(engine.params.min_elevation_rad)
    code = (sin_el >= s_min - SIN_EL_BAND).astype(np.int8)
    code += sin_el >= s_min + SIN_EL_BAND
    ax, ay = sat_axes[:, 0, :], sat_axes[:, 1, :]
    ux = (ut_pos_m @ ax.T - np.einsum("sk,sk->s", sat_pos_m, ax)[None, :]) / rho
    uy = (ut_pos_m @ ay.T - np.einsum("sk,sk->s", sat_pos_m, ay)[None, :]) / rho
    if engine.steering is not None:  # each satellite's own beam centres
        bound = steered_bound_lin(engine, ux, uy, sat_pos_m, sat_axes, sat_id)
    else:
        bound = envelope(ux, engine.beam_ux, cb.n_sub_x)
        bound *= envelope(uy, engine.beam_uy, cb.n_sub_y)
    bound *= (engine.k_lin * (1.0 + BOUND_SLACK)) * ut_factor[:, None] / rho2
    return code, np.where(code > 0, bound, -1.0), sin_el


def _ragged_numpy(engine, ut_pos_m, sats, ut_up, ut_factor, layout):
    """:func:`screen_ragged`'s code, bound and sin(elevation), flat, by :func:`_screen_numpy`
    per group (``sats``: the caps' positions, axes and global ids in a row)."""
    pos, axes, sat_id = sats
    cap_start, group, start = layout
    m = int(start[-1])
    out = (np.empty(m, np.int8), np.empty(m), np.empty(m))
    for g in range(len(cap_start) - 1):
        rows = np.flatnonzero(group == g)
        caps = slice(cap_start[g], cap_start[g + 1])
        if rows.size == 0 or caps.start == caps.stop:
            continue
        up = None if ut_up is None else ut_up[rows]
        block = _screen_numpy(engine, ut_pos_m[rows], pos[caps], axes[caps], up,
                              ut_factor[rows], sat_id[caps])  # fmt: skip
        flat = start[rows][:, None] + np.arange(caps.stop - caps.start)
        for o, b in zip(out, block, strict=True):
            o[flat] = b
    return out


def _compiled_inputs(engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, ut_factor):
    """The frames, lattice and per-UT scale of the compiled loops (:func:`_screen_pair`)."""
    if ut_up is None:  # the sphere's radial up
        ut_up = ut_pos_m / np.sqrt(np.einsum("uk,uk->u", ut_pos_m, ut_pos_m))[:, None]
    frames = (
        np.ascontiguousarray(ut_pos_m, float),
        np.ascontiguousarray(ut_up, float),
        np.ascontiguousarray(sat_pos_m, float),
        np.ascontiguousarray(sat_axes, float),
    )
    cb = engine.codebook
    lattice = (
        engine.beam_ux,
        engine.beam_uy,
        float(cb.n_sub_x),
        float(cb.n_sub_y),
        float(np.sin(engine.params.min_elevation_rad)),
    )
    scale = np.ascontiguousarray(ut_factor, float) * (engine.k_lin * (1.0 + BOUND_SLACK))
    return frames, lattice, scale


def _screen_compiled(engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, ut_factor):
    """:func:`screen`'s code, bound and sin(elevation) by the compiled :func:`_screen_rows`
    (the same quantities as :func:`_screen_numpy`, rounded otherwise: both bounds carry
    :data:`BOUND_SLACK`, both classes the :data:`SIN_EL_BAND`)."""
    shape = (ut_pos_m.shape[0], sat_pos_m.shape[0])
    frames, lattice, scale = _compiled_inputs(
        engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, ut_factor
    )
    out = (np.empty(shape, np.int8), np.empty(shape), np.empty(shape))
    compiled.run_rows(_screen_rows, shape[0], frames, lattice, scale, out, row_size=shape[1])
    return out


def _ragged_compiled(engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, ut_factor, layout):
    """:func:`screen_ragged`'s code, bound and sin(elevation), flat, by the compiled
    :func:`_ragged_rows` (``layout``: group starts into the rows of ``sat_pos_m``, each
    UT's group, each UT's first pair)."""
    frames, lattice, scale = _compiled_inputs(
        engine, ut_pos_m, sat_pos_m, sat_axes, ut_up, ut_factor
    )
    layout = tuple(np.ascontiguousarray(x, np.int64) for x in layout)
    m, n_u = int(layout[2][-1]), ut_pos_m.shape[0]
    out = (np.empty(m, np.int8), np.empty(m), np.empty(m))
    compiled.run_rows(_ragged_rows, n_u, frames, lattice, scale, layout, out,
                      row_size=max(1, m // max(n_u, 1)))  # fmt: skip
    return out


@compiled.jitable
def _screen_pair(frames, lattice, scale_u, u, s):
    """Code, bound (:func:`_envelope` of both axes, times ``scale_u / rho^2``) and
    sin(elevation) of UT row ``u`` with satellite row ``s`` (scalars): :func:`_pair_link`,
    :func:`_pair_code`, then :func:`_pair_bound` above the mask (-1 below)."""
    d, rho2, rho, se = _pair_link(frames, u, s)
    c = _pair_code(se, lattice[4])
    return c, -1.0 if c == 0 else _pair_bound(frames, lattice, scale_u, s, d, rho2), se


@compiled.jitable
def _pair_link(frames, u, s):
    """UT row ``u`` minus satellite row ``s`` (a tuple of 3 [m]), its squared length and
    length ``rho`` [m^2, m] and the sine of the elevation ``-(d . up) / rho``."""
    ut_pos, up, sat_pos, _ = frames
    d0, d1, d2 = (
        ut_pos[u, 0] - sat_pos[s, 0],
        ut_pos[u, 1] - sat_pos[s, 1],
        ut_pos[u, 2] - sat_pos[s, 2],
    )
    rho2 = d0 * d0 + d1 * d1 + d2 * d2
    rho = np.sqrt(rho2)
    return (d0, d1, d2), rho2, rho, -(d0 * up[u, 0] + d1 * up[u, 1] + d2 * up[u, 2]) / rho


@compiled.jitable
def _pair_code(sin_el, s_min):
    """0 below the mask's band, :data:`UNCERTAIN` within it, :data:`VISIBLE` above."""
    # int() of each test: numpy's bool + bool is their "or" (in Python, NUMBA_DISABLE_JIT=1)
    return int(sin_el >= s_min - SIN_EL_BAND) + int(sin_el >= s_min + SIN_EL_BAND)


@compiled.jitable
def _pair_bound(frames, lattice, scale_u, s, d, rho2):
    """The bound of a pair of :func:`_pair_link`'s ``d`` and ``rho2`` with satellite row
    ``s``: the two axes' :func:`_envelope` of the direction cosines, times ``scale_u /
    rho^2``."""
    axes = frames[3]
    beam_ux, beam_uy, n_x, n_y, _ = lattice
    d0, d1, d2 = d
    rho = np.sqrt(rho2)
    ux = (d0 * axes[s, 0, 0] + d1 * axes[s, 0, 1] + d2 * axes[s, 0, 2]) / rho
    uy = (d0 * axes[s, 1, 0] + d1 * axes[s, 1, 1] + d2 * axes[s, 1, 2]) / rho
    g = _envelope(ux, beam_ux, n_x) * _envelope(uy, beam_uy, n_y)
    return g * scale_u / rho2


# The loops below spell out :func:`_screen_pair`'s three steps instead of calling it: numba
# does not inline a call that returns the whole pair, and the call costs a pair ~30 ns,
# ~3x the work of the pairs below the mask (most of a tile's cap); the bound is computed
# for the pairs at or above the mask's band only.


@compiled.jit
def _screen_rows(frames, lattice, scale, out, lo, hi):
    """:func:`_screen_pair` of the UT rows ``lo .. hi - 1`` with every satellite."""
    code, bound, sin_el = out
    for u in range(lo, hi):
        for s in range(frames[2].shape[0]):
            d, rho2, _, se = _pair_link(frames, u, s)
            c = _pair_code(se, lattice[4])
            code[u, s], sin_el[u, s] = c, se
            bound[u, s] = -1.0 if c == 0 else _pair_bound(frames, lattice, scale[u], s, d, rho2)


@compiled.jit
def _ragged_rows(frames, lattice, scale, layout, out, lo, hi):
    """:func:`_screen_pair` of the UT rows ``lo .. hi - 1``, each with its group's satellite
    rows ``cap_start[g] .. cap_start[g + 1] - 1``, flat from ``start[u]``."""
    cap_start, group, start = layout
    code, bound, sin_el = out
    for u in range(lo, hi):
        p = start[u]
        for j in range(cap_start[group[u]], cap_start[group[u] + 1]):
            d, rho2, _, se = _pair_link(frames, u, j)
            c = _pair_code(se, lattice[4])
            code[p], sin_el[p] = c, se
            bound[p] = -1.0 if c == 0 else _pair_bound(frames, lattice, scale[u], j, d, rho2)
            p += 1


_SLACK_DB = 10.0 * np.log10(1.0 + BOUND_SLACK)


def _rx_bound(terminal):
    """The terminal whose gain bounds ``terminal``'s (:func:`pruning_terminal`), its gain
    [dB] if it is one constant, else the constants of its groups (or None)."""
    t = pruning_terminal(terminal)
    if t.elevation_independent:
        return t, float(t.gain_db(np.pi / 2)), None
    return t, None, (group_constants_db(t) if getattr(t, "group", None) is not None else None)


def _ut_factor(engine, rx, ut_id):
    """Each UT's bound of ``G_rx / L_atm`` (linear) where it does not depend on the
    elevation, NaN where it does (shape (n_u,))."""
    atm_db = engine.atmosphere.constant_db
    terminal, rx_const, rx_groups = rx
    if atm_db is None:
        return np.full(ut_id.shape, np.nan)
    if rx_const is not None:
        return np.full(ut_id.shape, 10.0 ** ((rx_const - atm_db + _SLACK_DB) / 10.0))
    out = np.full(ut_id.shape, np.nan)
    for g, rx_db in enumerate(rx_groups or ()):
        if rx_db is not None:
            out[terminal.group[ut_id] == g] = 10.0 ** ((rx_db - atm_db + _SLACK_DB) / 10.0)
    return out


def _pair_factor(engine, rx, sin_el, ut_id, sin_rx=None):
    """Bound of ``G_rx / L_atm`` (linear) at the screening elevations of pairs, (m,)
    (``sin_rx``: the sine of the angle the terminal gain takes, if not the elevation's)."""
    el = np.arcsin(np.clip(sin_el, -1.0, 1.0))
    terminal, rx_db, rx_groups = rx
    atm_db = engine.atmosphere.constant_db
    if rx_db is None:
        el_rx = el if sin_rx is None else np.arcsin(np.clip(sin_rx, -1.0, 1.0))
        rx_db = rows_gain_db(terminal, el_rx, ut_id, rx_groups)
    if atm_db is None:
        atm_db = engine.atmosphere(np.maximum(el, 0.0))
    return 10.0 ** ((rx_db - atm_db + _SLACK_DB) / 10.0)
