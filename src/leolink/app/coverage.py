"""``leolink coverage``: the link over a ground grid at one instant (paper Sec. 5, Figs. 7-9).

The grid lives in the paper's ROI plane of the satellite (Sec. 3.1): ``(x, y)`` along- and
cross-track, mapped to the ground by the central projection. The satellite is the one
that passes over the ROI centre, at its overhead instant.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

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


def run_coverage(cfg, out_dir, n_grid=201, margin=1.1, plots=True):
    """``leolink coverage``: write ``coverage.csv`` and the maps; return the paths."""
    from leolink.config import dump_toml
    from leolink.io.atomic import write_csv_atomic, write_text_atomic

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    df = coverage_grid(cfg, n_grid=n_grid, margin=margin)
    paths = [
        write_csv_atomic(df, out_dir / "coverage.csv"),
        write_text_atomic(out_dir / "config.resolved.toml", dump_toml(cfg)),
    ]
    if plots:
        from leolink.io.coverage_plots import plot_coverage

        paths += plot_coverage(
            df, out_dir, cfg.roi_semi_axes_m(), title_suffix=f" ({cfg.terminal.kind} terminal)"
        )
    return paths
