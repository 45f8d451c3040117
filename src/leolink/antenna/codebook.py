"""Oversampled 2-D DFT beam codebook pruned to the elliptical ROI (Sec. 3.2 of [1]).

Each subarray uses a DFT beam on the lattice ``u_k = 2 k / (O N_sub)``, ``|u_k| < 1``
(the paper's phases ``theta = pi u``); the codebook keeps the lattice beams whose boresight
ray from the satellite hits the ground inside the ROI ellipse ``(x/R_x)^2 + (y/R_y)^2 <= 1``
of the ROI plane (the paper's gnomonic parametrization, Sec. 3.1).

The geometry here is the canonical one: satellite at ``(0, 0, R + h)``, velocity along
``+x``, so body axes = ECI axes; rays, ground points and the ROI plane are mapped with
:mod:`leolink.geometry`.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
"""

from dataclasses import dataclass

import numpy as np

from leolink.antenna.array import beam_gain_lin
from leolink.constants import EARTH_RADIUS_M
from leolink.errors import LeolinkError, require_at_least
from leolink.geometry import direction_cosines, ground_to_roi, ray_to_ground, roi_to_ground


def dft_lattice(n_sub, oversampling):
    """Symmetric oversampled DFT lattice ``u_k = 2 k / (O n_sub)``, ``|u_k| < 1`` (Eq. (14)).

    leolink departs from the paper's index set ``{2 pi (n - 1) / (O N)}_{n=1}^{O N}``: for a
    non-integer ``O N`` (the paper's 1.2 x 12 = 14.4) that set is not uniform across the
    wrap at ``u = +-1``; the symmetric lattice equals it modulo 2 when ``O N`` is an
    integer (see docs/errata.md).

    Parameters
    ----------
    n_sub : int
        Subarray elements along the axis.
    oversampling : float
        Oversampling factor ``O > 0``.

    Returns
    -------
    ndarray, shape (n_k,)
        Beam direction cosines, ascending, symmetric about 0 [-].
    """
    k_max = int(np.floor(oversampling * n_sub / 2.0))
    k = np.arange(-k_max, k_max + 1)
    u = 2.0 * k / (oversampling * n_sub)
    return u[np.abs(u) < 1.0]


#: Direction of the canonical satellite's velocity (its body x axis).
CANONICAL_ALONG_TRACK = np.array([1.0, 0.0, 0.0])


def canonical_satellite(altitude_m, radius_m=EARTH_RADIUS_M):
    """Position [m] of the canonical satellite: over the pole, moving along +x, so that its
    body axes are the Earth-centred axes (the geometry of codebook design)."""
    return np.array([0.0, 0.0, radius_m + altitude_m])


def _ray_to_roi_plane(u_xy, altitude_m, radius_m):
    """ROI-plane (x, y) [m] where the ray u_xy (..., 2) hits the sphere; NaN if it misses."""
    sat = canonical_satellite(altitude_m, radius_m)
    ground = ray_to_ground(sat, CANONICAL_ALONG_TRACK, u_xy, radius_m)
    return ground_to_roi(ground, sat, CANONICAL_ALONG_TRACK, radius_m)


def _roi_radius_to_u(rho_m, altitude_m, radius_m):
    """|u| of the ray that hits the ROI-plane radius rho_m [m] (azimuth is preserved by the map)."""
    sat = canonical_satellite(altitude_m, radius_m)
    ground = roi_to_ground(rho_m, 0.0, sat, CANONICAL_ALONG_TRACK, radius_m)
    return np.hypot(*np.moveaxis(direction_cosines(sat, CANONICAL_ALONG_TRACK, ground), -1, 0))


@dataclass(frozen=True)
class Codebook:
    """Pruned DFT codebook of one satellite.

    Attributes
    ----------
    u_xy : ndarray, shape (n_beam, 2)
        Beam boresights, direction cosines in the body frame [-].
    beam_id : ndarray of int, shape (n_beam,)
        0..n_beam-1, row-major by (u_x, then u_y).
    oversampling : float
        Oversampling factor O.
    n_sub_x, n_sub_y : int
        Subarray size that forms each beam.
    """

    u_xy: np.ndarray
    beam_id: np.ndarray
    oversampling: float
    n_sub_x: int
    n_sub_y: int

    @property
    def n_beam(self):
        """Number of beams."""
        return self.u_xy.shape[0]

    @property
    def lattice_index(self):
        """Integer lattice indices (i, j) per beam, ``u = 2 (i / (O n_sub_x), j / (O n_sub_y))``.

        Returns
        -------
        ndarray of int, shape (n_beam, 2)
        """
        scale = 0.5 * self.oversampling * np.array([self.n_sub_x, self.n_sub_y])
        return np.rint(self.u_xy * scale).astype(int)

    def gain_lin(self, u_xy):
        """Linear gain of every beam towards directions ``u_xy (..., 2)`` -> ``(..., n_beam)``.

        Closed form :func:`leolink.antenna.array.beam_gain_lin`; peak ``n_sub_x n_sub_y``.
        """
        return beam_gain_lin(u_xy, self.u_xy, self.n_sub_x, self.n_sub_y)

    gain = gain_lin  # name used in docs/architecture.md


def _full_lattice(n_sub_x, n_sub_y, oversampling):
    """All lattice beams (n, 2), row-major by (u_x, u_y), inside the unit disc."""
    ux, uy = np.meshgrid(
        dft_lattice(n_sub_x, oversampling), dft_lattice(n_sub_y, oversampling), indexing="ij"
    )
    u = np.stack([ux.ravel(), uy.ravel()], axis=-1)
    return u[np.sum(u**2, axis=-1) < 1.0]


def _check_roi(rx_m, ry_m, altitude_m, radius_m):
    """Validate the ROI and the orbit."""
    require_at_least("roi.rx_m", rx_m, np.finfo(float).tiny, "ROI semi-axis along-track, > 0")
    require_at_least("roi.ry_m", ry_m, np.finfo(float).tiny, "ROI semi-axis cross-track, > 0")
    require_at_least("orbit.altitude_m", altitude_m, np.finfo(float).tiny, "height above sphere")


def build_codebook(n_sub_x, n_sub_y, oversampling, rx_m, ry_m, altitude_m, radius_m=EARTH_RADIUS_M):
    """Prune the full 2-D oversampled DFT lattice to the beams that point into the ROI (Sec. 3.2).

    Parameters
    ----------
    n_sub_x, n_sub_y : int
        Subarray size (elements along x and y).
    oversampling : float
        Oversampling factor O.
    rx_m, ry_m : float
        ROI semi-axes along-track and cross-track, in the ROI plane [m].
    altitude_m : float
        Satellite height above the sphere [m].
    radius_m : float, optional
        Earth radius [m].

    Returns
    -------
    Codebook
        Beams whose boresight ray hits the ground with ``(x/R_x)^2 + (y/R_y)^2 <= 1``.
    """
    require_at_least("codebook.oversampling", oversampling, np.finfo(float).tiny, "O > 0")
    _check_roi(rx_m, ry_m, altitude_m, radius_m)
    u = _full_lattice(n_sub_x, n_sub_y, oversampling)
    x_m, y_m = _ray_to_roi_plane(u, altitude_m, radius_m)
    with np.errstate(invalid="ignore"):
        inside = (x_m / rx_m) ** 2 + (y_m / ry_m) ** 2 <= 1.0  # NaN (ray misses) -> False
    u = u[inside]
    return Codebook(
        u_xy=u,
        beam_id=np.arange(u.shape[0]),
        oversampling=float(oversampling),
        n_sub_x=int(n_sub_x),
        n_sub_y=int(n_sub_y),
    )


def footprint_centres(codebook, altitude_m, radius_m=EARTH_RADIUS_M):
    """ROI-plane points where the beam boresights hit the ground.

    Returns
    -------
    x_m, y_m : ndarray, shape (n_beam,)
        ROI-plane coordinates [m] (canonical geometry, see the module docstring).
    """
    return _ray_to_roi_plane(codebook.u_xy, altitude_m, radius_m)


def _critical_oversampling(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m, k_max):
    """O at which lattice point (i, j), 0 <= i, j <= k_max, enters the ROI -> (ij (m, 2), o_c (m,)).

    The map u -> ROI plane keeps the azimuth and is monotone in |u|, so lattice point
    (i, j), at u = (2 / O) (i / n_sub_x, j / n_sub_y), is inside for O >= o_c and outside below.
    """
    i, j = np.meshgrid(np.arange(k_max + 1), np.arange(k_max + 1), indexing="ij")
    ij = np.stack([i.ravel(), j.ravel()], axis=-1)[1:]  # (0, 0) is always inside
    vx, vy = 2.0 * ij[:, 0] / n_sub_x, 2.0 * ij[:, 1] / n_sub_y  # = O * u
    psi = np.arctan2(vy, vx)
    rho_edge_m = 1.0 / np.hypot(np.cos(psi) / rx_m, np.sin(psi) / ry_m)
    return ij, np.hypot(vx, vy) / _roi_radius_to_u(rho_edge_m, altitude_m, radius_m)


def beam_count_steps(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m=EARTH_RADIUS_M, k_max=64):
    """The beam count of the pruned codebook as a step function of O, computed exactly.

    Returns
    -------
    edges : ndarray, shape (m,)
        Ascending O at which lattice points enter the ROI.
    count : ndarray of int, shape (m,)
        Beams for O in ``[edges[k], edges[k + 1])`` (1 beam, the boresight, below
        ``edges[0]``).
    """
    _check_roi(rx_m, ry_m, altitude_m, radius_m)
    ij, o_c = _critical_oversampling(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m, k_max)
    mult = np.where(ij[:, 0] > 0, 2, 1) * np.where(ij[:, 1] > 0, 2, 1)  # +-i, +-j copies
    edges, inv = np.unique(o_c, return_inverse=True)
    count = 1 + np.cumsum(np.bincount(inv.ravel(), weights=mult)).astype(np.int64)
    return edges, count


def oversampling_interval(
    n_sub_x, n_sub_y, n_rf, rx_m, ry_m, altitude_m, radius_m=EARTH_RADIUS_M, k_max=64
):
    """Interval ``[o_low, o_high)`` of O that gives exactly ``n_rf`` beams in the ROI.

    The beam count is a non-decreasing step function of O (each lattice point enters the ROI
    at its critical O and stays in); its steps are computed exactly, not searched.

    Raises
    ------
    LeolinkError
        If no O gives exactly ``n_rf`` beams (the count jumps over it: symmetric lattice
        points enter in pairs or fours).
    """
    edges, count = beam_count_steps(n_sub_x, n_sub_y, rx_m, ry_m, altitude_m, radius_m, k_max)
    hit = np.flatnonzero(count == n_rf)
    if n_rf == 1:
        return 0.0, float(edges[0])
    if hit.size == 0 or hit[0] + 1 >= edges.size:
        below = count[count < n_rf]
        raise LeolinkError(
            f"no oversampling factor gives exactly n_rf = {n_rf} beams in the ROI "
            f"(rx = {rx_m:.0f} m, ry = {ry_m:.0f} m, h = {altitude_m:.0f} m, subarray "
            f"{n_sub_x} x {n_sub_y}); the beam count jumps from "
            f"{int(below[-1]) if below.size else 1} to {int(count[count > n_rf][0])}"
        )
    return float(edges[hit[0]]), float(edges[hit[0] + 1])


def find_oversampling(n_sub_x, n_sub_y, n_rf, rx_m, ry_m, altitude_m, radius_m=EARTH_RADIUS_M):
    """Oversampling factor that gives exactly ``n_rf`` beams pointing into the ROI (Sec. 3.2).

    The paper: "the optimal O allows the creation of as many beams pointing to the ROI as
    available RF chains". Any O in :func:`oversampling_interval` does; this returns the
    **middle** of that interval: at either end a beam boresight lies exactly on the ROI
    boundary, so a rounding error (or a slightly different Earth radius or ROI) would
    change the beam count. The interval ends are available for other choices (a larger O
    lowers the straddling loss but raises inter-beam interference).

    Returns
    -------
    float
        Oversampling factor O.
    """
    low, high = oversampling_interval(n_sub_x, n_sub_y, n_rf, rx_m, ry_m, altitude_m, radius_m)
    return 0.5 * (low + high)


__all__ = [
    "CANONICAL_ALONG_TRACK",
    "Codebook",
    "beam_count_steps",
    "canonical_satellite",
    "build_codebook",
    "dft_lattice",
    "find_oversampling",
    "footprint_centres",
    "oversampling_interval",
]
