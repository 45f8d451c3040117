"""Issue 49: limits at the edge. Each bad input is refused with one line naming the key (or
the file and line) and exit 2, never an internal error (exit 3); ``validate`` says exactly
what ``run`` says and nothing is written. The corpus is :data:`BAD_INPUTS` (configs) and
:data:`BAD_STUDIES` (sweep and compare arguments)."""

from __future__ import annotations

import os
import re

import pytest

from leolink.app.guard import out_of_memory
from leolink.cli import EXIT_USAGE
from reliability_helpers import FAST, PAPER, TLE_CONFIG, cli, files_in

DIGITS = "1" * 5000  # over Python's 4,300-digit limit for integer text


def _deep_toml(tmp_path):
    path = tmp_path / "deep.toml"
    path.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    return path, []


def _big_int_toml(tmp_path):
    path = tmp_path / "big.toml"
    text = PAPER.read_text(encoding="utf-8")
    path.write_text(text + f"\n[kpi]\nping_pong_s = {DIGITS}\n", encoding="utf-8")
    return path, []


def _wide_track(tmp_path):
    path = tmp_path / "wide.csv"
    path.write_text(f"time_s,lat_deg,lon_deg,alt_m\n0,{'1' * 140_000},3,0\n", encoding="utf-8")
    population = f"population=[{{kind = 'track', name = 't', track_file = {str(path)!r}}}]"
    return PAPER, [population]


def _duplicate_column_track(tmp_path):
    path = tmp_path / "twice.csv"
    path.write_text("time_s,lat_deg,lon_deg,alt_m,lat_deg\n0,1,2,0,3\n", encoding="utf-8")
    population = f"population=[{{kind = 'track', name = 't', track_file = {str(path)!r}}}]"
    return PAPER, [population]


def _sets_only(*overrides, config=PAPER):
    return lambda tmp_path: (config, list(overrides))


ONE_UT = "population=[{kind = 'static', name = 'one', placement = 'center'}]"
#: 47 beams (O = 2) for the paper's 15 RF chains, lit by a hopping pattern.
HOPPING = ["satellite_array.oversampling=2.0", "satellite_array.active_beams='hopping'"]

# (id, config and overrides as a function of tmp_path, message regex)
BAD_INPUTS = [
    (
        "trace_format_twice",
        _sets_only('output.trace.formats=["csv", "csv"]'),
        r"output\.trace\.formats: give each format once",
    ),  # fmt: skip
    (
        "internal_source_key",
        _sets_only('source="elsewhere.toml"'),
        r"paper\.toml: source is not a known key",
    ),  # fmt: skip
    (
        "set_with_trailing_toml",
        _sets_only("run.seed=5\nsource = 1"),
        r"--set 'run\.seed=5\\nsource = 1' is not allowed: give one value",
    ),  # fmt: skip
    (
        "track_column_twice",
        _duplicate_column_track,
        r"twice\.csv: line 1: column 'lat_deg' appears twice",
    ),  # fmt: skip
    (
        "report_ut_5_of_one",
        _sets_only(ONE_UT, "output.report.enabled=true", "output.report.uts=[5]"),
        r"output\.report\.uts = \[5\] is not allowed; UT ids of this run are 0 to 0",
    ),
    ("toml_nested_5000_deep", _deep_toml, r"deep\.toml: tables or arrays nested more than 32"),
    (
        "toml_integer_5000_digits",
        _big_int_toml,
        r"big\.toml: an integer of more than 4,300 "
        r"digits \(line \d+\)",
    ),  # fmt: skip
    (
        "set_integer_5000_digits",
        _sets_only(f"run.seed={DIGITS}"),
        r"--set run\.seed: an integer of more than 4,300 digits is not allowed",
    ),  # fmt: skip
    (
        "set_nested_5000_deep",
        _sets_only("run.seed=" + "[" * 5000 + "]" * 5000),
        r"--set run\.seed: tables or arrays nested more than 32 deep",
    ),  # fmt: skip
    (
        "track_csv_field_140000_chars",
        _wide_track,
        r"wide\.csv: line 2: not a CSV line that leolink reads \(field larger than field limit",
    ),
    (
        "hopping_16_beams_for_15_chains",
        _sets_only(*HOPPING, "satellite_array.hopping.pattern=[" + str(list(range(16))) + "]"),
        r"hopping\.pattern\[0\] = \[0, 1, .*, 15\] is not allowed: 16 beams for n_rf = 15",
    ),
    (
        "hopping_repeated_beam_id",
        _sets_only(*HOPPING, "satellite_array.hopping.pattern=[[3], [0, 0, 1]]"),
        r"hopping\.pattern\[1\] = \[0, 0, 1\] is not allowed: give each beam id once",
    ),
    (
        "filter_reference_period_1e-300",
        _sets_only("controller.filter.reference_period_s=1e-300"),
        r"controller\.filter\.reference_period_s = 1e-300 is not allowed: input should be "
        r"greater than or equal to 0\.001",
    ),
    (
        "rlf_t310_1e300",
        _sets_only("controller.rlf.enabled=true", "controller.rlf.t310_s=1e300"),
        r"controller\.rlf\.t310_s = 1e\+300 is not allowed: input should be less than or "
        r"equal to 6 ",
    ),
    (
        "reuse_colors_float",
        _sets_only("link.reuse_colors=3.0"),
        r"link\.reuse_colors = 3\.0 is not allowed: input should be a whole number",
    ),
    (
        "start_year_0001",
        _sets_only("run.start_utc='0001-01-01T00:00:00Z'"),
        r"run\.start_utc = '0001-01-01T00:00:00Z' is not allowed: use a date in the years "
        r"1900 to 2100",
    ),
    (
        "tle_file_5000_chars",
        _sets_only(f"constellation.tle_file='{'a' * 5000}'", config=TLE_CONFIG),
        r"constellation\.tle_file = 'a{40}'\.\.\. \(5,000 characters\) is not allowed",
    ),
]


@pytest.mark.parametrize(("case", "build", "pattern"), BAD_INPUTS, ids=[b[0] for b in BAD_INPUTS])
def test_validate_and_run_refuse_a_bad_input_alike(case, build, pattern, tmp_path, capsys):
    config, overrides = build(tmp_path)
    out = tmp_path / "out"
    _refused_alike(capsys, config, overrides, out, pattern)
    assert files_in(out) == []


def _refused_alike(capsys, config, overrides, out, pattern):
    """``validate`` and ``run`` (into ``out``) both exit 2 with the same one line."""
    sets = [a for o in [*FAST, *overrides] for a in ("--set", o)]
    code_v, _, err_v = cli(capsys, "validate", config, *sets)
    code_r, _, err_r = cli(capsys, "run", config, *sets, "--out", out, "--quiet")
    assert code_v == code_r == EXIT_USAGE, (err_v, err_r)
    assert err_v == err_r and err_v.count("\n") == 1 and err_v.startswith("leolink: error: ")
    assert re.search(pattern, err_v), err_v


# (variable, value, message regex): the environment is checked before --out is made.
BAD_ENVIRONMENTS = [
    ("LEOLINK_JIT", "maybe", r"LEOLINK_JIT = 'maybe' is not allowed: use 1 .* or 0"),
    ("LEOLINK_THREADS", "0", r"LEOLINK_THREADS = '0' is not allowed: a whole number >= 1"),
    ("LEOLINK_THREADS", "-3", r"LEOLINK_THREADS = '-3' is not allowed"),
]


@pytest.mark.parametrize(("name", "value", "pattern"), BAD_ENVIRONMENTS)
def test_validate_and_run_refuse_a_bad_environment_alike(
    name, value, pattern, tmp_path, capsys, monkeypatch
):
    from leolink import compiled

    monkeypatch.setenv(name, value)
    monkeypatch.setattr(compiled, "n_threads", compiled.n_threads.__wrapped__)  # no cache
    out = tmp_path / "out"
    _refused_alike(capsys, PAPER, [], out, pattern)
    assert not out.exists()  # not even an empty folder


def test_threads_are_capped_at_the_cpus(monkeypatch):
    from leolink import compiled

    cpus = len(os.sched_getaffinity(0))
    for asked, threads in [("1", 1), ("100000", cpus), ("1" * 5000, cpus), (str(cpus), cpus)]:
        monkeypatch.setenv("LEOLINK_THREADS", asked)
        assert compiled.n_threads.__wrapped__() == threads, asked


def test_jit_words(monkeypatch):
    from leolink import compiled

    for word in ["0", "off", "No", " false "]:
        monkeypatch.setenv("LEOLINK_JIT", word)
        assert compiled.enabled.__wrapped__() is False, word
    for word in ["1", "ON", "yes", "true"]:
        monkeypatch.setenv("LEOLINK_JIT", word)
        compiled.check_environment()  # accepted (numba's presence decides the rest)


# (id, command line after the config, message regex)
BAD_STUDIES = [
    (
        "dask_without_address",
        ["sweep", "--param", "link.ptx_dbw=1,2", "--workers", "dask://"],
        r"--workers 'dask://' is not allowed; use dask://HOST:PORT",
    ),  # fmt: skip
    (
        "dask_colons",
        ["sweep", "--param", "link.ptx_dbw=1,2", "--workers", "dask://::::::"],
        r"--workers 'dask://::::::' is not allowed",
    ),  # fmt: skip
    (
        "dask_port_not_a_number",
        ["compare", "--policy", "a3", "--workers", "dask://h:x"],
        r"--workers 'dask://h:x' is not allowed",
    ),  # fmt: skip
    (
        "compare_seeds_1e11",
        ["compare", "--policy", "a3", "--seeds", "100000000000"],
        r"--seeds 100000000000 x 1 policies makes 100,000,000,000 runs, which is not allowed",
    ),
    (
        "sweep_grid_160000",
        [
            "sweep",
            "--param",
            "link.ptx_dbw=" + ",".join(map(str, range(400))),
            "--param",
            "run.seed=" + ",".join(map(str, range(400))),
        ],
        r"--param link\.ptx_dbw x run\.seed makes 160,000 runs",
    ),  # fmt: skip
    (
        "param_integer_5000_digits",
        ["sweep", "--param", f"run.seed=1,{DIGITS}"],
        r"--param run\.seed: an integer of more than 4,300 digits",
    ),  # fmt: skip
]


@pytest.mark.parametrize(("case", "argv", "pattern"), BAD_STUDIES, ids=[b[0] for b in BAD_STUDIES])
def test_a_bad_study_is_refused_before_any_run(case, argv, pattern, tmp_path, capsys):
    out = tmp_path / "out"
    code, _, err = cli(capsys, argv[0], PAPER, *argv[1:], "--out", out, "--quiet")
    assert code == EXIT_USAGE and err.count("\n") == 1, err
    assert re.search(pattern, err), err
    assert files_in(out) == []


def test_out_of_memory_is_one_line_with_the_size(monkeypatch, capsys):
    import numpy as np

    import leolink.cli as cli_module

    def huge(args):
        return np.empty((2**20, 2**20, 64))  # 512 TiB: numpy refuses it at once

    monkeypatch.setattr(cli_module, "cmd_validate", huge)
    with pytest.raises(MemoryError) as caught:
        huge(None)
    assert out_of_memory(caught.value) == (
        "out of memory (needs about 524288.0 GiB more; reduce UTs/epochs or use --workers)"
    )
    assert out_of_memory(MemoryError()) == "out of memory (reduce UTs/epochs or use --workers)"
    code, _, err = cli(capsys, "validate", PAPER)
    assert code == EXIT_USAGE and err == f"leolink: error: {out_of_memory(caught.value)}\n"


def test_a_byte_order_mark_is_no_part_of_a_config_or_a_track(tmp_path, capsys):
    config = tmp_path / "bom.toml"
    config.write_bytes(b"\xef\xbb\xbf" + PAPER.read_bytes())
    track = tmp_path / "bom.csv"
    track.write_bytes(b"\xef\xbb\xbftime_s,lat_deg,lon_deg,alt_m\n0,1,2,0\n10,1.1,2,0\n")
    population = f"population=[{{kind = 'track', name = 't', track_file = {str(track)!r}}}]"
    code, out, err = cli(capsys, "validate", config, "--set", population)
    assert code == 0 and "valid (1 population" in out, err
