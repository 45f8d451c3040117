"""Notebook views of a run result: figures, an HTML summary, a (time x UT) xarray.

:class:`ResultViews` is a mixin for the run result (``leolink.run(...)`` returns an object
with ``trace``, ``events`` and ``summary``); it adds ``plot_sinr(ut_ids=...)``,
``plot_map()``, ``plot_dwell()`` and friends (each returns a matplotlib Figure),
a one-line ``repr``, ``_repr_html_`` (Jupyter shows the KPI table) and :meth:`to_xarray`.

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
    t, it, u, iu = _axes(trace)
    return t, u, _grid(trace[column].to_numpy(float), it, iu, (t.size, u.size))


def _axes(trace):
    """The epochs and UTs of a trace, and each row's index into them."""
    t, it = np.unique(trace["time_s"].to_numpy(float), return_inverse=True)
    u, iu = np.unique(trace["ut_id"].to_numpy(), return_inverse=True)
    return t, it, u, iu


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

    def __repr__(self):
        return f"<leolink.Result: {self._headline()}>"

    def _headline(self):
        """One line: size of the run, handovers, outage, mean SNR/SINR, where it wrote."""
        run, o = self.summary["run"], self.summary["overall"]
        h = o["handovers"]
        db = lambda k: "n/a" if o[k]["mean"] is None else f"{o[k]['mean']:.2f} dB"  # noqa: E731
        where = getattr(self, "out_dir", None)
        return (
            f"{run['n_ut']} UTs x {run['n_epochs']} epochs of {run['epoch_s']:g} s, "
            f"{run['n_sat']} satellite(s), {run['n_beam']} beams; handovers "
            f"{h['beam_handover']} beam / {h['sat_handover']} satellite; outage "
            f"{100 * o['outage_fraction']:.2f} %; mean SNR {db('snr_db')}, SINR "
            f"{db('sinr_db')}; {'in memory' if where is None else f'in {where}'}"
        )

    def _repr_html_(self):
        from leolink.io.report.page import kpi_rows

        rows = "".join(
            f"<tr><td>{html.escape(k)}</td><td>{html.escape(str(v))}</td></tr>"
            for k, v in kpi_rows(self.summary)
        )
        head = html.escape(self._headline())
        return (
            f"<p><b>leolink run</b>: {head}</p><details open><summary>key figures</summary>"
            f"<table>{rows}</table></details><p><code>.trace</code>, <code>.events</code>, "
            "<code>.summary</code>, <code>.plot_map()</code>, <code>.plot_sinr(ut_ids)</code>, "
            "<code>.to_xarray()</code></p>"
        )

    def to_xarray(self):
        """The trace as an ``xarray.Dataset`` over ``(time, ut_id)``.

        Every trace column but ``time_s``, ``ut_id`` and ``population`` is a variable of
        shape ``(n_time, n_ut)``, with CF-style ``units`` and a ``description``
        (:data:`~leolink.io.table_schemas.TRACE_COLUMN_DOCS`); integer columns stay
        integers (-1 where a UT has no row at an epoch, as for "no beam"), floats are NaN
        there, names ``""``. Coordinates: ``time`` [s], ``ut_id``, ``population`` (per
        UT) and, when the run's UTC is known (``run.start_utc``, TLE runs),
        ``time_utc`` (``datetime64[ns]``, UTC).

        Needs xarray (``pip install "leolink[notebook]"``).
        """
        try:
            import xarray as xr
        except ImportError as exc:  # optional dependency
            raise ImportError('to_xarray() needs xarray: pip install "leolink[notebook]"') from exc
        trace = self.trace
        t, it, u, iu = _axes(trace)
        data = {
            c: (("time", "ut_id"), _grid(trace[c].to_numpy(), it, iu, (t.size, u.size)), _attrs(c))
            for c in trace.columns
            if c not in ("time_s", "ut_id", "population", "time_utc")  # (coordinates)
        }
        coords = {"time": ("time", t, _attrs("time_s")), "ut_id": ("ut_id", u, _attrs("ut_id"))}
        if "population" in trace:
            names = np.empty(u.size, dtype=object)
            names[iu] = trace["population"].to_numpy()
            coords["population"] = ("ut_id", names.astype(str), _attrs("population"))
        zero = getattr(self, "time_zero_utc", None)
        if zero:
            ns = np.round(t * 1e9).astype("timedelta64[ns]")
            utc = np.datetime64(zero.rstrip("Z"), "ns") + ns
            coords["time_utc"] = ("time", utc, {"description": "UTC of the epoch"})
        return xr.Dataset(data, coords=coords, attrs={"source": "leolink trace"})


def _grid(values, it, iu, shape):
    """Rows ``values`` at ``(it, iu)`` of a ``shape`` grid, of their dtype; holes are -1
    (integers), NaN (floats) or ``""`` (names)."""
    kind = values.dtype.kind
    fill = -1 if kind in "iu" else np.nan if kind == "f" else ""
    out = np.full(shape, fill, dtype=values.dtype if kind in "iuf" else object)
    out[it, iu] = values
    return out if kind in "iuf" else out.astype(str)


def _attrs(column):
    """CF-style attributes of a trace column: ``units`` (none for ids and names) and
    ``description`` (:data:`~leolink.io.table_schemas.TRACE_COLUMN_DOCS`)."""
    from leolink.io.table_schemas import TRACE_COLUMN_DOCS

    units, description = TRACE_COLUMN_DOCS.get(column, ("", ""))
    return {"units": units, "description": description} if units else {"description": description}
