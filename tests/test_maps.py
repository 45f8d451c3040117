"""Maps: the shipped coastline against published landmarks; what plot_map draws from a
real run."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import LineCollection, PathCollection, PolyCollection

from leolink.io.report.maps import (
    OUTAGE_COLOUR,
    beam_colour,
    break_at_antimeridian,
    coastlines,
    draw_footprints,
    map_extent,
    new_figure,
    plot_map,
)
from leolink.io.report.page import run_map_figure
from leolink.io.report.rebuild import stats_from_dir
from report_helpers import make_run

LANDMARKS = Path(__file__).parent / "data" / "coastal_landmarks.csv"
RADIUS_KM = 6371.0
# Natural Earth 1:50m is drawn for 1:50,000,000: a 0.2 mm pen line there is 10 km.
SCALE_TOLERANCE_KM = 10.0
NEMO_TO_LAND_KM = 2688.0  # Wikipedia, "Pole of inaccessibility" (Point Nemo)


def _distance_to_coast_km(lat_deg, lon_deg):
    """Distance from a point to the nearest coastline segment (local equirectangular)."""
    lon, lat = (a.astype(float) for a in coastlines())
    x = np.radians(lon - lon_deg) * np.cos(np.radians(lat_deg)) * RADIUS_KM
    y = np.radians(lat - lat_deg) * RADIUS_KM
    x0, y0, dx, dy = x[:-1], y[:-1], np.diff(x), np.diff(y)
    t = np.clip(-(x0 * dx + y0 * dy) / np.maximum(dx * dx + dy * dy, 1e-12), 0.0, 1.0)
    d = np.hypot(x0 + t * dx, y0 + t * dy)
    return float(np.nanmin(d))


def _great_circle_to_coast_km(lat_deg, lon_deg):
    lon, lat = (np.radians(a[np.isfinite(a)].astype(float)) for a in coastlines())
    p, q = np.radians(lat_deg), np.radians(lon_deg)
    h = np.sin((lat - p) / 2) ** 2 + np.cos(p) * np.cos(lat) * np.sin((lon - q) / 2) ** 2
    return float(2 * RADIUS_KM * np.arcsin(np.sqrt(h)).min())


def _landmarks(kind):
    df = pd.read_csv(LANDMARKS, comment="#").iloc[1:]  # skip the units row
    df = df[df["kind"] == kind]
    return [(r.name, float(r.lat_deg), float(r.lon_deg)) for r in df.itertuples()]


@pytest.mark.parametrize(("name", "lat", "lon"), _landmarks("coast"))
def test_coastline_passes_by_published_landmarks(name, lat, lon):
    assert _distance_to_coast_km(lat, lon) < SCALE_TOLERANCE_KM, name


def test_point_nemo_is_as_far_from_land_as_published():
    ((_, lat, lon),) = _landmarks("ocean")
    d_km = _great_circle_to_coast_km(lat, lon)
    # Vertices only (an upper bound of the true distance), and the tiny atolls that set
    # the published value may be absent at 1:50m: allow the scale tolerance below, 1 % above.
    assert NEMO_TO_LAND_KM - SCALE_TOLERANCE_KM < d_km < 1.01 * NEMO_TO_LAND_KM


def test_coastline_data_is_compact_and_in_range():
    lon, lat = coastlines()
    ok = np.isfinite(lon)
    assert lon.dtype == np.float32 and 50_000 < ok.sum() < 100_000
    assert np.all(np.abs(lon[ok]) <= 180.0) and np.all(np.abs(lat[ok]) <= 90.0)
    assert np.array_equal(ok, np.isfinite(lat))


def test_beam_colours_are_distinct_and_never_the_outage_grey():
    rgba = beam_colour(np.arange(18))
    assert np.unique(np.round(rgba * 255), axis=0).shape[0] == 18
    assert np.all(np.abs(rgba - OUTAGE_COLOUR).sum(axis=1) > 0.1)
    np.testing.assert_array_equal(beam_colour([-1])[0], OUTAGE_COLOUR)
    np.testing.assert_array_equal(beam_colour(18), beam_colour(0))  # the palette cycles


def test_tracks_break_at_the_antimeridian_and_between_tracks():
    lon, lat = break_at_antimeridian(
        [170.0, 179.0, -179.0, -170.0, 10.0], [0, 1, 2, 3, 4], group=[1, 1, 1, 1, 2]
    )
    assert np.isnan(lon).sum() == 2
    assert np.flatnonzero(np.isnan(lon)).tolist() == [2, 5]


def test_extent_holds_the_points_and_stays_on_the_globe():
    ext = map_extent([-179.5, -170.0], [85.0, 89.0])
    assert ext[0] == -180.0 and ext[3] == 90.0 and ext[1] > -170.0


@pytest.fixture(scope="module")
def paper_stats(tmp_path_factory):
    out = make_run(tmp_path_factory.mktemp("paper"))
    return stats_from_dir(out, series_ut=[0, 5, 6]), pd.read_csv(out / "trace.csv")


def test_run_map_draws_15_cells_and_colours_uts_by_their_trace_beam(paper_stats):
    stats, trace = paper_stats
    fig = run_map_figure(stats)
    ax = fig.axes[0]
    cells = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(cells) == 1 and len(cells[0].get_paths()) == 15  # one satellite, 15 beams
    # Dots: every UT at the middle kept epoch (t = 60 s), coloured by its trace beam then.
    (dots,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    now = trace[trace["time_s"] == 60.0].sort_values("ut_id")
    np.testing.assert_allclose(dots.get_facecolors(), beam_colour(now["beam_id"].to_numpy()))
    np.testing.assert_allclose(dots.get_offsets(), now[["lon_deg", "lat_deg"]].to_numpy())
    # Track segments: coloured by the beam serving at the segment's start (the collection
    # joins a UT's consecutive segments of one colour into a polyline: split them again).
    (tracks,) = [c for c in ax.collections if isinstance(c, LineCollection)]
    rows = trace.sort_values(["ut_id", "time_s"])
    start = rows.groupby("ut_id").head(len(stats.keep_times_s) - 1)  # all but the last epoch
    end = rows.groupby("ut_id").tail(len(stats.keep_times_s) - 1)  # all but the first
    paths, colours = tracks.get_paths(), tracks.get_colors()
    seg_colours = np.concatenate([np.repeat(c[None], len(p.vertices) - 1, axis=0)
                                  for p, c in zip(paths, colours, strict=True)])  # fmt: skip
    np.testing.assert_allclose(seg_colours, beam_colour(start["beam_id"].to_numpy()))
    seg_starts = np.concatenate([p.vertices[:-1] for p in paths])
    seg_ends = np.concatenate([p.vertices[1:] for p in paths])
    np.testing.assert_allclose(seg_starts, start[["lon_deg", "lat_deg"]].to_numpy())
    np.testing.assert_allclose(seg_ends, end[["lon_deg", "lat_deg"]].to_numpy())
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert x0 < trace["lon_deg"].min() and trace["lon_deg"].max() < x1
    assert y0 < trace["lat_deg"].min() and trace["lat_deg"].max() < y1


def test_plot_map_without_inputs_is_a_world_map():
    fig = plot_map()
    assert fig.axes[0].get_xlim() == (-180.0, 180.0)


def test_footprints_keep_order_skip_short_rings_and_stay_whole_across_180():
    """Cells in the order given; a ring across the antimeridian is unwrapped (181, not
    -179), a NaN point is left out of its ring, a ring with 2 finite points is dropped;
    colours and labels follow each drawn cell's beam (hand-made rings, known vertices)."""
    nan = np.nan
    lon = np.array([[179.0, -179.0, -179.0, 179.0], [10.0, 12.0, nan, 10.0],
                    [0.0, nan, nan, 1.0], [-20.0, -18.0, -18.0, -20.0]])  # fmt: skip
    lat = np.array([[1.0, 1.0, 3.0, 3.0], [5.0, 5.0, 7.0, 7.0],
                    [0.0, 0.0, 1.0, 1.0], [-1.0, -1.0, 1.0, 1.0]])  # fmt: skip
    fp = {"beam_id": np.array([4, 7, 9, 2]), "lat_deg": lat, "lon_deg": lon}
    fig, ax = new_figure((-30.0, 190.0, -10.0, 10.0))
    coll = draw_footprints(ax, fp, label_beams=True)
    rings = [[(179, 1), (181, 1), (181, 3), (179, 3)], [(10, 5), (12, 5), (10, 7)],
             [(-20, -1), (-18, -1), (-18, 1), (-20, 1)]]  # fmt: skip
    paths = coll.get_paths()
    assert len(paths) == 3
    for path, ring in zip(paths, rings, strict=True):
        np.testing.assert_allclose(path.vertices[: len(ring)], ring, atol=1e-12)
    np.testing.assert_array_equal(coll.get_edgecolors(), beam_colour([4, 7, 2]))
    # Each beam id written (a marker of its digits) at the mean of its drawn ring's points.
    labels = [(line.get_gid().removeprefix("beam "), tuple(xy)) for line in ax.lines
              if (line.get_gid() or "").startswith("beam ")
              for xy in line.get_xydata().tolist()]  # fmt: skip
    assert sorted(labels) == sorted([("4", (180.0, 2.0)), ("7", (32 / 3, 17 / 3)),
                                     ("2", (-19.0, 0.0))])  # fmt: skip
    assert draw_footprints(ax, {**fp, "beam_id": fp["beam_id"][:0], "lat_deg": lat[:0],
                                "lon_deg": lon[:0]}) is None  # fmt: skip


def test_run_map_labels_the_time_plot_uts_where_they_are(paper_stats):
    from matplotlib.text import Annotation

    stats, trace = paper_stats
    ax = run_map_figure(stats).axes[0]
    labels = {a.get_text(): a.xy for a in ax.texts if isinstance(a, Annotation)}
    assert sorted(labels) == ["UT 0", "UT 5", "UT 6"]  # series_ut of the fixture
    now = trace[trace["time_s"] == 60.0].set_index("ut_id")  # the map's instant
    for ut in (0, 5, 6):
        np.testing.assert_allclose(labels[f"UT {ut}"], now.loc[ut, ["lon_deg", "lat_deg"]])
