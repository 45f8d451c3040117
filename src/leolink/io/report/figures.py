"""Figures of a run for the report and notebooks, from data a streaming sink keeps.

Every function returns a :class:`matplotlib.figure.Figure` on the Agg canvas (no pyplot
state). Inputs are bounded whatever the run size: per-UT series only for a few chosen
UTs (``series``: the trace columns of those UTs, a dict of 1-D arrays as
:meth:`~leolink.io.report.stats.ReportStats.series_columns` gives or a DataFrame; ``events``
likewise), histograms or CDF points
for all UT-epochs (:class:`leolink.io.report.stats.ReportStats`), dwell histograms.
"""

from __future__ import annotations

import numpy as np

from leolink.io.report.headline import fmt_si
from leolink.io.report.maps import FIXED_TITLE_RC, beam_colour

__all__ = [
    "fig_angular_speed",
    "fig_cdfs",
    "fig_doppler",
    "fig_dwell",
    "fig_handover_timeline",
    "fig_outage_reasons",
    "fig_snr_time",
    "new_figure",
    "ut_line",
]

MAX_PANELS = 6
_KIND_STYLE = {"beam_handover": ("tab:purple", ":"), "sat_handover": ("tab:red", "--")}


_UT_DASHES = ("-", "--", ":", "-.")


def ut_line(i):
    """Line style of the ``i``-th chosen UT of a time plot: each later UT is drawn on top,
    thinner and dashed, so that a UT whose curve coincides with an earlier one's (UTs a
    few km apart see the same Doppler) leaves that one visible beneath it."""
    return {"linestyle": _UT_DASHES[i % len(_UT_DASHES)], "linewidth": max(2.2 - 0.4 * i, 1.0),
            "zorder": 2.0 + 0.01 * i}  # fmt: skip


#: Fixed margins of a figure [in]: room for tick labels, axis labels and titles. A layout
#: engine ("constrained") found them per figure at about a third of its drawing time.
MARGINS_IN = {"left": 0.85, "right": 0.25, "bottom": 0.6, "top": 0.45, "hspace": 0.45,
              "wspace": 0.75}  # fmt: skip
SUPTITLE_IN = 0.3  # more room at the top for a figure title above the axes' titles
LEGEND_RIGHT_IN = 1.45  # room on the right for a legend outside the axes


def new_figure(n_rows=1, n_cols=1, *, figsize=(9.0, 4.0), dpi=100, margins_in=None,
               fixed_titles=True, **subplot_kw):  # fmt: skip
    """An Agg figure and a 2-D array of axes placed with fixed margins [in]
    (:data:`MARGINS_IN`, updated by ``margins_in``); their titles at the fixed place of
    :data:`leolink.io.report.maps.FIXED_TITLE_RC` unless ``fixed_titles`` is false
    (then matplotlib lifts each over whatever is drawn above its axes)."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    m = {**MARGINS_IN, **(margins_in or {})}
    w_in, h_in = figsize
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    axes_w = (w_in - m["left"] - m["right"] - (n_cols - 1) * m["wspace"]) / n_cols
    axes_h = (h_in - m["bottom"] - m["top"] - (n_rows - 1) * m["hspace"]) / n_rows
    grid = {"left": m["left"] / w_in, "right": 1.0 - m["right"] / w_in,
            "bottom": m["bottom"] / h_in, "top": 1.0 - m["top"] / h_in,
            "wspace": m["wspace"] / axes_w, "hspace": m["hspace"] / axes_h}  # fmt: skip
    with rc_context(FIXED_TITLE_RC if fixed_titles else {}):
        axes = fig.subplots(n_rows, n_cols, squeeze=False, gridspec_kw=grid, **subplot_kw)
    return fig, axes


def _uts(series, ut_ids, limit=MAX_PANELS):
    """The UTs to draw: ``ut_ids`` present in ``series`` (default: all, in order of first
    appearance), at most ``limit``."""
    ut, first = np.unique(np.asarray(series["ut_id"], int), return_index=True)
    present = ut[np.argsort(first)].tolist()
    wanted = present if ut_ids is None else [int(u) for u in ut_ids if int(u) in set(present)]
    return wanted[:limit]


def _rows(series, ut_id):
    """The columns of ``series`` (mapping or DataFrame) at the rows of ``ut_id``, in time
    order: dict of arrays."""
    rows = np.flatnonzero(np.asarray(series["ut_id"]) == ut_id)
    rows = rows[np.argsort(np.asarray(series["time_s"], float)[rows], kind="stable")]
    return {k: np.asarray(series[k])[rows] for k in series}


def _event_times(events, ut_id, kind):
    """Times [s] of the events of ``kind`` of UT ``ut_id`` (``events``: mapping or DataFrame)."""
    if not len(events["ut_id"]):
        return np.empty(0)
    mask = (np.asarray(events["ut_id"]) == ut_id) & (np.asarray(events["kind"]) == kind)
    return np.asarray(events["time_s"], float)[mask]


def _empty(ax, text):
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=11)


def _outage_spans(ax, t_s, mask, colour, label):
    """Shade the epochs where ``mask`` holds (each epoch spans to the next)."""
    if mask.any():
        ax.fill_between(
            t_s,
            0,
            1,
            where=mask,
            step="post",
            color=colour,
            alpha=0.3,
            transform=ax.get_xaxis_transform(),
            label=label,
            linewidth=0,
        )


def fig_snr_time(series, events, ut_ids=None):
    """SNR and SINR vs time, one panel per UT, handovers as lines, outages shaded.

    Parameters
    ----------
    series : mapping of str to array_like, or pandas.DataFrame
        Trace rows of the chosen UTs: ``time_s, ut_id, snr_db, sinr_db, service``.
    events : mapping of str to array_like, or pandas.DataFrame
        ``time_s, ut_id, kind`` (beam/satellite handovers drawn; others ignored).
    ut_ids : sequence of int, optional
        UTs to show (default: all in ``series``, at most :data:`MAX_PANELS`).
    """
    uts = _uts(series, ut_ids)
    n = max(len(uts), 1)
    margins = {"top": MARGINS_IN["top"] + SUPTITLE_IN, "right": LEGEND_RIGHT_IN}
    fig, axes = new_figure(n, 1, figsize=(10.0, 2.3 * n + 0.8), margins_in=margins, sharex=True)
    for ax, ut in zip(axes[:, 0], uts, strict=False):
        r = _rows(series, ut)
        t = r["time_s"].astype(float)
        service = r["service"].astype(str)
        ax.plot(t, r["snr_db"], color="tab:blue", label="SNR", linewidth=1.2)
        ax.plot(t, r["sinr_db"], color="tab:orange", label="SINR", linewidth=1.2)
        _outage_spans(ax, t, service == "outage", "grey", "outage")
        _outage_spans(ax, t, service == "handover", "gold", "handover execution")
        for kind, (colour, style) in _KIND_STYLE.items():
            for i, te in enumerate(_event_times(events, ut, kind).tolist()):
                ax.axvline(
                    te,
                    color=colour,
                    linestyle=style,
                    linewidth=1.0,
                    label=kind.replace("_", " ") if i == 0 else None,
                )
        ax.set_ylabel("[dB]")
        ax.ticklabel_format(axis="y", useOffset=False)  # no offset text under the title
        ax.set_title(f"UT {ut}", fontsize=10, loc="left")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    if not uts:
        _empty(axes[0, 0], "no chosen UT in the data")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle("SNR and SINR vs time (dotted: beam handover, dashed: satellite handover)")
    return fig


def _lines(ax, series, uts, column, scale, ylabel):
    for i, ut in enumerate(uts):  # one line per chosen UT
        r = _rows(series, ut)
        ax.plot(r["time_s"], r[column].astype(float) * scale, label=f"UT {ut}", **ut_line(i))
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    if uts:
        ax.legend(fontsize=7, loc="best")
    else:
        _empty(ax, "no chosen UT in the data")


def fig_doppler(series, ut_ids=None):
    """Doppler shift [kHz] and Doppler rate [Hz/s] of the serving link vs time."""
    uts = _uts(series, ut_ids, limit=10)
    top = {"top": MARGINS_IN["top"] + SUPTITLE_IN}
    fig, axes = new_figure(2, 1, figsize=(10.0, 5.5), margins_in=top, sharex=True)
    _lines(axes[0, 0], series, uts, "doppler_hz", 1e-3, "Doppler [kHz]")
    _lines(axes[1, 0], series, uts, "doppler_rate_hz_s", 1.0, "Doppler rate [Hz/s]")
    axes[0, 0].axhline(0.0, color="black", linewidth=0.7)
    axes[1, 0].set_xlabel("time [s]")
    fig.suptitle("Doppler and its rate, serving satellite")
    return fig


def fig_angular_speed(series, ut_ids=None):
    """Angular speed of the serving satellite seen from the UT [deg/s] vs time."""
    uts = _uts(series, ut_ids, limit=10)
    fig, axes = new_figure(figsize=(10.0, 3.8))
    _lines(axes[0, 0], series, uts, "angular_speed_deg_s", 1.0, "angular speed [deg/s]")
    axes[0, 0].set_xlabel("time [s]")
    axes[0, 0].set_title("Relative angular speed of the serving satellite")
    return fig


def fig_dwell(edges_s, complete, censored, mean_s=None):
    """Histograms of dwell (time-of-stay) in a beam: complete dwells and censored apart.

    Parameters
    ----------
    edges_s : array_like, shape (n_bin + 1,)
        Bin edges [s].
    complete, censored : array_like of int, shape (n_bin,)
        Dwells per bin; censored = cut by the start or end of the run (a lower bound).
    mean_s : float, optional
        Mean of the complete dwells [s], drawn as a line: ``summary.json``'s
        ``dwell.mean_s`` (:attr:`ReportStats.dwell_mean_s`), never recomputed from the
        bins, so the figure and the tables show one number.
    """
    edges, parts = np.asarray(edges_s, float), (np.asarray(complete), np.asarray(censored))
    top = {"top": MARGINS_IN["top"] + SUPTITLE_IN}
    # Titles placed by matplotlib: counts from 10^6 put a multiplier above the y axis,
    # which the censored panel's long title would cover.
    fig, axes = new_figure(1, 2, figsize=(10.0, 3.8), margins_in=top, fixed_titles=False)
    titles = ("complete dwells", "censored dwells (cut by the run start or end)")
    means = (mean_s, None)  # a censored dwell is a lower bound: no mean of them
    for ax, counts, title, colour, mean in zip(
        axes[0], parts, titles, ("tab:blue", "tab:gray"), means, strict=True
    ):
        n = int(counts.sum())
        if n == 0:
            _empty(ax, "none")
        else:
            last = int(np.flatnonzero(counts)[-1]) + 1
            ax.stairs(counts[:last], edges[: last + 1], fill=True, color=colour, alpha=0.8)
        if n and mean is not None:
            ax.axvline(mean, color="black", linestyle="--", label=f"mean {fmt_si(mean)} s")
            ax.legend(fontsize=8)
        ax.set_title(f"{title}: {n}", fontsize=10)
        ax.set_xlabel("dwell [s]")
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("number of dwells")
    fig.suptitle("Time of stay in a beam, all UTs")
    return fig


def _label_spans(ax, spans, beams, sats, row):
    """Write ``beam`` (or ``sat:beam`` when several satellites serve) on wide segments."""
    total = sum(w for _, w in spans) or 1.0
    multi = np.unique(sats[sats >= 0]).size > 1
    for (t0, w), b, s in zip(spans, beams, sats, strict=True):
        if b >= 0 and w > 0.06 * total:
            ax.text(
                t0 + 0.5 * w,
                row,
                f"{s}:{b}" if multi else str(b),
                ha="center",
                va="center",
                fontsize=7,
                color="white",
                fontweight="bold",
            )


def fig_handover_timeline(series, events, ut_ids=None, max_rows=30):
    """Serving beam per UT over time (one bar per UT, coloured by beam; outage grey),
    with beam handovers (|) and satellite handovers (x) marked."""
    uts = _uts(series, ut_ids, limit=max_rows)
    fig, axes = new_figure(figsize=(10.0, 0.45 * max(len(uts), 1) + 1.6),
                           margins_in={"right": LEGEND_RIGHT_IN})  # fmt: skip
    ax = axes[0, 0]
    for row, ut in enumerate(uts):  # one bar per chosen UT
        r = _rows(series, ut)
        t = r["time_s"].astype(float)
        beam = r["beam_id"].astype(int)
        dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if t.size > 1 else 1.0))
        starts = np.flatnonzero(np.r_[True, beam[1:] != beam[:-1]])
        ends = np.r_[starts[1:], beam.size]
        spans = [(t[a], t[b - 1] + dt[b - 1] - t[a]) for a, b in zip(starts, ends, strict=True)]
        ax.broken_barh(spans, (row - 0.4, 0.8), facecolors=beam_colour(beam[starts]))
        _label_spans(ax, spans, beam[starts], r["sat_id"].astype(int)[starts], row)
        for kind, marker in (("beam_handover", "|"), ("sat_handover", "x")):
            te = _event_times(events, ut, kind)
            ax.plot(
                te,
                np.full(len(te), row),
                linestyle="none",
                marker=marker,
                color="black",
                markersize=9,
                label=kind.replace("_", " ") if row == 0 else None,
            )
    ax.set_yticks(range(len(uts)), [f"UT {u}" for u in uts])
    ax.set_ylim(-0.7, max(len(uts), 1) - 0.3)
    ax.invert_yaxis()
    ax.set_xlabel("time [s]")
    ax.set_title(
        "Handover timeline: serving beam per UT (label = beam id or sat:beam, grey = outage)",
        fontsize=10,
    )
    ax.grid(True, axis="x", alpha=0.3)
    if uts:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    else:
        _empty(ax, "no chosen UT in the data")
    return fig


def _cdf_axes(ax, x, f, label, scale=1.0):
    ok = np.isfinite(x)
    if f.size and f[-1] > 0:
        lo = np.searchsorted(f, 1e-4)  # trim the empty tails of the fixed bins
        hi = min(np.searchsorted(f, 1.0 - 1e-12) + 1, x.size)
        keep = np.zeros(x.size, bool)
        keep[max(lo - 1, 0) : hi] = True
        ax.step(x[ok & keep] * scale, f[ok & keep], where="post", label=label)


def fig_cdfs(cdfs):
    """Empirical CDFs of SNR, SINR (one axes) and throughput (another) over all UT-epochs.

    ``cdfs``: ``{"snr_db": (x, F), "sinr_db": (x, F), "throughput_bps": (x, F)}`` as
    :meth:`leolink.io.report.stats.ReportStats.cdf` returns.
    """
    fig, axes = new_figure(1, 2, figsize=(10.0, 3.8))
    for key, label in (("snr_db", "SNR"), ("sinr_db", "SINR")):
        _cdf_axes(axes[0, 0], *cdfs[key], label)
    axes[0, 0].set_xlabel("[dB]")
    axes[0, 0].legend(fontsize=8)
    _cdf_axes(axes[0, 1], *cdfs["throughput_bps"], "throughput", scale=1e-6)
    axes[0, 1].set_xlabel("throughput [Mb/s]")
    for ax, title in zip(axes[0], ("SNR and SINR CDF", "Throughput CDF"), strict=True):
        ax.set_ylabel("fraction of UT-epochs")
        ax.set_ylim(0.0, 1.02)
        ax.set_title(title, fontsize=10)
        ax.grid(True, alpha=0.3)
    return fig


def fig_outage_reasons(reason_counts, n_ut_epochs):
    """Outage UT-epochs by reason, as a fraction of all UT-epochs (bar chart)."""
    fig, axes = new_figure(figsize=(7.0, 3.2), margins_in={"left": 1.35})
    ax = axes[0, 0]
    names = sorted(reason_counts, key=lambda k: -reason_counts[k])
    if not names or not n_ut_epochs:
        _empty(ax, "no outage")
    else:
        frac = np.array([reason_counts[k] for k in names], float) / float(n_ut_epochs)
        ax.barh(range(len(names)), frac * 100.0, color="tab:gray")
        ax.set_yticks(range(len(names)), names)
        for i, (f, k) in enumerate(zip(frac, names, strict=True)):
            ax.text(f * 100.0, i, f" {reason_counts[k]}", va="center", fontsize=8)
    ax.set_xlabel("outage [% of UT-epochs]")
    ax.set_title("Outage by reason", fontsize=10)
    ax.grid(True, axis="x", alpha=0.3)
    return fig
