"""PNG maps of ``leolink coverage`` and the codebook plot of ``leolink codebook``.

Drawn on the Agg canvas and written atomically, as every plot (:mod:`leolink.io.plots`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from leolink.io.plots import (
    _AtomicPngs,
    _figure,
    _map_axes,
    _nan_quiet,
    _roi_outline,
)

__all__ = ["plot_codebook", "plot_coverage"]

MAP_WIDTH_IN = 8.0  # coverage maps; the height follows the grid aspect
_LABEL_BOX = {"boxstyle": "round,pad=0.15", "facecolor": "white", "alpha": 0.7, "linewidth": 0}


def _grid(df, column):
    """Values of ``column`` on the regular (y, x) grid; NaN where a node is missing.

    Returns ``x_m (n_x,), y_m (n_y,), values (n_y, n_x)``.
    """
    x_m, ix = np.unique(df["x_m"].to_numpy(float), return_inverse=True)
    y_m, iy = np.unique(df["y_m"].to_numpy(float), return_inverse=True)
    values = np.full((y_m.size, x_m.size), np.nan)
    values[iy, ix] = df[column].to_numpy(float)
    return x_m, y_m, values


def _map_figsize(x_m, y_m):
    """(width, height) [in] of a map figure: 8 in wide, tall enough for equal aspect."""
    ratio = np.ptp(y_m) / np.ptp(x_m) if np.ptp(x_m) > 0 else 1.0
    return MAP_WIDTH_IN, float(np.clip(6.0 * ratio + 1.6, 3.0, 9.0))


# --------------------------------------------------------------------------- coverage
_COVERAGE_MAPS = (
    # (file, column, title, colour-bar label, scale, colormap, centred on 0)
    ("coverage_snr.png", "snr_db", "SNR under the best beam", "SNR [dB]", 1.0, "viridis", False),
    (
        "coverage_sinr.png",
        "sinr_db",
        "SINR under the best beam",
        "SINR [dB]",
        1.0,
        "viridis",
        False,
    ),
    ("coverage_se.png", "se_bps_hz", "Spectral efficiency", "SE [bit/s/Hz]", 1.0, "cividis", False),
    ("coverage_doppler.png", "doppler_hz", "Doppler shift", "Doppler [kHz]", 1e-3, "RdBu_r", True),
    (
        "coverage_angular_speed.png",
        "angular_speed_deg_s",
        "Satellite angular speed seen from the ground",
        "angular speed [deg/s]",
        1.0,
        "plasma",
        False,
    ),
)


def _scalar_map(df, roi_axes_m, column, title, label, scale, cmap, centred):
    """One coverage map: pcolormesh of ``column`` over the grid, ROI outline, colour bar."""
    from matplotlib.colors import Normalize

    x_m, y_m, z = _grid(df, column)
    z = z * scale
    norm = None
    if centred:  # diverging colormap: white at 0, symmetric limits
        vmax = _nan_quiet(np.nanmax, np.abs(z)) if np.isfinite(z).any() else 1.0
        vmax = vmax if vmax > 0 else 1.0
        norm = Normalize(-vmax, vmax)
    fig, axes = _figure(figsize=_map_figsize(x_m, y_m))
    ax = axes[0, 0]
    mesh = ax.pcolormesh(x_m * 1e-3, y_m * 1e-3, z, cmap=cmap, norm=norm, shading="nearest")
    _roi_outline(ax, roi_axes_m)
    _map_axes(ax, title)
    cax = ax.inset_axes([1.03, 0.0, 0.035, 1.0])  # colour bar exactly as tall as the map
    fig.colorbar(mesh, cax=cax, label=label)
    return fig


def _beam_map(df, roi_axes_m, title):
    """Beam cells: one categorical colour per best beam, beam id at each cell centroid."""
    from matplotlib.colors import ListedColormap

    x_m, y_m, beam = _grid(df, "best_beam")
    ids = np.unique(beam[np.isfinite(beam) & (beam >= 0)]).astype(int)
    index = np.full(beam.shape, np.nan)
    ok = np.isfinite(beam) & (beam >= 0)
    index[ok] = np.searchsorted(ids, beam[ok].astype(int))
    palette = [*_tab_colours("tab20"), *_tab_colours("tab20b")]
    colours = [palette[i % len(palette)] for i in range(max(ids.size, 1))]
    cmap = ListedColormap(colours).with_extremes(bad="lightgrey")  # grey: no serving beam
    fig, axes = _figure(figsize=_map_figsize(x_m, y_m))
    ax = axes[0, 0]
    ax.pcolormesh(
        x_m * 1e-3,
        y_m * 1e-3,
        np.ma.masked_invalid(index),
        cmap=cmap,
        vmin=-0.5,
        vmax=max(ids.size, 1) - 0.5,
        shading="nearest",
    )
    cells = df[df["best_beam"] >= 0].groupby("best_beam")[["x_m", "y_m"]].mean()
    for beam_id, (cx_m, cy_m) in zip(cells.index, cells.to_numpy(), strict=True):
        ax.text(cx_m * 1e-3, cy_m * 1e-3, str(int(beam_id)), ha="center", va="center",
                fontsize=8, fontweight="bold", bbox=_LABEL_BOX)  # fmt: skip
    _roi_outline(ax, roi_axes_m)
    _map_axes(ax, title)
    return fig


def _tab_colours(name):
    from matplotlib import colormaps

    return list(colormaps[name].colors)


def _cuts(df, roi_axes_m, title_suffix):
    """SNR along y = 0 and x = 0, with the SNR range over the other axis inside the ROI."""
    x_m, y_m, snr_db = _grid(df, "snr_db")
    _, _, in_roi = _grid(df, "in_roi")
    inside_db = np.where(in_roi == 1, snr_db, np.nan)
    fig, axes = _figure(1, 2, figsize=(11.0, 4.5), sharey=True)
    cuts = (
        (axes[0, 0], x_m, snr_db[np.argmin(np.abs(y_m)), :], 0, "x, along-track", "y", y_m),
        (axes[0, 1], y_m, snr_db[:, np.argmin(np.abs(x_m))], 1, "y, cross-track", "x", x_m),
    )
    for ax, pos_m, line_db, other_axis, xlabel, other, other_m in cuts:
        near_m = other_m[np.argmin(np.abs(other_m))]
        lo_db = _nan_quiet(np.nanmin, inside_db, axis=other_axis)
        hi_db = _nan_quiet(np.nanmax, inside_db, axis=other_axis)
        ax.fill_between(pos_m * 1e-3, lo_db, hi_db, color="tab:blue", alpha=0.2,
                        label=f"range over {other} inside the ROI")  # fmt: skip
        ax.plot(pos_m * 1e-3, line_db, color="tab:blue", label=f"{other} = {near_m / 1e3:.1f} km")
        semi_km = roi_axes_m[other_axis] * 1e-3
        for edge in (-semi_km, semi_km):
            ax.axvline(edge, color="black", linestyle="--", linewidth=1)
        ax.set_xlabel(f"{xlabel} [km]")
        ax.set_title(f"SNR along {xlabel.split(',')[0]} (ROI edge dashed)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="lower center", fontsize=8)
    axes[0, 0].set_ylabel("SNR [dB]")
    fig.suptitle(f"SNR range over both axes{title_suffix}")
    return fig


def plot_coverage(df, out_dir, roi_axes_m, title_suffix=""):
    """Coverage maps of one instant over a regular ground grid.

    Parameters
    ----------
    df : pandas.DataFrame, one row per grid node
        Columns ``x_m, y_m`` (ROI plane, along-/cross-track) [m], ``best_beam``,
        ``snr_db, sinr_db`` [dB], ``se_bps_hz`` [bit/s/Hz], ``doppler_hz`` [Hz],
        ``angular_speed_deg_s`` [deg/s], ``in_roi`` (bool). ``lat_deg, lon_deg`` unused.
    out_dir : path-like
        Directory (created if missing).
    roi_axes_m : (float, float)
        ROI semi-axes ``(rx_m, ry_m)`` [m], drawn as a dashed ellipse.
    title_suffix : str
        Appended to every title (e.g. ``" (t = 0 s)"``).

    Returns
    -------
    list of pathlib.Path
        ``coverage_beams, _snr, _sinr, _se, _doppler, _angular_speed, _cuts`` PNGs.
    """
    with _AtomicPngs(out_dir) as out:
        out.save(_beam_map(df, roi_axes_m, f"Best beam cells{title_suffix}"), "coverage_beams.png")
        for name, column, title, label, scale, cmap, centred in _COVERAGE_MAPS:
            fig = _scalar_map(df, roi_axes_m, column, title + title_suffix, label, scale, cmap,
                              centred)  # fmt: skip
            out.save(fig, name)
        out.save(_cuts(df, roi_axes_m, title_suffix), "coverage_cuts.png")
    return out.written


# --------------------------------------------------------------------------- codebook
def plot_codebook(cfg, info, path):
    """Beam footprints in the ROI plane and the beams in direction-cosine space.

    Parameters
    ----------
    cfg : leolink.config.Config or None
        Only used for the title (array size and RF chains).
    info : dict
        ``{"oversampling": O, "roi_semi_axes_m": [rx, ry], "beams": [{"beam_id", "u_x",
        "u_y", "x_m", "y_m", ...}, ...]}``; positions [m], direction cosines [-].
    path : path-like
        Output PNG.

    Returns
    -------
    list of pathlib.Path
        ``[path]``.
    """
    path = Path(path)
    beams = info["beams"]
    beam_id = np.array([b["beam_id"] for b in beams], dtype=int)
    uv = np.array([[b["u_x"], b["u_y"]] for b in beams], dtype=float).reshape(-1, 2)
    xy_km = np.array([[b["x_m"], b["y_m"]] for b in beams], dtype=float).reshape(-1, 2) * 1e-3
    fig, axes = _figure(1, 2, figsize=(12.0, 5.0))
    ax_xy, ax_u = axes[0]
    _roi_outline(ax_xy, info["roi_semi_axes_m"], label="ROI")
    ax_xy.scatter(xy_km[:, 0], xy_km[:, 1], s=18, color="tab:red", zorder=3)
    ax_u.scatter(uv[:, 0], uv[:, 1], s=18, color="tab:blue", zorder=3)
    for i, b in enumerate(beam_id):  # one label per beam
        ax_xy.annotate(str(b), xy_km[i], textcoords="offset points", xytext=(3, 3), fontsize=7)
        ax_u.annotate(str(b), uv[i], textcoords="offset points", xytext=(3, 3), fontsize=7)
    _map_axes(ax_xy, "Footprint centres in the ROI plane")
    ax_xy.autoscale_view()
    ax_u.set_xlabel("u_x, along-track direction cosine [-]")
    ax_u.set_ylabel("u_y, cross-track direction cosine [-]")
    ax_u.set_aspect("equal", adjustable="datalim")
    ax_u.set_title("Beams in direction-cosine space")
    for ax in (ax_xy, ax_u):
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"DFT codebook: O = {float(info['oversampling']):.3g}, {beam_id.size} beams"
                 f"{_array_label(cfg)}")  # fmt: skip
    with _AtomicPngs(path.parent) as out:
        out.save(fig, path.name)
    return out.written


def _array_label(cfg):
    """', 128x64 elements, 8x8 RF chains' from a Config, or '' if unavailable."""
    arr = getattr(cfg, "satellite_array", None)
    try:
        return f", {arr.n_x}x{arr.n_y} elements, {arr.n_rf_x}x{arr.n_rf_y} RF chains"
    except AttributeError:
        return ""
