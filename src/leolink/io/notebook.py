"""Notebook views of a run result: figures, an HTML summary, a (time x UT) xarray.

:class:`ResultViews` is a mixin for the run result (``leolink.run(...)`` returns an object
with ``trace``, ``events`` and ``summary``); it adds ``plot_sinr(ut_ids=...)``,
``plot_map()``, ``plot_dwell()`` and friends (each returns a matplotlib Figure),
``_repr_html_`` (Jupyter shows the KPI table) and :meth:`to_xarray`.

The figures come from a :class:`~leolink.io.report.stats.ReportStats`: the result's own
``report_stats`` when the run kept one (large runs: no trace in memory), else one built
once from the in-memory ``trace`` (and its ``satellites`` / ``codebook`` if given).
"""

from __future__ import annotations

import html

import numpy as np

# figures (matplotlib, pandas) and ReportStats (pandas) are imported when a view is drawn:
# importing them here cost every run ~1.5 s of start-up.

__all__ = ["ResultViews", "dense", "stats_from_frames"]


def stats_from_frames(trace, events, summary, series_ut, satellites=None, codebook=None):
    """A :class:`ReportStats` from in-memory tables (``satellites``: DataFrame ``time_s,
    sat_id, x_m .. vz_m_s``; ``codebook``: ``leolink codebook --json`` dict)."""
    from leolink.io.report.stats import ReportStats

    run = summary["run"]
    stats = ReportStats(run["n_ut"], run["start_s"], run["end_s"], run["epoch_s"], series_ut)
    stats.add_trace({c: trace[c].to_numpy() for c in trace.columns})
    if events is not None and len(events):
        stats.add_events(events)
    stats.add_dwells_from_summary(summary)
    if satellites is not None:
        for t_s, rows in satellites.groupby("time_s", sort=True):  # per epoch
            stats.add_satellites(
                t_s,
                rows[["x_m", "y_m", "z_m"]].to_numpy(),
                rows[["vx_m_s", "vy_m_s", "vz_m_s"]].to_numpy(),
                rows["sat_id"].to_numpy(),
            )
    if codebook is not None:
        stats.set_codebook(
            [[b["u_x"], b["u_y"]] for b in codebook["beams"]],
            codebook["n_sub_x"],
            codebook["n_sub_y"],
        )
    return stats


def _figures():
    from leolink.io.report import figures

    return figures


def dense(trace, column):
    """One trace column as a ``(n_time, n_ut)`` array (NaN where a row is missing).

    Returns ``time_s (n_time,)``, ``ut_id (n_ut,)``, ``values (n_time, n_ut)``.
    """
    t, it = np.unique(trace["time_s"].to_numpy(float), return_inverse=True)
    u, iu = np.unique(trace["ut_id"].to_numpy(int), return_inverse=True)
    out = np.full((t.size, u.size), np.nan)
    out[it, iu] = trace[column].to_numpy(float)
    return t, u, out


class ResultViews:
    """Mixin: needs ``summary`` (dict) and either ``report_stats`` or ``trace`` / ``events``.

    Optional attributes: ``satellites`` and ``codebook`` (for the map's ground tracks and
    beam cells when no ``report_stats`` is kept).
    """

    _views_cache = None

    def _stats(self, ut_ids=None):
        kept = getattr(self, "report_stats", None)
        wanted = None if ut_ids is None else tuple(int(u) for u in ut_ids)
        if kept is not None and (wanted is None or set(wanted) <= set(kept.series_ut.tolist())):
            return kept
        key = wanted or (0,)
        if self._views_cache is None or self._views_cache[0] != key:
            stats = stats_from_frames(
                self.trace,
                getattr(self, "events", None),
                self.summary,
                key,
                getattr(self, "satellites", None),
                getattr(self, "codebook", None),
            )
            self._views_cache = (key, stats)
        return self._views_cache[1]

    def plot_sinr(self, ut_ids=(0,)):
        """SNR/SINR vs time of ``ut_ids`` with handovers and outages marked (Figure)."""
        s = self._stats(ut_ids)
        return _figures().fig_snr_time(s.series(), s.events(), ut_ids)

    def plot_doppler(self, ut_ids=(0,)):
        """Doppler and Doppler rate vs time (Figure)."""
        return _figures().fig_doppler(self._stats(ut_ids).series(), ut_ids)

    def plot_angular_speed(self, ut_ids=(0,)):
        """Angular speed of the serving satellite vs time (Figure)."""
        return _figures().fig_angular_speed(self._stats(ut_ids).series(), ut_ids)

    def plot_timeline(self, ut_ids=(0,)):
        """Serving beam per UT over time with handovers (Figure)."""
        s = self._stats(ut_ids)
        return _figures().fig_handover_timeline(s.series(), s.events(), ut_ids)

    def plot_dwell(self):
        """Dwell histograms, complete and censored apart (Figure)."""
        s = self._stats()
        return _figures().fig_dwell(
            s.dwell_edges_s, s.dwell_complete, s.dwell_censored, s.dwell_mean_s
        )

    def plot_cdfs(self):
        """SNR, SINR and throughput CDFs over all UT-epochs (Figure)."""
        s = self._stats()
        return _figures().fig_cdfs({k: s.cdf(k) for k in ("snr_db", "sinr_db", "throughput_bps")})

    def plot_outage(self):
        """Outage UT-epochs by reason (Figure)."""
        s = self._stats()
        return _figures().fig_outage_reasons(s.outage_reason_counts, sum(s.service_counts.values()))

    def plot_map(self):
        """Ground tracks, serving beam cells and UT tracks (Figure)."""
        from leolink.io.report.page import run_map_figure

        return run_map_figure(self._stats())

    def _repr_html_(self):
        from leolink.io.report.page import kpi_rows

        rows = "".join(
            f"<tr><td>{html.escape(k)}</td><td>{html.escape(str(v))}</td></tr>"
            for k, v in kpi_rows(self.summary)
        )
        return f"<table><tr><th colspan='2'>leolink run</th></tr>{rows}</table>"

    def to_xarray(self, columns=("snr_db", "sinr_db", "throughput_bps", "doppler_hz", "beam_id")):
        """The trace as an ``xarray.Dataset`` with dimensions ``(time_s, ut_id)``.

        Needs xarray (``pip install xarray``); integer columns become float (NaN where a
        UT has no row at an epoch).
        """
        try:
            import xarray as xr
        except ImportError as exc:  # optional dependency
            raise ImportError("to_xarray() needs xarray: pip install xarray") from exc
        data = {}
        for col in columns:
            t, u, values = dense(self.trace, col)
            data[col] = (("time_s", "ut_id"), values)
        return xr.Dataset(data, coords={"time_s": t, "ut_id": u})
