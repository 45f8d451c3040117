"""UT tiles: nearby UTs grouped so that each group is screened against the satellites its
cap can see, not against the satellites every UT of the run might see.

The cap of a group of UTs: with ``c`` the group's mean direction, ``s`` the largest
Earth-central angle of one of its UTs from ``c`` and ``a`` the Earth-central angle at which a
satellite is seen at the mask (:func:`leolink.geometry.earth_central_angle_rad`), a
satellite that some UT of the group sees at or above the mask is within ``s + a`` of ``c``
(the triangle inequality on the sphere of directions). ``a`` is taken at the group's lowest
UT radius and the satellites' highest, with the mask lowered by the largest angle between a
UT's local up (WGS 84: the ellipsoid's normal) and its radius, since the elevation above
the plane normal to the radius is at least the elevation minus that angle. Each of the
three only widens ``a``: the cap holds every satellite some UT sees, on the sphere and on
the ellipsoid, for UTs below the surface and in the air, so pruning by caps stays exact.

Groups (:func:`choose_groups`): the cells of a cube map of the UTs' directions (``m x m``
cells of equal angle per face, ~90/m deg wide), with ``m`` chosen, once per block of
epochs, to minimise the pairs screened plus :data:`GROUP_COST_PAIRS` per group (a
screening costs a few numpy calls however small); ``m = 0`` is one group of every UT (the
cone of UTs in one ROI), kept unless tiles cost less than :data:`TILE_GAIN` of it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.geometry import earth_central_angle_rad

__all__ = ["CAP_MARGIN_RAD", "GROUP_COST_PAIRS", "SUBDIVISIONS", "choose_groups", "cube_cells"]
__all__ += ["TILE_GAIN", "Caps", "group_cones"]

#: Cells per cube face tried by :func:`choose_groups` (0: one group of every UT).
SUBDIVISIONS = (0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32)
#: The fixed cost of screening a group, in screened pairs (measured: a screening of a few
#: UTs costs ~40 us of calls, the compiled loop ~10 ns a pair).
GROUP_COST_PAIRS = 4096
#: Tiles are used when their cost is below this share of one group's (the one group
#: of UTs in one ROI is screened densely, ~30 % faster per pair than by caps).
TILE_GAIN = 0.5
#: A cap's margin over rounding [rad]: arccos near 1 errs by ~1e-8 rad.
CAP_MARGIN_RAD = 1e-3


def cube_cells(unit, m):
    """Cell of each direction on a cube map of ``m x m`` equal-angle cells per face.

    Parameters
    ----------
    unit : ndarray, shape (n, 3)
        Unit vectors.
    m : int
        Cells per face edge; 0: every direction in cell 0.

    Returns
    -------
    ndarray of int, shape (n,)
        ``(face m + i) m + j``, ``face = 2 axis + (component < 0)`` of the largest
        component, ``i, j`` the cells of the angles ``atan(u_k / |u_axis|)`` in
        ``[-pi/4, pi/4]`` of the two other components.
    """
    n = len(unit)
    if m == 0:
        return np.zeros(n, np.int64)
    axis = np.argmax(np.abs(unit), axis=1)
    rows = np.arange(n)
    major = np.abs(unit[rows, axis])
    face = 2 * axis + (unit[rows, axis] < 0)
    cells = [
        np.clip(((np.arctan2(unit[rows, (axis + k) % 3], major) / (np.pi / 2) + 0.5) * m)
                .astype(np.int64), 0, m - 1)
        for k in (1, 2)
    ]  # fmt: skip
    return (face * m + cells[0]) * m + cells[1]


def _centres(unit, group, n_group):
    """Mean direction (n_group, 3) and angular spread [rad] (n_group,) of each group of
    ``unit`` (``group``: each row's group); spread pi where the mean is ~0 (no cap)."""
    total = np.stack([np.bincount(group, unit[:, k], n_group) for k in range(3)], axis=1)
    norm = np.linalg.norm(total, axis=1)
    counts = np.bincount(group, minlength=n_group)
    flat = norm < 1e-6 * np.maximum(counts, 1)  # directions all over the globe
    centre = total / np.where(flat, 1.0, norm)[:, None]
    cos = np.einsum("nk,nk->n", unit, centre[group])
    spread = np.zeros(n_group)
    np.maximum.at(spread, group, np.arccos(np.clip(cos, -1.0, 1.0)))
    spread[flat] = np.pi
    return centre, spread


def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def choose_groups(ut_pos_m, n_sat, reach_rad):
    """Groups of UTs for screening (module docstring): each a sorted array of UT indices.

    Parameters
    ----------
    ut_pos_m : ndarray, shape (n_ut, 3)
        The UTs (one epoch of a block).
    n_sat : int
        Satellites of the constellation.
    reach_rad : float
        A typical Earth-central angle of the mask [rad] (the cost model's only; the caps
        are computed by :func:`group_cones`).

    Returns
    -------
    list of ndarray of int
        The groups of the cheapest subdivision.
    """
    unit = _unit(ut_pos_m)
    best = None
    for m in SUBDIVISIONS:
        _, group, counts = np.unique(cube_cells(unit, m), return_inverse=True, return_counts=True)
        _, spread = _centres(unit, group.reshape(-1), len(counts))
        cap = 0.5 * (1.0 - np.cos(np.minimum(spread + reach_rad, np.pi)))  # share of the sky
        cost = n_sat * float(counts @ cap) + GROUP_COST_PAIRS * len(counts)
        if best is None:
            one = cost  # m = 0: every UT in one group
            if GROUP_COST_PAIRS > TILE_GAIN * one:  # no tiling can cost less (>= 1 group)
                return [np.arange(len(unit))]
        if best is None or cost < best[0]:
            best = (cost, group.reshape(-1))
    if best[0] > TILE_GAIN * one:  # (the one group's dense path is the faster per pair)
        return [np.arange(len(unit))]
    order = np.argsort(best[1], kind="stable")
    return np.split(order, np.flatnonzero(np.diff(best[1][order])) + 1)


@dataclasses.dataclass
class Caps:
    """The satellites of each group's cap, flat.

    Attributes
    ----------
    sat : ndarray of int, shape (m,)
        Satellites (ascending within a group).
    start : ndarray of int, shape (n_group + 1,)
        Group ``g``'s satellites are ``sat[start[g] : start[g + 1]]``.
    group : ndarray of int, shape (n_ut,)
        Each UT's group.
    """

    sat: np.ndarray
    start: np.ndarray
    group: np.ndarray

    def of(self, g):
        """The satellites of group ``g``."""
        return self.sat[self.start[g] : self.start[g + 1]]

    def pairs(self, ut_start, flat):
        """UT and satellite of the flat pair indices ``flat`` (ascending) of a layout where
        UT ``i``'s pairs, its group's satellites in order, are ``ut_start[i] ..
        ut_start[i + 1] - 1``."""
        size = np.diff(ut_start)
        ut = np.repeat(np.arange(size.size), size)[flat]
        return ut, self.sat[(self.start[self.group] - ut_start[:-1])[ut] + flat]


def group_cones(sat_pos_m, ut_pos_m, ut_up, min_elevation_rad, group, n_group):
    """The satellites each group's cap holds (module docstring).

    Parameters
    ----------
    sat_pos_m : ndarray, shape (n_sat, 3)
    ut_pos_m : ndarray, shape (n_ut, 3)
    ut_up : ndarray, shape (n_ut, 3), or None
        Local up of each UT (WGS 84); None: the radial up.
    min_elevation_rad : float
    group : ndarray of int, shape (n_ut,)
        Each UT's group, in ``0 .. n_group - 1``.
    n_group : int

    Returns
    -------
    Caps
        The ids (ascending) of the satellites in each group's cap.
    """
    r_ut = np.linalg.norm(ut_pos_m, axis=1)
    unit = ut_pos_m / r_ut[:, None]
    centre, spread = _centres(unit, group, n_group)
    r_low = np.full(n_group, np.inf)
    np.minimum.at(r_low, group, r_ut)
    tilt = np.zeros(n_group)
    if ut_up is not None:  # the mask, measured from the radius, drops by the up's tilt
        cos_tilt = np.clip(np.einsum("nk,nk->n", ut_up, unit), -1.0, 1.0)
        np.maximum.at(tilt, group, np.arccos(cos_tilt))
    r_sat = np.linalg.norm(sat_pos_m, axis=1)
    reach = earth_central_angle_rad(min_elevation_rad - tilt, r_sat.max() - r_low, r_low)
    cos_cap = np.cos(np.minimum(spread + reach + CAP_MARGIN_RAD, np.pi))
    near = centre @ (sat_pos_m / r_sat[:, None]).T >= cos_cap[:, None]  # (n_group, n_sat)
    g, s = np.nonzero(near)
    start = np.zeros(n_group + 1, np.int64)
    np.cumsum(np.bincount(g, minlength=n_group), out=start[1:])
    return Caps(s, start, group)
