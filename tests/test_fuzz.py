"""Issue 19: a fuzz suite (hypothesis) over every reader of user input.

The config loader (TOML text, and structured tables of real keys with values of every
type and size), ``--set``, track CSV, GPX and TLE files: any input either succeeds or
raises a :class:`~leolink.errors.LeolinkError` of one line; never another exception.
Configs that load are also built as ``leolink validate`` builds them
(:func:`leolink.app.validate.checked_scenario`) for extreme numbers at every bound.
Derandomized (the same cases every run) so CI is repeatable; the case counts are in
docs/testing.md (:data:`CASES`). The suite takes ~30 s.
"""

from __future__ import annotations

import math
import tempfile
import typing
from datetime import UTC, datetime
from pathlib import Path

import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from leolink.config import config_model, load_config
from leolink.errors import LeolinkError
from reliability_helpers import FAST, PAPER, iss_lines, with_checksum

#: Cases per fuzz test (docs/testing.md states their total).
CASES = {
    "toml_text": 150,
    "config_tables": 300,
    "set_overrides": 300,
    "built_scenarios": 30,
    "track_csv": 200,
    "gpx": 120,
    "tle": 300,
}
T0 = datetime(2019, 12, 9, 16, 37, 29, tzinfo=UTC)


def _settings(name):
    return settings(
        max_examples=CASES[name],
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    )


def _one_line_or_success(fn, *args):
    """Call ``fn``; a LeolinkError must be one line; anything else fails the test."""
    try:
        return fn(*args)
    except LeolinkError as exc:
        text = str(exc)
        assert text and "\n" not in text, repr(text)
        return None


_FOLDER = tempfile.TemporaryDirectory(prefix="leolink-fuzz-")  # removed at exit


def _file(text, suffix, binary=False):
    """The input as a file (one per suffix, rewritten by every case)."""
    path = Path(_FOLDER.name) / f"input{suffix}"
    path.write_bytes(text) if binary else path.write_text(text, encoding="utf-8")
    return path


# --------------------------------------------------------------------------- configs
def _keys():
    """``(section, key)`` of every plain field of the fixed sections and the chosen
    kinds' tables (``terminal.upa``, ...), from the model itself."""
    out = []
    for name, info in config_model().model_fields.items():
        ann = info.annotation
        if not (isinstance(ann, type) and issubclass(ann, BaseModel)):
            continue
        for key, sub in ann.model_fields.items():
            inner = sub.annotation
            if isinstance(inner, type) and issubclass(inner, BaseModel):
                out += [(f"{name}.{key}", k) for k in inner.model_fields]
            else:
                out.append((name, key))
    return sorted(out)


KEYS = _keys()
NUMBERS = st.one_of(
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e-300, 1e308, -1e308, 5e-324, 2**53 + 1, 1e17, 0.1]),
)
VALUES = st.one_of(
    NUMBERS,
    st.booleans(),
    st.text(max_size=12),
    st.lists(NUMBERS, max_size=4),
    st.lists(st.lists(NUMBERS, max_size=5), max_size=3),
    st.dictionaries(st.text(max_size=6), NUMBERS, max_size=2),
)


def _nest(items):
    data: dict = {}
    for (section, key), value in items:
        node = data
        for part in section.split("."):
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                break
        else:
            node[key] = value
    return data


@_settings("toml_text")
@given(st.text(max_size=300))
def test_any_toml_text_loads_or_says_why(text):
    _one_line_or_success(load_config, _file(text, ".toml"))


@_settings("config_tables")
@given(st.lists(st.tuples(st.sampled_from(KEYS), VALUES), min_size=1, max_size=5))
def test_any_table_of_real_keys_loads_or_says_why(items):
    try:
        text = tomli_w.dumps(_nest(items))
    except (TypeError, ValueError):  # not representable in TOML: not a user's input
        return
    _one_line_or_success(load_config, _file(text, ".toml"))


OVERRIDE_KEYS = st.one_of(
    st.sampled_from([f"{s}.{k}" for s, k in KEYS]),
    st.sampled_from(["population.0.count", "population.9.x", "population", "run", "a..b", ""]),
    st.text(max_size=20),
)
OVERRIDE_VALUES = st.one_of(
    st.text(max_size=20),
    st.sampled_from(["[1, 2]", "{a = 1}", "true", "nan", "inf", "-1e308", '"x"', "[[", "'"]),
)


@_settings("set_overrides")
@given(st.lists(st.tuples(OVERRIDE_KEYS, st.sampled_from(["=", ""]), OVERRIDE_VALUES),
                min_size=1, max_size=3))  # fmt: skip
def test_any_set_override_applies_or_says_why(items):
    overrides = [f"{k}{sep}{v}" for k, sep, v in items]
    _one_line_or_success(load_config, PAPER, overrides)


NUMERIC_KEYS = [
    f"{s}.{k}"
    for s, k in KEYS
    if s in ("run", "link", "satellite_array", "constellation", "roi", "earth", "controller")
    and k not in ("seed",)
]


EXTREMES = st.one_of(
    st.sampled_from([0.0, 1e-300, 1e-6, 1.0, 1e3, 1e6, 1e9, 1e15, 1e308, -1e308, -1.0]),
    st.floats(min_value=-1e12, max_value=1e12, allow_nan=False),
)


@_settings("built_scenarios")
@given(st.lists(st.tuples(st.sampled_from(NUMERIC_KEYS), EXTREMES), max_size=2))
def test_configs_that_load_also_build_or_say_why(items):
    """Extreme numbers through the whole of ``validate``: the codebook, the engine, the
    populations (an overflow here was exit 3 before bounds)."""
    from leolink.app.validate import checked_scenario

    overrides = [*FAST, "run.duration_s=2", *(f"{k}={v!r}" for k, v in items)]
    cfg = _one_line_or_success(load_config, PAPER, overrides)
    if cfg is not None:
        _one_line_or_success(checked_scenario, cfg)


# --------------------------------------------------------------------------- tracks
CELLS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-(10**20), max_value=10**20).map(str),
    st.sampled_from(["", "nan", "1e999", "2019-12-09T16:38:29Z", "noon", '"', "a,b"]),
    st.text(max_size=8),
)
HEADERS = st.sampled_from(
    [
        ["time_s", "lat_deg", "lon_deg", "alt_m"],
        ["time_s", "ut", "lat_deg", "lon_deg", "alt_m"],
        ["time_utc", "lat_deg", "lon_deg", "alt_m"],
        ["lat_deg", "lon_deg"],
        ["time_s", "time_s", "lat_deg", "lon_deg", "alt_m"],
    ]
)


@_settings("track_csv")
@given(HEADERS, st.lists(st.lists(CELLS, min_size=0, max_size=6), max_size=6), st.booleans())
def test_any_track_csv_reads_or_says_why(header, rows, utc):
    from leolink.io.tracks import read_track_csv

    text = "\n".join([",".join(header), *(",".join(r) for r in rows)]) + "\n"
    _one_line_or_success(read_track_csv, _file(text, ".csv"), T0 if utc else None)


POINT = st.tuples(
    st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.text(max_size=6)),
    st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.text(max_size=6)),
    st.one_of(st.none(), st.floats(allow_nan=True).map(repr), st.text(max_size=6)),
    st.one_of(
        st.none(), st.sampled_from(["2019-12-09T16:38:29Z", "2019-12-09T16:38:28Z", "x", ""])
    ),
)


def _gpx(points, broken):
    body = ""
    for lat, lon, ele, when in points:
        inner = (f"<ele>{ele}</ele>" if ele is not None else "") + (
            f"<time>{when}</time>" if when is not None else ""
        )
        body += f'<trkpt lat="{lat}" lon="{lon}">{inner}</trkpt>'
    doc = (
        '<?xml version="1.0"?><gpx version="1.1" creator="fuzz" '
        'xmlns="http://www.topografix.com/GPX/1/1"><trk><name>t</name><trkseg>'
        f"{body}</trkseg></trk></gpx>"
    )
    return doc[: len(doc) // 2] if broken else doc


@_settings("gpx")
@given(st.lists(POINT, max_size=4), st.booleans())
def test_any_gpx_reads_or_says_why(points, broken):
    from leolink.io.tracks import read_track_gpx

    _one_line_or_success(read_track_gpx, _file(_gpx(points, broken), ".gpx"), T0)


# --------------------------------------------------------------------------- TLEs
EDIT = st.tuples(
    st.integers(min_value=0, max_value=1), st.integers(min_value=0, max_value=70),
    st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), min_size=0, max_size=3),
)  # fmt: skip


@_settings("tle")
@given(st.lists(EDIT, max_size=3), st.booleans(), st.sampled_from(["", "ISS\n", "0 X\n", "\n"]))
def test_any_tle_file_reads_or_says_why(edits, fix_checksum, name):
    """The ISS's TLE with a few columns replaced (checksums recomputed or not)."""
    from leolink.io.tle import read_tle_file

    lines = list(iss_lines())
    for which, col, text in edits:
        line = lines[which]
        lines[which] = line[:col] + text + line[col + len(text) :]
    if fix_checksum:
        lines = [with_checksum(ln[:68]) if len(ln) >= 68 else ln for ln in lines]
    tles = _one_line_or_success(read_tle_file, _file(name + "\n".join(lines) + "\n", ".tle"))
    if tles:  # what the reader accepts, sgp4 parses into finite elements
        from sgp4.api import Satrec

        sat = Satrec.twoline2rv(tles[0][1], tles[0][2])
        assert math.isfinite(sat.inclo) and 0.0 <= sat.ecco < 1.0 and sat.no_kozai >= 0.0


def test_the_fuzz_inputs_are_real_ones():
    """The generators produce what users give: a table of real keys is a valid config
    with its defaults, and the unmodified TLE and a good track read."""
    from leolink.io.tle import read_tle_file
    from leolink.io.tracks import read_track_csv

    assert ("link", "bandwidth_hz") in KEYS and ("terminal.upa", "n_x") in KEYS
    assert load_config(_file(tomli_w.dumps(_nest([(("link", "ptx_dbw"), 12.0)])), ".toml"))
    assert len(read_tle_file(_file("\n".join(iss_lines()) + "\n", ".tle"))) == 1
    text = "time_s,lat_deg,lon_deg,alt_m\n0,42,-8,0\n10,42.1,-8,0\n"
    assert len(read_track_csv(_file(text, ".csv"))) == 1


def _bound_cases():
    """``(key, value, extra overrides)`` at every bound of every numeric key of the
    sections and of every kind's table (the kind chosen), just inside open bounds."""
    model, cases = config_model(), []
    for name, info in model.model_fields.items():
        ann = info.annotation
        if not (isinstance(ann, type) and issubclass(ann, BaseModel)) or name == "output":
            continue
        tables = [(name, ann, [])]
        for key, sub in ann.model_fields.items():
            inner = sub.annotation
            if isinstance(inner, type) and issubclass(inner, BaseModel):
                choose = [f"{name}.{ann.selector}={key!r}"] if hasattr(ann, "selector") else []
                tables.append((f"{name}.{key}", inner, choose))
        for prefix, table, choose in tables:
            for key, sub in table.model_fields.items():
                meta = [*sub.metadata]
                for arg in typing.get_args(sub.annotation):
                    meta += getattr(arg, "metadata", [])
                for m in meta:
                    for kind in ("gt", "ge", "lt", "le"):
                        bound = getattr(m, kind, None)
                        if isinstance(bound, int | float) and not isinstance(bound, bool):
                            nudge = {"gt": 1, "lt": -1}.get(kind, 0) * max(abs(bound), 1) * 1e-9
                            value = bound + nudge if isinstance(bound, float) or nudge else bound
                            cases.append((f"{prefix}.{key}", value, choose))
    return cases


BOUND_CASES = _bound_cases()


def test_every_numeric_bound_builds_or_says_why():
    """The bounds are physical: a config at any of them builds as ``validate`` builds it
    (or is refused by a cross-key rule in one line), never an overflow (exit 3)."""
    from leolink.app.validate import checked_scenario

    assert len(BOUND_CASES) > 80  # 88 when written: every section and kind table
    for key, value, choose in BOUND_CASES:
        cfg = _one_line_or_success(
            load_config, PAPER, [*FAST, "run.duration_s=2", *choose, f"{key}={value!r}"]
        )
        if cfg is not None:
            _one_line_or_success(checked_scenario, cfg)
