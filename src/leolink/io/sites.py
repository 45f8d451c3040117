"""Site files: named places where static or starting UTs stand (``placement = "sites"``).

A CSV with a header naming the columns ``name, lat_deg, lon_deg`` and optionally ``alt_m``
(any order; ``#`` lines and blank lines skipped): one UT per row, in file order. Latitudes
in [-90, 90], longitudes in [-180, 180] [deg], heights in [-500, 20000] [m], as for the
config's ``lat_deg``/``lon_deg``/``alt_m`` lists. Errors name the file, the line and the
column; a value is shown only once parsed as a number.
"""

import csv

from leolink.errors import ConfigError
from leolink.textfile import read_text

__all__ = ["SITE_LIMITS", "read_sites", "with_sites"]

#: Bounds of a site's columns: (low, high, meaning), the config lists' bounds.
SITE_LIMITS = {
    "lat_deg": (-90.0, 90.0, "latitude"),
    "lon_deg": (-180.0, 180.0, "longitude"),
    "alt_m": (-500.0, 20_000.0, "height above the Earth model"),
}


def _number(path, line_no, col, text):
    low, high, meaning = SITE_LIMITS[col]
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{path}: line {line_no}, column {col!r}: not a number") from None
    if not low <= value <= high:
        raise ConfigError(
            f"{path}: line {line_no}, {col} = {value!r} is not allowed: use "
            f"[{low:g}, {high:g}] ({meaning})"
        )
    return value


def read_sites(path):
    """The sites of a CSV file.

    Returns
    -------
    dict
        ``site_names`` (list of str), ``lat_deg``, ``lon_deg``, ``alt_m`` (lists of float),
        one entry per data row.
    """
    rows = [
        (i, [c.strip() for c in fields])
        for i, line in enumerate(read_text(path, "sites file", ConfigError).splitlines(), 1)
        if line.strip() and not line.lstrip().startswith("#")
        for fields in csv.reader([line])
    ]
    if not rows:
        raise ConfigError(f"{path}: no header line (name, lat_deg, lon_deg[, alt_m])")
    header = rows[0][1]
    missing = [c for c in ("name", "lat_deg", "lon_deg") if c not in header]
    if missing:
        raise ConfigError(f"{path}: line {rows[0][0]}: the header lacks {', '.join(missing)}")
    if len(rows) < 2:
        raise ConfigError(f"{path}: no sites after the header")
    at = {c: header.index(c) for c in ("name", *SITE_LIMITS) if c in header}
    out = {"site_names": [], "lat_deg": [], "lon_deg": [], "alt_m": []}
    for line_no, fields in rows[1:]:
        if len(fields) != len(header):
            raise ConfigError(
                f"{path}: line {line_no} has {len(fields)} fields; the header has {len(header)}"
            )
        out["site_names"].append(fields[at["name"]])
        for col in SITE_LIMITS:
            text = fields[at[col]] if col in at else "0"
            out[col].append(_number(path, line_no, col, text))
    return out


def with_sites(params):
    """A population's parameters with its ``sites_file`` read into the lists (the same
    path as sites given in the config); other populations unchanged."""
    path = getattr(params, "sites_file", "")
    if not path:
        return params
    return params.model_copy(update={**read_sites(path), "sites_file": ""})
