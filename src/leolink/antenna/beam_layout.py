"""Hexagonal multibeam layout on the UV plane, 3GPP TR 38.821 Table 6.1.1.1-4 and -6.

TR 38.821's system-level calibration maps the beam boresights of one satellite onto a
hexagonal grid of the UV plane of the satellite frame (nadir at ``(0, 0)``), spaced by the
adjacent beam spacing

    ABS = sqrt(3) sin(HPBW / 2)                                   (Table 6.1.1.1-4)

from the 3 dB beamwidth ``HPBW`` alone ("only the 3 dB beam width parameters should be
used"). With that spacing the vertices of each beam's hexagonal cell, at ``ABS / sqrt(3)
= sin(HPBW / 2)`` from its centre, lie on the beam's -3 dB contour (for the small UV
offsets of a LEO beam). The baseline is 19 beams (the central beam and 2 tiers); the
interference of the surrounding beams is simulated explicitly with 2 more tiers at
frequency reuse 1 (61 beams) and 4 more at reuse > 1 (127 beams) (text under Table
6.1.1.1-5); only UTs in the inner 19 cells count for the statistics.

Beams are numbered tier by tier (the central beam 0, tier 1 is 1..6, tier 2 is 7..18, ...),
so the inner ``1 + 3 t (t + 1)`` beams are the first ones. Lattice indices ``(i, j)`` are
the axial coordinates of the grid with basis vectors ``ABS (1, 0)`` and
``ABS (1/2, sqrt(3)/2)``; the reuse colours are those of the lattice indices
(:func:`leolink.engine.links.reuse_colors`; 3 colours: ``(i + 2 j) mod 3``, no two
neighbours alike on this grid either), given by the caller (:mod:`leolink.multibeam`).

References
----------
.. [1] 3GPP TR 38.821 V16.2.0, Tables 6.1.1.1-4, 6.1.1.1-5 and 6.1.1.1-6.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = [
    "HexBeamLayout",
    "adjacent_beam_spacing_uv",
    "hex_beam_layout",
    "hex_lattice",
    "n_beams_within",
]


def adjacent_beam_spacing_uv(hpbw_rad):
    """``ABS = sqrt(3) sin(HPBW / 2)`` on the UV plane [-] (TR 38.821 Table 6.1.1.1-4)."""
    return np.sqrt(3.0) * np.sin(0.5 * np.asarray(hpbw_rad, dtype=float))


def n_beams_within(n_tiers):
    """Beams of the central beam and ``n_tiers`` hexagonal tiers: ``1 + 3 t (t + 1)``."""
    return 1 + 3 * n_tiers * (n_tiers + 1)


def hex_lattice(n_tiers):
    """Axial indices ``(i, j)`` of the grid points within ``n_tiers`` hexagonal steps.

    Returns
    -------
    ij : ndarray of int, shape (n, 2)
        Ordered by tier (hexagonal distance ``max(|i|, |j|, |i + j|)``), then by angle.
    tier : ndarray of int, shape (n,)
    """
    r = np.arange(-n_tiers, n_tiers + 1)
    i, j = (a.ravel() for a in np.meshgrid(r, r, indexing="ij"))
    tier = np.maximum(np.maximum(np.abs(i), np.abs(j)), np.abs(i + j))
    keep = tier <= n_tiers
    i, j, tier = i[keep], j[keep], tier[keep]
    angle = np.mod(np.arctan2(np.sqrt(3.0) / 2.0 * j, i + 0.5 * j), 2.0 * np.pi)
    order = np.lexsort((angle, tier))
    return np.stack([i[order], j[order]], axis=1), tier[order]


@dataclasses.dataclass(frozen=True)
class HexBeamLayout:
    """Beam boresights of one satellite on the UV plane.

    Attributes
    ----------
    beam_uv : ndarray, shape (n_beam, 2)
        Direction cosines of each boresight in the satellite frame [-].
    tier : ndarray of int, shape (n_beam,)
        Hexagonal ring of each beam (0: the central beam).
    lattice_ij : ndarray of int, shape (n_beam, 2)
        Axial lattice indices of each beam.
    spacing_uv : float
        Adjacent beam spacing ``ABS`` [-].
    """

    beam_uv: np.ndarray
    tier: np.ndarray
    lattice_ij: np.ndarray
    spacing_uv: float


def hex_beam_layout(n_tiers, hpbw_rad):
    """The hexagonal layout of TR 38.821 Table 6.1.1.1-4, central beam at nadir.

    Parameters
    ----------
    n_tiers : int
        Tiers around the central beam (4: 61 beams, reuse 1; 6: 127 beams, reuse > 1).
    hpbw_rad : float
        3 dB beamwidth the spacing comes from [rad] (TR 38.821 Table 6.1.1.1-1).

    Returns
    -------
    HexBeamLayout
    """
    ij, tier = hex_lattice(n_tiers)
    spacing = float(adjacent_beam_spacing_uv(hpbw_rad))
    i, j = ij[:, 0].astype(float), ij[:, 1].astype(float)
    uv = spacing * np.stack([i + 0.5 * j, np.sqrt(3.0) / 2.0 * j], axis=1)
    return HexBeamLayout(uv, tier, ij, spacing)
