"""``leolink report DIR``: rebuild the report of an output folder without rerunning.

:func:`build_report_from_dir` reads ``summary.json`` and ``report_stats.npz`` (saved by the
run's report sink) or, without it, streams the folder's trace into a fresh
:class:`~leolink.io.report.stats.ReportStats` with :func:`stats_from_dir`: Parquet record
batches or CSV chunks of ``chunk_rows`` rows, only the columns the statistics use, so
memory stays bounded whatever the trace size.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from leolink.constants import EARTH_RADIUS_M
from leolink.io.report.page import build_run_report
from leolink.io.report.stats import SERIES_COLUMNS, ReportStats

__all__ = [
    "build_report_from_dir",
    "rebuild_report",
    "stats_from_dir",
    "tracks_from_stats",
    "write_exports",
]


def _trace_chunks(out_dir, chunk_rows):
    """Trace rows as dicts of numpy arrays, ``chunk_rows`` at a time (Parquet or CSV).

    Only the columns the statistics use are decoded (a third of the trace's bytes)."""
    wanted = set(SERIES_COLUMNS) | {"outage_reason", "alt_m"}
    parquet, csv = out_dir / "trace.parquet", out_dir / "trace.csv"
    if parquet.exists():
        import pyarrow.parquet as pq

        source = pq.ParquetFile(parquet)
        cols = [c for c in source.schema_arrow.names if c in wanted]
        for batch in source.iter_batches(batch_size=chunk_rows, columns=cols):
            yield {
                name: batch.column(name).to_numpy(zero_copy_only=False)
                for name in batch.schema.names
            }
    else:
        for df in pd.read_csv(csv, chunksize=chunk_rows, usecols=lambda c: c in wanted):
            yield {c: df[c].to_numpy() for c in df.columns}


def stats_from_dir(out_dir, series_ut=None, n_sample_ut=500, max_frames=120, chunk_rows=200_000):
    """Rebuild :class:`ReportStats` from an output folder by streaming its files.

    Reads ``summary.json`` (run times, dwells), ``trace.parquet`` or ``trace.csv`` (in
    chunks), ``events.csv``, and when present ``satellites.csv`` (``time_s, sat_id, x_m,
    y_m, z_m, vx_m_s, vy_m_s, vz_m_s``) and ``codebook.json`` (``leolink codebook --json``).
    """
    out_dir = Path(out_dir)
    summary = json.loads((out_dir / "summary.json").read_text())
    run = summary["run"]
    series_ut = (0,) if series_ut is None else series_ut
    stats = ReportStats(
        run["n_ut"],
        run["start_s"],
        run["end_s"],
        run["epoch_s"],
        series_ut,
        n_sample_ut,
        max_frames,
    )
    for chunk in _trace_chunks(out_dir, chunk_rows):
        stats.add_trace(chunk)
    if (out_dir / "events.csv").exists():
        stats.add_events(pd.read_csv(out_dir / "events.csv"))
    if "dwells_file" in summary:  # a run with many UTs: the dwells beside summary.json
        d = pd.read_parquet(out_dir / summary["dwells_file"])
        stats.add_dwells(d["end_s"] - d["start_s"], d["censored_start"] | d["censored_end"])
    else:
        stats.add_dwells_from_summary(summary)
    if (out_dir / "satellites.csv").exists():
        sats = pd.read_csv(out_dir / "satellites.csv")
        for t_s, rows in sats.groupby("time_s", sort=True):  # per epoch, as a sink feeds it
            stats.add_satellites(
                t_s,
                rows[["x_m", "y_m", "z_m"]].to_numpy(),
                rows[["vx_m_s", "vy_m_s", "vz_m_s"]].to_numpy(),
                rows["sat_id"].to_numpy(),
            )
    if (out_dir / "codebook.json").exists():
        cb = json.loads((out_dir / "codebook.json").read_text())
        stats.set_codebook(
            [[b["u_x"], b["u_y"]] for b in cb["beams"]], cb["n_sub_x"], cb["n_sub_y"]
        )
    return stats


def _stats_for(out_dir, series_ut):
    """The saved statistics when they hold exactly ``series_ut`` (or none was asked), else
    the folder's trace streamed anew, with the saved satellites and codebook when the kept
    epochs agree (a run writes no ``satellites.csv``)."""
    path = out_dir / "report_stats.npz"
    saved = ReportStats.load(path) if path.exists() else None
    if saved is not None and (series_ut is None or set(series_ut) == set(saved.series_ut)):
        return saved
    if saved is None:
        return stats_from_dir(out_dir, series_ut)
    stats = stats_from_dir(out_dir, series_ut, max_frames=saved.keep_times_s.size)
    if stats.sat_pos_m is None and np.array_equal(stats.keep_times_s, saved.keep_times_s):
        stats.sat_ids, stats.sat_pos_m, stats.sat_vel_m_s = (
            saved.sat_ids, saved.sat_pos_m, saved.sat_vel_m_s
        )  # fmt: skip
    if stats.beam_u_xy is None and saved.beam_u_xy is not None:
        stats.set_codebook(saved.beam_u_xy, *saved.n_sub_xy)
    return stats


def build_report_from_dir(out_dir, series_ut=None, animate=True, exports=False):
    """``leolink report DIR``: rebuild ``report.html`` (and ``footprint.gif``) from a folder.

    Uses ``report_stats.npz`` when the run saved one (and ``series_ut`` is None or its
    UTs), else :func:`stats_from_dir`. With ``exports``, also writes ``run.geojson`` and
    ``run.czml`` (:func:`write_exports`).
    Returns ``{"report": path, "animation": path or None, "exports": paths or ()}``.
    """
    out_dir = Path(out_dir)
    summary = json.loads((out_dir / "summary.json").read_text())
    stats = _stats_for(out_dir, series_ut)
    gif = None
    if animate and stats.sat_pos_m is not None and stats.beam_u_xy is not None:
        from leolink.io.report.animation import (
            animation_frames,
            frames_from_stats,
            write_footprint_gif,
        )

        frames = frames_from_stats(stats, animation_frames(stats.keep_times_s.size))
        gif = write_footprint_gif(out_dir / "footprint.gif", frames)["path"]
    elif (out_dir / "footprint.gif").exists():
        gif = out_dir / "footprint.gif"  # the run's animation, kept as it is
    config = out_dir / "config.resolved.toml"
    text = config.read_text() if config.exists() else ""
    manifest = out_dir / "run.json"  # the run's date, not the rebuild's
    run_utc = json.loads(manifest.read_text()).get("finished_utc") if manifest.exists() else None
    page = build_run_report(
        out_dir / "report.html", summary, stats, text, animation_path=gif, run_utc=run_utc
    )
    written = write_exports(stats, out_dir) if exports else ()
    return {"report": page, "animation": gif, "exports": written}


def rebuild_report(out_dir, series_ut=None, animate=True, exports=False, *, version):
    """``leolink report DIR`` on a finished run's folder: :func:`build_report_from_dir`,
    then ``run.json`` updated with the rewritten and the new files (``version``: the
    ``leolink.__version__`` that rebuilt them).

    Raises
    ------
    OutputFolderError
        ``out_dir`` has no ``run.json`` (not a finished run), or is not a ``leolink run``
        folder.
    """
    from leolink.io.run_dir import OutputFolderError, read_manifest, write_manifest

    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise OutputFolderError(f"{out_dir} is not a folder")
    manifest = read_manifest(out_dir)
    if manifest is None:
        raise OutputFolderError(
            f"{out_dir} is not a finished leolink run (no run.json; an interrupted run leaves "
            "none): rerun it with --overwrite"
        )
    if manifest.get("command") != "run":
        raise OutputFolderError(
            f"{out_dir} holds the output of 'leolink {manifest.get('command')}'; leolink "
            "report rebuilds the report of a 'leolink run' folder"
        )
    built = build_report_from_dir(out_dir, series_ut, animate, exports)
    files = [out_dir / e["path"] for e in manifest["files"]]
    files += [p for p in (built["report"], built["animation"], *built["exports"]) if p]
    config = out_dir / "config.resolved.toml"
    write_manifest(
        out_dir,
        [p for p in files if p.is_file()],
        "run",
        config.read_text() if config.exists() else "",
        manifest.get("arguments"),
        version=version,
    )
    return built


def tracks_from_stats(stats, max_frames=120):
    """Satellite tracks, UT tracks and footprint frames from :class:`ReportStats`.

    Returns
    -------
    sat_tracks : dict or None
        ``sat_id, time_s, lat_deg, lon_deg, alt_m`` of the satellites that serve a sampled
        UT (``alt_m`` above ``leolink.constants.EARTH_RADIUS_M``).
    ut_tracks : dict
        ``ut_id, time_s, lat_deg, lon_deg, beam_id`` of the sampled UTs.
    footprint_frames : list of (time_s, footprints)
        As the exporters take them.
    """
    from leolink.io.report.animation import frames_from_stats
    from leolink.io.report.maps import subsatellite_points

    n_k, n_s = stats.ut_lat_deg.shape
    ut_tracks = {
        "ut_id": np.repeat(stats.sample_ut, n_k),
        "time_s": np.tile(stats.keep_times_s, n_s),
        "lat_deg": stats.ut_lat_deg.T.ravel(),
        "lon_deg": stats.ut_lon_deg.T.ravel(),
        "beam_id": stats.ut_beam.T.ravel(),
    }
    if stats.sat_pos_m is None:
        return None, ut_tracks, []
    cols = np.flatnonzero(np.isin(stats.sat_ids, stats.ut_sat[stats.ut_sat >= 0]))
    pos = stats.sat_pos_m[:, cols]  # (n_k, n_serving, 3)
    lat, lon = subsatellite_points(pos)
    sat_tracks = {
        "sat_id": np.repeat(stats.sat_ids[cols], n_k),
        "time_s": np.tile(stats.keep_times_s, cols.size),
        "lat_deg": lat.T.ravel(),
        "lon_deg": lon.T.ravel(),
        "alt_m": np.linalg.norm(pos, axis=-1).T.ravel() - EARTH_RADIUS_M,
    }
    frames = []
    if stats.beam_u_xy is not None:
        frames = [(f.time_s, f.footprints) for f in frames_from_stats(stats, max_frames)]
    return sat_tracks, ut_tracks, frames


def write_exports(stats, out_dir, epoch_utc=None):
    """Write ``run.geojson`` and ``run.czml`` of a run's statistics into ``out_dir``.

    ``epoch_utc``: ISO 8601 time of ``t = 0`` for CZML (default: the one the run saved in
    the statistics, a TLE run's epoch, else J2000, see :mod:`leolink.io.exports`). Returns
    the two paths.
    """
    from leolink.io.exports import DEFAULT_EPOCH_UTC, write_czml, write_geojson

    sats, uts, frames = tracks_from_stats(stats)
    out_dir = Path(out_dir)
    saved = getattr(stats, "epoch_utc", None)
    epoch_utc = epoch_utc or (str(saved) if saved is not None else None)
    geo = write_geojson(out_dir / "run.geojson", sats, uts, frames)
    czml = write_czml(
        out_dir / "run.czml",
        stats.start_s,
        stats.end_s,
        sats,
        uts,
        frames,
        epoch_utc=epoch_utc or DEFAULT_EPOCH_UTC,
    )
    return geo, czml
