"""Tests of leolink.config: the paper's Table, error wording, --set overrides, round trip.

Expected numbers are typed from the paper's Table (tab:system_param of Palacios et al.,
"A hybrid beamforming design for massive MIMO LEO satellite communications"), never read
from configs/paper.toml.
"""

import math
import tomllib
from pathlib import Path

import pytest

from leolink.config import Config, apply_overrides, dump_toml, load_config, parse_config
from leolink.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"
DATA = Path(__file__).resolve().parent / "data"
ALL_CONFIGS = sorted((ROOT / "configs").glob("*.toml")) + sorted(
    (ROOT / "configs" / "examples").glob("*.toml")
)

# The paper's Table, typed by hand: (attribute path, value in leolink's SI units).
PAPER_TABLE = [
    ("constellation.altitude_m", 1300e3),  # h_sat = 1300 km
    ("constellation.n_planes", 83),  # N_p
    ("constellation.sats_per_plane", 53),  # N_s
    ("constellation.inclination_deg", 53.0),  # theta_op
    ("roi.semi_axis_x_m", 534.1e3),  # semiradius x, 534.1 km
    ("roi.semi_axis_y_m", 170.5e3),  # semiradius y, 170.5 km
    ("link.freq_hz", 11.45e9),  # f_DL = 11.45 GHz
    ("link.bandwidth_hz", 250e6),  # B_DL = 250 MHz
    ("atmosphere.fixed.loss_db", 0.017),  # LP_at = 0.017 dB
    ("link.rician_k", 10.0),  # K_r
    ("satellite_array.n_x", 60),  # N^sat_x
    ("satellite_array.n_y", 72),  # N^sat_y
    ("satellite_array.n_rf_x", 5),  # N^RF_x
    ("satellite_array.n_rf_y", 3),  # N^RF_y
    ("link.ptx_dbw", 15.0),  # P_TX = 15 dBW
    ("satellite_array.oversampling", 1.2),  # O
    ("terminal.upa.n_x", 24),  # N^UT_x
    ("terminal.upa.n_y", 24),  # N^UT_y
    ("terminal.metasurface.peak_gain_db", 33.0),  # Kymeta peak gain G_RX = 33 dB
    ("terminal.metasurface.rolloff", 1.2),  # Kymeta roll-off factor
    ("link.noise_temp_dbk", 24.1),  # T = 24.1 dBK
]
# The Table prints the ROI to 0.1 km; Sec. 3.1's formula for 83 x 53 at 53 deg gives
# 534.1 x 272.4 km (printed the same way), so half a printed digit is the tolerance.
PRINTED_KM_TOL_M = 50.0
DERIVED_ROI_KM = (534.1, 272.4)


def _get(cfg, dotted):
    obj = cfg
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


def _paper_dict():
    return tomllib.loads(PAPER.read_text(encoding="utf-8"))


def _parse_with(overrides):
    return parse_config(apply_overrides(_paper_dict(), overrides), source="paper.toml")


def _without_semi_axes(tmp_path):
    lines = PAPER.read_text(encoding="utf-8").splitlines()
    kept = [s for s in lines if not s.startswith(("semi_axis_x_m", "semi_axis_y_m"))]
    assert len(kept) == len(lines) - 2, "paper.toml should hold exactly two semi-axis lines"
    path = tmp_path / "paper_derived_roi.toml"
    path.write_text("\n".join(kept) + "\n", encoding="utf-8")
    return path


# -- the paper's Table ------------------------------------------------------------


@pytest.mark.parametrize(("key", "expected"), PAPER_TABLE, ids=[k for k, _ in PAPER_TABLE])
def test_paper_config_holds_the_table(key, expected):
    cfg = load_config(PAPER)
    # Values typed in the TOML and here are the same decimal literals: exact up to
    # float parsing, so a relative 1e-12 is ample.
    assert _get(cfg, key) == pytest.approx(expected, rel=1e-12)


def test_paper_config_is_the_papers_scenario():
    cfg = load_config(PAPER)
    assert (cfg.roi.center_lat_deg, cfg.roi.center_lon_deg) == (42.24, -8.72)
    assert cfg.terminal.kind == "upa"  # the Table's 24 x 24 UPA
    assert cfg.controller.policy == "max_snr"
    assert cfg.atmosphere.model == "fixed"
    assert cfg.constellation.kind == "pass"


def test_roi_semi_axes_explicit_are_the_tables():
    rx_m, ry_m = load_config(PAPER).roi_semi_axes_m()
    assert rx_m == pytest.approx(534.1e3, abs=1e-6)
    assert ry_m == pytest.approx(170.5e3, abs=1e-6)


def test_roi_semi_axes_default_to_the_tables_when_lines_removed(tmp_path):
    cfg = load_config(_without_semi_axes(tmp_path))
    assert cfg.roi_semi_axes_m() == load_config(PAPER).roi_semi_axes_m()
    assert parse_config({}).roi_semi_axes_m() == (534.1e3, 170.5e3)


def test_roi_semi_axes_derived_on_request():
    cfg = _parse_with(['roi.semi_axis_x_m="derived"', 'roi.semi_axis_y_m="derived"'])
    rx_m, ry_m = cfg.roi_semi_axes_m()
    assert rx_m == pytest.approx(DERIVED_ROI_KM[0] * 1e3, abs=PRINTED_KM_TOL_M)
    assert ry_m == pytest.approx(DERIVED_ROI_KM[1] * 1e3, abs=PRINTED_KM_TOL_M)


def test_roi_semi_axes_mix_explicit_and_derived():
    cfg = _parse_with(["roi.semi_axis_y_m=100000", "roi.semi_axis_x_m=derived"])
    rx_m, ry_m = cfg.roi_semi_axes_m()
    assert rx_m == pytest.approx(DERIVED_ROI_KM[0] * 1e3, abs=PRINTED_KM_TOL_M)
    assert ry_m == 100000.0


# -- every kind of mistake: a message naming the key, the value, what is allowed ----

MISTAKES = [
    (["foo=1"], r"foo is not a known key"),
    (["link.bandwith_hz=250e6"], r"link\.bandwith_hz is not a known key"),
    (['link.freq_hz="high"'], r"link\.freq_hz = 'high' is not allowed: .*valid number"),
    (
        ["constellation.altitude_m=-5000"],
        r"constellation\.altitude_m = -5000 is not allowed: .*greater than 100000",
    ),
    (
        ["link.bandwidth_hz=0"],
        r"link\.bandwidth_hz = 0 is not allowed: .*greater than or equal to 1000",
    ),
    (
        ["constellation.min_elevation_deg=95"],
        r"constellation\.min_elevation_deg = 95 is not allowed: .*less than or equal to 90",
    ),
    (
        ["constellation.min_elevation_deg=-1"],
        r"constellation\.min_elevation_deg = -1 is not allowed: .*greater than or equal to 0",
    ),
    (
        ["satellite_array.n_x=61"],
        r"satellite_array\.n_x = 61 is not allowed: .*multiple of n_rf_x = 5",
    ),
    (
        ['terminal.kind="dish"'],
        r"terminal\.kind = 'dish' is not allowed: .*'isotropic', 'fixed', 'upa', 'leaky_wave' or "
        r"'metasurface'",
    ),
    (
        ['controller.policy="greedy"'],
        r"controller\.policy = 'greedy' is not allowed: .*'max_snr', 'hysteresis', "
        r"'predictive', 'a3', .*'time_to_exit', 'cho', 'a2a4' or 'slotted'",
    ),
    (
        ["population.1.x_m=[1.0, 2.0, 3.0]"],
        r"population 'static': placement = 'points' needs x_m and y_m lists of one length "
        r"\(got 3 and 4\)",
    ),
    (
        ["roi.center_lat_deg=60"],
        r"roi\.center_lat_deg = 60(\.0)? is not allowed: an orbit inclined 53(\.0)? deg never "
        r"passes over it",
    ),
    (
        ['constellation.kind="tle"'],
        r"constellation\.tle_file is required when constellation\.kind = 'tle'",
    ),
    (['population.3.speed="rocket"'], r"population\.3\.speed = 'rocket' is not allowed"),
]


@pytest.mark.parametrize(("overrides", "pattern"), MISTAKES, ids=[m[0][0] for m in MISTAKES])
def test_mistake_gives_clear_message(overrides, pattern):
    with pytest.raises(ConfigError, match=pattern) as info:
        _parse_with(overrides)
    text = str(info.value)
    assert text.startswith("paper.toml: ")  # says which config
    assert "\n" not in text  # one line for the CLI


def test_unknown_key_in_file_names_file_and_key(tmp_path):
    path = tmp_path / "typo.toml"
    path.write_text("[link]\nbandwith_hz = 250e6\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"typo\.toml: link\.bandwith_hz is not a known key"):
        load_config(path)


def test_missing_file_is_named(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(ConfigError, match=r"config file '.*nope\.toml' does not exist"):
        load_config(path)


def test_invalid_toml_syntax_names_file_and_line():
    path = DATA / "config_invalid_syntax.toml"
    with pytest.raises(ConfigError, match=r"config_invalid_syntax\.toml: not valid TOML: .*line 6"):
        load_config(path)


def test_several_mistakes_are_all_reported():
    with pytest.raises(ConfigError) as info:
        load_config(DATA / "config_several_mistakes.toml")
    text = str(info.value)
    for key in ("link.bandwith_hz", "link.bandwidth_hz = 0.0", "min_elevation_deg = 95.0"):
        assert key in text
    assert text.count(";") >= 2


def test_several_override_mistakes_are_all_reported():
    with pytest.raises(ConfigError) as info:
        _parse_with(["link.bandwidth_hz=0", "constellation.altitude_m=-5", "foo=1"])
    text = str(info.value)
    assert "link.bandwidth_hz = 0" in text
    assert "constellation.altitude_m = -5" in text
    assert "foo is not a known key" in text


# -- --set overrides ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("item", "key", "expected"),
    [
        ("run.seed=7", ("run", "seed"), 7),
        ("link.freq_hz=12e9", ("link", "freq_hz"), 12e9),
        ("link.ptx_dbw=-3.5", ("link", "ptx_dbw"), -3.5),
        ('controller.policy="hysteresis"', ("controller", "policy"), "hysteresis"),
        ("controller.policy=hysteresis", ("controller", "policy"), "hysteresis"),  # bare word
        ("output.plots.enabled=false", ("output", "plots", "enabled"), False),
        ("earth.rotation=true", ("earth", "rotation"), True),
        (
            'output.trace.formats=["csv", "parquet"]',
            ("output", "trace", "formats"),
            ["csv", "parquet"],
        ),
        ("output.plots.uts=[1, 2]", ("output", "plots", "uts"), [1, 2]),
        (" link.ptx_dbw = 10 ", ("link", "ptx_dbw"), 10),  # spaces around key and value
        ("new_section.key=1", ("new_section", "key"), 1),  # created; validation rejects it
    ],
)
def test_override_parses_toml_values(item, key, expected):
    value = apply_overrides(_paper_dict(), [item])
    for part in key:
        value = value[part]
    assert value == expected
    assert type(value) is type(expected)


def test_override_does_not_touch_its_input():
    data = _paper_dict()
    apply_overrides(data, ["link.ptx_dbw=0", "population.0.count=3"])
    assert data["link"]["ptx_dbw"] == 15.0
    assert "count" not in data["population"][0]


def test_override_indexes_population():
    cfg = _parse_with(["population.0.count=3", "population.3.alt_m=9000"])
    assert cfg.population[0].count == 3
    assert cfg.population[3].alt_m == 9000.0
    assert cfg.population[1].count == 1  # the others untouched


@pytest.mark.parametrize("index", ["9", "4", "-1", "x"])
def test_override_bad_population_index(index):
    # paper.toml has populations 0..3
    pattern = rf"--set population\.{index}\.count: index '{index}' is not allowed; use 0\.\.3"
    with pytest.raises(ConfigError, match=pattern):
        apply_overrides(_paper_dict(), [f"population.{index}.count=3"])


@pytest.mark.parametrize("item", ["link.freq_hz", "=5", ""])
def test_override_without_equals_or_key(item):
    with pytest.raises(ConfigError, match=r"--set .* is not allowed: use section\.key=value"):
        apply_overrides(_paper_dict(), [item])


def test_override_list_needs_index_and_key():
    with pytest.raises(ConfigError, match=r"give an index and a key, e\.g\. population\.0"):
        apply_overrides(_paper_dict(), ["population.0=5"])


def test_override_value_that_is_not_toml_is_a_string():
    with pytest.raises(ConfigError, match=r"run\.seed = 'abc' is not allowed"):
        _parse_with(["run.seed=abc"])


def test_load_config_applies_overrides_before_validation():
    cfg = load_config(PAPER, ["roi.semi_axis_y_m=272400", "controller.policy=hysteresis"])
    assert cfg.roi.semi_axis_y_m == 272400.0
    assert cfg.controller.policy == "hysteresis"


# -- dump_toml round trip and paths ---------------------------------------------------


@pytest.mark.parametrize("path", ALL_CONFIGS, ids=[p.name for p in ALL_CONFIGS])
def test_dump_toml_round_trip(path, tmp_path):
    cfg = load_config(path)
    out = tmp_path / "resolved.toml"
    out.write_text(dump_toml(cfg), encoding="utf-8")
    again = load_config(out)
    # `source` names the file it came from, so it differs by design.
    assert again.model_copy(update={"source": ""}) == cfg.model_copy(update={"source": ""})
    assert again.roi_semi_axes_m() == cfg.roi_semi_axes_m()


def test_dump_toml_writes_every_default():
    text = dump_toml(parse_config({}))
    data = tomllib.loads(text)
    for section in Config.model_fields:
        if section != "source":
            assert section in data
    assert "source" not in data
    assert parse_config(data) == parse_config({})


def test_relative_paths_resolved_against_config_folder(tmp_path):
    folder = tmp_path / "scenario"
    folder.mkdir()
    abs_track = tmp_path / "elsewhere" / "abs.csv"
    path = folder / "cfg.toml"
    path.write_text(
        "[constellation]\n"
        'kind = "tle"\n'
        'tle_file = "tles/sats.tle"\n'
        "[[population]]\n"
        'name = "rel"\n'
        'kind = "track"\n'
        'track_file = "tracks/ship.csv"\n'
        "[[population]]\n"
        'name = "abs"\n'
        'kind = "track"\n'
        f"track_file = {str(abs_track)!r}\n",
        encoding="utf-8",
    )
    cfg = load_config(path)
    assert Path(cfg.constellation.tle_file) == folder / "tles" / "sats.tle"
    assert Path(cfg.population[0].track_file) == folder / "tracks" / "ship.csv"
    assert Path(cfg.population[1].track_file) == abs_track


def test_relative_paths_independent_of_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = load_config(ROOT / "configs" / "examples" / "ship.toml")
    assert Path(cfg.population[1].track_file).is_file()


# -- every shipped config ---------------------------------------------------------------


def test_there_are_example_configs():
    names = {p.name for p in ALL_CONFIGS}
    expected = {"car", "train", "ship", "aircraft", "walker", "tle", "hysteresis"}
    assert {"paper.toml"} | {f"{n}.toml" for n in expected} <= names


@pytest.mark.parametrize("path", ALL_CONFIGS, ids=[p.name for p in ALL_CONFIGS])
def test_every_config_loads_and_validates(path, capsys):
    from leolink.cli import main

    cfg = load_config(path)
    for pop in cfg.population:
        if pop.kind == "track":
            assert Path(pop.track_file).is_file(), pop.track_file
    if cfg.constellation.kind == "tle":
        assert Path(cfg.constellation.tle_file).is_file()
    # short enough to run in a few seconds at the configured epoch
    assert cfg.run.duration_s / cfg.run.epoch_s <= 600
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "valid" in out and ("covers the Earth" in out or "leaves gaps" in out)


def _example(name):
    return load_config(ROOT / "configs" / "examples" / f"{name}.toml")


def _haversine_m(lat1_deg, lon1_deg, lat2_deg, lon2_deg, radius_m=6371e3):
    p1, p2 = math.radians(lat1_deg), math.radians(lat2_deg)
    dp, dl = p2 - p1, math.radians(lon2_deg - lon1_deg)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * radius_m * math.asin(math.sqrt(a))


def test_train_waypoints_mean_100_m_s_near_the_roi_centre():
    cfg = _example("train")
    (train,) = [p for p in cfg.population if p.kind == "waypoints"]
    rows = train.waypoints
    # waypoints are printed to 1e-6 deg (0.1 m); 0.1 m/s is far above that rounding.
    for (t0, la0, lo0, _), (t1, la1, lo1, _) in zip(rows, rows[1:], strict=False):
        assert _haversine_m(la0, lo0, la1, lo1) / (t1 - t0) == pytest.approx(100.0, abs=0.1)
    assert any(
        _haversine_m(la, lo, cfg.roi.center_lat_deg, cfg.roi.center_lon_deg) < 1.0
        for _, la, lo, _ in rows
    )


def test_mobility_examples_hold_their_speeds():
    car = _example("car")
    assert [p.speed_m_s for p in car.population] == [30.0, 30.0]
    assert {p.heading_deg for p in car.population} == {"random", "along_track"}
    (plane,) = _example("aircraft").population
    assert (plane.speed_m_s, plane.alt_m, plane.heading_deg) == (250.0, 10e3, "against_track")
    ship = _example("ship")
    assert any(p.kind == "track" for p in ship.population)


def test_walker_and_hysteresis_examples():
    w = _example("walker")
    c = w.constellation
    assert (c.kind, c.n_planes, c.sats_per_plane, c.inclination_deg) == ("walker", 12, 10, 53.0)
    assert (c.altitude_m, c.min_elevation_deg, w.run.duration_s) == (1300e3, 25.0, 600.0)
    # The ROI is the cap seen above the 25 deg mask: by the law of sines at the UT, the
    # off-nadir angle is asin(R cos(el) / (R + h)), the central angle 90 - el - that, and
    # the ROI-plane radius R tan(central) (gnomonic); the config rounds to 0.1 km.
    el, r, h = math.radians(25.0), w.earth.radius_m, c.altitude_m
    central = math.pi / 2 - el - math.asin(r * math.cos(el) / (r + h))
    assert (
        w.roi.semi_axis_x_m == w.roi.semi_axis_y_m == pytest.approx(r * math.tan(central), abs=100)
    )
    h = _example("hysteresis").controller
    assert (
        h.policy,
        h.hysteresis.margin_db,
        h.hysteresis.time_to_trigger_s,
        h.handover_time_s,
    ) == (
        "hysteresis",
        3.0,
        2.0,
        0.1,
    )


def test_tle_example_puts_the_iss_over_the_roi_centre_at_60_s():
    """Checked with skyfield (independent of leolink's orbit code)."""
    from datetime import datetime, timedelta

    skyfield_api = pytest.importorskip("skyfield.api")
    from skyfield.framelib import itrs

    cfg = _example("tle")
    lines = Path(cfg.constellation.tle_file).read_text(encoding="utf-8").splitlines()
    ts = skyfield_api.load.timescale(builtin=True)
    sat = skyfield_api.EarthSatellite(lines[1], lines[2], lines[0], ts)
    t0 = datetime.fromisoformat(cfg.run.start_utc)
    assert cfg.utc_of_time_zero() == t0
    # simulation time 0 is 60 s before the TLE epoch (to the TLE's 1e-8 day = 1 ms)
    assert (sat.epoch.utc_datetime() - t0).total_seconds() == pytest.approx(60.0, abs=1e-3)
    x, y, z = sat.at(ts.from_datetime(t0 + timedelta(seconds=60))).frame_xyz(itrs).m
    lat_deg = math.degrees(math.atan2(z, math.hypot(x, y)))  # geocentric: leolink's sphere
    lon_deg = math.degrees(math.atan2(y, x))
    # config rounds to 0.01 deg; polar motion and UT1 are ignored by leolink (< 0.01 deg)
    assert lat_deg == pytest.approx(cfg.roi.center_lat_deg, abs=0.02)
    assert lon_deg == pytest.approx(cfg.roi.center_lon_deg, abs=0.02)
    height_m = math.sqrt(x * x + y * y + z * z) - cfg.earth.radius_m
    assert height_m == pytest.approx(cfg.constellation.altitude_m, abs=2e3)


def test_config_reference_doc_is_up_to_date():
    """docs/config.md is generated from the models: regenerate it with
    ``python -m leolink.config.reference > docs/config.md`` when a key changes."""
    from leolink.config import Config
    from leolink.config.reference import reference_markdown

    doc = (Path(__file__).resolve().parents[1] / "docs" / "config.md").read_text()
    assert doc == reference_markdown()
    for section in Config.model_fields:
        if section != "source":
            assert f"`[{section}]`" in doc or f"`[[{section}]]`" in doc


def test_config_reference_documents_every_key_of_every_table():
    """Every key a config accepts, nested tables (``[controller.rlf]``) and per-kind
    tables included, has a row in docs/config.md (walked from a fully resolved config)."""
    import json

    doc = (Path(__file__).resolve().parents[1] / "docs" / "config.md").read_text()
    data = json.loads(json.dumps(load_config(ROOT / "configs" / "constellation.toml").to_dict()))
    missing = []

    def walk(node, where):
        for key, value in node.items():
            if isinstance(value, dict):
                walk(value, f"{where}.{key}")
            elif f"| `{key}` |" not in doc:
                missing.append(f"{where}.{key}")

    walk({k: v for k, v in data.items() if isinstance(v, dict)}, "")
    assert missing == []
    for table in ("controller.rlf", "controller.filter"):
        assert f"### `[{table}]`" in doc
