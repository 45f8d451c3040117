"""``leolink coverage``: the link over a ground grid at one instant (paper Sec. 5, Figs. 7-9).

The grid lives in the paper's ROI plane of the satellite (Sec. 3.1): ``(x, y)`` along- and
cross-track, mapped to the ground by the central projection. The satellite is the one
that passes over the ROI centre, at its overhead instant.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from leolink.app.guard import raise_pending
from leolink.app.scenario import build_engine, overhead_satellite
from leolink.coverage import evaluate_points
from leolink.geometry import ecef_to_geodetic, roi_to_ground
from leolink.roi import in_ellipse

__all__ = ["COVERAGE_COLUMNS", "coverage_grid", "run_coverage"]

COVERAGE_COLUMNS = [
    "x_m",
    "y_m",
    "lat_deg",
    "lon_deg",
    "best_beam",
    "snr_db",
    "sinr_db",
    "se_bps_hz",
    "doppler_hz",
    "angular_speed_deg_s",
    "in_roi",
]


def coverage_grid(cfg, n_grid=201, margin=1.1):
    """Evaluate the ROI-plane grid; returns a DataFrame with :data:`COVERAGE_COLUMNS`."""
    engine = build_engine(cfg)
    rx, ry = cfg.roi_semi_axes_m()
    x = np.linspace(-margin * rx, margin * rx, n_grid)
    y = np.linspace(-margin * ry, margin * ry, n_grid)
    xx, yy = np.meshgrid(x, y)  # rows: y, columns: x
    xx, yy = xx.ravel(), yy.ravel()
    sat_pos, sat_vel, sat_acc = overhead_satellite(cfg)
    ground = roi_to_ground(xx, yy, sat_pos[0], sat_vel[0], cfg.earth.radius_m)
    cols = evaluate_points(engine, ground, sat_pos, sat_vel, sat_acc)
    lat, lon, _ = ecef_to_geodetic(ground, cfg.earth.radius_m)
    df = pd.DataFrame(
        {
            "x_m": xx,
            "y_m": yy,
            "lat_deg": np.degrees(lat),
            "lon_deg": np.degrees(lon),
            "best_beam": cols["best_beam"],
            "snr_db": cols["snr_db"],
            "sinr_db": cols["sinr_db"],
            "se_bps_hz": cols["se_bps_hz"],
            "doppler_hz": cols["doppler_hz"],
            "angular_speed_deg_s": cols["angular_speed_deg_s"],
            "in_roi": in_ellipse(xx, yy, rx, ry),
        }
    )
    return df


#: Columns summarised in the coverage report's table (over the grid points in the ROI).
REPORT_COLUMNS = ("snr_db", "sinr_db", "se_bps_hz", "doppler_hz", "angular_speed_deg_s")


def coverage_table(df):
    """Statistics of :data:`REPORT_COLUMNS` over the grid points inside the ROI: one row
    per quantity, ``min, p5, median, mean, p95, max`` (NaN points ignored)."""
    inside = df[df["in_roi"]]
    rows = []
    for col in REPORT_COLUMNS:
        v = inside[col].to_numpy(float)
        v = v[np.isfinite(v)]
        stats = (
            [v.min(), *np.percentile(v, [5, 50]), v.mean(), np.percentile(v, 95), v.max()]
            if v.size
            else [np.nan] * 6
        )
        rows.append([col, *stats])
    return pd.DataFrame(rows, columns=["quantity", "min", "p5", "median", "mean", "p95", "max"])


def run_coverage(cfg, out_dir, n_grid=201, margin=1.1, plots=True, overwrite=False):
    """``leolink coverage``: write ``coverage.csv``, the maps, ``report.html`` and last
    ``run.json``; return the paths. An earlier output in ``out_dir`` is refused unless
    ``overwrite`` (:func:`leolink.io.run_dir.claim_out_dir`)."""
    import leolink
    from leolink.config import dump_toml
    from leolink.io.atomic import write_csv_atomic, write_text_atomic
    from leolink.io.report.page import build_table_report
    from leolink.io.run_dir import claim_out_dir, write_manifest

    df = coverage_grid(cfg, n_grid=n_grid, margin=margin)
    out_dir = claim_out_dir(out_dir, overwrite)
    config_text = dump_toml(cfg)
    paths = [
        write_csv_atomic(df, out_dir / "coverage.csv"),
        write_text_atomic(out_dir / "config.resolved.toml", config_text),
    ]
    if plots:
        from leolink.io.coverage_plots import plot_coverage

        paths += plot_coverage(
            df, out_dir, cfg.roi_semi_axes_m(), title_suffix=f" ({cfg.terminal.kind} terminal)"
        )
    n_in = int(df["in_roi"].sum())
    paths.append(
        build_table_report(
            out_dir / "report.html",
            "leolink coverage report",
            coverage_table(df),
            [(p.stem.replace("_", " "), p) for p in paths if p.suffix == ".png"],
            config_text,
            notes=f"{n_in:,} of {len(df):,} grid points ({n_grid} x {n_grid}) are in the ROI; "
            "the statistics are over those.",
        )
    )
    arguments = {"n_grid": int(n_grid), "margin": float(margin), "plots": bool(plots)}
    version = leolink.__version__
    raise_pending()  # a stop caught inside a library: no manifest (leolink.app.guard)
    paths.append(
        write_manifest(out_dir, paths, "coverage", config_text, arguments, version=version)
    )
    return paths
