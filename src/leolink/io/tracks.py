"""Recorded UT tracks: CSV files of time-stamped positions, read into motion models.

Registers the ``track`` population kind (:data:`leolink.sim.populations.MOBILITY`): the
file is read here, in the io layer, and the motion model gets arrays.
"""

import csv
import math

import numpy as np
from pydantic import Field, model_validator

from leolink.errors import LeolinkError
from leolink.sim.mobility import Track, Waypoints
from leolink.sim.populations import MOBILITY, PopulationParams

__all__ = ["TrackFileError", "TrackParams", "read_track_csv"]


class TrackFileError(LeolinkError, ValueError):
    """A recorded-track CSV file that leolink cannot read (names file, line, column)."""


_TRACK_COLUMNS = ("time_s", "lat_deg", "lon_deg", "alt_m")
_TRACK_LIMITS = {  # column: (low, high, meaning)
    "lat_deg": (-90.0, 90.0, "latitude"),
    "lon_deg": (-180.0, 360.0, "longitude"),
    "alt_m": (-11_000.0, 100_000.0, "height between the deepest ocean and 100 km"),
}


def _data_lines(path):
    """(line number, parsed fields) of the non-blank, non-``#`` lines of a CSV file."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise TrackFileError(f"{path}: cannot read track file ({exc})") from None
    return [
        (i, [c.strip() for c in next(csv.reader([s]))])
        for i, s in enumerate(lines, 1)
        if s.strip() and not s.lstrip().startswith("#")
    ]


def _parse_row(path, line_no, header, fields):
    """Dict column -> float (and ``ut`` str) of one CSV row, validated."""
    if len(fields) != len(header):
        raise TrackFileError(
            f"{path}: line {line_no}: {len(fields)} fields, expected "
            f"{len(header)} ({', '.join(header)})"
        )
    row = dict(zip(header, fields, strict=True))
    out = {"ut": row.get("ut", "")}
    for col in _TRACK_COLUMNS:
        try:
            value = float(row[col])
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise TrackFileError(
                f"{path}: line {line_no}, column '{col}': {row[col]!r} is not a finite number"
            )
        low, high, meaning = _TRACK_LIMITS.get(col, (-math.inf, math.inf, ""))
        if not low <= value <= high:
            raise TrackFileError(
                f"{path}: line {line_no}, column '{col}': {value!r} is out "
                f"of [{low:g}, {high:g}] ({meaning})"
            )
        out[col] = value
    return out


def read_track_csv(path):
    """Read time-stamped UT tracks from a CSV file.

    Format: optional ``#`` comment lines, a header with ``time_s, lat_deg, lon_deg, alt_m``
    and optionally ``ut`` (a label; rows of several UTs may be interleaved), other columns
    ignored. Within each UT, times must increase strictly. Without a ``ut`` column the file
    holds one track labelled by the file name (without extension).

    Parameters
    ----------
    path : str or path-like
        CSV file.

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
    missing = [c for c in _TRACK_COLUMNS if c not in header]
    if missing:
        raise TrackFileError(
            f"{path}: line {header_line}: missing column(s) "
            f"{', '.join(map(repr, missing))}; found {', '.join(header)}"
        )
    default_ut = str(path).replace("\\", "/").rsplit("/", 1)[-1].rsplit(".", 1)[0]
    tracks, last = {}, {}
    for line_no, fields in rows[1:]:
        row = _parse_row(path, line_no, header, fields)
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


class TrackParams(PopulationParams):
    track_file: str = Field(
        "", description="CSV with time_s, lat_deg, lon_deg, alt_m[, ut] (relative to the config)"
    )

    @model_validator(mode="after")
    def _file(self):
        if not self.track_file:
            raise ValueError(f"population '{self.name}': kind = 'track' needs track_file")
        return self


MOBILITY.add(
    "track",
    lambda p, ctx: Waypoints(read_track_csv(p.track_file), radius_m=ctx.radius_m),
    config=TrackParams,
    doc="UTs replaying recorded tracks from a CSV file",
)
