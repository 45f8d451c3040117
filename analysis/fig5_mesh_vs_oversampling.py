"""Fig. 5: rectangular beam mesh over the ROI vs the DFT oversampling factor O.

128 x 64 satellite array with 8 x 8 RF chains (16 x 8 subarrays) at O = 2 and O = 2.49,
and the number of beams pointing into the ROI as a function of O for that array and for
the paper's main 60 x 72 / 5 x 3 array (12 x 24 subarrays, O = 1.2, 15 beams).

Paper (Sec. 5): "with O = 2, only 39 out of 64 potential beams are used"; O = 2.49 uses
all of them. With the paper's ROI (534.1 x 170.5 km, h = 1300 km) leolink finds 17 and 33
beams (see docs/errata.md); 39 beams needs O in [2.678, 2.783).

The beam count is computed twice: by ``build_codebook`` (closed-form ray -> ROI-plane
map) and by brute force here (``geometry.ray_to_ground`` then ``ground_to_roi`` from a
satellite in a generic orientation).

Run: ``python analysis/fig5_mesh_vs_oversampling.py [--fast] [--out DIR]``.
"""

from __future__ import annotations

import sys

import numpy as np
from _common import figure, paper_config, parse_args, report, roi_outline, save

from leolink.antenna.codebook import (
    _full_lattice,
    build_codebook,
    footprint_centres,
    oversampling_interval,
)
from leolink.geometry import ground_to_roi, ray_to_ground, roi_to_ground
from leolink.roi import in_ellipse

BIG = {"name": "128x64, 8x8 RF", "n_sub": (16, 8), "n_rf": 64}
PAPER = {"name": "60x72, 5x3 RF", "n_sub": (12, 24), "n_rf": 15}
O_MESH = (2.0, 2.49)
O_PAPER = 1.2


def _satellite(radius_m, altitude_m):
    """A satellite over (lat 30 deg, lon 40 deg) moving north-east: a generic body frame."""
    lat, lon = np.radians(30.0), np.radians(40.0)
    up = np.array([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    east = np.array([-np.sin(lon), np.cos(lon), 0.0])
    north = np.cross(up, east)
    return (radius_m + altitude_m) * up, 7000.0 * (east + north) / np.sqrt(2.0)


def brute_force_count(n_sub, o, rx_m, ry_m, altitude_m, radius_m):
    """Lattice beams whose boresight hits the ROI ellipse, through the geometry module."""
    sat_pos, sat_vel = _satellite(radius_m, altitude_m)
    u = _full_lattice(n_sub[0], n_sub[1], o)
    ground = ray_to_ground(sat_pos, sat_vel, u, radius_m)
    x_m, y_m = ground_to_roi(ground, sat_pos, sat_vel, radius_m)
    with np.errstate(invalid="ignore"):
        return int(np.sum((x_m / rx_m) ** 2 + (y_m / ry_m) ** 2 <= 1.0))


def beam_cells(codebook, rx_m, ry_m, altitude_m, radius_m, n_grid, margin=1.15):
    """Best beam (max gain) on an ROI-plane grid: x (n,), y (m,), beam (m, n)."""
    sat_pos, sat_vel = _satellite(radius_m, altitude_m)
    x = np.linspace(-margin * rx_m, margin * rx_m, n_grid)
    y = np.linspace(-margin * ry_m, margin * ry_m, max(n_grid // 2, 11))
    xx, yy = np.meshgrid(x, y)
    ground = roi_to_ground(xx, yy, sat_pos, sat_vel, radius_m)
    from leolink.geometry import direction_cosines

    u = direction_cosines(sat_pos, sat_vel, ground)
    return x, y, np.argmax(codebook.gain_lin(u), axis=-1)


def count_curve(n_sub, o_grid, rx_m, ry_m, altitude_m, radius_m):
    """Beams in the ROI for each O (build_codebook)."""
    return np.array(
        [build_codebook(*n_sub, o, rx_m, ry_m, altitude_m, radius_m).n_beam for o in o_grid]
    )


def _mesh_panel(ax, cb, rx_m, ry_m, h_m, radius_m, n_grid):
    x, y, beam = beam_cells(cb, rx_m, ry_m, h_m, radius_m, n_grid)
    xx, yy = np.meshgrid(x, y)
    beam = np.where(in_ellipse(xx, yy, rx_m * 1.15, ry_m * 1.15), beam, -1)
    shuffled = np.random.default_rng(0).permutation(cb.n_beam)  # neighbours differ in colour
    shown = np.ma.masked_less(np.where(beam >= 0, shuffled[beam], -1), 0)
    ax.pcolormesh(x * 1e-3, y * 1e-3, shown, cmap="tab20", shading="nearest", alpha=0.55)
    fx, fy = footprint_centres(cb, h_m, radius_m)
    ax.plot(fx * 1e-3, fy * 1e-3, "o", color="green", ms=4, label="beam boresight")
    roi_outline(ax, rx_m, ry_m, label="ROI")
    ax.set_aspect("equal")
    ax.set_xlabel("x, along-track [km]")
    ax.set_ylabel("y, cross-track [km]")
    ax.set_title(f"{BIG['name']}: O = {cb.oversampling:g}, {cb.n_beam} of {BIG['n_rf']} beams")
    ax.legend(loc="upper right", fontsize=7)


def main(argv=None):
    args = parse_args(argv, __doc__)
    cfg = paper_config()
    rx_m, ry_m = cfg.roi_semi_axes_m()
    h_m, radius_m = cfg.constellation.altitude_m, cfg.earth.radius_m
    n_grid = 121 if args.fast else 481
    o_grid = np.linspace(0.8, 4.2, 200 if args.fast else 1500)

    fig, axes = figure(2, 1, figsize=(8.0, 6.5))
    counts = {}
    for ax, o in zip(axes[:, 0], O_MESH, strict=True):
        cb = build_codebook(*BIG["n_sub"], o, rx_m, ry_m, h_m, radius_m)
        counts[o] = (cb.n_beam, brute_force_count(BIG["n_sub"], o, rx_m, ry_m, h_m, radius_m))
        _mesh_panel(ax, cb, rx_m, ry_m, h_m, radius_m, n_grid)
    pngs = [save(fig, args.out, "fig5_mesh.png")]

    fig, axes = figure(figsize=(7.5, 4.5))
    ax = axes[0, 0]
    for arr, colour in ((BIG, "tab:blue"), (PAPER, "tab:orange")):
        n = count_curve(arr["n_sub"], o_grid, rx_m, ry_m, h_m, radius_m)
        ax.step(o_grid, n, where="post", color=colour, label=f"{arr['name']} (max {arr['n_rf']})")
        ax.axhline(arr["n_rf"], color=colour, linestyle=":", linewidth=1)
    ax.plot([O_PAPER], [PAPER["n_rf"]], "o", color="tab:orange", label="O = 1.2: 15 beams")
    for o in O_MESH:
        ax.axvline(o, color="grey", linestyle="--", linewidth=0.8)
    o39 = oversampling_interval(*BIG["n_sub"], 39, rx_m, ry_m, h_m, radius_m)
    ax.axvspan(
        *o39, color="tab:red", alpha=0.2, label=f"39 beams: O in [{o39[0]:.3f}, {o39[1]:.3f})"
    )
    ax.axhline(39, color="tab:red", linestyle=":", linewidth=1)
    ax.set_xlabel("oversampling factor O")
    ax.set_ylabel("beams pointing into the ROI")
    ax.set_title("Beam count vs O (ROI 534.1 x 170.5 km, h = 1300 km)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    pngs.append(save(fig, args.out, "fig5_beams_vs_oversampling.png"))

    o15 = oversampling_interval(*PAPER["n_sub"], 15, rx_m, ry_m, h_m, radius_m)
    n_paper = build_codebook(*PAPER["n_sub"], O_PAPER, rx_m, ry_m, h_m, radius_m).n_beam
    numbers = {
        "paper_array_beams_at_O_1.2": n_paper,
        "paper_array_beams_at_O_1.2_brute_force": brute_force_count(
            PAPER["n_sub"], O_PAPER, rx_m, ry_m, h_m, radius_m
        ),
        "paper_array_O_interval_for_15_beams": list(o15),
        "big_array_beams_at_O_2": counts[2.0][0],
        "big_array_beams_at_O_2_brute_force": counts[2.0][1],
        "big_array_beams_at_O_2.49": counts[2.49][0],
        "big_array_beams_at_O_2.49_brute_force": counts[2.49][1],
        "paper_big_array_beams_at_O_2": 39,
        "paper_big_array_beams_at_O_2.49": 64,
        "big_array_O_interval_for_39_beams": list(o39),
        "reproduced_39_of_64": counts[2.0][0] == 39,
        "note": "39/64 are NOT reproduced with the paper's ROI (17 and 33 beams); "
        "39 beams need O in [2.678, 2.783); 64 is unreachable (63 -> 67).",
    }
    report(args.out, "fig5_mesh_vs_oversampling", numbers, pngs)
    return numbers


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
