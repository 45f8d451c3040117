"""Tests of leolink.antenna.codebook: DFT lattice, ROI pruning, oversampling search."""

import numpy as np
import pytest

from leolink.antenna.array import explicit_gain, steering_vector
from leolink.antenna.codebook import (
    build_codebook,
    dft_lattice,
    find_oversampling,
    footprint_centres,
    oversampling_interval,
)
from leolink.constants import EARTH_RADIUS_M
from leolink.errors import LeolinkError

# The paper's table: h = 1300 km, ROI 534.1 x 170.5 km, subarrays 12 x 24, O = 1.2.
H_M, RX_M, RY_M = 1300e3, 534.1e3, 170.5e3


def _roi_by_vectors(u_xy, altitude_m):
    """Second computation: ray/sphere by 3-D vectors and numpy.roots, then (x, y) = R p/p_z."""
    r = EARTH_RADIUS_M
    sat = np.array([0.0, 0.0, r + altitude_m])
    d = np.concatenate([u_xy, -np.sqrt(1 - np.sum(u_xy**2, -1, keepdims=True))], -1)
    # solve |sat + t d|^2 = r^2 with numpy.roots, smallest positive root
    out = []
    for di in d:
        t = min(np.roots([1.0, 2 * sat @ di, sat @ sat - r**2]).real)
        p = sat + t * di
        out.append(r * p[:2] / p[2])
    return np.array(out)


def test_dft_lattice_symmetric_and_spaced():
    u = dft_lattice(12, 1.2)
    np.testing.assert_allclose(np.diff(u), 2 / 14.4, rtol=1e-12)
    np.testing.assert_allclose(u, -u[::-1], atol=1e-15)
    assert np.all(np.abs(u) < 1) and u.size == 15  # k = -7..7 (|u_7| = 0.972)
    # integer O N: the symmetric lattice equals the paper's set {2 (n-1) / (O N)} mod 2
    paper = (2.0 * np.arange(16) / 16 + 1.0) % 2.0 - 1.0
    assert set(np.round(dft_lattice(8, 2.0), 12)) == set(np.round(paper, 12)) - {-1.0}


def test_paper_codebook_has_5_by_3_beams():
    cb = build_codebook(12, 24, 1.2, RX_M, RY_M, H_M)
    assert cb.n_beam == 15
    ij = cb.lattice_index
    assert set(ij[:, 0]) == {-2, -1, 0, 1, 2} and set(ij[:, 1]) == {-1, 0, 1}
    # row-major by (u_x, then u_y)
    assert np.array_equal(np.lexsort((cb.u_xy[:, 1], cb.u_xy[:, 0])), cb.beam_id)


def test_boresights_inside_roi_and_match_vector_geometry():
    cb = build_codebook(12, 24, 1.2, RX_M, RY_M, H_M)
    x_m, y_m = footprint_centres(cb, H_M)
    assert np.all((x_m / RX_M) ** 2 + (y_m / RY_M) ** 2 <= 1)
    ref = _roi_by_vectors(cb.u_xy, H_M)
    np.testing.assert_allclose(np.stack([x_m, y_m], -1), ref, atol=1e-3)  # 1 mm of 6e6 m


def test_pruning_keeps_exactly_the_lattice_points_in_the_roi():
    cb = build_codebook(12, 24, 2.0, RX_M, RY_M, H_M)
    u = np.stack(np.meshgrid(dft_lattice(12, 2.0), dft_lattice(24, 2.0), indexing="ij"), -1)
    u = u.reshape(-1, 2)
    u = u[np.sum(u**2, -1) < 0.6]  # far beyond the ROI (|u| < 0.37), all hit the Earth
    xy = _roi_by_vectors(u, H_M)
    inside = (xy[:, 0] / RX_M) ** 2 + (xy[:, 1] / RY_M) ** 2 <= 1
    assert cb.n_beam == inside.sum()
    assert set(map(tuple, np.round(cb.u_xy, 12))) == set(map(tuple, np.round(u[inside], 12)))


def test_more_beams_at_larger_oversampling():
    counts = [build_codebook(12, 24, o, RX_M, RY_M, H_M).n_beam for o in (1.2, 1.3, 2.0, 2.49)]
    assert counts[0] == 15
    assert all(b > a for a, b in zip(counts, counts[1:], strict=False))


def test_find_oversampling_gives_n_rf_beams():
    o = find_oversampling(12, 24, 15, RX_M, RY_M, H_M)
    low, high = oversampling_interval(12, 24, 15, RX_M, RY_M, H_M)
    assert low < o < high and low < 1.2 < high  # the paper's O = 1.2 is in the interval
    assert build_codebook(12, 24, o, RX_M, RY_M, H_M).n_beam == 15
    # step edges: just inside the interval 15 beams, just outside not
    assert build_codebook(12, 24, low * (1 + 1e-9), RX_M, RY_M, H_M).n_beam == 15
    assert build_codebook(12, 24, low * (1 - 1e-9), RX_M, RY_M, H_M).n_beam < 15
    assert build_codebook(12, 24, high * (1 - 1e-9), RX_M, RY_M, H_M).n_beam == 15
    assert build_codebook(12, 24, high * (1 + 1e-9), RX_M, RY_M, H_M).n_beam > 15


def test_find_oversampling_for_several_counts_by_brute_force_grid():
    grid = np.linspace(0.3, 3.0, 2701)
    counts = np.array([build_codebook(12, 24, o, RX_M, RY_M, H_M).n_beam for o in grid])
    for n_rf in (9, 15, 27):
        o = find_oversampling(12, 24, n_rf, RX_M, RY_M, H_M)
        hits = grid[counts == n_rf]
        assert hits.min() - 1e-3 <= o <= hits.max() + 1e-3


def test_find_oversampling_reports_impossible_count():
    with pytest.raises(LeolinkError, match="no oversampling factor gives exactly n_rf = 7"):
        find_oversampling(12, 24, 7, RX_M, RY_M, H_M)


def test_codebook_gain_matches_explicit():
    cb = build_codebook(12, 24, 1.2, RX_M, RY_M, H_M)
    rng = np.random.default_rng(5)
    u = rng.uniform(-0.4, 0.4, (200, 2))
    ref = explicit_gain(u, steering_vector(cb.u_xy, 12, 24).T, 12, 24)
    np.testing.assert_allclose(cb.gain_lin(u), ref, rtol=1e-9, atol=1e-10 * 288)
