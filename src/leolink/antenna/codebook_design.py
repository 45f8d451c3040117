"""Choosing the oversampling factor O and checking that the codebook leaves no holes.

A pruned DFT codebook (:mod:`leolink.antenna.codebook`, Sec. 3.2 of [1]) tiles the ROI
only if neighbouring beams overlap. With ``O < 1`` the lattice spacing ``2 / (O N)``
exceeds the distance ``2 / N`` from a beam's peak to its first null: each neighbour peaks
outside the other's main lobe, and the crossing between them sinks from the 3.9 dB of
orthogonal beams (O = 1, per axis) towards the nulls (O = 0.5). With any O, a ROI that
reaches far beyond its outermost beams leaves its edge uncovered. Both are measured by
one number, the **worst-case loss inside the ROI**: over points of the ROI, the largest
gap between the beam peak ``n_sub_x n_sub_y`` and the best beam's gain there.

A design has **holes** if ``O < 1`` (with more than one beam) or that loss exceeds
:data:`HOLE_LOSS_DB`, the first sidelobe level of a uniform array (13.26 dB): a point
where even the best beam is weaker than a beam's own first sidelobe lies outside every
useful main lobe. The paper's design (O = 1.2, 534.1 x 170.5 km) has 11.2 dB at the edge
of its ROI; O = 1 over the same ROI has 16.5 dB and counts as holes (its outer beams'
nulls reach the ROI boundary).

``oversampling = "auto"`` (:func:`auto_design`) picks, among the O whose pruned codebook
has at most ``n_rf`` beams (one per RF chain, paper Sec. 2.1), the largest beam count
that leaves no holes, and inside that count's O interval the O with the least worst-case
loss. The paper's rule ("as many beams pointing to the ROI as available RF chains") is the
special case where that count equals ``n_rf``.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications", Sec. 3.2.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from leolink.antenna.array import dirichlet_kernels, dirichlet_trig
from leolink.antenna.codebook import (
    CANONICAL_ALONG_TRACK,
    Codebook,
    beam_count_steps,
    build_codebook,
    canonical_satellite,
)
from leolink.constants import EARTH_RADIUS_M
from leolink.geometry import direction_cosines, roi_to_ground

__all__ = [
    "HOLE_LOSS_DB",
    "CodebookDesign",
    "RoiLoss",
    "auto_design",
    "design_at",
    "roi_sample_points",
    "smallest_hole_free",
    "worst_roi_loss",
]

#: First sidelobe of a uniform linear array, ``max |sin x / x|^2`` beyond the first null
#: (x = 4.4934, tan x = x): 20 log10(0.21723) = -13.26 dB. A point of the ROI where the
#: best beam is further below its peak than this is a hole.
HOLE_LOSS_DB = 13.26
#: Sampling of the ROI: a grid of this many points per axis (inside the ellipse) plus
#: this many points on its boundary (the worst point is usually there or where four
#: beams meet; tests check the sampled worst against a 4x finer grid to 0.1 dB).
N_GRID, N_EDGE = 201, 5760
#: Fractions of an O interval tried by ``auto`` (the ends are avoided: there a beam
#: boresight lies exactly on the ROI boundary and rounding would change the count).
_TRIES = np.linspace(0.1, 0.9, 9)
#: Directions per chunk of :func:`_best_gain_lin`'s maxima (they then stay in cache).
_CHUNK = 4096


@dataclass(frozen=True)
class RoiLoss:
    """Worst-case loss inside the ROI: ``loss_db`` [dB] >= 0 at ROI-plane point
    ``(x_m, y_m)`` [m]."""

    loss_db: float
    x_m: float
    y_m: float


@dataclass(frozen=True)
class CodebookDesign:
    """A codebook with its coverage figures.

    Attributes
    ----------
    codebook : Codebook
    n_rf : int, RF chains (beams that can be radiated at once).
    loss : RoiLoss, worst-case loss inside the ROI.
    """

    codebook: Codebook
    n_rf: int
    loss: RoiLoss

    @property
    def oversampling(self) -> float:
        return self.codebook.oversampling

    @property
    def n_beam(self) -> int:
        return self.codebook.n_beam

    @property
    def idle_rf(self) -> int:
        """RF chains without a beam (negative: more beams than chains)."""
        return self.n_rf - self.n_beam

    @property
    def overlapping(self) -> bool:
        """Neighbouring main lobes touch: ``O >= 1`` (a single beam has no neighbour)."""
        return self.oversampling >= 1.0 or self.n_beam == 1

    @property
    def holes(self) -> bool:
        """``O < 1`` or a point of the ROI more than :data:`HOLE_LOSS_DB` below the peak."""
        return not self.overlapping or self.loss.loss_db > HOLE_LOSS_DB

    def describe(self) -> str:
        """One line: O, beams, RF chains, worst-case loss and where."""
        idle = f"{self.idle_rf} idle" if self.idle_rf >= 0 else f"{-self.idle_rf} too many"
        return (
            f"O = {self.oversampling:.4g}, {self.n_beam} beams for {self.n_rf} RF chains "
            f"({idle}); worst point of the ROI {self.loss.loss_db:.1f} dB below the beam "
            f"peak, at x = {self.loss.x_m / 1e3:.0f} km, y = {self.loss.y_m / 1e3:.0f} km"
        )


def roi_sample_points(rx_m, ry_m, n_grid=N_GRID, n_edge=N_EDGE):
    """ROI-plane points: a grid inside the ellipse and points on its boundary.

    Returns
    -------
    x_m, y_m : ndarray, shape (n,)
        About ``pi / 4 n_grid^2 + n_edge`` points [m].
    """
    x = np.linspace(-rx_m, rx_m, n_grid)
    y = np.linspace(-ry_m, ry_m, n_grid)
    xx, yy = np.meshgrid(x, y, indexing="ij")
    inside = (xx / rx_m) ** 2 + (yy / ry_m) ** 2 <= 1.0
    phi = np.linspace(0.0, 2.0 * np.pi, n_edge, endpoint=False)
    return np.r_[xx[inside], rx_m * np.cos(phi)], np.r_[yy[inside], ry_m * np.sin(phi)]


@functools.lru_cache(maxsize=16)
def _roi_directions(rx_m, ry_m, altitude_m, radius_m, n_grid, n_edge):
    """ROI sample points and their direction cosines from the canonical satellite."""
    x, y = roi_sample_points(rx_m, ry_m, n_grid, n_edge)
    sat = canonical_satellite(altitude_m, radius_m)
    ground = roi_to_ground(x, y, sat, CANONICAL_ALONG_TRACK, radius_m)
    u = direction_cosines(sat, CANONICAL_ALONG_TRACK, ground)
    for a in (x, y, u):
        a.setflags(write=False)
    return x, y, u


@functools.lru_cache(maxsize=4)  # ~2.4 MB each with the default sampling
def _roi_trig(directions_key, n_sub_x, n_sub_y):
    """:func:`~leolink.antenna.array.dirichlet_trig` of the ROI samples along x and y:
    the same for every O that ``auto`` tries (a third of a design's time)."""
    u = _roi_directions(*directions_key)[2]
    trig = dirichlet_trig(u[:, 0], n_sub_x), dirichlet_trig(u[:, 1], n_sub_y)
    for axis in trig:
        for a in axis:
            a.setflags(write=False)
    return trig


def _best_gain_lin(codebook, u_xy, trig=(None, None)):
    """Best beam's linear gain at each direction ``u_xy (n, 2)`` -> (n,) (``trig``: the
    directions' :func:`~leolink.antenna.array.dirichlet_trig` along x and y, if known)."""
    bx, ix = np.unique(codebook.u_xy[:, 0], return_inverse=True)
    by, iy = np.unique(codebook.u_xy[:, 1], return_inverse=True)
    # max_b kx[ix_b] ky[iy_b] = max_i kx[i] max_{b: ix_b = i} ky[iy_b]: the kernels are
    # >= 0 and rounding is monotone, so the y-maximum first gives the same bits, with one
    # product per lattice column instead of one per beam.
    present = np.zeros((bx.size, by.size), bool)  # beam at lattice column i, row j
    present[ix, iy] = True
    columns = []
    for i in range(bx.size):
        rows = np.flatnonzero(present[i])  # sorted, as np.unique of iy[ix == i]
        contiguous = rows[-1] - rows[0] + 1 == rows.size  # the usual case: a run of rows
        columns.append(slice(rows[0], rows[-1] + 1) if contiguous else rows)
    kx = dirichlet_kernels(u_xy[:, 0], bx, codebook.n_sub_x, trig[0])
    ky = dirichlet_kernels(u_xy[:, 1], by, codebook.n_sub_y, trig[1])
    best = np.zeros(u_xy.shape[0])
    column = np.empty(min(best.size, _CHUNK))
    for lo in range(0, best.size, _CHUNK):  # chunks of directions that stay in cache
        part = slice(lo, lo + _CHUNK)
        out, col = best[part], column[: best[part].size]
        for i, rows in enumerate(columns):
            np.max(ky[rows, part], axis=0, out=col)
            col *= kx[i, part]
            np.maximum(out, col, out=out)
    return best


#: Relative gap below which two sampled points' gains tie (the kernels' rounding: ~1e-13).
TIE_REL = 1e-9


def worst_roi_loss(
    codebook, rx_m, ry_m, altitude_m, radius_m=EARTH_RADIUS_M, n_grid=N_GRID, n_edge=N_EDGE
):
    """Worst-case loss of the best beam below the beam peak over the ROI (sampled).

    Canonical geometry of :mod:`leolink.antenna.codebook` (the ROI under the satellite).

    Parameters
    ----------
    codebook : Codebook
    rx_m, ry_m : float, ROI semi-axes [m].
    altitude_m, radius_m : float, satellite height and Earth radius [m].
    n_grid, n_edge : int, sampling of :func:`roi_sample_points`.

    Returns
    -------
    RoiLoss
        ``10 log10(n_sub_x n_sub_y / max_b G_b)`` at the worst sampled point [dB].
    """
    key = (float(rx_m), float(ry_m), float(altitude_m), float(radius_m), int(n_grid), int(n_edge))
    x, y, u = _roi_directions(*key)
    if codebook.n_beam == 0:
        return RoiLoss(np.inf, float(x[0]), float(y[0]))
    trig = _roi_trig(key, int(codebook.n_sub_x), int(codebook.n_sub_y))
    gain = _best_gain_lin(codebook, u, trig) / (codebook.n_sub_x * codebook.n_sub_y)
    # Symmetric points of the ROI tie: the first within TIE_REL of the least, so that the
    # point reported does not depend on how the kernels were rounded.
    k = int(np.argmax(gain <= gain.min() * (1.0 + TIE_REL)))
    with np.errstate(divide="ignore"):
        return RoiLoss(float(-10.0 * np.log10(gain[k])), float(x[k]), float(y[k]))


@functools.lru_cache(maxsize=256)
def design_at(n_sub_x, n_sub_y, n_rf, oversampling, rx_m, ry_m, altitude_m, radius_m):
    """The :class:`CodebookDesign` of one given O (cached: ``auto`` tries the same O's
    again for every command that builds the codebook)."""
    cb = build_codebook(n_sub_x, n_sub_y, oversampling, rx_m, ry_m, altitude_m, radius_m)
    return CodebookDesign(cb, int(n_rf), worst_roi_loss(cb, rx_m, ry_m, altitude_m, radius_m))


def _intervals(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m):
    """``[(o_low, o_high, n_beam), ...]``: the O intervals of each beam count, ascending."""
    edges, count = beam_count_steps(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m)
    lows = np.r_[0.0, edges[:-1]]
    return [
        (float(lo), float(hi), int(n))
        for lo, hi, n in zip(lows, edges, np.r_[1, count[:-1]], strict=True)
    ]


def _best_in(interval, n_sub_x, n_sub_y, n_rf, geometry, allow_holes):
    """Least-loss design inside one O interval (only O >= 1 unless holes are allowed)."""
    lo, hi, _ = interval
    tries = lo + (hi - lo) * _TRIES
    if not allow_holes:
        tries = tries[tries >= 1.0]
    geometry = tuple(float(g) for g in geometry)
    designs = [design_at(int(n_sub_x), int(n_sub_y), int(n_rf), float(o), *geometry) for o in tries]
    if not designs:
        return None
    # Least loss; among equal losses (to 0.01 dB) the O nearest the interval's middle.
    mid = 0.5 * (lo + hi)
    return min(designs, key=lambda d: (round(d.loss.loss_db, 2), abs(d.oversampling - mid)))


def auto_design(
    n_sub_x, n_sub_y, n_rf, rx_m, ry_m, altitude_m, radius_m=EARTH_RADIUS_M, allow_holes=False
):
    """``oversampling = "auto"``: the most beams the RF chains can drive without holes.

    Beam counts are tried from the largest ``<= n_rf`` downwards; in each count's O
    interval, 9 values of O (10 % to 90 % of the interval) are tried and the one with the
    least worst-case ROI loss is kept. With ``allow_holes`` the largest count wins
    whatever its holes.

    Returns
    -------
    best : CodebookDesign or None
        The chosen design; None if every count ``<= n_rf`` leaves holes.
    largest : CodebookDesign
        The least-loss design of the largest count ``<= n_rf`` (what the chains could
        drive if holes were allowed), for messages.
    """
    geometry = (rx_m, ry_m, altitude_m, radius_m)
    steps = _intervals(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m)
    fits = [iv for iv in steps if iv[2] <= n_rf][::-1]
    largest = _best_in(fits[0], n_sub_x, n_sub_y, n_rf, geometry, allow_holes=True)
    if allow_holes:
        return largest, largest
    for interval in fits:
        if interval[1] <= 1.0:
            break  # every O of this count and of all smaller counts is < 1
        design = _best_in(interval, n_sub_x, n_sub_y, n_rf, geometry, allow_holes=False)
        if design is not None and not design.holes:
            return design, largest
    return None, largest


def smallest_hole_free(
    n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m=EARTH_RADIUS_M, max_tries=40
):
    """The hole-free design with the fewest beams (how many RF chains would do), or None.

    Only counts whose O interval reaches ``O >= 1`` are tried, at most ``max_tries``.
    """
    geometry = (rx_m, ry_m, altitude_m, radius_m)
    tried = 0
    for interval in _intervals(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m):
        if interval[1] <= 1.0:
            continue
        design = _best_in(interval, n_sub_x, n_sub_y, interval[2], geometry, False)
        if design is not None and not design.holes:
            return design
        tried += 1
        if tried >= max_tries:
            break
    return None
