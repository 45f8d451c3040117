"""Exports that other tools read: GeoJSON (RFC 7946), CZML (Cesium), events as Parquet.

GeoJSON: one ``FeatureCollection``; satellite and UT tracks are ``LineString`` (a static
UT is a ``Point``), beam footprints ``Polygon``; positions are ``[longitude, latitude]``
in degrees rounded to 6 decimals (~0.1 m, RFC 7946 Sec. 11.2); rings are closed and
counter-clockwise (Sec. 3.1.6); a geometry that crosses the antimeridian is cut in two
(Sec. 3.1.9), becoming a ``MultiLineString`` / ``MultiPolygon``.

CZML: a JSON array of packets; the first is the ``document`` packet (``version`` "1.0",
the clock over the run); satellites and UTs have sampled ``position.cartographicDegrees``
``[t, lon, lat, h, ...]`` (seconds from ``position.epoch``); each footprint is a polygon
packet available from its frame time to the next. Decision: positions are leolink's
spherical latitude, longitude and height above the sphere, written as cartographic
degrees as they are (not re-projected onto WGS 84), so that UTs, footprints and
sub-satellite points line up in Cesium exactly as in leolink's own maps; heights are then
off by the sphere/ellipsoid difference (< 22 km), which does not move the ground tracks.
The run has no calendar time unless given: ``epoch_utc`` defaults to J2000
(2000-01-01T12:00:00Z).
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

from leolink.io.atomic import atomic_file, write_text_atomic
from leolink.io.report.maps import beam_colour

__all__ = [
    "EVENT_SCHEMA",
    "czml_document",
    "geojson_document",
    "split_ring_at_antimeridian",
    "write_czml",
    "write_events",
    "write_geojson",
]

DEFAULT_EPOCH_UTC = "2000-01-01T12:00:00Z"
_DECIMALS = 6
EVENT_SCHEMA = (
    ("time_s", "float64"),
    ("ut_id", "int64"),
    ("kind", "string"),
    ("from_sat", "int64"),
    ("from_beam", "int64"),
    ("to_sat", "int64"),
    ("to_beam", "int64"),
    ("snr_before_db", "float64"),
    ("snr_after_db", "float64"),
)


# ----------------------------------------------------------------------- geometry helpers
def _split_line(lon, lat):
    """Pieces of a polyline cut where it crosses +-180 deg (crossing point on both sides)."""
    pieces, start, head = [], 0, ([], [])
    for i in np.flatnonzero(np.abs(np.diff(lon)) > 180.0):  # a few crossings per track
        edge = 180.0 if lon[i] > 0 else -180.0
        f = (edge - lon[i]) / (lon[i + 1] + 2.0 * edge - lon[i])  # next point moved by 360
        lat_x = lat[i] + f * (lat[i + 1] - lat[i])
        pieces.append(
            (np.r_[head[0], lon[start : i + 1], edge], np.r_[head[1], lat[start : i + 1], lat_x])
        )
        head, start = ([-edge], [lat_x]), i + 1
    pieces.append((np.r_[head[0], lon[start:]], np.r_[head[1], lat[start:]]))
    return pieces


def _clip_halfplane(ring, keep_left, x0=180.0):
    """Sutherland-Hodgman: the part of a closed ring (n, 2) with x <= x0 (or >= x0)."""
    out = []
    inside = (ring[:, 0] <= x0) if keep_left else (ring[:, 0] >= x0)
    for i in range(ring.shape[0]):  # a footprint ring has ~72 points
        p, q, p_in, q_in = ring[i - 1], ring[i], inside[i - 1], inside[i]
        if p_in != q_in:
            f = (x0 - p[0]) / (q[0] - p[0])
            out.append([x0, p[1] + f * (q[1] - p[1])])
        if q_in:
            out.append(q.tolist())
    return np.asarray(out).reshape(-1, 2)


def _closed_ccw(ring):
    """Close a ring and orient it counter-clockwise (positive shoelace area in lon/lat)."""
    x, y = ring[:, 0], ring[:, 1]
    if 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) < 0:
        ring = ring[::-1]
    return np.vstack([ring, ring[:1]])


def split_ring_at_antimeridian(lon_deg, lat_deg):
    """Polygon rings (closed, CCW, lon in [-180, 180]) of a footprint, cut at 180 deg.

    Parameters
    ----------
    lon_deg, lat_deg : array_like, shape (n,)
        Ring points [deg], not closed; NaN points are dropped.

    Returns
    -------
    list of ndarray, each (m, 2) ``[lon, lat]``
        One ring, or two when the footprint crosses the antimeridian; empty if < 3 points.
    """
    lon, lat = np.asarray(lon_deg, float), np.asarray(lat_deg, float)
    ok = np.isfinite(lon) & np.isfinite(lat)
    if ok.sum() < 3:
        return []
    ring = np.column_stack([np.degrees(np.unwrap(np.radians(lon[ok]))), lat[ok]])
    ring[:, 0] -= 360.0 * np.round(np.mean(ring[:, 0]) / 360.0)  # centre in [-180, 180]
    if ring[:, 0].max() <= 180.0 and ring[:, 0].min() >= -180.0:
        return [_closed_ccw(ring)]
    edge = 180.0 if ring[:, 0].max() > 180.0 else -180.0
    parts = [_clip_halfplane(ring, edge > 0, edge), _clip_halfplane(ring, edge < 0, edge)]
    parts[1] = parts[1] - [360.0 * np.sign(edge), 0.0]  # the part beyond the edge wraps
    return [_closed_ccw(p) for p in parts if p.shape[0] >= 3]


def _positions(lon, lat):
    return np.round(np.column_stack([lon, lat]), _DECIMALS).tolist()


def _line_geometry(lon, lat):
    ok = np.isfinite(lon) & np.isfinite(lat)
    lon, lat = lon[ok], lat[ok]
    if lon.size == 0:
        return None
    if np.unique(np.round(np.column_stack([lon, lat]), _DECIMALS), axis=0).shape[0] == 1:
        return {"type": "Point", "coordinates": _positions(lon[:1], lat[:1])[0]}
    pieces = [p for p in _split_line(lon, lat) if p[0].size >= 2]
    if len(pieces) == 1:
        return {"type": "LineString", "coordinates": _positions(*pieces[0])}
    return {"type": "MultiLineString", "coordinates": [_positions(*p) for p in pieces]}


def _track_features(tracks, id_key, kind):
    ids, order = np.asarray(tracks[id_key]), None
    order = np.lexsort((np.asarray(tracks["time_s"], float), ids))
    t, lon, lat = (np.asarray(tracks[k], float)[order] for k in ("time_s", "lon_deg", "lat_deg"))
    ids = ids[order]
    bounds = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1], True])
    features = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):  # one feature per track
        geometry = _line_geometry(lon[a:b], lat[a:b])
        if geometry is not None:
            props = {
                "kind": kind,
                id_key: int(ids[a]),
                "start_s": float(t[a]),
                "end_s": float(t[b - 1]),
            }
            features.append({"type": "Feature", "geometry": geometry, "properties": props})
    return features


def _footprint_features(frames):
    features = []
    for t_s, fp in frames:  # one feature per (frame, satellite, beam)
        for k in range(len(fp["beam_id"])):
            rings = split_ring_at_antimeridian(fp["lon_deg"][k], fp["lat_deg"][k])
            if not rings:
                continue
            coords = [[np.round(r, _DECIMALS).tolist()] for r in rings]
            geometry = (
                {"type": "Polygon", "coordinates": coords[0]}
                if len(coords) == 1
                else {"type": "MultiPolygon", "coordinates": coords}
            )
            props = {
                "kind": "beam_footprint",
                "time_s": float(t_s),
                "sat_id": int(fp["sat_id"][k]),
                "beam_id": int(fp["beam_id"][k]),
            }
            features.append({"type": "Feature", "geometry": geometry, "properties": props})
    return features


def geojson_document(sat_tracks=None, ut_tracks=None, footprint_frames=()):
    """A GeoJSON ``FeatureCollection`` (dict) of tracks and footprints.

    Parameters
    ----------
    sat_tracks : dict, optional
        ``sat_id, time_s, lat_deg, lon_deg (n,)``: sub-satellite points.
    ut_tracks : dict, optional
        ``ut_id, time_s, lat_deg, lon_deg (m,)``.
    footprint_frames : sequence of (time_s, footprints)
        ``footprints``: ``sat_id, beam_id (k,)``, ``lat_deg, lon_deg (k, n_points)``.

    Returns
    -------
    dict
    """
    features = []
    if sat_tracks is not None:
        features += _track_features(sat_tracks, "sat_id", "satellite_track")
    if ut_tracks is not None:
        features += _track_features(ut_tracks, "ut_id", "ut_track")
    features += _footprint_features(footprint_frames)
    return {"type": "FeatureCollection", "features": features}


def write_geojson(path, *args, **kwargs):
    """:func:`geojson_document` written to ``path`` atomically; returns the path."""
    return write_text_atomic(path, json.dumps(geojson_document(*args, **kwargs)))


# ----------------------------------------------------------------------- CZML
def _iso(epoch, t_s):
    return (epoch + timedelta(seconds=float(t_s))).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _sampled(t_s, lon, lat, h_m, epoch_utc):
    ok = np.isfinite(lon) & np.isfinite(lat)
    flat = np.column_stack([t_s[ok], lon[ok], lat[ok], h_m[ok]])
    return {"epoch": epoch_utc, "cartographicDegrees": np.round(flat, _DECIMALS).ravel().tolist()}


def _czml_tracks(tracks, id_key, prefix, epoch, epoch_utc, style):
    ids = np.asarray(tracks[id_key])
    order = np.lexsort((np.asarray(tracks["time_s"], float), ids))
    cols = {k: np.asarray(tracks[k], float)[order] for k in ("time_s", "lon_deg", "lat_deg")}
    h = np.asarray(tracks.get("alt_m", np.zeros(ids.size)), float)[order]
    ids = ids[order]
    bounds = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1], True])
    packets = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):  # one packet per satellite / UT
        t = cols["time_s"][a:b]
        packets.append(
            {
                "id": f"{prefix}/{int(ids[a])}",
                "name": f"{prefix} {int(ids[a])}",
                "availability": f"{_iso(epoch, t[0])}/{_iso(epoch, t[-1])}",
                "position": {
                    "interpolationAlgorithm": "LAGRANGE",
                    "interpolationDegree": 1,
                    **_sampled(t, cols["lon_deg"][a:b], cols["lat_deg"][a:b], h[a:b], epoch_utc),
                },
                **style,
            }
        )
    return packets


def _czml_footprints(frames, end_s, epoch):
    packets = []
    times = [t for t, _ in frames] + [end_s]
    for k, (t_s, fp) in enumerate(frames):  # one packet per (frame, satellite, beam)
        interval = f"{_iso(epoch, t_s)}/{_iso(epoch, times[k + 1])}"
        for j in range(len(fp["beam_id"])):
            for r, ring in enumerate(
                split_ring_at_antimeridian(fp["lon_deg"][j], fp["lat_deg"][j])
            ):
                rgba = (np.round(beam_colour(int(fp["beam_id"][j])) * 255).astype(int)).tolist()
                positions = np.column_stack([ring[:-1], np.zeros(ring.shape[0] - 1)])
                packets.append(
                    {
                        "id": f"footprint/{int(fp['sat_id'][j])}/{int(fp['beam_id'][j])}/{k}/{r}",
                        "availability": interval,
                        "polygon": {
                            "positions": {
                                "cartographicDegrees": np.round(positions, _DECIMALS)
                                .ravel()
                                .tolist()
                            },
                            "material": {"solidColor": {"color": {"rgba": [*rgba[:3], 60]}}},
                            "outline": True,
                            "outlineColor": {"rgba": [*rgba[:3], 255]},
                            "height": 0.0,
                        },
                    }
                )
    return packets


def czml_document(
    start_s,
    end_s,
    sat_tracks=None,
    ut_tracks=None,
    footprint_frames=(),
    epoch_utc=DEFAULT_EPOCH_UTC,
    name="leolink run",
):
    """A CZML document (list of packets) of satellites, UTs and beam footprints.

    Parameters
    ----------
    start_s, end_s : float
        Run interval [s from ``epoch_utc``].
    sat_tracks : dict, optional
        ``sat_id, time_s, lat_deg, lon_deg, alt_m (n,)``: sub-satellite points and height
        above the sphere [deg, m].
    ut_tracks : dict, optional
        ``ut_id, time_s, lat_deg, lon_deg (m,)`` and optionally ``alt_m``.
    footprint_frames : sequence of (time_s, footprints)
        As :func:`geojson_document`; frame ``k`` is shown until frame ``k + 1``.
    epoch_utc : str
        ISO 8601 UTC time of ``t = 0`` ("...Z").

    Returns
    -------
    list of dict
    """
    epoch = datetime.fromisoformat(epoch_utc.replace("Z", "+00:00")).astimezone(UTC)
    interval = f"{_iso(epoch, start_s)}/{_iso(epoch, end_s)}"
    doc = [
        {
            "id": "document",
            "name": name,
            "version": "1.0",
            "clock": {
                "interval": interval,
                "currentTime": _iso(epoch, start_s),
                "multiplier": 10,
                "range": "LOOP_STOP",
                "step": "SYSTEM_CLOCK_MULTIPLIER",
            },
        }
    ]
    if sat_tracks is not None:
        style = {
            "point": {"pixelSize": 8, "color": {"rgba": [214, 39, 40, 255]}},
            "path": {
                "width": 1,
                "leadTime": 0,
                "trailTime": float(end_s - start_s),
                "material": {"solidColor": {"color": {"rgba": [214, 39, 40, 160]}}},
            },
        }
        doc += _czml_tracks(sat_tracks, "sat_id", "satellite", epoch, epoch_utc, style)
    if ut_tracks is not None:
        style = {"point": {"pixelSize": 6, "color": {"rgba": [0, 0, 0, 255]}}}
        doc += _czml_tracks(ut_tracks, "ut_id", "ut", epoch, epoch_utc, style)
    return doc + _czml_footprints(list(footprint_frames), end_s, epoch)


def write_czml(path, *args, **kwargs):
    """:func:`czml_document` written to ``path`` atomically; returns the path."""
    return write_text_atomic(path, json.dumps(czml_document(*args, **kwargs)))


# ----------------------------------------------------------------------- events
def write_events(events, out_dir):
    """Write ``events.csv`` and ``events.parquet`` (same rows and columns) atomically.

    ``events``: DataFrame with the event columns (:data:`EVENT_SCHEMA`); returns both paths.
    """
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    out_dir = Path(out_dir)
    df = pd.DataFrame(events)[[name for name, _ in EVENT_SCHEMA]]
    schema = pa.schema(
        [
            (name, pa.string() if t == "string" else pa.from_numpy_dtype(np.dtype(t)))
            for name, t in EVENT_SCHEMA
        ]
    )
    table = pa.Table.from_pandas(
        df.astype({n: t for n, t in EVENT_SCHEMA if t != "string"}),
        schema=schema,
        preserve_index=False,
    )
    with atomic_file(out_dir / "events.parquet") as f:
        pq.write_table(table, f)
    with atomic_file(out_dir / "events.csv") as f:
        df.to_csv(f, index=False)
    return out_dir / "events.csv", out_dir / "events.parquet"
