"""Recorded UT tracks: CSV or GPX files of time-stamped positions, read into motion models.

Registers the ``track`` population kind (:data:`leolink.sim.mobility.populations.MOBILITY`): the
file is read here, in the io layer, and the motion model gets arrays.

Times: a CSV gives ``time_s`` (simulation time) or ``time_utc`` (ISO 8601, UTC when no
offset is given); GPX track points carry UTC times. UTC timestamps become simulation
time through ``run.start_utc`` (``t = utc - start_utc + run.start_s``). Before a track's
first fix and after its last the UT holds that fix; the run reports it
(:func:`leolink.app.tracks.track_coverage`).

Errors name the file, the line and the column, never the file's text (a config may point
at any file): a value is shown only once parsed as a number.
"""

import csv
import math
import re
from datetime import UTC, datetime

import numpy as np
from pydantic import Field, model_validator

from leolink.errors import LeolinkError
from leolink.sim.mobility.models import Track, Waypoints
from leolink.sim.mobility.populations import FIX_LIMITS, MOBILITY, PopulationParams
from leolink.textfile import read_text

__all__ = ["TrackFileError", "TrackParams", "read_track", "read_track_csv", "read_track_gpx"]


class TrackFileError(LeolinkError, ValueError):
    """A recorded-track CSV file that leolink cannot read (names file, line, column)."""


_TRACK_COLUMNS = ("time_s", "lat_deg", "lon_deg", "alt_m")
_POSITION_COLUMNS = _TRACK_COLUMNS[1:]
_TRACK_LIMITS = FIX_LIMITS  # column: (low, high, meaning), as for configured waypoints
_COLUMN_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,39}")


def _data_lines(path):
    """(line number, parsed fields) of the non-blank, non-``#`` lines of a CSV file."""
    lines = read_text(path, "track file", TrackFileError).splitlines()
    return [
        (i, _fields(path, i, s))
        for i, s in enumerate(lines, 1)
        if s.strip() and not s.lstrip().startswith("#")
    ]


def _fields(path, line, text):
    try:
        return [c.strip() for c in next(csv.reader([text]))]
    except csv.Error as exc:  # a field over csv.field_size_limit() (131,072 characters)
        raise TrackFileError(
            f"{path}: line {line}: not a CSV line that leolink reads ({exc})"
        ) from None


def _utc_seconds(path, where, text, time_zero_utc):
    """Seconds from ``time_zero_utc`` to the ISO 8601 UTC instant ``text``."""
    try:
        when = datetime.fromisoformat(text)
    except ValueError:
        raise TrackFileError(
            f"{path}: {where}: not an ISO 8601 date and time (e.g. 2019-12-09T16:38:29Z)"
        ) from None
    when = when.astimezone(UTC) if when.tzinfo else when.replace(tzinfo=UTC)
    return (when - time_zero_utc).total_seconds()


def _need_time_zero(path, time_zero_utc):
    if time_zero_utc is None:
        raise TrackFileError(
            f"{path}: the track has UTC timestamps; set run.start_utc (ISO 8601) so that "
            "they can be placed on the simulation's time axis"
        )


def _parse_row(path, line_no, header, fields, time_zero_utc=None):
    """Dict column -> float (and ``ut`` str) of one CSV row, validated."""
    if len(fields) != len(header):
        raise TrackFileError(
            f"{path}: line {line_no}: {len(fields)} fields, expected "
            f"{len(header)} ({', '.join(header)})"
        )
    row = dict(zip(header, fields, strict=True))
    out = {"ut": row.get("ut", "")}
    columns = _TRACK_COLUMNS
    if "time_s" not in row:
        where = f"line {line_no}, column 'time_utc'"
        out["time_s"] = _utc_seconds(path, where, row["time_utc"], time_zero_utc)
        columns = _POSITION_COLUMNS
    for col in columns:
        try:
            value = float(row[col])
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise TrackFileError(f"{path}: line {line_no}, column '{col}': not a finite number")
        low, high, meaning = _TRACK_LIMITS.get(col, (-math.inf, math.inf, ""))
        if not low <= value <= high:
            raise TrackFileError(
                f"{path}: line {line_no}, column '{col}': {value!r} is out "
                f"of [{low:g}, {high:g}] ({meaning})"
            )
        out[col] = value
    return out


def read_track_csv(path, time_zero_utc=None):
    """Read time-stamped UT tracks from a CSV file.

    Format: optional ``#`` comment lines, a header with ``time_s`` or ``time_utc`` (ISO
    8601), ``lat_deg, lon_deg, alt_m`` and optionally ``ut`` (a label; rows of several UTs
    may be interleaved), other columns ignored. Within each UT, times must increase
    strictly. Without a ``ut`` column the file holds one track labelled by the file name
    (without extension).

    Parameters
    ----------
    path : str or path-like
        CSV file.
    time_zero_utc : datetime, optional
        Aware UTC instant of simulation time 0; required by ``time_utc``.

    Returns
    -------
    list of Track
        One per UT, in order of first appearance.

    Raises
    ------
    TrackFileError
        Naming the file, the line, the column and the problem.
    """
    rows = _data_lines(path)
    if not rows:
        raise TrackFileError(
            f"{path}: empty track file; expected a header line {', '.join(_TRACK_COLUMNS)}[, ut]"
        )
    header_line, header = rows[0]
    twice = sorted({c for c in header if header.count(c) > 1})
    if twice:
        raise TrackFileError(
            f"{path}: line {header_line}: column {twice[0]!r} appears twice; give each once"
        )
    wanted = _TRACK_COLUMNS if "time_s" in header or "time_utc" not in header else _POSITION_COLUMNS
    missing = [c for c in wanted if c not in header]
    if missing:
        raise TrackFileError(
            f"{path}: line {header_line}: missing column(s) "
            f"{', '.join(map(repr, missing))}; found {_header_text(header)}"
        )
    if "time_s" not in header:
        _need_time_zero(path, time_zero_utc)
    default_ut = _file_label(path)
    tracks, last = {}, {}
    for line_no, fields in rows[1:]:
        row = _parse_row(path, line_no, header, fields, time_zero_utc)
        ut = row["ut"] if "ut" in header else default_ut
        if ut in last and not row["time_s"] > last[ut][0]:
            raise TrackFileError(
                f"{path}: line {line_no}, column 'time_s': {row['time_s']!r} s is not after "
                f"{last[ut][0]!r} s (line {last[ut][1]}) of ut {ut!r}; times must increase"
            )
        last[ut] = (row["time_s"], line_no)
        tracks.setdefault(ut, []).append([row[c] for c in _TRACK_COLUMNS])
    if not tracks:
        raise TrackFileError(f"{path}: no data rows after the header (line {header_line})")
    out = []
    for ut, values in tracks.items():
        t, lat, lon, alt = np.array(values).T
        out.append(Track(t, np.radians(lat), np.radians(lon), alt, ut_id=ut))
    return out


def _header_text(header):
    """The columns found, if they look like column names (else only how many)."""
    if all(_COLUMN_NAME.fullmatch(h) for h in header) and len(header) <= 20:
        return ", ".join(header)
    return f"{len(header)} field(s) that are not column names"


def _file_label(path):
    return str(path).replace("\\", "/").rsplit("/", 1)[-1].rsplit(".", 1)[0]


def read_track_gpx(path, time_zero_utc):
    """Read the tracks of a GPX 1.0/1.1 file (gpxpy): one UT per ``<trk>``.

    A track's segments are joined in file order; every point needs a ``<time>`` (UTC);
    ``<ele>`` is taken as the height above the Earth model (GPX gives it above mean sea
    level: the geoid undulation, within +-110 m, is neglected), 0 where absent. Routes
    and waypoints are ignored. Labels: the track's ``<name>``, else ``<file>-<index>``.

    Raises
    ------
    TrackFileError
        Naming the file, the track and point, and the problem.
    """
    import gpxpy
    import gpxpy.gpx

    text = read_text(path, "GPX file", TrackFileError)
    try:
        gpx = gpxpy.parse(text)
    except (gpxpy.gpx.GPXException, ValueError) as exc:
        line = re.search(r"line (\d+)", str(exc))
        where = f"line {line.group(1)}: " if line else ""
        raise TrackFileError(
            f"{path}: {where}not a valid GPX file ({type(exc).__name__})"
        ) from None
    _need_time_zero(path, time_zero_utc)
    out = []
    for i, trk in enumerate(gpx.tracks):
        label = trk.name or f"{_file_label(path)}-{i}"
        points = [pt for seg in trk.segments for pt in seg.points]
        if not points:
            continue
        for k, pt in enumerate(points):
            if pt.time is None:
                raise TrackFileError(f"{path}: track {label!r}, point {k}: no <time>")
        when = [pt.time.astimezone(UTC) if pt.time.tzinfo else pt.time.replace(tzinfo=UTC)
                for pt in points]  # fmt: skip
        t = np.array([(w - time_zero_utc).total_seconds() for w in when])
        bad = np.flatnonzero(np.diff(t) <= 0.0)
        if bad.size:
            raise TrackFileError(
                f"{path}: track {label!r}, point {bad[0] + 1}: time {when[bad[0] + 1]} is not "
                f"after {when[bad[0]]}; times must increase"
            )
        lat = np.array([pt.latitude for pt in points], dtype=float)
        lon = np.array([pt.longitude for pt in points], dtype=float)
        alt = np.array([pt.elevation or 0.0 for pt in points], dtype=float)
        _check_gpx_values(path, label, {"lat_deg": lat, "lon_deg": lon, "alt_m": alt})
        out.append(Track(t, np.radians(lat), np.radians(lon), alt, ut_id=label))
    if not out:
        raise TrackFileError(f"{path}: no track points (<trk><trkseg><trkpt>) in the GPX file")
    return out


def _check_gpx_values(path, label, columns):
    for col, values in columns.items():
        low, high, meaning = _TRACK_LIMITS[col]
        bad = np.flatnonzero(~((values >= low) & (values <= high)))  # NaN is bad too
        if bad.size:
            raise TrackFileError(
                f"{path}: track {label!r}, point {bad[0]}: {col} = {values[bad[0]]!r} is out "
                f"of [{low:g}, {high:g}] ({meaning})"
            )


def read_track(path, time_zero_utc=None):
    """Tracks of a ``.gpx`` file (:func:`read_track_gpx`) or of a CSV file."""
    if str(path).lower().endswith(".gpx"):
        return read_track_gpx(path, time_zero_utc)
    return read_track_csv(path, time_zero_utc)


class TrackParams(PopulationParams):
    track_file: str = Field(
        "",
        description="GPX file, or CSV with time_s or time_utc, lat_deg, lon_deg, alt_m[, ut] "
        "(relative to the config)",
    )

    @model_validator(mode="after")
    def _file(self):
        if not self.track_file:
            raise ValueError(f"population '{self.name}': kind = 'track' needs track_file")
        return self


MOBILITY.add(
    "track",
    lambda p, ctx: Waypoints(
        read_track(p.track_file, getattr(ctx, "time_zero_utc", None)), radius_m=ctx.radius_m
    ),
    config=TrackParams,
    doc="UTs replaying recorded tracks from a CSV or GPX file",
)
