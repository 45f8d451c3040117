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
    "TRACE_COLUMN_DOCS",
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
    # Timing (DESIGN output contract): one-way UT-satellite delay [s] and its rate [s/s].
    "delay_s",
    "delay_rate_s_s",
)
#: Columns of a run that models UT environments (``RunInfo.environment``), after
#: ``TRACE_COLUMNS``: the serving path's LoS state (1 / 0, NaN without a link) and its
#: shadowing, clutter and scintillation losses [dB] (:mod:`leolink.sim.environment`).
ENVIRONMENT_COLUMNS = ("los", "shadow_db", "clutter_db", "scintillation_db")
#: Trace column -> (CF ``units``, description): ``Result.to_xarray()``'s attributes and
#: the docs. Units are UDUNITS strings; the dB family (``dB``, ``dBW``, ``dB-Hz``) is a
#: label (UDUNITS has no logarithmic units); ids, names and counts have none (``""``).
TRACE_COLUMN_DOCS = {
    "time_s": ("s", "simulation time of the epoch"),
    "ut_id": ("", "user terminal id"),
    "sat_id": ("", "serving satellite id (-1: none)"),
    "beam_id": ("", "serving beam id of the codebook (-1: none)"),
    "lat_deg": ("degrees_north", "UT latitude"),
    "lon_deg": ("degrees_east", "UT longitude"),
    "elevation_deg": ("degree", "elevation of the link (in outage: the best candidate's)"),
    "slant_range_m": ("m", "slant range UT-satellite"),
    "gain_tx_db": ("dB", "satellite array gain towards the UT"),
    "gain_rx_db": ("dB", "UT antenna gain towards the satellite"),
    "fspl_db": ("dB", "free-space path loss"),
    "atm_db": ("dB", "atmospheric loss"),
    "snr_db": ("dB", "signal-to-noise ratio of the serving link"),
    "sinr_db": ("dB", "signal-to-interference-plus-noise ratio of the serving link"),
    "se_bps_hz": ("bit s-1 Hz-1", "spectral efficiency (served part of the epoch)"),
    "throughput_bps": ("bit s-1", "throughput (served part of the epoch)"),
    "doppler_hz": ("Hz", "Doppler shift, satellite and UT parts"),
    "doppler_sat_hz": ("Hz", "Doppler shift of the satellite's motion"),
    "doppler_ut_hz": ("Hz", "Doppler shift of the UT's motion"),
    "doppler_rate_hz_s": ("Hz s-1", "rate of change of the Doppler shift"),
    "angular_speed_deg_s": ("degree s-1", "angular speed of the satellite seen from the UT"),
    "service": ("", "served, handover or outage"),
    "outage_reason": ("", "why the UT is not served (none if it is)"),
    "n_visible": ("", "satellites above the minimum elevation"),
    "best_snr_db": ("dB", "SNR of the best candidate beam, also in outage"),
    "azimuth_deg": ("degree", "azimuth of the link, clockwise from north"),
    "alt_m": ("m", "UT height above the Earth model"),
    "population": ("", "name of the UT's population"),
    "interruption_s": ("s", "part of the epoch without service (handover execution)"),
    "eirp_dbw": ("dBW", "EIRP of the serving beam"),
    "cn0_dbhz": ("dB-Hz", "thermal carrier-to-noise density C/N0"),
    "esn0_db": ("dB", "Es/N0 of the link (from the SINR, with the roll-off)"),
    "margin_db": ("dB", "margin against the chosen MODCOD's required Es/N0"),
    "modcod": ("", "best DVB-S2X MODCOD that closes the link (none: no MODCOD)"),
    "delay_s": ("s", "one-way UT-satellite propagation delay (slant range / c)"),
    "delay_rate_s_s": ("1", "rate of change of the one-way delay (range rate / c)"),
    "ta_s": ("s", "[timing] full TA from the believed ephemeris (TS 38.211 4.3.1)"),
    "common_ta_s": ("s", "[timing] common TA: RTT satellite - reference point (TS 38.213 4.2)"),
    "k_offset_ms": ("ms", "[timing] cell-specific K_offset, slots of 15 kHz (TS 38.213)"),
    "doppler_residual_hz": ("Hz", "[timing] true minus pre-compensated (believed) Doppler"),
    "los": ("1", "line of sight of the serving path (1 / 0)"),
    "shadow_db": ("dB", "shadow fading loss (TR 38.811 clause 6.6.2)"),
    "clutter_db": ("dB", "clutter loss (TR 38.811 clause 6.6.2)"),
    "scintillation_db": ("dB", "tropospheric scintillation loss (TR 38.811 clause 6.6.6)"),
}
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
