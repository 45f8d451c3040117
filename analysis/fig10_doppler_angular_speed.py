"""Fig. 10: Doppler and angular speed over the ROI, satellite overhead the ROI centre.

(a) Doppler from the satellite's motion, (b) angular speed of the satellite seen from a
static UT, (c) Doppler from a UT moving at 30 m/s (horizontal, along-track heading).
Closed-form maxima (Eq. doppler_ang_max of the paper) beside the maxima of the maps and a
brute-force maximum over the ROI boundary: the exact closed form matches the brute force;
the small-ROI shortcut ``R_x v_sat / h f / c`` is ~10 % high with the paper's ROI
(docs/errata.md).

Run: ``python analysis/fig10_doppler_angular_speed.py [--fast] [--out DIR]``.
"""

from __future__ import annotations

import sys

import numpy as np
from _common import figure, paper_config, parse_args, report, roi_outline, save

from leolink.app.scenario import overhead_satellite
from leolink.constants import SPEED_OF_LIGHT_M_S
from leolink.geometry import body_frame, look_angles, roi_to_ground
from leolink.kinematics import (
    angular_speed_rad_s,
    doppler_sat_hz,
    doppler_ut_hz,
    max_angular_speed_rad_s,
    max_doppler_sat_hz,
    max_doppler_sat_small_roi_hz,
    mean_abs_doppler_ut_hz,
)
from leolink.roi import in_ellipse

UT_SPEED_M_S = 30.0  # a car (paper's UT-Doppler example)


def horizontal_along_track(ground_m, sat_pos_m, sat_vel_m_s):
    """Unit vectors (n, 3): the satellite's along-track axis projected on the local horizon."""
    ex = body_frame(sat_pos_m, sat_vel_m_s)[0]
    up = ground_m / np.linalg.norm(ground_m, axis=-1, keepdims=True)
    h = ex - np.sum(ex * up, axis=-1, keepdims=True) * up
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def kinematics_maps(cfg, n_grid):
    """x (n,), y (m,), dict of (m, n) maps (NaN outside the ROI) and the ground points."""
    rx_m, ry_m = cfg.roi_semi_axes_m()
    pos, vel, _ = overhead_satellite(cfg)
    x = np.linspace(-rx_m, rx_m, n_grid)
    y = np.linspace(-ry_m, ry_m, max(n_grid // 2 | 1, 11))
    xx, yy = np.meshgrid(x, y)
    ground = roi_to_ground(xx, yy, pos[0], vel[0], cfg.earth.radius_m)
    f = cfg.link.freq_hz
    v_ut = UT_SPEED_M_S * horizontal_along_track(ground, pos[0], vel[0])
    inside = in_ellipse(xx, yy, rx_m, ry_m)
    maps = {
        "doppler_sat_hz": doppler_sat_hz(pos[0], vel[0], ground, f),
        "angular_speed_deg_s": np.degrees(angular_speed_rad_s(pos[0], vel[0], ground)),
        "doppler_ut_hz": doppler_ut_hz(ground, v_ut, pos[0], f),
    }
    return x, y, {k: np.where(inside, v, np.nan) for k, v in maps.items()}, ground


def boundary_max_doppler_hz(cfg, n_pts):
    """max |Doppler| over the ROI ellipse boundary (brute force)."""
    rx_m, ry_m = cfg.roi_semi_axes_m()
    pos, vel, _ = overhead_satellite(cfg)
    t = np.linspace(0.0, 2.0 * np.pi, n_pts)
    ground = roi_to_ground(rx_m * np.cos(t), ry_m * np.sin(t), pos[0], vel[0], cfg.earth.radius_m)
    return float(np.max(np.abs(doppler_sat_hz(pos[0], vel[0], ground, cfg.link.freq_hz))))


def tip_elevation_rad(cfg):
    """Elevation of the satellite seen from the along-track ROI tip (x = R_x, y = 0)."""
    pos, vel, _ = overhead_satellite(cfg)
    tip = roi_to_ground(cfg.roi_semi_axes_m()[0], 0.0, pos[0], vel[0], cfg.earth.radius_m)
    return float(look_angles(tip, pos[0])[0])


def _panel(ax, x, y, z, title, label, cmap, rx_m, ry_m):
    m = ax.pcolormesh(x * 1e-3, y * 1e-3, z, cmap=cmap, shading="nearest")
    roi_outline(ax, rx_m, ry_m)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x, along-track [km]")
    ax.set_ylabel("y [km]")
    ax.figure.colorbar(m, ax=ax, label=label, shrink=0.8)


def main(argv=None):
    args = parse_args(argv, __doc__)
    cfg = paper_config()
    rx_m, _ = cfg.roi_semi_axes_m()
    h, f, radius = cfg.constellation.altitude_m, cfg.link.freq_hz, cfg.earth.radius_m
    x, y, maps, _ = kinematics_maps(cfg, 81 if args.fast else 401)
    fig, axes = figure(3, 1, figsize=(7.5, 9.0))
    ry_m = cfg.roi_semi_axes_m()[1]
    _panel(axes[0, 0], x, y, maps["doppler_sat_hz"] * 1e-3, "(a) Doppler, satellite motion",
           "kHz", "RdBu_r", rx_m, ry_m)  # fmt: skip
    _panel(axes[1, 0], x, y, maps["angular_speed_deg_s"], "(b) angular speed seen by a static UT",
           "deg/s", "plasma", rx_m, ry_m)  # fmt: skip
    _panel(axes[2, 0], x, y, maps["doppler_ut_hz"], f"(c) Doppler, UT at {UT_SPEED_M_S:g} m/s "
           "along-track", "Hz", "RdBu_r", rx_m, ry_m)  # fmt: skip
    pngs = [save(fig, args.out, "fig10_doppler_angular_speed.png")]

    exact = float(max_doppler_sat_hz(rx_m, h, f, radius, cfg.earth.gm_m3_s2))
    shortcut = float(max_doppler_sat_small_roi_hz(rx_m, h, f, radius, cfg.earth.gm_m3_s2))
    w_max = float(np.degrees(max_angular_speed_rad_s(h, radius, cfg.earth.gm_m3_s2)))
    numbers = {
        "max_doppler_sat_hz_map": float(np.nanmax(np.abs(maps["doppler_sat_hz"]))),
        "max_doppler_sat_hz_boundary_brute_force": boundary_max_doppler_hz(
            cfg, 2001 if args.fast else 20001
        ),
        "max_doppler_sat_hz_closed_form_exact": exact,
        "max_doppler_sat_hz_small_roi_shortcut": shortcut,
        "shortcut_excess_percent": 100.0 * (shortcut / exact - 1.0),
        "max_angular_speed_deg_s_map": float(np.nanmax(maps["angular_speed_deg_s"])),
        "max_angular_speed_deg_s_closed_form": w_max,
        "max_doppler_ut_hz_map": float(np.nanmax(np.abs(maps["doppler_ut_hz"]))),
        # horizontal motion along-track: |v.l| = v cos(el), largest at the lowest elevation
        "max_doppler_ut_hz_closed_form_v_cos_el_tip": UT_SPEED_M_S
        * f
        / SPEED_OF_LIGHT_M_S
        * np.cos(tip_elevation_rad(cfg)),
        "elevation_deg_at_roi_tip": np.degrees(tip_elevation_rad(cfg)),
        "max_doppler_ut_hz_bound_v_f_over_c": UT_SPEED_M_S * f / SPEED_OF_LIGHT_M_S,
        "mean_abs_doppler_ut_hz_uniform_direction": float(mean_abs_doppler_ut_hz(UT_SPEED_M_S, f)),
        "paper_mean_abs_doppler_ut_hz_v_over_6": UT_SPEED_M_S / 6.0 * f / SPEED_OF_LIGHT_M_S,
    }
    report(args.out, "fig10_doppler_angular_speed", numbers, pngs)
    return numbers


if __name__ == "__main__":
    sys.exit(0 if main() is not None else 1)
