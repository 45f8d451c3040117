"""What the engine computes for (UT, satellite) pairs, and the dense view of a full grid.

:class:`Links` is the engine's unit of work: a flat list of ``m`` pairs ``(ut[p], sat[p])``
with their geometry, path and beam kernels. The simulator evaluates only the pairs that
can matter (:mod:`leolink.engine.screening`); :class:`Snapshot` is the full grid of
``n_ut x n_sat`` pairs (satellite-major, ``p = s n_ut + u``) seen as the
``(n_ut, n_sat[, n_beam])`` arrays of the public API. Both give the same numbers for the
same pair: every quantity is an element-wise function of the pair's positions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from leolink import compiled
from leolink.antenna.array import dirichlet_kernels, kernels_of_direction
from leolink.engine.steered import beam_centres, steered_kernels
from leolink.geometry import body_frame

__all__ = ["Links", "Snapshot", "beam_snr_db", "group_constants_db", "pair_geometry"]
__all__ += ["panel_elevation_of_pairs", "reuse_colors", "rows_gain_db"]


@dataclass(frozen=True)
class LinkParams:
    """Scalars of the link budget (paper's Table).

    ``ptx_dbw``: power of one beam (one RF chain), as in the paper; ``other_loss_db``: the
    losses besides FSPL and atmosphere (TR 38.821 Table 6.1.3.3-1)."""

    freq_hz: float
    bandwidth_hz: float
    ptx_dbw: float
    cable_loss_db: float
    noise_temp_dbk: float
    min_elevation_rad: float
    other_loss_db: float = 0.0


@dataclass
class Links:
    """Link quantities of ``m`` (UT, satellite) pairs.

    Attributes
    ----------
    ut, sat : ndarray of int, shape (m,)
        Rows of the UT and satellite arrays the pairs were evaluated from.
    rel_m : ndarray, shape (m, 3)
        Satellite -> UT vector [m].
    slant_range_m, elevation_rad : ndarray, shape (m,)
    visible : ndarray of bool, shape (m,)
        Above the minimum elevation.
    path_lin : ndarray, shape (m,)
        SNR per unit transmit gain: ``K / rho^2 x G_rx / L_atm`` (also below the mask).
    kx, ky : ndarray, shapes (n_kx, m) and (n_ky, m)
        Along- and cross-track Dirichlet kernels of the distinct beam cosines.
    rx_db : ndarray, shape (m,), or float
        UT receive gain towards the satellite [dB].
    """

    ut: np.ndarray
    sat: np.ndarray
    rel_m: np.ndarray
    slant_range_m: np.ndarray
    elevation_rad: np.ndarray
    visible: np.ndarray
    path_lin: np.ndarray
    kx: np.ndarray
    ky: np.ndarray
    rx_db: np.ndarray | float

    @property
    def n_pair(self) -> int:
        return self.ut.shape[0]

    def take(self, idx):
        """The pairs ``idx`` (any order), as a new :class:`Links`."""
        rx = self.rx_db if np.ndim(self.rx_db) == 0 else self.rx_db[idx]
        return Links(
            self.ut[idx], self.sat[idx], self.rel_m[idx], self.slant_range_m[idx],
            self.elevation_rad[idx], self.visible[idx], self.path_lin[idx],
            self.kx[:, idx], self.ky[:, idx], rx,
        )  # fmt: skip

    @classmethod
    def concat(cls, parts):
        """The pairs of ``parts`` one after the other (their ``ut``, ``sat`` rows must
        index the same arrays)."""
        parts = list(parts)
        if len(parts) == 1:
            return parts[0]
        rx = [p.rx_db for p in parts]
        if all(np.ndim(r) == 0 for r in rx) and len({float(r) for r in rx}) == 1:
            rx_db = rx[0]
        else:
            rx_db = np.concatenate(
                [np.broadcast_to(r, p.ut.shape) for r, p in zip(rx, parts, strict=True)]
            )
        return cls(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in _PAIR_FIELDS),
            *(np.concatenate([getattr(p, f) for p in parts], axis=1) for f in ("kx", "ky")),
            rx_db,
        )

    @cached_property
    def path_snr_lin(self):
        """SNR per unit transmit gain, NaN where not visible, shape (m,)."""
        return np.where(self.visible, self.path_lin, np.nan)

    def gain_tx_bm(self, beam_ix, beam_iy):
        """Linear TX gain of every beam, beam-major, shape (n_beam, m)."""
        return self.kx[beam_ix] * self.ky[beam_iy]

    def snr_db_bm(self, beam_ix, beam_iy, pairs=None):
        """SNR of every beam [dB], beam-major, shape (n_beam, m); NaN where not visible.

        ``10 log10(k_x k_y p) = 10 log10 k_x + 10 log10 k_y + 10 log10 p``: only the
        ``n_x + n_y`` kernels take a logarithm, not the ``n_beam`` products. ``pairs``
        (indices): those pairs only, shape (n_beam, len(pairs)), the values of
        ``take(pairs).snr_db_bm`` without copying the pairs' geometry. Where the compiled
        loops run, :func:`_snr_rows` forms the same sums pair by pair.
        """
        kx, ky, path_snr_lin = self.kx, self.ky, self.path_snr_lin
        if compiled.use(self.n_pair):  # the same sums pair by pair, no (n_beam, m) temporaries
            if pairs is None or isinstance(pairs, slice):
                idx = np.arange(self.n_pair)[pairs if pairs is not None else slice(None)]
            else:
                idx = np.asarray(pairs)
                idx = np.flatnonzero(idx) if idx.dtype == bool else idx.astype(np.int64)
            out = np.empty((len(beam_ix), idx.size))
            beams = np.stack([beam_ix, beam_iy]).astype(np.int64)
            compiled.run_rows(_snr_rows, idx.size, kx, ky, path_snr_lin, beams, idx, out)
            return out
        if pairs is not None:
            kx, ky, path_snr_lin = kx[:, pairs], ky[:, pairs], path_snr_lin[pairs]
        with np.errstate(divide="ignore"):
            lx, ly = 10.0 * np.log10(kx), 10.0 * np.log10(ky)
            path_db = 10.0 * np.log10(path_snr_lin)
        return lx[beam_ix] + ly[beam_iy] + path_db

    def best_beam(self, beam_ix, beam_iy, with_snr_db=False):
        """Each pair's beam of largest SNR (the paper's max-SNR beam), and its SNR [dB].

        ``numpy.argmax`` of :meth:`snr_db_bm` over the beams: ties go to the first beam,
        a pair not visible (every beam NaN) to beam 0. The compiled loop
        (:func:`_best_beam_rows`) forms the same sums pair by pair, without the
        (n_beam, m) matrix.

        Returns
        -------
        beam : ndarray of int64, shape (m,)
        snr_db : ndarray, shape (m,), or None
            With ``with_snr_db``: that beam's entry of :meth:`snr_db_bm` (NaN where not
            visible); None otherwise.
        """
        if compiled.use(self.n_pair):
            best, best_db = np.empty(self.n_pair, np.int64), np.empty(self.n_pair)
            beams = np.stack([beam_ix, beam_iy]).astype(np.int64)
            compiled.run_rows(_best_beam_rows, self.n_pair, self.kx, self.ky, self.path_snr_lin,
                              beams, bool(with_snr_db), (best, best_db))  # fmt: skip
            return best, (best_db if with_snr_db else None)
        snr = self.snr_db_bm(beam_ix, beam_iy)
        beam = np.argmax(snr, axis=0)
        return beam, (snr[beam, np.arange(self.n_pair)] if with_snr_db else None)


@compiled.jitable
def beam_snr_db(kx, ky, path_snr_lin, p, ix, iy):
    """SNR [dB] of the beam of kernel rows ``ix``, ``iy`` of pair ``p``: the sum
    ``10 log10 k_x + 10 log10 k_y + 10 log10 p`` of :meth:`Links.snr_db_bm`, for a
    compiled loop that needs a few beams of a pair, not all."""
    lx, ly = 10.0 * np.log10(kx[ix, p]), 10.0 * np.log10(ky[iy, p])
    return lx + ly + 10.0 * np.log10(path_snr_lin[p])


@compiled.jitable
def _pair_db(kx, ky, path_snr_lin, p, lx, ly):
    """``10 log10`` of pair ``p``'s kernels into ``lx``, ``ly``, and of its path SNR
    (returned): the terms :meth:`Links.snr_db_bm` sums."""
    for i in range(lx.size):
        lx[i] = 10.0 * np.log10(kx[i, p])
    for i in range(ly.size):
        ly[i] = 10.0 * np.log10(ky[i, p])
    return 10.0 * np.log10(path_snr_lin[p])


@compiled.jit
def _snr_rows(kx, ky, path_snr_lin, beams, idx, out, lo, hi):
    """:meth:`Links.snr_db_bm` of the pairs ``idx[lo:hi]`` into the columns ``lo .. hi - 1``
    of ``out`` (``beams``: the rows of ``kx`` and ``ky`` of each beam, (2, n_beam))."""
    beam_ix, beam_iy = beams[0], beams[1]
    lx, ly = np.empty(kx.shape[0]), np.empty(ky.shape[0])
    for q in range(lo, hi):
        path_db = _pair_db(kx, ky, path_snr_lin, idx[q], lx, ly)
        for b in range(beam_ix.size):
            out[b, q] = lx[beam_ix[b]] + ly[beam_iy[b]] + path_db


#: Relative gap between the two largest linear SNRs of a pair above which the largest is
#: also the largest in dB as :meth:`Links.snr_db_bm` sums it: a gap of 1e-9 is 4.3e-9 dB,
#: the dB sums err by < 1e-12 dB (three logarithms of ~1 ulp each, terms < 1e3 dB).
CLEAR_GAP = 1e-9


@compiled.jit
def _best_beam_rows(kx, ky, path_snr_lin, beams, with_db, out, lo, hi):
    """:meth:`Links.best_beam` of the pairs ``lo .. hi - 1`` (``beams``: the rows of
    ``kx`` and ``ky`` of each beam, (2, n_beam)). Each beam's linear gain ``k_x k_y``; where
    the largest exceeds the second by :data:`CLEAR_GAP` it is the dB argmax, and only its dB
    value is formed (``10 log10 k_x + 10 log10 k_y + 10 log10 p``, as :meth:`Links.
    snr_db_bm` sums it; none without ``with_db``, ``best_db`` then left unset); otherwise
    every beam's dB value and the first maximum, or the first NaN (``numpy.argmax``'s
    rule). ``out``: ``(best, best_db)``."""
    beam_ix, beam_iy = beams[0], beams[1]
    best, best_db = out
    lx, ly = np.empty(kx.shape[0]), np.empty(ky.shape[0])
    gx, gy = np.empty(kx.shape[0]), np.empty(ky.shape[0])
    for p in range(lo, hi):
        for i in range(gx.size):
            gx[i] = kx[i, p]
        for i in range(gy.size):
            gy[i] = ky[i, p]
        top, second, arg = -1.0, -1.0, 0
        for b in range(beam_ix.size):
            g = gx[beam_ix[b]] * gy[beam_iy[b]]
            if g > top:
                top, second, arg = g, top, b
            elif g > second:
                second = g
        path = path_snr_lin[p]
        if second < top * (1.0 - CLEAR_GAP) and not np.isnan(path):
            best[p] = arg
            if not with_db:
                continue
            best_db[p] = beam_snr_db(kx, ky, path_snr_lin, p, beam_ix[arg], beam_iy[arg])
            continue
        path_db = _pair_db(kx, ky, path_snr_lin, p, lx, ly)
        best[p], best_db[p] = 0, lx[beam_ix[0]] + ly[beam_iy[0]] + path_db
        for b in range(1, beam_ix.size):
            if np.isnan(best_db[p]):
                break
            v = lx[beam_ix[b]] + ly[beam_iy[b]] + path_db
            if v > best_db[p] or np.isnan(v):
                best[p], best_db[p] = b, v


_PAIR_FIELDS = ("ut", "sat", "rel_m", "slant_range_m", "elevation_rad", "visible", "path_lin")


def _grid(a, n_sat, n_ut):
    """A pair array (m, ...) of a satellite-major grid -> (n_ut, n_sat, ...), C-contiguous
    (the layout of the per-UT arrays; reductions over it then add in the same order)."""
    grid = a.reshape((n_sat, n_ut) + a.shape[1:])
    return np.ascontiguousarray(np.swapaxes(grid, 0, 1))


@dataclass
class Snapshot:
    """What :meth:`~leolink.engine.LinkEngine.evaluate` computed: every (UT, satellite) pair.

    Attributes
    ----------
    engine : LinkEngine
        The engine that computed it (beam lattice indices).
    links : Links
        The ``n_sat x n_ut`` pairs, satellite-major (``p = s n_ut + u``).
    n_ut, n_sat : int
    path_no_rx_lin, u_panel : ndarray or None
        With other-satellite interference: the path without the UT gain, (n_ut, n_sat),
        zero below the horizon; each satellite's direction in the UT panel's cosines,
        (n_ut, n_sat, 2).
    ut_pos_m : ndarray, shape (n_ut, 3)
    ut_enu : ndarray, shape (n_ut, 3, 3), or None
        The UTs' local east, north, up rows when given to ``evaluate`` (WGS 84); None:
        the sphere's, from the positions.

    The per-pair arrays are also seen per UT: ``rel_m (n_ut, n_sat, 3)``,
    ``slant_range_m``, ``elevation_rad``, ``visible``, ``path_snr_lin`` (NaN where not
    visible) ``(n_ut, n_sat)``; the kernels ``kx, ky`` as ``(n_k, n_sat, n_ut)``.
    """

    engine: object = field(repr=False)
    links: Links = field(repr=False)
    n_ut: int
    n_sat: int
    ut_pos_m: np.ndarray | None = None
    ut_enu: np.ndarray | None = None
    path_no_rx_lin: np.ndarray | None = None
    u_panel: np.ndarray | None = None

    @property
    def kx(self):
        return self.links.kx.reshape(-1, self.n_sat, self.n_ut)

    @property
    def ky(self):
        return self.links.ky.reshape(-1, self.n_sat, self.n_ut)

    @cached_property
    def rel_m(self):
        return _grid(self.links.rel_m, self.n_sat, self.n_ut)

    @cached_property
    def slant_range_m(self):
        return _grid(self.links.slant_range_m, self.n_sat, self.n_ut)

    @cached_property
    def elevation_rad(self):
        return _grid(self.links.elevation_rad, self.n_sat, self.n_ut)

    @cached_property
    def visible(self):
        return _grid(self.links.visible, self.n_sat, self.n_ut)

    @cached_property
    def path_snr_lin(self):
        return _grid(self.links.path_snr_lin, self.n_sat, self.n_ut)

    @cached_property
    def path_lin(self):
        return _grid(self.links.path_lin, self.n_sat, self.n_ut)

    @property
    def rx_db(self):
        rx = self.links.rx_db
        return rx if np.ndim(rx) == 0 else _grid(rx, self.n_sat, self.n_ut)

    @cached_property
    def gain_tx_bm(self):
        """Beam-major linear TX gains, shape (n_beam, n_sat, n_ut)."""
        e = self.engine
        return self.kx[e.beam_ix] * self.ky[e.beam_iy]

    @property
    def gain_tx_lin(self):
        """Linear TX gain of every beam, shape (n_ut, n_sat, n_beam)."""
        return self.gain_tx_bm.transpose(2, 1, 0)

    @cached_property
    def snr_db(self):
        """SNR of every beam [dB], shape (n_ut, n_sat, n_beam); NaN where not visible."""
        e = self.engine
        out = self.links.snr_db_bm(e.beam_ix, e.beam_iy)
        return out.reshape(-1, self.n_sat, self.n_ut).transpose(2, 1, 0)

    @property
    def gain_rx_db(self):
        return np.broadcast_to(self.rx_db, (self.n_ut, self.n_sat))


def rows_gain_db(terminal, elevation_rad, ut_id, constants=None):
    """``terminal.gain_db`` of pairs whose UTs are ``ut_id`` (a per-population
    :class:`~leolink.antenna.terminal.TerminalGroups` answers per UT row).

    ``constants``: :func:`group_constants_db` of the terminal, if already known.
    """
    groups = getattr(terminal, "group", None)
    if groups is None:
        return terminal.gain_db(elevation_rad)
    constants = group_constants_db(terminal) if constants is None else constants
    group = groups[ut_id]
    out = np.empty(elevation_rad.shape)
    for g, term in enumerate(terminal.terminals):
        rows = group == g
        if constants[g] is not None:
            out[rows] = constants[g]
        elif rows.any():
            out[rows] = term.gain_db(elevation_rad[rows])
    return out


def group_constants_db(terminal):
    """The gain [dB] of each elevation-independent member of a ``TerminalGroups``
    (``gain_db(pi / 2)``, as it evaluates them), None for the others."""
    return [
        float(t.gain_db(np.pi / 2)) if t.elevation_independent else None for t in terminal.terminals
    ]


def pair_geometry(engine, ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up, sat_id=None,
                  steer=None):  # fmt: skip
    """The numpy reference of ``LinkEngine.evaluate_pairs``'s geometry and beam kernels:
    rel, rho2, rho, elevation, visible, kx, ky (the Dirichlet kernels by the compiled loop
    of :func:`~leolink.antenna.array.dirichlet_kernels` where it runs).
    ``sat_id``: the global satellite of each satellite row (None: row = satellite);
    ``steer``: ``(pos, vel)`` the satellites steer their beams by (an estimated ephemeris;
    None: the true states)."""
    if engine.steering is None and compiled.use(ut.shape[0]):  # one pass per pair
        return _fused_geometry(engine, ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up)
    u_pos = ut_pos_m[ut]
    rel = u_pos - sat_pos_m[sat]  # satellite -> UT, (m, 3)
    rho2 = np.einsum("pk,pk->p", rel, rel)
    rho = np.sqrt(rho2)
    if ut_up is None:
        r_ut = np.sqrt(np.einsum("uk,uk->u", ut_pos_m, ut_pos_m))
        sin_el = -np.einsum("pk,pk->p", rel, u_pos) / (rho * r_ut[ut])
    else:
        sin_el = -np.einsum("pk,pk->p", rel, ut_up[ut]) / rho
    elevation = np.arcsin(np.clip(sin_el, -1.0, 1.0))
    visible = elevation >= engine.params.min_elevation_rad

    axes = body_frame(sat_pos_m, sat_vel_m_s)[sat]  # (m, 3, 3) rows u_x, u_y, u_z
    inv_rho = 1.0 / rho
    ux = np.einsum("pk,pk->p", rel, axes[:, 0, :]) * inv_rho
    uy = np.einsum("pk,pk->p", rel, axes[:, 1, :]) * inv_rho
    if engine.steering is not None:  # beams of their own per satellite row
        s_pos, s_vel = (sat_pos_m, sat_vel_m_s) if steer is None else steer
        v, on = beam_centres(engine, s_pos, body_frame(s_pos, s_vel), sat_id)
        kx, ky = steered_kernels(engine, ux, uy, sat, v, on)
        return rel, rho2, rho, elevation, visible, kx, ky
    kx = dirichlet_kernels(ux, engine.beam_ux, engine.codebook.n_sub_x)
    ky = dirichlet_kernels(uy, engine.beam_uy, engine.codebook.n_sub_y)
    return rel, rho2, rho, elevation, visible, kx, ky


def _fused_geometry(engine, ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up):
    """:func:`pair_geometry` of the codebook's lattice by the compiled :func:`_pair_rows`."""
    m, cb = ut.shape[0], engine.codebook
    ut_pos_m = np.ascontiguousarray(ut_pos_m, float)
    frames = (
        ut_pos_m,
        ut_pos_m if ut_up is None else np.ascontiguousarray(ut_up, float),
        np.ascontiguousarray(sat_pos_m, float),
        body_frame(sat_pos_m, sat_vel_m_s),
    )
    cx, cy = engine.kernel_coefficients
    lattice = (
        (engine.beam_ux, cx, float(cb.n_sub_x)),
        (engine.beam_uy, cy, float(cb.n_sub_y)),
        float(engine.params.min_elevation_rad),
        ut_up is None,
    )
    out = (
        np.empty((m, 3)),
        np.empty(m),
        np.empty(m),
        np.empty(m),
        np.empty(m, bool),
        np.empty((engine.beam_ux.size, m)),
        np.empty((engine.beam_uy.size, m)),
    )
    pairs = (np.asarray(ut, np.int64), np.asarray(sat, np.int64))
    compiled.run_rows(_pair_rows, m, frames, pairs, lattice, out)
    return out


@compiled.jit
def _pair_rows(frames, pairs, lattice, out, lo, hi):
    """:func:`pair_geometry` of the pairs ``lo .. hi - 1``, each in one pass: the vector
    satellite -> UT, its length, the elevation over the UT's up, the direction cosines in
    the satellite body frame and their Dirichlet kernels (:func:`kernels_of_direction`,
    ``beams_x``, ``beams_y``: the lattice's cosines, coefficients and elements). ``sphere``:
    ``up`` holds the UTs' positions, the sphere's radial up once divided by their norm."""
    ut_pos, up, sat_pos, axes = frames
    ut, sat = pairs
    beams_x, beams_y, min_el, sphere = lattice
    rel, rho2, rho, elevation, visible, kx, ky = out
    for p in range(lo, hi):
        u, s = ut[p], sat[p]
        for k in range(3):
            rel[p, k] = ut_pos[u, k] - sat_pos[s, k]
        d = rel[p]
        rho2[p] = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        rho[p] = np.sqrt(rho2[p])
        sin_el = -(d[0] * up[u, 0] + d[1] * up[u, 1] + d[2] * up[u, 2]) / rho[p]
        if sphere:
            sin_el /= np.sqrt(up[u, 0] * up[u, 0] + up[u, 1] * up[u, 1] + up[u, 2] * up[u, 2])
        elevation[p] = np.arcsin(min(max(sin_el, -1.0), 1.0))
        visible[p] = elevation[p] >= min_el
        ux = (d[0] * axes[s, 0, 0] + d[1] * axes[s, 0, 1] + d[2] * axes[s, 0, 2]) / rho[p]
        uy = (d[0] * axes[s, 1, 0] + d[1] * axes[s, 1, 1] + d[2] * axes[s, 1, 2]) / rho[p]
        kernels_of_direction(ux, beams_x, kx, p)
        kernels_of_direction(uy, beams_y, ky, p)


def panel_elevation_of_pairs(rel_m, slant_range_m, ut_normal, ut):
    """Angle above the panel plane ``arcsin(v . n)`` of each pair [rad], shape (m,).

    ``v = -rel / rho`` is the unit vector UT -> satellite (``rel_m (m, 3)``, satellite ->
    UT, and ``slant_range_m (m,)`` as :func:`pair_geometry` gives them), ``n`` the panel
    normal of the pair's UT row (``ut_normal[ut]``, ``(n_u, 3)``): the elevation itself for
    a panel lying flat.
    """
    v = -rel_m / slant_range_m[:, None]
    s = np.einsum("pk,pk->p", v, ut_normal[ut])
    return np.arcsin(np.clip(s, -1.0, 1.0))


def reuse_colors(lattice_ij, n_colors):
    """Frequency-reuse colour of each beam from its lattice indices (i, j).

    1 colour: full reuse (the paper). 4 colours: a 2 x 2 pattern, so that no two
    neighbours along an axis share a carrier. 3 colours: (i + 2 j) mod 3, the classic
    3-colour tiling of a lattice where no two edge neighbours share a colour.
    Each colour gets ``1 / n_colors`` of the bandwidth.
    """
    i, j = np.asarray(lattice_ij).T
    if n_colors == 1:
        return np.zeros(i.shape, dtype=np.int64)
    if n_colors == 4:
        return (i % 2) * 2 + (j % 2)
    if n_colors == 3:
        return (i + 2 * j) % 3
    raise ValueError(f"reuse_colors = {n_colors!r} is not allowed; use 1, 3 or 4")
