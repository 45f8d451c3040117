"""UTs placed by latitude and longitude: sites (lists or a CSV file), a near-equal-area
lat/lon grid, uniform draws in a region, land only (leolink.land), movers from a site.

Checks against independent numbers: the trace's lat_deg/lon_deg equal the configured
sites (sphere and WGS 84); the grid's point count equals the region's area over the cell
area; the share of uniform draws below a latitude equals the area formula; the land
share of the globe is the published ~29 %; named places on land and at sea.
"""

import math
from pathlib import Path

import numpy as np
import pytest

import leolink
from leolink.cli import main
from leolink.config import load_config
from leolink.greatcircle import destination_point
from leolink.land import is_land
from leolink.placement import has_land, lat_lon_grid, random_region
from leolink.sim.mobility.populations import MOBILITY, PopulationContext

DATA = Path(__file__).resolve().parent / "data"
CITIES = DATA / "cities_20.toml"
SITES = DATA / "cities_20.csv"
#: The trace's positions are float64 degrees from radians and back: a few ulps of 180.
SITE_TOL_DEG = 1e-9


def _sites():
    rows = [
        line.split(",")
        for line in SITES.read_text().splitlines()
        if line and not line.startswith(("#", "name"))
    ]
    return (
        [r[0] for r in rows],
        np.array([float(r[1]) for r in rows]),
        np.array([float(r[2]) for r in rows]),
        np.array([float(r[3]) for r in rows]),
    )


def _ctx(seed=0):
    return PopulationContext(
        center_lat_rad=0.7, center_lon_rad=-0.15, semi_axes_m=(534e3, 170e3),
        track_heading_rad=0.3, rng=np.random.default_rng(seed), t0_s=0.0, radius_m=6_371_000.0,
    )  # fmt: skip


def _static(**keys):
    params = MOBILITY["static"].config(name="p", **keys)
    return MOBILITY.build("static", params, _ctx()).state(0.0)


@pytest.mark.parametrize("earth", ["sphere", "wgs84"])
def test_twenty_cities_are_where_the_trace_puts_them(earth):
    names, lat, lon, alt = _sites()
    cfg = load_config(CITIES, [f'earth.model="{earth}"'])
    trace = leolink.run(cfg).trace
    assert len(names) == 20 and trace["ut_id"].nunique() == 20
    for _, rows in trace.groupby("time_s"):
        rows = rows.sort_values("ut_id")
        np.testing.assert_allclose(rows["lat_deg"], lat, rtol=0, atol=SITE_TOL_DEG)
        np.testing.assert_allclose(rows["lon_deg"], lon, rtol=0, atol=SITE_TOL_DEG)
        np.testing.assert_allclose(rows["alt_m"], alt, rtol=0, atol=1e-6)
    served = trace[trace["sat_id"] >= 0]
    assert served["elevation_deg"].min() >= 40.0  # every city served by what sees it


def test_sites_file_and_lists_give_the_same_uts():
    names, lat, lon, alt = _sites()
    listed = _static(
        placement="sites", lat_deg=lat.tolist(), lon_deg=lon.tolist(), alt_m=alt.tolist(),
        site_names=names,
    )  # fmt: skip
    np.testing.assert_array_equal(np.degrees(listed.lat_rad), np.degrees(np.radians(lat)))
    np.testing.assert_array_equal(listed.alt_m, alt)
    cfg = load_config(CITIES)
    from leolink.app.scenario import build_populations

    ((_, model),) = build_populations(cfg, 0.0, np.random.default_rng(0))
    np.testing.assert_array_equal(model.state(0.0).pos_m, listed.pos_m)


def test_a_mover_leaves_its_site_on_its_heading():
    names, lat, lon, _ = _sites()
    params = MOBILITY["constant_velocity"].config(
        name="m", placement="sites", lat_deg=lat.tolist(), lon_deg=lon.tolist(),
        speed_m_s=250.0, heading_deg=63.0,
    )  # fmt: skip
    model = MOBILITY.build("constant_velocity", params, _ctx())
    s = model.state(600.0)
    want_lat, want_lon = destination_point(
        np.radians(lat), np.radians(lon), math.radians(63.0), 250.0 * 600.0
    )
    np.testing.assert_allclose(s.lat_rad, want_lat, atol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (s.lon_rad - want_lon))), 0.0, atol=1e-12)


@pytest.mark.parametrize(
    ("spacing", "band", "lons"),
    [(1.0, (-53.0, 53.0), (-180.0, 180.0)), (0.5, (35.0, 44.0), (-10.0, 4.0)), (2.0, (-90, 90),
     (-180, 180))],
)  # fmt: skip
def test_grid_points_stand_for_equal_areas(spacing, band, lons):
    lat, lon = lat_lon_grid(spacing, band, lons)
    assert np.all((lat > band[0]) & (lat < band[1]) & (lon > lons[0]) & (lon < lons[1]))
    # Area of the region / area of one cell (spacing^2 on the unit sphere, in rad^2).
    area = (
        (lons[1] - lons[0])
        * math.pi
        / 180.0
        * (math.sin(math.radians(band[1])) - math.sin(math.radians(band[0])))
    )
    expected = area / math.radians(spacing) ** 2
    assert len(lat) == pytest.approx(expected, rel=0.02)


def test_uniform_draws_follow_the_area_of_the_sphere():
    lat, lon = random_region(200_000, (-90.0, 90.0), (-180.0, 180.0), np.random.default_rng(3))
    # The zone |lat| < 30 deg is half the sphere (sin 30 deg = 1/2); 5 sigma = 0.0056.
    assert np.mean(np.abs(lat) < 30.0) == pytest.approx(0.5, abs=0.0056)
    lat, lon = random_region(10_000, (10.0, 20.0), (100.0, 101.0), np.random.default_rng(3))
    assert lat.min() >= 10 and lat.max() <= 20 and lon.min() >= 100 and lon.max() <= 101


PLACES = [
    ("Madrid", 40.4168, -3.7038, True), ("Tokyo", 35.6895, 139.6917, True),
    ("N'Djamena", 12.1348, 15.0557, True), ("Lake Victoria (water, not a hole)", -1.0, 33.0, True),
    ("Wrangel Island, east of 180", 71.2, -179.8, True),
    ("Wrangel Island, west of 180", 71.2, 179.5, True), ("Vanua Levu, Fiji", -16.6, 179.5, True),
    ("South Pole", -89.9, 45.0, True), ("Antarctica, 85 S", -85.0, 0.0, True),
    ("mid-Atlantic", 30.0, -40.0, False), ("Point Nemo", -48.8767, -123.3933, False),
    ("Caspian Sea (a hole)", 42.0, 50.5, False), ("Bering Sea", 60.0, -179.0, False),
    ("Ross Ice Shelf (not land)", -80.0, -170.0, False),
]  # fmt: skip


@pytest.mark.parametrize(("name", "lat", "lon", "land"), PLACES, ids=[p[0] for p in PLACES])
def test_named_places_are_on_land_or_at_sea(name, lat, lon, land):
    assert bool(is_land([lat], [lon])[0]) is land


def test_land_is_29_percent_of_the_globe():
    # Land: 148.9 M km2 of 510.1 M km2 (29.2 %); Natural Earth leaves out Antarctica's ice
    # shelves (~1.5 M km2, 28.9 %). 20,000 uniform points: sigma 0.32 %.
    lat, lon = random_region(20_000, (-90.0, 90.0), (-180.0, 180.0), np.random.default_rng(5))
    assert np.mean(is_land(lat, lon)) == pytest.approx(0.289, abs=0.012)


def test_land_only_keeps_land_and_only_land():
    grid = dict(placement="lat_lon_grid", spacing_deg=2.0, lat_band_deg=[-53.0, 53.0])
    everything, land = _static(**grid), _static(**grid, land_only=True)
    lat_all, lon_all = np.degrees(everything.lat_rad), np.degrees(everything.lon_rad)
    on = is_land(lat_all, lon_all)
    np.testing.assert_allclose(np.degrees(land.lat_rad), lat_all[on], atol=1e-12)
    assert 0.2 < land.n_ut / everything.n_ut < 0.4
    drawn = _static(placement="random_region", count=500, lat_band_deg=[-53, 53], land_only=True)
    assert drawn.n_ut == 500
    assert is_land(np.degrees(drawn.lat_rad), np.degrees(drawn.lon_rad)).all()


def test_a_region_has_land_when_a_coast_or_its_inside_is_land():
    assert has_land((40.0, 41.0), (-4.0, -3.0))  # inland Spain: no coast in the box
    assert has_land((36.0, 37.0), (-7.0, -5.0))  # Gulf of Cadiz coast
    assert not has_land((-5.0, 0.0), (-140.0, -130.0))  # the Pacific
    assert not has_land((30.0, 31.0), (-41.0, -40.0))  # the Atlantic


BAD = [
    ("site latitude", ["population.0.placement='sites'", "population.0.lat_deg=[95.0]",
                       "population.0.lon_deg=[0.0]"], "population.0.lat_deg.0 = 95"),
    ("site longitude", ["population.0.placement='sites'", "population.0.lat_deg=[10.0]",
                        "population.0.lon_deg=[-181.0]"], "population.0.lon_deg.0 = -181"),
    ("missing file", ["population.0.sites_file='nowhere.csv'"], "sites_file"),
    ("empty region", ["population.0.placement='random_region'",
                      "population.0.lat_band_deg=[10.0, 10.0]"], "empty region"),
    ("no land", ["population.0.placement='random_region'", "population.0.land_only=true",
                 "population.0.lat_band_deg=[-5.0, 0.0]",
                 "population.0.lon_range_deg=[-140.0, -130.0]"], "has no land"),
    ("grid too coarse", ["population.0.placement='lat_lon_grid'", "population.0.spacing_deg=5",
                         "population.0.lat_band_deg=[10.0, 11.0]"], "has no point"),
    ("empty grid band", ["population.0.placement='lat_lon_grid'",
                         "population.0.lat_band_deg=[10.0, 10.0]"],
     "lat_band_deg = [10, 10] is an empty region"),
    ("empty longitudes", ["population.0.placement='random_region'",
                          "population.0.lon_range_deg=[170.0, -170.0]"],
     "lon_range_deg = [170, -170] is an empty region"),
    ("grid without land", ["population.0.placement='lat_lon_grid'", "population.0.land_only=true",
                           "population.0.lat_band_deg=[-5.0, 0.0]",
                           "population.0.lon_range_deg=[-140.0, -130.0]"],
     "lat_band_deg = [-5, 0] x lon_range_deg = [-140, -130] has no land"),
]  # fmt: skip


@pytest.mark.parametrize(("sets", "needle"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_geography_is_one_line_and_validate_agrees(sets, needle, capsys, tmp_path):
    args = [str(CITIES)] + [a for s in sets for a in ("--set", s)]
    lines = []
    for command in (["validate"], ["run", "--out", str(tmp_path / "out")]):
        assert main([*command, *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err
        lines.append(err[0])
    assert lines[0] == lines[1]
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


@pytest.mark.parametrize(
    ("row", "needle"),
    [("B,95.0,20.0", "line 3, lat_deg = 95.0 is not allowed: use [-90, 90]"),
     ("B,10.0,-180.5", "line 3, lon_deg = -180.5 is not allowed: use [-180, 180]"),
     ("B,ten,20.0", "line 3, column 'lat_deg': not a number")],
)  # fmt: skip
def test_a_bad_site_in_a_sites_file_is_one_line_and_validate_agrees(row, needle, capsys,
                                                                     tmp_path):  # fmt: skip
    sites = tmp_path / "sites.csv"
    sites.write_text(f"name,lat_deg,lon_deg\nA,10.0,20.0\n{row}\n")
    args = [str(CITIES), "--set", f"population.0.sites_file='{sites}'"]
    lines = []
    for command in (["validate"], ["run", "--out", str(tmp_path / "out")]):
        assert main([*command, *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"{sites}: {needle}" in err[0], err
        lines.append(err[0])
    assert lines[0] == lines[1]
    assert not (tmp_path / "out").exists()
