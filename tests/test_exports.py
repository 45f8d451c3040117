"""GeoJSON (RFC 7946), CZML (CZML guide: document packet, sampled positions, intervals)
and events Parquet, from a real 10-minute Walker run."""

import json
import tomllib
from datetime import datetime

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from leolink.antenna.array import upa_gain
from leolink.geometry import direction_cosines, geodetic_to_ecef
from leolink.io.exports import (
    czml_document,
    geojson_document,
    split_ring_at_antimeridian,
    write_czml,
    write_events,
    write_geojson,
)
from leolink.io.report.animation import frames_from_stats
from leolink.io.report.maps import subsatellite_points
from leolink.io.report.rebuild import stats_from_dir
from report_helpers import WALKER, ephemeris, make_run

GEOMETRIES = {"Point", "LineString", "MultiLineString", "Polygon", "MultiPolygon"}


@pytest.fixture(scope="module")
def walker(tmp_path_factory):
    out = make_run(tmp_path_factory.mktemp("walker"), WALKER)
    stats = stats_from_dir(out, series_ut=[0], max_frames=20)
    frames = frames_from_stats(stats, max_frames=20)
    lat, lon = subsatellite_points(stats.sat_pos_m)  # (n_k, n_sat)
    r_m = np.linalg.norm(stats.sat_pos_m, axis=-1)
    n_k, n_sat = lat.shape
    sats = {
        "sat_id": np.tile(stats.sat_ids, n_k),
        "time_s": np.repeat(stats.keep_times_s, n_sat),
        "lat_deg": lat.ravel(),
        "lon_deg": lon.ravel(),
        "alt_m": r_m.ravel() - 6371e3,
    }
    trace = pd.read_csv(out / "trace.csv")
    uts = {k: trace[k].to_numpy() for k in ("ut_id", "time_s", "lat_deg", "lon_deg")}
    cfg = tomllib.loads((out / "config.resolved.toml").read_text())
    return {
        "out": out,
        "stats": stats,
        "frames": [(f.time_s, f.footprints) for f in frames],
        "sats": sats,
        "uts": uts,
        "eph": ephemeris(cfg),
    }


# ----------------------------------------------------------------------- GeoJSON
def _check_position(p):
    assert len(p) in (2, 3) and all(isinstance(v, float | int) for v in p)
    assert -180.0 <= p[0] <= 180.0 and -90.0 <= p[1] <= 90.0  # RFC 7946 3.1.1: lon, lat


def _signed_area(ring):
    x, y = np.asarray(ring)[:, 0], np.asarray(ring)[:, 1]
    return 0.5 * np.sum(x[:-1] * y[1:] - x[1:] * y[:-1])


def _check_geometry(g):
    assert g["type"] in GEOMETRIES
    c = g["coordinates"]
    lines = {"Point": [], "LineString": [c], "MultiLineString": c}.get(g["type"])
    polys = {"Polygon": [c], "MultiPolygon": c}.get(g["type"], [])
    if g["type"] == "Point":
        _check_position(c)
    for line in lines or []:
        assert len(line) >= 2  # 3.1.4
        for p in line:
            _check_position(p)
        assert np.all(np.abs(np.diff(np.asarray(line)[:, 0])) <= 180.0)  # cut at 3.1.9
    for poly in polys:
        for ring in poly:  # 3.1.6: closed, >= 4 positions, exterior counter-clockwise
            assert len(ring) >= 4 and ring[0] == ring[-1]
            for p in ring:
                _check_position(p)
        assert _signed_area(poly[0]) > 0


def _check_feature_collection(doc):
    assert doc["type"] == "FeatureCollection" and isinstance(doc["features"], list)
    for f in doc["features"]:
        assert f["type"] == "Feature" and isinstance(f["properties"], dict)
        _check_geometry(f["geometry"])


def test_geojson_follows_rfc_7946(walker, tmp_path):
    path = write_geojson(tmp_path / "run.geojson", walker["sats"], walker["uts"], walker["frames"])
    doc = json.loads(path.read_text())
    _check_feature_collection(doc)
    kinds = pd.Series([f["properties"]["kind"] for f in doc["features"]]).value_counts()
    assert kinds["satellite_track"] == 120 and kinds["ut_track"] == 4
    assert kinds["beam_footprint"] == sum(len(fp["beam_id"]) for _, fp in walker["frames"])
    types = {f["geometry"]["type"] for f in doc["features"]}
    assert "MultiLineString" in types  # some of the 120 ground tracks cross 180 deg
    assert {
        f["geometry"]["type"] for f in doc["features"] if f["properties"]["kind"] == "ut_track"
    } == {"Point"}  # the Walker example's UTs are static


def test_geojson_footprint_vertices_are_at_half_power_of_their_beam(walker):
    doc = geojson_document(footprint_frames=walker["frames"][:5])
    beams = walker["stats"].beam_u_xy
    checked = 0
    for f in doc["features"]:
        p = f["properties"]
        pos, vel, _ = walker["eph"](p["time_s"])  # the ephemeris, not the report's copy
        ring = np.asarray(f["geometry"]["coordinates"][0])[:-1]
        if f["geometry"]["type"] != "Polygon" or np.any(np.abs(ring[:, 0]) == 180.0):
            continue  # points added on the antimeridian cut are not contour points
        ground = geodetic_to_ecef(np.radians(ring[:, 1]), np.radians(ring[:, 0]))
        u = direction_cosines(pos[0, p["sat_id"]], vel[0, p["sat_id"]], ground)
        b = beams[p["beam_id"]]
        n_sub = walker["stats"].n_sub_xy  # the walker example's subarray, from its codebook
        g = upa_gain(u[:, 0] - b[0], u[:, 1] - b[1], *n_sub) / (n_sub[0] * n_sub[1])
        np.testing.assert_allclose(g, 0.5, atol=2e-4)  # 6 decimals of a degree ~ 0.1 m
        checked += 1
    assert checked >= 15


def test_footprint_across_the_antimeridian_is_cut_into_two_rings_of_the_same_area():
    theta = np.linspace(0.0, 2 * np.pi, 60, endpoint=False)
    lon = np.mod(179.5 + np.cos(theta) + 180.0, 360.0) - 180.0  # wraps to -179.5 ...
    lat = 0.5 * np.sin(theta)
    rings = split_ring_at_antimeridian(lon, lat)
    assert len(rings) == 2
    assert {np.sign(r[:, 0].mean()) for r in rings} == {-1.0, 1.0}
    whole = np.column_stack([179.5 + np.cos(theta), lat])
    whole = np.vstack([whole, whole[:1]])
    assert sum(_signed_area(r) for r in rings) == pytest.approx(_signed_area(whole), rel=1e-12)
    for r in rings:
        _check_geometry({"type": "Polygon", "coordinates": [r.tolist()]})


def test_a_clockwise_ring_is_reversed():
    ring = split_ring_at_antimeridian([0.0, 0.0, 1.0, 1.0], [0.0, 1.0, 1.0, 0.0])[0]
    assert _signed_area(ring) > 0 and np.array_equal(ring[0], ring[-1])


# ----------------------------------------------------------------------- CZML
def _interval(text):
    a, b = text.split("/")
    return datetime.fromisoformat(a.replace("Z", "+00:00")), datetime.fromisoformat(
        b.replace("Z", "+00:00")
    )


def test_czml_has_a_document_packet_unique_ids_and_valid_intervals(walker, tmp_path):
    path = write_czml(
        tmp_path / "run.czml", 0.0, 600.0, walker["sats"], walker["uts"], walker["frames"]
    )
    doc = json.loads(path.read_text())
    assert isinstance(doc, list) and doc[0]["id"] == "document" and doc[0]["version"] == "1.0"
    start, stop = _interval(doc[0]["clock"]["interval"])
    assert (stop - start).total_seconds() == 600.0
    ids = [p["id"] for p in doc]
    assert len(ids) == len(set(ids))
    for p in doc[1:]:
        a, b = _interval(p["availability"])
        assert start <= a <= b <= stop
        if "position" in p:
            samples = np.asarray(p["position"]["cartographicDegrees"]).reshape(-1, 4)
            assert np.all(np.diff(samples[:, 0]) > 0)  # [t, lon, lat, h], times increasing
            assert datetime.fromisoformat(p["position"]["epoch"].replace("Z", "+00:00")) == start
        if "polygon" in p:
            assert len(p["polygon"]["positions"]["cartographicDegrees"]) % 3 == 0
    assert sum(p["id"].startswith("satellite/") for p in doc) == 120
    assert sum(p["id"].startswith("ut/") for p in doc) == 4


def test_czml_satellite_samples_are_the_ephemeris_positions(walker):
    doc = czml_document(0.0, 600.0, sat_tracks=walker["sats"])
    for p in doc[1:6]:
        sat = int(p["id"].split("/")[1])
        t, lon, lat, h = np.asarray(p["position"]["cartographicDegrees"]).reshape(-1, 4).T
        pos = geodetic_to_ecef(np.radians(lat), np.radians(lon), h)
        expected = walker["eph"](t)[0][:, sat]
        # 1e-6 deg at 7,671 km is 0.13 m; heights rounded to 1e-6 m.
        np.testing.assert_allclose(pos, expected, atol=0.5)


# ----------------------------------------------------------------------- events
def test_events_parquet_has_the_rows_of_the_csv(walker, tmp_path):
    events = pd.read_csv(walker["out"] / "events.csv")
    csv_path, pq_path = write_events(events, tmp_path)
    table = pq.read_table(pq_path)
    assert table.schema.field("kind").type == "string"
    assert str(table.schema.field("ut_id").type) == "int64"
    back = table.to_pandas()
    again = pd.read_csv(csv_path)
    assert len(back) == len(events) > 0
    pd.testing.assert_frame_equal(back, again, check_dtype=False)
    pd.testing.assert_frame_equal(again, events)


def test_write_exports_of_a_run_gives_valid_files_of_the_serving_satellites(walker, tmp_path):
    from leolink.io.report.rebuild import write_exports

    stats = walker["stats"]
    geo, czml = write_exports(stats, tmp_path, epoch_utc="2026-01-01T00:00:00Z")
    doc = json.loads(geo.read_text())
    _check_feature_collection(doc)
    serving = set(np.unique(stats.ut_sat[stats.ut_sat >= 0]).tolist())
    kinds = [f["properties"] for f in doc["features"]]
    sats = {p["sat_id"] for p in kinds if p["kind"] == "satellite_track"}
    assert sats == serving and len(serving) > 1
    packets = json.loads(czml.read_text())
    assert packets[0]["clock"]["currentTime"].startswith("2026-01-01T00:00:00")
    assert {int(p["id"].split("/")[1]) for p in packets if p["id"].startswith("satellite/")} == sats
