"""Issue 19: ``validate`` means ``run``, and a clear word for every bad input.

Every case asserts the exit code, the message (one line naming the key or the file and
line, never a file's content) and the files left (none: a refused run writes nothing).
``validate`` and ``run`` are run on every example config and on every broken one, and
must agree: both succeed, or both fail with the same line.
"""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

from leolink.cli import EXIT_USAGE
from leolink.config import load_config
from reliability_helpers import (
    FAST,
    PAPER,
    ROOT,
    SYSTEM_LINE,
    TLE_CONFIG,
    cli,
    decayed_tle,
    eccentric_tle,
    files_in,
    garbage_field_tle,
)

EXAMPLES = sorted([*ROOT.glob("configs/*.toml"), *ROOT.glob("configs/examples/*.toml")])


def _short(config):
    """Overrides that keep a run of ``config`` to two epochs, without plots and report."""
    epoch = load_config(config).run.epoch_s
    return [*FAST, "run.warmup_s=0", f"run.duration_s={2 * epoch!r}"]


def _sets(overrides):
    return [a for o in overrides for a in ("--set", o)]


@pytest.mark.parametrize("config", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_validate_and_run_agree_on_every_example(config, tmp_path, capsys):
    sets = _sets(_short(config))
    code_v, _, err_v = cli(capsys, "validate", config, *sets)
    code_r, _, err_r = cli(capsys, "run", config, *sets, "--out", tmp_path / "o", "--quiet")
    assert (code_v, err_v) == (0, "")
    assert code_r == 0 and "error" not in err_r
    assert "run.json" in files_in(tmp_path / "o")


def _tle_file(tmp_path, text, name="sat.tle", binary=False):
    path = tmp_path / name
    path.write_bytes(text) if binary else path.write_text(text, encoding="utf-8")
    return [f"constellation.tle_file={str(path)!r}"]


def _waypoints(rows):
    return [f"population=[{{kind = 'waypoints', name = 'w', waypoints = {rows}}}]"]


# (id, config, overrides (or a function of tmp_path giving them), message regex)
BROKEN = [
    (
        "derived_roi",
        None,
        ["roi.semi_axis_y_m=derived"],
        r"oversampling = 1\.2 gives 21 beams .* 15 RF chains",
    ),
    (
        "decayed_tle",
        TLE_CONFIG,
        lambda t: [*_tle_file(t, decayed_tle()), "run.start_utc='2019-12-10T16:38:29Z'"],
        r"tle_file = .*sat\.tle.*: sgp4 cannot propagate any of its 1 satellite.*'SAT' first "
        r"at t = 0\.0 s \(sgp4 error 6: mrt is less than 1\.0",
    ),
    (
        "eccentric_tle",
        TLE_CONFIG,
        lambda t: _tle_file(t, eccentric_tle()),
        r"sgp4 cannot propagate any of its 1 satellite.*sgp4 error 4: semilatus rectum",
    ),
    (
        "far_epoch_decaying_tle",  # propagated 5 days past its epoch: error 1
        TLE_CONFIG,
        lambda t: [*_tle_file(t, decayed_tle()), "run.start_utc='2019-12-14T16:37:29Z'"],
        r"sgp4 cannot propagate any of its 1 satellite.*sgp4 error [16]",
    ),
    ("empty_tle_file", TLE_CONFIG, lambda t: _tle_file(t, ""), r"sat\.tle: no TLE in the file"),
    (
        "non_utf8_tle",
        TLE_CONFIG,
        lambda t: _tle_file(t, b"\xff\xfe garbage\n", binary=True),
        r"TLE file '.*sat\.tle' is not UTF-8 text \(byte 0\)",
    ),
    (
        "garbage_tle_field_valid_checksum",
        TLE_CONFIG,
        lambda t: _tle_file(t, garbage_field_tle()),
        r"sat\.tle:3: TLE line 2, columns 9-16 \(inclination \[deg\]\): not a valid value",
    ),
    (
        "system_file_as_tle",
        TLE_CONFIG,
        lambda t: _tle_file(t, SYSTEM_LINE + "\nbin:x:1:1\ndaemon:x:2:2\n"),
        r"sat\.tle:2: TLE line 1 is malformed",
    ),
    (
        "system_file_as_track",
        PAPER,
        lambda t: [
            f"population=[{{kind = 'track', track_file = {str(_sys(t))!r}}}]",
        ],
        r"passwd: line 1: missing column\(s\) 'time_s', .*found 1 field\(s\) that are not",
    ),
    (
        "missing_track_file",
        PAPER,
        ["population=[{kind = 'track', track_file = '/nonexistent/t.csv'}]"],
        r"population\.0\.track_file = '/nonexistent/t\.csv' does not exist",
    ),
    (
        "waypoint_row_of_two_values",
        PAPER,
        _waypoints("[[0.0, 1.0], [10.0, 42.0, -8.7, 0.0]]"),
        r"population\.0: waypoints row 0 has 2 values; use \[time_s, lat_deg, lon_deg, alt_m\]",
    ),
    (
        "waypoint_latitude_200",
        PAPER,
        _waypoints("[[0.0, 200.0, -8.7, 0.0], [10.0, 42.0, -8.7, 0.0]]"),
        r"waypoints row 0, lat_deg = 200\.0 is not allowed: use \[-90, 90\]",
    ),
    (
        "waypoint_buried_ut",
        PAPER,
        _waypoints("[[0.0, 42.0, -8.7, -1e7], [10.0, 42.0, -8.7, 0.0]]"),
        r"waypoints row 0, alt_m = -10000000\.0 is not allowed: use \[-11000, 100000\]",
    ),
    (
        "tiny_bandwidth",
        PAPER,
        ["link.bandwidth_hz=1e-300"],
        r"link\.bandwidth_hz = 1e-300 is not allowed: input should be greater than or equal to "
        r"1000",
    ),
    ("huge_power", PAPER, ["link.ptx_dbw=1e308"], r"link\.ptx_dbw = 1e\+308 is not allowed"),
    (
        "huge_oversampling",
        PAPER,
        ["satellite_array.oversampling=1e308"],
        r"satellite_array\.oversampling = 1e\+308 is not allowed: input should be less than or "
        r"equal to 100, or input should be 'auto'",
    ),
    (
        "exceedance_99_9",
        PAPER,
        ["atmosphere.model='itu_p618'", "atmosphere.itu_p618.exceedance_percent=99.9"],
        r"atmosphere\.itu_p618\.exceedance_percent = 99\.9 is not allowed: .*less than or "
        r"equal to 5",
    ),
    ("start_1e17", PAPER, ["run.start_s=1e17"], r"run\.start_s = 1e\+17 is not allowed"),
    (
        "epochs_lose_precision",
        PAPER,
        ["run.start_s=3e9", "run.epoch_s=1e-6", "run.duration_s=0.001"],
        r"run\.start_s = 3000000000\.0 is not allowed with run\.epoch_s = 1e-06: epoch times "
        r"near 3e\+09 s are only resolved to 4\.77e-07 s",
    ),
    (
        "epoch_does_not_divide_duration",
        PAPER,
        ["run.epoch_s=3", "run.duration_s=10"],
        r"run\.duration_s = 10\.0 is not allowed: it must be a whole number of epochs "
        r"\(run\.epoch_s"
        r" = 3\.0; 3 epochs give 9 s\)",
    ),
    (
        "bool_for_number",
        PAPER,
        ["satellite_array.oversampling=true"],
        r"satellite_array\.oversampling = True is not allowed: input should be a valid number",
    ),
    ("bool_seed", PAPER, ["run.seed=true"], r"run\.seed = True is not allowed: .*valid integer"),
    (
        "string_for_table",
        PAPER,
        ['output.plots="yes"'],
        r"output\.plots = 'yes' is not allowed",
    ),
    (
        "string_for_number",
        PAPER,
        ['run.epoch_s="1.0"'],
        r"run\.epoch_s = '1\.0' is not allowed: input should be a valid number",
    ),
    (
        "roi_beyond_visible_cap",
        PAPER,
        ["roi.semi_axis_x_m=9e6", "roi.semi_axis_y_m=9e6"],
        r"roi\.semi_axis_x_m = 9000000\.0 is not allowed: it must be at most 2\.988e\+06 m",
    ),
    ("right_key_name", PAPER, ["link.rician_k=-1"], r"^leolink: error: \S+: link\.rician_k = -1 "),
    (
        "smtc_window_longer_than_its_period",
        PAPER,
        [
            "controller.measurement.smtc_period_s=0.02",
            "controller.measurement.smtc_duration_s=0.03",
        ],
        r"controller\.measurement\.smtc_duration_s = 0\.03 is not allowed: use at most",
    ),
    (
        "measurement_model_of_a_policy_without_triggers",
        PAPER,
        ["controller.policy=max_snr", "controller.measurement.error_db=2"],
        r"controller\.measurement\.error_db = 2\.0 is not allowed with controller\.policy = "
        r"'max_snr': the measurement model feeds the 3GPP trigger policies",
    ),
    (
        "d1_points_without_points",
        PAPER,
        ["controller.policy=d1", "controller.d1.reference='points'"],
        r"controller\.d1\.reference = 'points' is not allowed without "
        r"\[\[controller\.reference_points\]\]",
    ),
    (
        "cho_d1_on_cells_of_body_fixed_beams",
        PAPER,
        [
            "controller.policy=cho",
            "controller.cho.release=18",
            "controller.cho.execute=[{kind='d1', reference='cell'}]",
        ],
        r"controller\.cho\.execute\.0\.reference = 'cell' is not allowed with "
        r"satellite_array\.steering = 'body_fixed'",
    ),  # fmt: skip
    (
        "reference_point_of_no_satellite",
        PAPER,
        [
            "controller.policy=d1",
            "controller.d1.reference='points'",
            "controller.reference_points=[{sat_id=5, lat_deg=0, lon_deg=0}]",
        ],
        r"controller\.reference_points\.0\.sat_id = 5 is not allowed: use 0 \.\. 0",
    ),  # fmt: skip
]


def _sys(tmp_path):
    """A copy of a system file's first line under a system-like name."""
    path = tmp_path / "passwd"
    path.write_text(SYSTEM_LINE + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("case", "config", "overrides", "pattern"), BROKEN, ids=[b[0] for b in BROKEN]
)
def test_validate_and_run_agree_on_broken_configs(
    case, config, overrides, pattern, tmp_path, capsys
):
    if config is None:
        config = tmp_path / "empty.toml"
        config.write_text("", encoding="utf-8")
    overrides = overrides(tmp_path) if callable(overrides) else overrides
    sets = _sets([*FAST, *overrides])
    out = tmp_path / "out"
    code_v, _, err_v = cli(capsys, "validate", config, *sets)
    code_r, _, err_r = cli(capsys, "run", config, *sets, "--out", out, "--quiet")
    assert code_v == code_r == EXIT_USAGE, (err_v, err_r)
    assert err_v == err_r, "validate and run must refuse with the same line"
    assert err_v.count("\n") == 1 and err_v.startswith("leolink: error: ")
    assert re.search(pattern, err_v), err_v
    assert SYSTEM_LINE not in err_v and "root:x" not in err_v
    assert files_in(out) == []  # nothing written, not even the folder's files


def test_a_far_tle_is_noted_and_a_failing_satellite_named(tmp_path, capsys):
    """Two satellites, one decayed: the run goes on, the failing one is named (which,
    when, what code); the ISS's TLE 400 days from the run is noted."""
    from reliability_helpers import ISS_TLE

    text = ISS_TLE.read_text(encoding="utf-8") + decayed_tle().replace("SAT", "DEAD")
    day_later = "run.start_utc='2019-12-10T16:38:29Z'"
    sets = _sets([*_short(TLE_CONFIG), *_tle_file(tmp_path, text), day_later])
    code, out, _ = cli(capsys, "validate", TLE_CONFIG, *sets)
    assert code == 0
    assert (
        "satellite 1 of 2 fail in sgp4 at some epochs and serve no UT then: 'DEAD' first at "
        "t = 0.0 s (sgp4 error 6" in out
    )
    code, _, err = cli(capsys, "run", TLE_CONFIG, *sets, "--out", tmp_path / "o", "--quiet")
    assert code == 0 and "note: satellite 1 of 2 fail in sgp4" in err  # shown even if quiet
    far = _sets([*_short(TLE_CONFIG), "run.start_utc='2021-01-12T16:37:29Z'"])
    code, out, _ = cli(capsys, "validate", TLE_CONFIG, *far)
    assert code == 0 and "satellite TLEs are up to 400 days from the run's start" in out


@pytest.mark.parametrize(
    ("argv", "pattern"),
    [
        (["coverage", PAPER, "--grid", "0"], r"--grid 0 is not allowed; use 2\.\.5001"),
        (["coverage", PAPER, "--margin", "nan"], r"--margin nan is not allowed"),
        (["coverage", PAPER, "--margin", "-1"], r"--margin -1\.0 is not allowed"),
    ],
)
def test_coverage_arguments(argv, pattern, tmp_path, capsys):
    out = tmp_path / "cov"
    code, _, err = cli(capsys, *argv, "--out", out)
    assert code == EXIT_USAGE and re.search(pattern, err) and err.count("\n") == 1
    assert files_in(out) == []


def test_codebook_plot_into_a_folder(tmp_path, capsys):
    folder = tmp_path / "plots"
    folder.mkdir()
    code, _, err = cli(capsys, "codebook", PAPER, "--plot", folder)
    assert code == EXIT_USAGE and f"--plot {folder} is a folder; give the path of a PNG" in err
    assert files_in(folder) == []


def test_a_list_valued_param_names_the_point_on_one_line(tmp_path, capsys):
    out = tmp_path / "sw"
    code, _, err = cli(capsys, "sweep", PAPER, "--param", "link.ptx_dbw=[1,2]", "--out", out)
    assert code == EXIT_USAGE and err.count("\n") == 1
    assert (
        "sweep point link.ptx_dbw=[1, 2]: " in err and "link.ptx_dbw = [1, 2] is not allowed" in err
    )
    assert files_in(out) == []


def test_a_failed_sweep_point_is_a_row_and_the_others_run(tmp_path, capsys):
    """One point's codebook cannot be driven (oversampling 1.5 -> too many beams): its row
    has the error, the other point runs; exit 1."""
    out = tmp_path / "sw"
    sets = _sets([*FAST, "run.duration_s=2"])
    code, _, err = cli(
        capsys, "sweep", PAPER, *sets, "--param", "satellite_array.oversampling=auto,1.5",
        "--out", out, "--quiet",
    )  # fmt: skip
    assert code == 1
    pattern = (
        r"1 of 2 sweep points failed .* first: 0001_satellite_array\.oversampling=1\.5: "
        r"sweep point satellite_array\.oversampling=1\.5: .* beams"
    )
    assert re.search(pattern, err), err
    import pandas as pd

    table = pd.read_csv(out / "sweep.csv", keep_default_na=False)
    assert list(table["error"] == "") == [True, False]
    assert "beams" in table["error"][1] and table["snr_db_mean"][1] == ""
    left = files_in(out)
    assert "runs/0000_satellite_array.oversampling=auto/run.json" in left
    assert not [f for f in left if f.startswith("runs/0001")] and "run.json" in left


def test_sweep_never_deletes_an_existing_sweep_csv(tmp_path, capsys):
    out = tmp_path / "sw"
    out.mkdir()
    (out / "sweep.csv").write_text("my own table\n", encoding="utf-8")
    sets = _sets([*FAST, "run.duration_s=2"])
    code, _, err = cli(capsys, "sweep", PAPER, *sets, "--param", "link.ptx_dbw=15", "--out", out)
    assert code == EXIT_USAGE and "rerun with --overwrite (or --resume" in err
    assert (out / "sweep.csv").read_text(encoding="utf-8") == "my own table\n"
    assert files_in(out) == ["sweep.csv"]


def test_sweep_sends_absolute_paths_to_its_workers(tmp_path, monkeypatch, capsys):
    """A relative config (whose track file is relative to it) and a relative --out, from
    another working directory: the jobs carry absolute paths (dask workers have their own
    working directories), and the point runs."""
    import leolink.app.sweep_exec as sweep_exec

    conf = tmp_path / "conf"
    shutil.copytree(ROOT / "configs" / "examples", conf)
    monkeypatch.chdir(tmp_path)
    seen = []
    real = sweep_exec.run_jobs
    monkeypatch.setattr(
        sweep_exec,
        "run_jobs",
        lambda fn, jobs, done, w: seen.extend(jobs) or real(fn, jobs, done, w),
    )
    sets = _sets([*FAST, "run.duration_s=2"])
    code, _, err = cli(capsys, "sweep", "conf/car.toml", *sets, "--param", "run.seed=1",
                       "--out", "sw", "--quiet")  # fmt: skip
    assert code == 0, err
    ((_, (cfg_path, _, run_dir, _)),) = seen
    assert cfg_path == str(conf / "car.toml") and run_dir.startswith(str(tmp_path / "sw"))
    assert "run.json" in files_in(tmp_path / "sw")


def test_a_long_tle_run_is_checked_on_a_sample_of_its_epochs(tmp_path, capsys):
    """30,000 epochs (more than HEALTH_SAMPLES): a regular sample, first and last epoch
    included; the decaying satellite (fine at its epoch, error 6 from ~12 h after it,
    error 1 from 2 days) is found and named."""
    from leolink.app.validate import HEALTH_SAMPLES, _sample
    from reliability_helpers import ISS_TLE

    times = np.arange(30_000) * 10.0
    sample = _sample(times, 2)
    assert len(sample) == HEALTH_SAMPLES and sample[0] == 0.0 and sample[-1] == times[-1]
    assert set(sample) <= set(times)
    text = ISS_TLE.read_text(encoding="utf-8") + decayed_tle().replace("SAT", "DEAD")
    sets = _sets([*FAST, "run.epoch_s=10", "run.duration_s=300000", *_tle_file(tmp_path, text)])
    code, out, err = cli(capsys, "validate", TLE_CONFIG, *sets)
    assert code == 0, err
    found = re.search(r"satellite 1 of 2 fail in sgp4 .*'DEAD' first at t = (\S+) s", out)
    # The onset by sgp4 itself, every second of the run (t = 0 is 60 s before the epoch)
    from sgp4.api import Satrec

    _, l1, l2 = decayed_tle().splitlines()
    sat = Satrec.twoline2rv(l1, l2)
    t = np.arange(0.0, 300_000.0, 1.0)
    err, _, _ = sat.sgp4_array(
        np.full(t.size, sat.jdsatepoch), sat.jdsatepochF + (t - 60.0) / 86400
    )
    onset = t[np.argmax(err != 0)]
    step = 300_000.0 / (HEALTH_SAMPLES - 1)
    assert found and onset <= float(found.group(1)) <= onset + step + 10.0  # one sample late
