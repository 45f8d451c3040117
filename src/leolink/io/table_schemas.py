"""The fixed schemas of the trace and event tables: columns, types, coded string columns.

Ids are int32, the string columns (``service``, ``kind``, ``outage_reason``,
``population``, ``modcod``) strings, the rest float64 (:func:`schema_for`); every field is
non-nullable. ``trace.parquet`` takes :func:`float32_schema` of the trace's schema. The
trace ``service`` column holds the names ``served``, ``handover``, ``outage``
(``controller.SERVICE_NAMES``), ``outage_reason`` the names ``none``, ``handover``,
``no_satellite``, ``below_threshold``, ``blocked``, ``rlf`` (``processes.OUTAGE_REASONS``)
and ``modcod`` the DVB-S2X MODCOD names (``leolink.link.modcod``, ``none`` for code -1);
integer codes given to a writer are mapped to them (:mod:`leolink.io.tables`).
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa

from leolink.engine import SERVE_COLUMNS, SERVE_GEOMETRY_COLUMNS
from leolink.io.arrow import UTC_TIMESTAMP, decoded_array, numeric_array
from leolink.link.acm import FIGURE_COLUMNS
from leolink.link.modcod import modcod_table
from leolink.sim.handover.controller import EVENT_COLUMNS, SERVICE_NAMES
from leolink.sim.processes import OUTAGE_REASONS

__all__ = [
    "ENVIRONMENT_COLUMNS",
    "EVENT_SCHEMA",
    "FORMATS",
    "NO_MODCOD_NAME",
    "TRACE_COLUMNS",
    "TRACE_FLOAT64_COLUMNS",
    "TIMESTAMP_COLUMNS",
    "TRACE_SCHEMA",
    "csv_schema",
    "float32_schema",
    "schema_for",
    "to_table",
    "trace_schema",
]

TRACE_COLUMNS = (
    "time_s",
    "ut_id",
    "sat_id",
    "beam_id",
    "lat_deg",
    "lon_deg",
    *SERVE_COLUMNS,  # the serving link, as LinkEngine.serve computes it
    "service",
    # Diagnostics (DESIGN output contract): why a UT is not served, what it could see.
    "outage_reason",
    "n_visible",  # satellites above the minimum elevation
    "best_snr_db",  # the best candidate's SNR, also in outage [dB]
    *SERVE_GEOMETRY_COLUMNS,  # azimuth_deg
    "alt_m",  # UT height above the Earth model [m]
    "population",
    "interruption_s",  # part of the epoch without service: handover execution [s]
    *FIGURE_COLUMNS,  # eirp_dbw, cn0_dbhz, esn0_db, margin_db, modcod (leolink.link.acm)
)
#: Columns of a run that models UT environments (``RunInfo.environment``), after
#: ``TRACE_COLUMNS``: the serving path's LoS state (1 / 0, NaN without a link) and its
#: shadowing, clutter and scintillation losses [dB] (:mod:`leolink.sim.environment`).
ENVIRONMENT_COLUMNS = ("los", "shadow_db", "clutter_db", "scintillation_db")
_INT_COLUMNS = {
    "ut_id", "sat_id", "beam_id", "from_sat", "from_beam", "to_sat", "to_beam", "n_visible",
    "n_sharing",
}  # fmt: skip
_STRING_COLUMNS = {"service", "kind", "outage_reason", "population", "modcod"}
#: Name of MODCOD code -1 (no MODCOD closes the link, or no link).
NO_MODCOD_NAME = "none"
#: Columns given as integer codes and written as names (code -1: the last name).
_CODED_COLUMNS = {
    "service": SERVICE_NAMES,
    "outage_reason": OUTAGE_REASONS,
    "modcod": (*modcod_table().names, NO_MODCOD_NAME),
}
FORMATS = ("csv", "parquet")
#: Columns of UTC instants: a timestamp in Parquet, ISO 8601 text in CSV
#: (:func:`csv_schema`); given to a writer as int64 microseconds since 1970 (UTC).
TIMESTAMP_COLUMNS = ("time_utc",)
#: Float columns of ``trace.parquet`` that stay float64: epoch times (float32 would round
#: 86,400 s to 8 ms) and positions (float32 would round a longitude to 1.7 m).
TRACE_FLOAT64_COLUMNS = ("time_s", "lat_deg", "lon_deg")


def _arrow_type(name):
    if name in TIMESTAMP_COLUMNS:
        return UTC_TIMESTAMP
    if name in _INT_COLUMNS:
        return pa.int32()
    if name in _STRING_COLUMNS:
        return pa.string()
    return pa.float64()


def _coded(schema):
    """``schema`` with its string columns as dictionaries of int32 codes (the Parquet
    writer's input: see ``TableWriter._open``)."""
    coded = pa.dictionary(pa.int32(), pa.string())
    return pa.schema([f.with_type(coded) if pa.types.is_string(f.type) else f for f in schema])


def schema_for(columns):
    """Fixed Arrow schema: ids int32, ``service``/``kind`` string, the rest float64.

    Every field is declared non-nullable, as the writers' arrays are (a missing value is
    a NaN, :mod:`leolink.io.arrow`): Parquet then stores no definition levels, 20 % of
    the writer's time (``bench_sim``'s 3.6 M-row trace: 0.73-0.78 -> 0.57-0.62 s)."""
    return pa.schema([pa.field(name, _arrow_type(name), nullable=False) for name in columns])


def csv_schema(schema):
    """``schema`` with its timestamp columns as strings: the CSV's ISO 8601 text."""
    text = lambda f: f.name in TIMESTAMP_COLUMNS  # noqa: E731
    return pa.schema([f.with_type(pa.string()) if text(f) else f for f in schema])


def float32_schema(schema, keep=TRACE_FLOAT64_COLUMNS):
    """``schema`` with its float64 columns as float32, except those in ``keep``."""
    as32 = lambda f: pa.types.is_float64(f.type) and f.name not in keep  # noqa: E731
    return pa.schema([f.with_type(pa.float32()) if as32(f) else f for f in schema])


TRACE_SCHEMA = schema_for(TRACE_COLUMNS)
TRACE_ENVIRONMENT_SCHEMA = schema_for(TRACE_COLUMNS + ENVIRONMENT_COLUMNS)


def trace_schema(info):
    """The trace schema of a run (:class:`~leolink.sim.streams.RunInfo`): with the
    ``ENVIRONMENT_COLUMNS`` when it models environments, then its ``extra_columns``."""
    base = TRACE_ENVIRONMENT_SCHEMA if getattr(info, "environment", ()) else TRACE_SCHEMA
    extra = tuple(getattr(info, "extra_columns", ()))
    return schema_for(tuple(base.names) + extra) if extra else base


EVENT_SCHEMA = schema_for(EVENT_COLUMNS)


def _check(name, values):
    if values.ndim != 1:
        raise ValueError(f"column {name!r} must be 1-D, got shape {values.shape}")
    if name in _INT_COLUMNS and values.dtype.kind not in "iub":
        raise ValueError(f"column {name!r} must be integer, got dtype {values.dtype}")


def _column_array(name, values, field):
    """One column -> Arrow array of the field's type (checks the dtype)."""
    values = np.asarray(values)
    _check(name, values)
    if pa.types.is_string(field.type):
        if name in _CODED_COLUMNS and values.dtype.kind in "iu":
            names = _CODED_COLUMNS[name]  # code -1: the last name
            return decoded_array(np.where(values < 0, values + len(names), values), names)
        names, codes = np.unique(values.astype(str), return_inverse=True)
        return decoded_array(codes, names.tolist())
    return numeric_array(values, field.type)


def to_table(columns, schema):
    """Dict of equal-length 1-D arrays -> ``pyarrow.Table`` in the schema's column order."""
    missing = [n for n in schema.names if n not in columns]
    extra = sorted(set(columns) - set(schema.names))
    if missing or extra:
        raise ValueError(f"columns missing: {missing}; unexpected: {extra}")
    arrays = [_column_array(f.name, columns[f.name], f) for f in schema]
    lengths = {len(a) for a in arrays}
    if len(lengths) > 1:
        raise ValueError(f"columns have different lengths: {sorted(lengths)}")
    return pa.Table.from_arrays(arrays, schema=schema)
