"""The self-contained ``report.html`` of a run (and of compare / sweep / coverage tables).

One HTML file: inline CSS, every image a ``data:image/png;base64`` URI (the animation a
``data:image/gif`` URI, or a relative link to ``footprint.gif`` beside the page when it is
over ``embed_max_bytes``), no script, no font, no style sheet fetched from anywhere: it
opens offline. The content is the resolved config, the summary and KPI tables and the
figures of :mod:`leolink.io.report.figures` and :mod:`leolink.io.report.maps`.

Scale: the page is built from a :class:`~leolink.io.report.stats.ReportStats` (histograms,
a few UT series, a UT sample at subsampled epochs), never from the whole trace. With
``report_stats.npz`` saved by the run, ``leolink report DIR``
(:func:`leolink.io.report.rebuild.build_report_from_dir`) only reads that and
``summary.json``; without it, the trace is streamed in chunks (Parquet record batches or
CSV chunks), so memory stays bounded either way.
"""

from __future__ import annotations

import base64
import html
import io
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from leolink.io.atomic import write_text_atomic
from leolink.io.report import figures as F
from leolink.io.report.headline import header_lines, headline_figures
from leolink.io.report.maps import draw_ut_labels, plot_map, subsatellite_points

__all__ = [
    "KPIS",
    "build_run_report",
    "build_table_report",
    "figure_data_uri",
    "kpi_rows",
    "rendered_figures",
    "run_map_figure",
    "run_figures",
]

N_TIME_FIGURES = 4  # run_figures: the map, 4 time series, then the distributions
PER_UT_ROWS = 30  # per-UT table rows shown; the rest stay in summary.json
_CSS = """
body{font-family:sans-serif;margin:1.5em auto;max-width:1100px;color:#222;padding:0 1em}
h1{font-size:1.6em}h2{font-size:1.25em;border-bottom:1px solid #ccc;padding-bottom:.2em;
margin-top:1.6em}table{border-collapse:collapse;font-size:.85em;margin:.5em 0}
td,th{border:1px solid #ccc;padding:.2em .5em;text-align:right}th{background:#f2f2f2}
td:first-child,th:first-child{text-align:left}pre{background:#f7f7f7;padding:.8em;
overflow:auto;font-size:.8em;max-height:30em}img{max-width:100%;height:auto;display:block;
margin:.5em 0}figure{margin:1em 0}figcaption{font-size:.85em;color:#555}
.row{display:flex;gap:2em;flex-wrap:wrap;align-items:flex-start}.wide{overflow-x:auto}
header h1{margin:.2em 0 .1em}header p{margin:.2em 0}.meta{color:#555;font-size:.9em}
.headline{display:grid;grid-template-columns:repeat(3,1fr);gap:.8em;margin:1em 0}
.fig{border:1px solid #ddd;border-radius:6px;padding:.6em .8em;background:#fafafa}
.fig .label{font-size:.85em;color:#555}.fig .value{font-size:1.7em;font-weight:bold;
margin:.1em 0}.fig p{font-size:.82em;margin:.2em 0;color:#333}.fig.warn{border-color:#d9822b;
background:#fff6ec}details{margin:1em 0}summary{cursor:pointer;font-weight:bold}
"""


PNG_COMPRESS_LEVEL = 3  # zlib level: 6 (Pillow's default) costs ~1.6x the time for 7 % less


def figure_data_uri(fig, dpi=100):
    """PNG ``data:`` URI of a matplotlib figure (left as it is: clearing it would rebuild
    every axes' ticks, ~10 % of its drawing, for a figure that is dropped anyway)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _fmt(value):
    if isinstance(value, bool) or value is None:
        return "-" if value is None else str(value)
    if isinstance(value, int | np.integer):
        return f"{int(value):,}"
    if isinstance(value, float | np.floating):
        v = float(value)
        return f"{v:.4g}" if abs(v) < 1e5 or v == 0 else f"{v:.4e}"
    return html.escape(str(value))


def _table(header, rows):
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_fmt(v)}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _flatten(d, prefix=""):
    """``{"a": {"b": 1}}`` -> ``[("a.b", 1)]``; lists (e.g. dwell durations) are skipped."""
    rows = []
    for key, value in d.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            rows.extend(_flatten(value, name + "."))
        elif not isinstance(value, list):
            rows.append((name, value))
    return rows


KPIS = (
    ("UTs", ("overall", "n_ut"), ""),
    ("beam handovers", ("overall", "handovers", "beam_handover"), ""),
    ("satellite handovers", ("overall", "handovers", "sat_handover"), ""),
    ("complete / censored dwells", ("overall", "dwell", "n_complete"), ""),
    ("mean dwell (complete)", ("overall", "dwell", "mean_s"), "s"),
    ("outage fraction", ("overall", "outage_fraction"), ""),
    ("mean SNR", ("overall", "snr_db", "mean"), "dB"),
    ("mean SINR", ("overall", "sinr_db", "mean"), "dB"),
    ("mean throughput", ("overall", "mean_throughput_bps"), "b/s"),
    ("max |Doppler|", ("overall", "max_abs_doppler_hz"), "Hz"),
    ("max angular speed", ("overall", "max_angular_speed_deg_s"), "deg/s"),
)


def _get(d, path):
    for key in path:
        d = d.get(key) if isinstance(d, dict) else None
    return d


def kpi_rows(summary):
    """``(name, "value unit")`` rows of the key figures of a summary, then ``overall.kpi``."""
    rows = []
    for name, path, unit in KPIS:
        value = _get(summary, path)
        if path[-1] == "n_complete":
            value = f"{_fmt(value)} / {_fmt(_get(summary, ('overall', 'dwell', 'n_censored')))}"
        rows.append((name, f"{value if isinstance(value, str) else _fmt(value)} {unit}".strip()))
    kpi = _get(summary, ("overall", "kpi")) or {}
    rows += [(k, _fmt(v)) for k, v in _flatten(kpi)]
    return rows


#: Columns of the per-UT table: summary.json's record keys, and per_ut.parquet's names.
PER_UT_COLUMNS = {
    "handovers.beam_handover": "n_beam_handover",
    "handovers.sat_handover": "n_sat_handover",
    "dwell.n_complete": "n_dwell_complete",
    "dwell.mean_s": "dwell_mean_s",
    "outage_fraction": "outage_fraction",
    "snr_db.mean": "snr_mean_db",
    "sinr_db.mean": "sinr_mean_db",
    "mean_throughput_bps": "mean_throughput_bps",
    "max_abs_doppler_hz": "max_abs_doppler_hz",
}


def _shown(n_ut, first_uts):
    order = [u for u in first_uts if 0 <= u < n_ut]
    return (
        order
        + [i for i in range(min(n_ut, PER_UT_ROWS + len(order))) if i not in order][
            : PER_UT_ROWS - len(order)
        ]
    )


def _per_ut_rows(summary, first_uts, folder):
    """``(rows, n_ut, where)``: the shown UTs' values, from ``summary["per_ut"]`` or, for a
    run with many UTs, from ``per_ut.parquet`` beside the page (only the shown rows)."""
    per_ut = summary.get("per_ut")
    if per_ut is not None or "per_ut_file" not in summary:
        per_ut = per_ut or []
        order = _shown(len(per_ut), first_uts)
        flat = [dict(_flatten(per_ut[i])) for i in order]
        rows = [[per_ut[i].get("ut_id", i), *(f.get(c) for c in PER_UT_COLUMNS)]
                for i, f in zip(order, flat, strict=True)]  # fmt: skip
        return rows, len(per_ut), "summary.json"
    import pyarrow.parquet as pq

    name = summary["per_ut_file"]
    table = pq.read_table(Path(folder) / name, columns=["ut_id", *PER_UT_COLUMNS.values()])
    order = _shown(table.num_rows, first_uts)
    cols = {k: table.column(k).take(order).to_pylist() for k in table.column_names}
    nan_none = lambda v: None if isinstance(v, float) and v != v else v  # noqa: E731
    rows = [[nan_none(v) for v in r] for r in zip(*cols.values(), strict=True)]
    return rows, table.num_rows, name


def _per_ut_table(summary, first_uts, folder="."):
    rows, n_ut, where = _per_ut_rows(summary, first_uts, folder)
    note = f"<p>{len(rows)} of {n_ut:,} UTs shown (the chosen UTs first); all are in {where}.</p>"
    return '<div class="wide">' + _table(["ut_id", *PER_UT_COLUMNS], rows) + "</div>" + note


def run_map_figure(stats):
    """Ground tracks (satellites serving a sampled UT), cells at the middle kept epoch, UTs."""
    if stats.sat_pos_m is None:
        return _labelled(plot_map(ut_tracks=_ut_tracks(stats)), _ut_labels(stats))
    serving = np.unique(stats.ut_sat[stats.ut_sat >= 0])
    cols = np.flatnonzero(np.isin(stats.sat_ids, serving))
    lat, lon = subsatellite_points(stats.sat_pos_m[:, cols])  # (n_k, n_serving)
    tracks = {
        "sat_id": np.repeat(stats.sat_ids[cols], lat.shape[0]),
        "time_s": np.tile(stats.keep_times_s, cols.size),
        "lat_deg": lat.T.ravel(),
        "lon_deg": lon.T.ravel(),
    }
    footprints, t_s, now_uts = None, None, None
    k = stats.keep_times_s.size // 2
    if stats.beam_u_xy is not None:
        from leolink.io.report.animation import footprint_cells

        t_s = stats.keep_times_s[k]
        now = np.unique(stats.ut_sat[k][stats.ut_sat[k] >= 0])
        footprints = footprint_cells(
            stats.sat_ids,
            stats.sat_pos_m[k],
            stats.sat_vel_m_s[k],
            now,
            stats.beam_u_xy,
            stats.n_sub_xy,
        )
        now_uts = {
            "lat_deg": stats.ut_lat_deg[k],
            "lon_deg": stats.ut_lon_deg[k],
            "beam_id": stats.ut_beam[k],
        }
    title = "Satellite ground tracks, UT tracks coloured by serving beam"
    if t_s is not None:
        title += f"\nbeam cells (half power) and UTs (dots) at t = {t_s:.0f} s"
    labels = _ut_labels(stats, k if t_s is not None else None)
    return _labelled(plot_map(tracks, footprints, _ut_tracks(stats), now_uts, title=title), labels)


def _labelled(fig, ut_labels):
    """The map ``fig`` with ``UT n`` written beside the UTs of ``ut_labels``."""
    draw_ut_labels(fig.axes[0], ut_labels)
    return fig


def _ut_labels(stats, k=None):
    """Where to write ``UT n`` for the time-plot UTs: at kept epoch ``k``, or (None) at
    each one's last sampled position."""
    j = np.searchsorted(stats.sample_ut, stats.series_ut)
    lat, lon = stats.ut_lat_deg[:, j], stats.ut_lon_deg[:, j]
    if k is None:  # the last finite row of each column
        k = np.maximum(lat.shape[0] - 1 - np.argmax(np.isfinite(lat[::-1]), axis=0), 0)
        lat, lon = lat[k, np.arange(j.size)], lon[k, np.arange(j.size)]
    else:
        lat, lon = lat[k], lon[k]
    return {"ut_id": stats.series_ut, "lat_deg": lat, "lon_deg": lon}


def _ut_tracks(stats, max_uts=200):
    j = np.unique(
        np.round(
            np.linspace(0, stats.sample_ut.size - 1, min(max_uts, stats.sample_ut.size))
        ).astype(int)
    )
    n_k = stats.keep_times_s.size
    return {
        "ut_id": np.repeat(stats.sample_ut[j], n_k),
        "time_s": np.tile(stats.keep_times_s, j.size),
        "lat_deg": stats.ut_lat_deg[:, j].T.ravel(),
        "lon_deg": stats.ut_lon_deg[:, j].T.ravel(),
        "beam_id": stats.ut_beam[:, j].T.ravel(),
    }


def run_figures(stats, summary=None):
    """The report's figures: list of ``(caption, Figure)``."""
    series, events = stats.series_columns(), stats.events_columns()
    n_ut_epochs = sum(stats.service_counts.values())
    cdfs = {k: stats.cdf(k) for k in ("snr_db", "sinr_db", "throughput_bps")}
    return [
        ("Map", run_map_figure(stats)),
        ("SNR and SINR of the chosen UTs", F.fig_snr_time(series, events)),
        ("Handover timeline of the chosen UTs", F.fig_handover_timeline(series, events)),
        ("Doppler and Doppler rate", F.fig_doppler(series)),
        ("Angular speed", F.fig_angular_speed(series)),
        (
            "Dwell (time of stay) in a beam, all UTs",
            F.fig_dwell(
                stats.dwell_edges_s, stats.dwell_complete, stats.dwell_censored, stats.dwell_mean_s
            ),
        ),
        ("CDFs over all UT-epochs", F.fig_cdfs(cdfs)),
        (
            "Outage by reason, all UT-epochs",
            F.fig_outage_reasons(stats.outage_reason_counts, n_ut_epochs),
        ),
    ]


def rendered_figures(stats):
    """:func:`run_figures` as PNG ``data:`` URIs: list of ``(caption, uri)``."""
    return [(cap, figure_data_uri(fig)) for cap, fig in run_figures(stats)]


def _page(title, sections, header=None):
    body = "".join(f"<h2>{html.escape(h)}</h2>{content}" for h, content in sections)
    header = f"<h1>{html.escape(title)}</h1>" if header is None else header
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head>"
        f"<body>{header}{body}</body></html>\n"
    )


def _img(uri, caption):
    cap = html.escape(caption)
    return f'<figure><img src="{uri}" alt="{cap}"><figcaption>{cap}</figcaption></figure>'


def _animation_html(path, page_dir, embed_max_bytes):
    path = Path(path)
    if path.stat().st_size <= embed_max_bytes:
        uri = "data:image/gif;base64," + base64.b64encode(path.read_bytes()).decode("ascii")
    else:  # too big to inline: link the file beside the page (still offline)
        uri = html.escape(
            str(path.relative_to(page_dir) if path.is_relative_to(page_dir) else path.name)
        )
    return _img(uri, "Beam cells moving over the ground; UTs coloured by serving beam")


def _header(summary, run_utc):
    """The page's header: title, what was run, and the headline figures."""
    title, meta, description = header_lines({**summary.get("run", {}), "run_utc": run_utc})
    cards = "".join(
        f'<div class="fig{" warn" if h.warn else ""}"><div class="label">{html.escape(h.label)}'
        f'</div><div class="value">{html.escape(h.value)}</div><p>{html.escape(h.sentence)}</p>'
        "</div>"
        for h in headline_figures(summary)
    )
    return (
        f"<header><h1>{html.escape(title)}</h1>"
        + (f"<p>{html.escape(description)}</p>" if description else "")
        + f'<p class="meta">{html.escape(meta)}</p></header>'
        + f'<section class="headline">{cards}</section>'
    )


def _details(summary_text, content):
    return f"<details><summary>{html.escape(summary_text)}</summary>{content}</details>"


def _tables(summary, stats, config_text, folder):
    """The full tables, each folded: every number of the summary once."""
    run = dict(summary.get("run", {}))
    notes = "".join(f"<li>{html.escape(str(n))}</li>" for n in run.get("notes", []))
    return "".join(
        [
            _details("Summary, all UTs (summary.json)", _table(
                ["quantity", "value"], _flatten(summary.get("overall", {})))),
            _details("Run", _table(["run", "value"], _flatten(run))
                     + (f"<ul>{notes}</ul>" if notes else "")),
            _details("Per UT", _per_ut_table(summary, stats.series_ut.tolist(), folder)),
            _details("Resolved config", f"<pre>{html.escape(config_text)}</pre>"),
        ]
    )  # fmt: skip


def build_run_report(
    path,
    summary,
    stats,
    config_text="",
    *,
    animation_path=None,
    embed_max_bytes=8_000_000,
    figures=None,
    run_utc=None,
):
    """Write ``report.html`` of a run: the story first (header and headline figures), then
    the map and animation, time series, distributions, and the full tables folded.

    Parameters
    ----------
    path : path-like
        Output file (written atomically).
    summary : dict
        As ``summary.json``: ``overall``, ``per_ut``, ``run``.
    stats : ReportStats
    config_text : str
        The resolved config (TOML), shown verbatim.
    animation_path : path-like, optional
        A GIF to embed (or link when over ``embed_max_bytes`` bytes).
    figures : list of (caption, str), optional
        :func:`rendered_figures` of ``stats``, if already drawn (default: drawn here).
    run_utc : str, optional
        ISO 8601 UTC of the run, shown in the header (default: now).

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    if run_utc is None:
        run_utc = datetime.now(UTC).isoformat(timespec="seconds")
    figures = rendered_figures(stats) if figures is None else figures
    shown = [f"<h3>{html.escape(cap)}</h3>" + _img(uri, cap) for cap, uri in figures]
    where = shown[0]
    if animation_path is not None and Path(animation_path).exists():
        where += _animation_html(animation_path, path.parent, embed_max_bytes)
    sections = [
        ("Where the UTs are served", where),
        *_geography(summary.get("overall", {}), path.parent),
        ("Over time", "".join(shown[1:N_TIME_FIGURES + 1])),
        ("Distributions, all UTs", "".join(shown[N_TIME_FIGURES + 1:])),
        ("Full tables", _tables(summary, stats, config_text, path.parent)),
    ]  # fmt: skip
    title = header_lines(summary.get("run", {}))[0]
    return write_text_atomic(path, _page(title, sections, _header(summary, run_utc)))


#: The columns of the table of KPIs by latitude band (``overall.by_latitude``).
_BAND_COLUMNS = ("lat_min_deg", "lat_max_deg", "n_ut_epochs", "handover_rate_per_ut_min",
                 "outage_fraction", "sinr_mean_db")  # fmt: skip


def _geography(overall, folder):
    """The KPIs by latitude band, and the world map of per-UT values (``ut_map.png``,
    :mod:`leolink.io.ut_map`) where the run wrote one."""
    out = []
    bands = overall.get("by_latitude") or []
    if bands:
        rows = [[b.get(k) for k in _BAND_COLUMNS] for b in bands]
        out.append(("KPIs by latitude band", _table(_BAND_COLUMNS, rows)))
    world = Path(folder) / "ut_map.png"
    if world.exists():
        caption = "Per-UT handover rate, outage and mean SINR (ut_map.csv, ut_map.geojson)"
        out.append((caption, _img(_any_figure_uri(world), caption)))
    return out


def _any_figure_uri(fig):
    """``data:`` URI of a Figure, or of a PNG file already written."""
    if isinstance(fig, str | Path):
        return "data:image/png;base64," + base64.b64encode(Path(fig).read_bytes()).decode("ascii")
    return figure_data_uri(fig)


def build_table_report(path, title, table, figures=(), config_text="", notes=""):
    """Write a report page for ``compare`` / ``sweep`` / ``coverage``.

    Parameters
    ----------
    path : path-like
        Output file (written atomically).
    title : str
    table : DataFrame or anything ``pandas.DataFrame`` takes
        The results, one row each (e.g. ``compare.csv``: ``policy`` + the KPIs).
    figures : list of (caption, Figure or path of a PNG)
    config_text : str
        The resolved config (TOML), shown verbatim.
    notes : str
        A sentence above the table.
    """
    import pandas as pd  # here only: a run's report page needs no pandas

    frame = pd.DataFrame(table)
    sections = [
        (
            "Results",
            (f"<p>{html.escape(notes)}</p>" if notes else "")
            + '<div class="wide">'
            + _table(list(frame.columns), frame.itertuples(index=False))
            + "</div>",
        )
    ]
    sections += [(cap, _img(_any_figure_uri(fig), cap)) for cap, fig in figures]
    if config_text:
        sections.append(("Resolved config", f"<pre>{html.escape(config_text)}</pre>"))
    return write_text_atomic(Path(path), _page(title, sections))
