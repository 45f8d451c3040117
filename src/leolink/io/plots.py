"""PNG plots of coverage maps, codebooks, run traces and sweeps.

Every figure is a :class:`matplotlib.figure.Figure` drawn on the non-interactive Agg
canvas (no display, no pyplot state). Files are written atomically
(:class:`leolink.io.atomic.PendingFiles`): every figure of a call is rendered to a
partial file, then all are renamed; if anything fails the partial files are removed and
the error propagates, so a reader never sees a truncated PNG.

The inputs are the run's output contract (``docs/architecture.md``, DESIGN "Output
contract"): the coverage grid, ``trace``, ``events`` and ``summary`` of ``leolink run``.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from leolink.errors import LeolinkError
from leolink.io.atomic import PendingFiles

DPI = 150
MAP_WIDTH_IN = 8.0  # coverage maps; the height follows the grid aspect
MAX_PANELS_UT = 6  # snr_time.png: one panel per UT, at most this many
MAX_BARS_UT = 30  # handovers.png: more UTs than this -> histogram of rates instead
HANDOVER_KINDS = ("beam_handover", "sat_handover")
_KIND_COLOURS = {"beam_handover": "tab:purple", "sat_handover": "tab:red"}
_LABEL_BOX = {"boxstyle": "round,pad=0.15", "facecolor": "white", "alpha": 0.7, "linewidth": 0}


# --------------------------------------------------------------------------- helpers
def _figure(n_rows=1, n_cols=1, *, figsize=(7.0, 5.0), **subplot_kw):
    """A constrained-layout Agg figure and its axes (always a 2-D array of axes)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n_rows, n_cols, squeeze=False, **subplot_kw)
    return fig, axes


class _AtomicPngs(PendingFiles):
    """Figures rendered to partial files; all renamed together when the block succeeds."""

    def __init__(self, out_dir):
        super().__init__()
        self.out_dir = Path(out_dir)
        self.written = []

    def __enter__(self):
        self.out_dir.mkdir(parents=True, exist_ok=True)
        return self

    def save(self, fig, name):
        try:
            fig.savefig(self.open(self.out_dir / name), format="png", dpi=DPI)
        finally:
            fig.clear()  # release the artists; Figure objects are not kept by pyplot
        self.written.append(self.out_dir / name)


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


def _roi_outline(ax, roi_axes_m, scale=1e-3, **kw):
    """Draw the ROI ellipse (semi-axes [m]) in axes whose unit is ``1/scale`` m."""
    from matplotlib.patches import Ellipse

    rx_m, ry_m = roi_axes_m
    style = {"fill": False, "edgecolor": "black", "linewidth": 1.5, "linestyle": "--"}
    style.update(kw)
    ax.add_patch(Ellipse((0.0, 0.0), 2 * rx_m * scale, 2 * ry_m * scale, **style))


def _map_axes(ax, title):
    ax.set_xlabel("x, along-track [km]")
    ax.set_ylabel("y, cross-track [km]")
    ax.set_aspect("equal")
    ax.set_title(title)


def _nan_quiet(func, *args, **kw):
    """Call a nan-reduction without its all-NaN RuntimeWarning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return func(*args, **kw)


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


# --------------------------------------------------------------------------- run
def _selected(trace, ut_ids):
    """The requested UT ids that are present in the trace, at most MAX_PANELS_UT."""
    present = set(trace["ut_id"].unique().tolist())
    return [int(u) for u in ut_ids if int(u) in present][:MAX_PANELS_UT]


def _events_of(events, ut_id, kind):
    if events is None or len(events) == 0:
        return np.empty(0)
    sel = (events["ut_id"] == ut_id) & (events["kind"] == kind)
    return events.loc[sel, "time_s"].to_numpy(float)


def _snr_panel(ax, rows, events, ut_id):
    """SNR/SINR vs time, serving beam on a twin axis, handover lines, outage shading."""
    from matplotlib.ticker import MaxNLocator

    t_s = rows["time_s"].to_numpy(float)
    beam = rows["beam_id"].to_numpy(float)
    outage = (beam < 0) | ~np.isfinite(rows["snr_db"].to_numpy(float))
    ax.plot(t_s, rows["snr_db"], color="tab:blue", label="SNR")
    ax.plot(t_s, rows["sinr_db"], color="tab:orange", label="SINR")
    ax.fill_between(t_s, 0, 1, where=outage, step="mid", color="grey", alpha=0.3,
                    transform=ax.get_xaxis_transform(), label="outage")  # fmt: skip
    for kind, style in (("beam_handover", ":"), ("sat_handover", "--")):
        for i, t in enumerate(_events_of(events, ut_id, kind)):
            ax.axvline(t, color=_KIND_COLOURS[kind], linestyle=style, linewidth=1,
                       label=kind.replace("_", " ") if i == 0 else None)  # fmt: skip
    twin = ax.twinx()
    twin.step(t_s, np.where(beam >= 0, beam, np.nan), where="post", color="tab:green",
              linewidth=1, alpha=0.8, label="serving beam")  # fmt: skip
    twin.yaxis.set_major_locator(MaxNLocator(integer=True))
    twin.set_ylabel("serving beam id", color="tab:green")
    twin.tick_params(axis="y", colors="tab:green")
    if outage.all():
        ax.text(0.5, 0.5, "always in outage", transform=ax.transAxes, ha="center", va="center")
        ax.set_yticks([])
        twin.set_yticks([])
    ax.set_ylabel("SNR, SINR [dB]")
    ax.set_title(f"UT {ut_id}")
    ax.grid(True, alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    h2, l2 = twin.get_legend_handles_labels()
    ax.legend(handles + h2, labels + l2, loc="upper left", bbox_to_anchor=(1.1, 1.0), fontsize=8)


def _snr_time(trace, events, uts):
    fig, axes = _figure(max(len(uts), 1), 1, figsize=(10.0, 2.8 * max(len(uts), 1) + 0.6),
                        sharex=True)  # fmt: skip
    for ax, ut_id in zip(axes[:, 0], uts, strict=False):
        _snr_panel(ax, trace[trace["ut_id"] == ut_id].sort_values("time_s"), events, ut_id)
    if not uts:
        axes[0, 0].text(0.5, 0.5, "no selected UT in the trace", ha="center", va="center")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle("SNR and SINR vs time (dotted: beam handover, dashed: satellite handover)")
    return fig


def _doppler_time(trace, uts):
    fig, axes = _figure(figsize=(10.0, 4.5))
    ax = axes[0, 0]
    for ut_id in uts:  # one line per UT
        rows = trace[trace["ut_id"] == ut_id].sort_values("time_s")
        ax.plot(rows["time_s"], rows["doppler_hz"] * 1e-3, label=f"UT {ut_id}")
    if uts:
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no selected UT in the trace", transform=ax.transAxes, ha="center")
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("Doppler [kHz]")
    ax.set_title("Doppler shift of the serving link vs time")
    ax.grid(True, alpha=0.3)
    return fig


def _dwell_hist(summary):
    overall = summary.get("overall", {})
    dwell_s = overall.get("dwell_times_s")
    if dwell_s is None:  # fall back to the per-UT lists
        dwell_s = [d for u in summary.get("per_ut", []) for d in u.get("dwell_times_s", [])]
    dwell_s = np.asarray(dwell_s, dtype=float)
    dwell_s = dwell_s[np.isfinite(dwell_s)]
    fig, axes = _figure(figsize=(7.0, 4.5))
    ax = axes[0, 0]
    if dwell_s.size == 0:
        ax.text(0.5, 0.5, "no complete dwell", transform=ax.transAxes, ha="center",
                va="center", fontsize=14)  # fmt: skip
    else:
        ax.hist(dwell_s, bins="auto", color="tab:blue", edgecolor="white")
        ax.axvline(np.mean(dwell_s), color="black", linestyle="--",
                   label=f"mean {np.mean(dwell_s):.1f} s")  # fmt: skip
        ax.axvline(np.median(dwell_s), color="tab:red", linestyle=":",
                   label=f"median {np.median(dwell_s):.1f} s")  # fmt: skip
        ax.legend()
    ax.set_xlabel("complete beam dwell time [s]")
    ax.set_ylabel("number of dwells")
    ax.set_title(f"Beam dwell times, all UTs ({dwell_s.size} complete dwells)")
    ax.grid(True, alpha=0.3)
    return fig


def _handovers(duration_s, summary):
    per_ut = summary.get("per_ut", [])
    ut_ids = np.array([u["ut_id"] for u in per_ut], dtype=int)
    counts = {
        k: np.array([u.get("handovers", {}).get(k, 0) for u in per_ut], dtype=float)
        for k in HANDOVER_KINDS
    }
    fig, axes = _figure(figsize=(8.0, 4.5))
    ax = axes[0, 0]
    if ut_ids.size > MAX_BARS_UT and duration_s > 0:
        rate_per_min = sum(counts.values()) / (duration_s / 60.0)
        ax.hist(rate_per_min, bins="auto", color="tab:blue", edgecolor="white")
        ax.set_xlabel("handovers per UT [1/min] (beam + satellite)")
        ax.set_ylabel("number of UTs")
        ax.set_title(f"Handover rate over {ut_ids.size} UTs")
    else:
        pos = np.arange(ut_ids.size)
        bottom = np.zeros(ut_ids.size)
        for kind in HANDOVER_KINDS:  # one stacked layer per kind
            ax.bar(pos, counts[kind], bottom=bottom, color=_KIND_COLOURS[kind],
                   label=kind.replace("_", " "))  # fmt: skip
            bottom += counts[kind]
        ax.set_xticks(pos, [str(u) for u in ut_ids])
        ax.set_xlabel("UT id")
        ax.set_ylabel("number of handovers")
        ax.set_title("Handovers per UT by kind")
        ax.legend()
        if ut_ids.size == 0:
            ax.text(0.5, 0.5, "no UT in the summary", transform=ax.transAxes, ha="center")
    ax.grid(True, axis="y", alpha=0.3)
    return fig


def plot_run(trace, events, summary, out_dir, ut_ids=(0,), duration_s=None):
    """Time series and statistics of a ``leolink run``.

    Parameters
    ----------
    trace : pandas.DataFrame
        One row per UT per epoch; columns ``time_s, ut_id, beam_id, snr_db, sinr_db,
        doppler_hz`` at least (``beam_id`` = -1 and NaN SNR in outage).
    events : pandas.DataFrame or None
        ``time_s, ut_id, kind, ...``; may be empty.
    summary : dict
        ``summary["per_ut"]`` (``ut_id``, ``dwell_times_s``, ``handovers``) and
        ``summary["overall"]`` (``handovers``, ``dwell_times_s`` [s]).
    out_dir : path-like
        Directory (created if missing).
    ut_ids : sequence of int
        UTs shown in the time plots; ids absent from the trace are skipped.
    duration_s : float, optional
        Recorded time span of the run [s] (handover rates); default from ``trace``.

    Returns
    -------
    list of pathlib.Path
        ``snr_time.png, doppler_time.png, dwell_hist.png, handovers.png``.
    """
    uts = _selected(trace, ut_ids)
    with _AtomicPngs(out_dir) as out:
        out.save(_snr_time(trace, events, uts), "snr_time.png")
        out.save(_doppler_time(trace, uts), "doppler_time.png")
        out.save(_dwell_hist(summary), "dwell_hist.png")
        if duration_s is None:
            duration_s = float(np.ptp(trace["time_s"].to_numpy(float))) if len(trace) else 0.0
        out.save(_handovers(duration_s, summary), "handovers.png")
    return out.written


# --------------------------------------------------------------------------- sweep
def plot_sweep(table, out_dir, x, ys):
    """Summary metrics versus one swept parameter, one panel per metric.

    Parameters
    ----------
    table : pandas.DataFrame
        One row per sweep point; column ``x`` and the columns ``ys``.
    out_dir : path-like
        Directory (created if missing).
    x : str
        Swept parameter (column name, ideally with its unit suffix).
    ys : str or sequence of str
        Metrics to plot.

    Returns
    -------
    list of pathlib.Path
        ``[out_dir / f"sweep_{x}.png"]`` (dots in ``x`` replaced by ``_``).
    """
    ys = [ys] if isinstance(ys, str) else list(ys)
    missing = [c for c in [x, *ys] if c not in table.columns]
    if missing:
        raise LeolinkError(
            f"sweep table has no column {missing[0]!r}; columns are {list(table.columns)}"
        )
    data = table.sort_values(x)
    fig, axes = _figure(len(ys), 1, figsize=(7.0, 2.6 * len(ys) + 0.6), sharex=True)
    for ax, y in zip(axes[:, 0], ys, strict=True):  # one panel per metric
        ax.plot(data[x], data[y], marker="o")
        ax.set_ylabel(y)
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel(x)
    fig.suptitle(f"Sweep over {x}")
    with _AtomicPngs(out_dir) as out:
        out.save(fig, f"sweep_{x.replace('.', '_').replace('/', '_')}.png")
    return out.written
