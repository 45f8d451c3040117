"""Figs. 7-9: coverage of the ROI by the 15-beam codebook at the overhead instant.

Fig. 7: beam cells (boresights in green), SNR and SINR under the best beam (UPA terminal);
Fig. 8: SNR along both axes, on the axis (maximum) and on the ROI boundary (minimum);
Fig. 9: spectral efficiency without and with inter-beam interference; plus SNR/SINR maps
for the leaky-wave and metasurface terminals.

Paper (Sec. 5): centre-to-edge gain difference of a cell "in the order of 3 dB" on both
axes; SINR not larger than -4.77 dB (= 1/3) where 4 beams meet and -3 dB (= 1/2) where 3
meet. Exactly where ``k`` beams have equal gain, ``S / (I + N) <= 1 / (k - 1)`` whatever
the noise: the SINR is evaluated at the exact lattice corners (mid-way between 4 beams in
direction-cosine space), not read off the grid.

Run: ``python analysis/fig7_9_coverage.py [--fast] [--out DIR]``.
"""

from __future__ import annotations

import sys

import numpy as np
from _common import figure, paper_config, parse_args, report, roi_outline, save

from leolink.antenna.codebook import footprint_centres
from leolink.app.coverage import coverage_grid
from leolink.app.scenario import build_engine, overhead_satellite
from leolink.coverage import evaluate_points
from leolink.geometry import ray_to_ground, roi_to_ground

TERMINALS = ("upa", "leaky_wave", "metasurface")
BOUND_4_DB = 10.0 * np.log10(1.0 / 3.0)  # -4.77 dB
BOUND_3_DB = 10.0 * np.log10(1.0 / 2.0)  # -3.01 dB
BOUND_2_DB = 0.0


class Geometry:
    """Engine, overhead satellite and ROI of one config."""

    def __init__(self, cfg):
        self.cfg = cfg
        self.engine = build_engine(cfg)
        self.sat = overhead_satellite(cfg)
        self.rx_m, self.ry_m = cfg.roi_semi_axes_m()
        self.radius_m = cfg.earth.radius_m

    def at_xy(self, x_m, y_m):
        """Serving-link columns at ROI-plane points (n,)."""
        ground = roi_to_ground(x_m, y_m, self.sat[0][0], self.sat[1][0], self.radius_m)
        return evaluate_points(self.engine, ground, *self.sat)

    def at_u(self, u_xy):
        """Serving-link columns where the rays u_xy (n, 2) hit the ground."""
        ground = ray_to_ground(self.sat[0][0], self.sat[1][0], u_xy, self.radius_m)
        snap = self.engine.evaluate(ground, self.sat[0], self.sat[1])
        cols = evaluate_points(self.engine, ground, *self.sat)
        g = np.sort(snap.gain_tx_lin[:, 0, :], axis=-1)[:, ::-1]
        cols["gain_spread_db"] = 10.0 * np.log10(g[:, 0] / g[:, 3 if u_xy.shape[0] else 0])
        return cols


def lattice_corners(u_xy):
    """Interior points mid-way between 4 neighbouring beams of a rectangular lattice (n, 2)."""
    ux, uy = np.unique(np.round(u_xy[:, 0], 12)), np.unique(np.round(u_xy[:, 1], 12))
    cx, cy = np.meshgrid(0.5 * (ux[1:] + ux[:-1]), 0.5 * (uy[1:] + uy[:-1]), indexing="ij")
    return np.stack([cx.ravel(), cy.ravel()], axis=-1)


def lattice_edges(u_xy):
    """Mid-points between two neighbouring beams along x and along y (n, 2)."""
    ux, uy = np.unique(np.round(u_xy[:, 0], 12)), np.unique(np.round(u_xy[:, 1], 12))
    mx = np.stack(np.meshgrid(0.5 * (ux[1:] + ux[:-1]), uy, indexing="ij"), -1).reshape(-1, 2)
    my = np.stack(np.meshgrid(ux, 0.5 * (uy[1:] + uy[:-1]), indexing="ij"), -1).reshape(-1, 2)
    return np.concatenate([mx, my])


def crossover_loss_db(n_sub, oversampling):
    """Closed-form gain drop of a DFT beam half-way to its neighbour, ``du = 1 / (O N)``."""
    x = np.pi / (2.0 * oversampling)
    return -20.0 * np.log10(np.sin(x) / (n_sub * np.sin(x / n_sub)))


def centre_to_edge_db(geo, axis, n_pts):
    """SNR at the ROI centre minus SNR where the central cell ends along ``axis`` (0: x)."""
    semi = (geo.rx_m, geo.ry_m)[axis]
    s = np.linspace(0.0, semi, n_pts)
    zero = np.zeros_like(s)
    cols = geo.at_xy(*((s, zero) if axis == 0 else (zero, s)))
    first_out = np.flatnonzero(cols["best_beam"] != cols["best_beam"][0])[0]
    edge = first_out - 1
    return float(cols["snr_db"][0] - cols["snr_db"][edge]), float(s[edge])


def _map(ax, df, column, title, label, geo, cmap="viridis"):
    x = np.unique(df["x_m"].to_numpy())
    y = np.unique(df["y_m"].to_numpy())
    z = df[column].to_numpy().reshape(y.size, x.size)
    z = np.where(df["in_roi"].to_numpy().reshape(z.shape), z, np.nan)
    mesh = ax.pcolormesh(x * 1e-3, y * 1e-3, z, cmap=cmap, shading="nearest")
    roi_outline(ax, geo.rx_m, geo.ry_m)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x [km]")
    ax.set_ylabel("y [km]")
    ax.figure.colorbar(mesh, ax=ax, label=label, shrink=0.8)


def fig7(df, geo, out):
    fig, axes = figure(3, 1, figsize=(7.5, 9.0))
    _map(axes[0, 0], df, "best_beam", "(a) beam cells; green: boresights", "beam id", geo, "tab20")
    fx, fy = footprint_centres(geo.engine.codebook, geo.cfg.constellation.altitude_m, geo.radius_m)
    axes[0, 0].plot(fx * 1e-3, fy * 1e-3, "o", color="lime", mec="k", ms=5)
    _map(axes[1, 0], df, "snr_db", "(b) SNR, best beam (UPA)", "SNR [dB]", geo)
    _map(axes[2, 0], df, "sinr_db", "(c) SINR, best beam (UPA)", "SINR [dB]", geo)
    return save(fig, out, "fig7_coverage_upa.png")


def fig8(geo, out, n_pts):
    fig, axes = figure(1, 2, figsize=(11.0, 4.0), sharey=True)
    for ax, axis in zip(axes[0], (0, 1), strict=True):
        semi, other = (geo.rx_m, geo.ry_m) if axis == 0 else (geo.ry_m, geo.rx_m)
        s = np.linspace(-semi, semi, n_pts)
        edge = other * np.sqrt(np.clip(1.0 - (s / semi) ** 2, 0.0, 1.0))
        for off, label, style in (
            (0.0 * s, "on the axis (max)", "-"),
            (edge, "ROI boundary (min)", "--"),
        ):
            xy = (s, off) if axis == 0 else (off, s)
            ax.plot(s * 1e-3, geo.at_xy(*xy)["snr_db"], style, label=label)
        ax.set_xlabel(f"{'x, along' if axis == 0 else 'y, cross'}-track [km]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title(f"SNR along {'x' if axis == 0 else 'y'} (UPA)")
    axes[0, 0].set_ylabel("SNR [dB]")
    return save(fig, out, "fig8_snr_cuts.png")


def fig9(df, geo, out):
    df = df.copy()
    df["se_no_interference"] = np.log2(1.0 + 10.0 ** (df["snr_db"] / 10.0))
    fig, axes = figure(2, 1, figsize=(7.5, 6.2))
    _map(axes[0, 0], df, "se_no_interference", "(a) SE without interference", "bit/s/Hz", geo,
         "cividis")  # fmt: skip
    _map(axes[1, 0], df, "se_bps_hz", "(b) SE with interference", "bit/s/Hz", geo, "cividis")
    inside = df["in_roi"].to_numpy()
    return save(fig, out, "fig9_spectral_efficiency.png"), (
        float(df["se_no_interference"][inside].mean()),
        float(df["se_bps_hz"][inside].mean()),
    )


def terminal_maps(frames, geos, out):
    fig, axes = figure(2, 2, figsize=(13.0, 5.5))
    for row, kind in enumerate(("leaky_wave", "metasurface")):
        for col, (column, name) in enumerate((("snr_db", "SNR"), ("sinr_db", "SINR"))):
            _map(axes[row, col], frames[kind], column, f"{name}, {kind}", f"{name} [dB]",
                 geos[kind])  # fmt: skip
    return save(fig, out, "fig7_coverage_terminals.png")


def main(argv=None):
    args = parse_args(argv, __doc__)
    n_grid, n_pts = (81, 801) if args.fast else (401, 4001)
    frames, geos, numbers = {}, {}, {}
    for kind in TERMINALS:
        cfg = paper_config([f"terminal.kind={kind!r}".replace("'", '"')])
        frames[kind] = coverage_grid(cfg, n_grid=n_grid, margin=1.05)
        geos[kind] = Geometry(cfg)
        inside = frames[kind][frames[kind]["in_roi"]]
        numbers[f"{kind}_snr_db_range_in_roi"] = [inside["snr_db"].min(), inside["snr_db"].max()]
        numbers[f"{kind}_sinr_db_range_in_roi"] = [inside["sinr_db"].min(), inside["sinr_db"].max()]
    geo, df = geos["upa"], frames["upa"]
    u_beams = geo.engine.codebook.u_xy
    corners, edges = geo.at_u(lattice_corners(u_beams)), geo.at_u(lattice_edges(u_beams))
    for axis, name in ((0, "x"), (1, "y")):
        diff_db, where_m = centre_to_edge_db(geo, axis, n_pts)
        numbers[f"centre_to_edge_snr_db_{name}"] = diff_db
        numbers[f"central_cell_half_width_km_{name}"] = where_m * 1e-3
        n_sub = (geo.engine.codebook.n_sub_x, geo.engine.codebook.n_sub_y)[axis]
        o = geo.engine.codebook.oversampling
        numbers[f"beam_crossover_loss_db_closed_form_{name}"] = crossover_loss_db(n_sub, o)
    numbers.update(
        {
            "paper_centre_to_edge_db": 3.0,
            "n_beams": geo.engine.n_beam,
            "n_4beam_corners": len(corners["sinr_db"]),
            "max_sinr_db_at_4beam_corners": float(np.max(corners["sinr_db"])),
            "max_gain_spread_db_of_4_beams_at_corners": float(np.max(corners["gain_spread_db"])),
            "paper_sinr_bound_4_beams_db": BOUND_4_DB,
            "max_sinr_db_at_2beam_edges": float(np.max(edges["sinr_db"])),
            "paper_sinr_bound_3_beams_db": BOUND_3_DB,
            "sinr_bound_2_beams_db": BOUND_2_DB,
            "note_3_beams": "a rectangular DFT lattice has no point where exactly 3 beams tie; "
            "4-beam corners (<= -4.77 dB) and 2-beam edges (<= 0 dB) are checked instead",
        }
    )
    pngs = [fig7(df, geo, args.out), fig8(geo, args.out, n_pts // 4)]
    png9, (se_n, se_i) = fig9(df, geo, args.out)
    numbers["mean_se_bps_hz_in_roi_no_interference"] = se_n
    numbers["mean_se_bps_hz_in_roi_with_interference"] = se_i
    pngs += [png9, terminal_maps(frames, geos, args.out)]
    report(args.out, "fig7_9_coverage", numbers, pngs)
    return numbers


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
