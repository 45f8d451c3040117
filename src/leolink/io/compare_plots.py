"""Figures of ``leolink compare``: the KPI trade-off per policy and the SINR CDF per policy."""

from __future__ import annotations

import numpy as np

from leolink.io.plots import _AtomicPngs, _figure

__all__ = ["plot_compare", "sinr_cdf"]

#: (column, axis label, scale) of the trade-off panels.
TRADE_OFF = (
    ("kpi_handover_rate_per_ut_min", "handovers per UT-minute", 1.0),
    ("kpi_ping_pong_fraction", "ping-pong fraction (cell)", 1.0),
    ("kpi_ping_pong_fraction_satellite", "ping-pong fraction (satellite)", 1.0),
    ("mean_throughput_bps", "mean throughput [Mb/s]", 1e-6),
    ("kpi_rlf_rate_per_ut_min", "RLFs per UT-minute", 1.0),
)


def sinr_cdf(sinr_db):
    """``(x_db, F)`` of the empirical CDF of per-UT-epoch SINR, NaN (unserved) at -inf:
    ``F`` starts at the unserved fraction."""
    sinr_db = np.asarray(sinr_db, float)
    served = np.sort(sinr_db[np.isfinite(sinr_db)])
    n = max(sinr_db.size, 1)
    unserved = (sinr_db.size - served.size) / n
    return served, unserved + np.arange(1, served.size + 1) / n


def plot_compare(table, out_dir, cdfs=None):
    """``compare_kpis.png`` (one bar panel per KPI, error bars: standard deviation over
    seeds), ``compare_tradeoff.png`` (handover rate vs mean throughput, colour: satellite
    ping-pong fraction) and, with ``cdfs`` ``{policy: (x_db, F)}``, ``compare_sinr_cdf.png``.

    ``table``: ``compare.csv`` as a DataFrame (columns ``policy``, KPI, ``KPI_std``).
    Returns the written paths.
    """
    labels = list(table["policy"])
    pos = np.arange(len(labels))
    panels = [p for p in TRADE_OFF if p[0] in table.columns]
    with _AtomicPngs(out_dir) as out:
        fig, axes = _figure(len(panels), 1, figsize=(8.0, 2.2 * len(panels) + 1.0), sharex=True)
        for ax, (col, label, scale) in zip(axes[:, 0], panels, strict=True):
            std = table.get(f"{col}_std")
            err = None if std is None else np.nan_to_num(std.to_numpy(float)) * scale
            ax.bar(pos, table[col].to_numpy(float) * scale, yerr=err, capsize=3, color="C0")
            ax.set_ylabel(label)
            ax.grid(True, axis="y", alpha=0.3)
        axes[-1, 0].set_xticks(pos, labels, rotation=30, ha="right")
        fig.suptitle("Handover KPIs per policy (bars: mean over seeds; whiskers: std)")
        out.save(fig, "compare_kpis.png")

        fig, axes = _figure(figsize=(7.0, 5.0))
        ax = axes[0, 0]
        x = table["kpi_handover_rate_per_ut_min"].to_numpy(float)
        y = table["mean_throughput_bps"].to_numpy(float) * 1e-6
        # (compare.csv leaves out a column no policy has: no satellite handover, no ping-pong)
        pp = table.get("kpi_ping_pong_fraction_satellite", np.nan * x)
        pp = np.asarray(pp, float)
        sc = ax.scatter(x, y, c=np.nan_to_num(pp), cmap="viridis", s=60, zorder=3)
        for xi, yi, name in zip(x, y, labels, strict=True):
            ax.annotate(name, (xi, yi), textcoords="offset points", xytext=(5, 4), fontsize=8)
        fig.colorbar(sc, ax=ax, label="ping-pong fraction (satellite)")
        ax.set_xlabel("handovers per UT-minute")
        ax.set_ylabel("mean throughput [Mb/s]")
        ax.grid(True, alpha=0.3)
        ax.set_title("Handover rate vs throughput vs ping-pong")
        out.save(fig, "compare_tradeoff.png")

        if cdfs:
            fig, axes = _figure(figsize=(7.0, 5.0))
            ax = axes[0, 0]
            for name, (xs, f) in cdfs.items():
                ax.step(xs, f, where="post", label=name)
            ax.set_xlabel("SINR per UT-epoch [dB] (unserved epochs at -inf)")
            ax.set_ylabel("CDF")
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=8)
            ax.set_title("SINR CDF per policy (all seeds pooled)")
            out.save(fig, "compare_sinr_cdf.png")
    return out.written
