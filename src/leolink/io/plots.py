"""PNG plots of run traces and sweeps, and the helpers every leolink plot shares.

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
from leolink.io.report.figures import ut_line
from leolink.io.report.headline import fmt_si

DPI = 150
MAX_PANELS_UT = 6  # snr_time.png: one panel per UT, at most this many
MAX_BARS_UT = 30  # handovers.png: more UTs than this -> histogram of rates instead
HANDOVER_KINDS = ("beam_handover", "sat_handover")
_KIND_COLOURS = {"beam_handover": "tab:purple", "sat_handover": "tab:red"}


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
    if outage.any():  # no "outage" in the legend of a panel without one
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
    for i, ut_id in enumerate(uts):  # one line per UT
        rows = trace[trace["ut_id"] == ut_id].sort_values("time_s")
        ax.plot(rows["time_s"], rows["doppler_hz"] * 1e-3, label=f"UT {ut_id}", **ut_line(i))
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


#: Most bins of the dwell histogram ("auto" gives thousands for a long run's many dwells,
#: each a matplotlib patch: tens of MB that grew with the run length).
MAX_DWELL_BINS = 100


def _dwell_durations(summary, dwells=None):
    """Complete and censored dwell durations [s]: of the dwell table (``dwells.parquet``
    columns) if given, else of a summary (``summary.json`` layout)."""
    if dwells is not None:
        duration = np.asarray(dwells["end_s"], float) - np.asarray(dwells["start_s"], float)
        cut = np.asarray(dwells["censored_start"], bool) | np.asarray(dwells["censored_end"], bool)
        return duration[~cut], duration[cut]
    complete = summary["overall"]["dwell"]["complete_s"]
    censored = [r["duration_s"] for u in summary["per_ut"] for r in u["dwell"]["censored"]]
    return np.asarray(complete, dtype=float), np.asarray(censored, dtype=float)


def _dwell_hist(summary, dwells=None):
    """Complete dwells, and apart from them the dwells cut by the run's start or end."""
    complete_s, censored_s = _dwell_durations(summary, dwells)
    fig, axes = _figure(figsize=(7.0, 4.5))
    ax = axes[0, 0]
    if complete_s.size == 0:
        ax.text(0.5, 0.5, "no complete dwell", transform=ax.transAxes, ha="center",
                va="center", fontsize=14)  # fmt: skip
    else:
        every = np.concatenate([complete_s, censored_s])
        edges = np.histogram_bin_edges(every, bins="auto")
        if edges.size > MAX_DWELL_BINS + 1:  # one drawn patch per bin: bounded memory
            edges = np.histogram_bin_edges(every, bins=MAX_DWELL_BINS)
        ax.hist(complete_s, bins=edges, color="tab:blue", edgecolor="white", label="complete")
        d = summary["overall"].get("dwell", {})  # the one mean and median: summary.json's
        mean, median = (
            d.get("mean_s", np.mean(complete_s)),
            d.get("median_s", np.median(complete_s)),
        )
        ax.axvline(mean, color="black", linestyle="--", label=f"mean {fmt_si(mean)} s")
        ax.axvline(median, color="tab:red", linestyle=":", label=f"median {fmt_si(median)} s")
        if censored_s.size:
            ax.hist(censored_s, bins=edges, histtype="step", color="grey", linewidth=1.5,
                    label=f"censored ({censored_s.size}, cut by the run)")  # fmt: skip
        ax.legend()
    ax.set_xlabel("beam dwell time [s]")
    ax.set_ylabel("number of dwells")
    ax.set_title(f"Beam dwell times, all UTs ({complete_s.size} complete dwells)")
    ax.grid(True, alpha=0.3)
    return fig


def _handover_counts(summary, per_ut_table=None):
    """UT ids and handover counts by kind: of the per-UT table if given, else the summary."""
    if per_ut_table is not None:
        ids = np.asarray(per_ut_table["ut_id"], int)
        return ids, {k: np.asarray(per_ut_table[f"n_{k}"], float) for k in HANDOVER_KINDS}
    per_ut = summary.get("per_ut", [])
    ut_ids = np.array([u["ut_id"] for u in per_ut], dtype=int)
    counts = {
        k: np.array([u.get("handovers", {}).get(k, 0) for u in per_ut], dtype=float)
        for k in HANDOVER_KINDS
    }
    return ut_ids, counts


#: Room above the highest bar of handovers.png for its one-row legend (part of the bar).
BAR_HEADROOM = 0.25


def _legend_above_bars(ax, top):
    """Integer counts up to ``top`` plus :data:`BAR_HEADROOM`, the legend in one row in the
    room above the bars (never over one)."""
    from matplotlib.ticker import MaxNLocator

    ax.set_ylim(0.0, max(top, 1.0) * (1.0 + BAR_HEADROOM))
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.legend(loc="upper center", ncols=len(HANDOVER_KINDS), fontsize=9)


def _handovers(duration_s, summary, per_ut_table=None):
    ut_ids, counts = _handover_counts(summary, per_ut_table)
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
        _legend_above_bars(ax, bottom.max(initial=0.0))
        if ut_ids.size == 0:
            ax.text(0.5, 0.5, "no UT in the summary", transform=ax.transAxes, ha="center")
    ax.grid(True, axis="y", alpha=0.3)
    return fig


def plot_run(
    trace, events, summary, out_dir, ut_ids=(0,), duration_s=None, per_ut=None, dwells=None
):
    """Time series and statistics of a ``leolink run``.

    Parameters
    ----------
    trace : pandas.DataFrame
        One row per UT per epoch; columns ``time_s, ut_id, beam_id, snr_db, sinr_db,
        doppler_hz`` at least (``beam_id`` = -1 and NaN SNR in outage).
    events : pandas.DataFrame or None
        ``time_s, ut_id, kind, ...``; may be empty.
    summary : dict
        The ``summary.json`` layout (:class:`leolink.io.summary.accumulator.SummaryAccumulator`):
        ``summary["per_ut"]`` (``ut_id``, ``handovers``, ``dwell.censored``) and
        ``summary["overall"]`` (``handovers``, ``dwell.complete_s`` [s]).
    out_dir : path-like
        Directory (created if missing).
    ut_ids : sequence of int
        UTs shown in the time plots; ids absent from the trace are skipped.
    duration_s : float, optional
        Recorded time span of the run [s] (handover rates); default from ``trace``.
    per_ut, dwells : dict of columns, optional
        ``SummaryAccumulator.per_ut_table()`` and ``.dwell_table()``: used instead of
        ``summary["per_ut"]`` (absent from the summary of a run with many UTs).

    Returns
    -------
    list of pathlib.Path
        ``snr_time.png, doppler_time.png, dwell_hist.png, handovers.png``.
    """
    uts = _selected(trace, ut_ids)
    with _AtomicPngs(out_dir) as out:
        out.save(_snr_time(trace, events, uts), "snr_time.png")
        out.save(_doppler_time(trace, uts), "doppler_time.png")
        out.save(_dwell_hist(summary, dwells), "dwell_hist.png")
        if duration_s is None:
            duration_s = float(np.ptp(trace["time_s"].to_numpy(float))) if len(trace) else 0.0
        out.save(_handovers(duration_s, summary, per_ut), "handovers.png")
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
