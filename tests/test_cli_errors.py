"""The CLI reports user mistakes as one line ``leolink: error: ...`` with exit code 2.

Also ``leolink validate`` on the paper's config: the Table's ROI (534.1 x 170.5 km) fails
the paper's own coverage condition of Sec. 3.1, the derived 534.1 x 272.4 km one meets it.
"""

import json
import math
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from leolink.cli import EXIT_USAGE, main

ROOT = Path(__file__).resolve().parents[1]
PAPER = str(ROOT / "configs" / "paper.toml")
DATA = Path(__file__).resolve().parent / "data"

# (id, argv after "validate", text the one error line must contain)
MISTAKES = [
    ("missing_file", ["nope/missing.toml"], "missing.toml' does not exist"),
    ("bad_toml", [str(DATA / "config_invalid_syntax.toml")], "not valid TOML"),
    ("unknown_top_key", [PAPER, "--set", "foo=1"], "foo is not a known key"),
    ("unknown_key", [PAPER, "--set", "link.bandwith_hz=1"], "link.bandwith_hz is not a known"),
    ("wrong_type", [PAPER, "--set", 'link.freq_hz="high"'], "link.freq_hz = 'high'"),
    ("negative_alt", [PAPER, "--set", "constellation.altitude_m=-1"], "altitude_m = -1"),
    ("zero_bandwidth", [PAPER, "--set", "link.bandwidth_hz=0"], "link.bandwidth_hz = 0"),
    (
        "elevation",
        [PAPER, "--set", "constellation.min_elevation_deg=95"],
        "constellation.min_elevation_deg = 95",
    ),
    ("n_x", [PAPER, "--set", "satellite_array.n_x=61"], "satellite_array.n_x = 61"),
    ("terminal", [PAPER, "--set", "terminal.kind=dish"], "terminal.kind = 'dish'"),
    ("policy", [PAPER, "--set", "controller.policy=greedy"], "controller.policy = 'greedy'"),
    ("points", [PAPER, "--set", "population.1.y_m=[0.0]"], "needs x_m and y_m"),
    ("roi_lat", [PAPER, "--set", "roi.center_lat_deg=60"], "roi.center_lat_deg = 60"),
    ("bad_index", [PAPER, "--set", "population.7.count=3"], "population.7.count: index '7'"),
    ("no_equals", [PAPER, "--set", "link.freq_hz"], "--set 'link.freq_hz' is not allowed"),
    (
        "several",
        [str(DATA / "config_several_mistakes.toml")],
        "link.bandwith_hz is not a known key",
    ),
]


def _check_one_error_line(code, err, needle):
    assert code == EXIT_USAGE == 2
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("leolink: error: ")
    assert needle in lines[0]


@pytest.mark.parametrize(
    ("argv", "needle"), [m[1:] for m in MISTAKES], ids=[m[0] for m in MISTAKES]
)
def test_validate_mistake_exits_2_with_one_line(argv, needle, capsys):
    code = main(["validate", *argv])
    out, err = capsys.readouterr()
    _check_one_error_line(code, err, needle)
    assert out == ""


def test_several_mistakes_all_on_the_one_line(capsys):
    code = main(["validate", str(DATA / "config_several_mistakes.toml")])
    _, err = capsys.readouterr()
    _check_one_error_line(code, err, "link.bandwidth_hz = 0.0")
    assert "link.bandwith_hz" in err and "min_elevation_deg = 95.0" in err


# Other subcommands: only mistakes that fail before any physics runs.
OTHER = [
    ("budget", ["--elevation-deg", "30"]),
    ("codebook", []),
    ("coverage", ["--out", "OUT"]),
    ("run", ["--out", "OUT"]),
    ("sweep", ["--out", "OUT", "--param", "link.ptx_dbw=10,15"]),
]


@pytest.mark.parametrize(("command", "extra"), OTHER, ids=[c for c, _ in OTHER])
@pytest.mark.parametrize(
    ("config", "overrides", "needle"),
    [
        ("nope/missing.toml", [], "does not exist"),
        (PAPER, ["--set", "link.bandwith_hz=1"], "link.bandwith_hz is not a known key"),
        (PAPER, ["--set", "population.9.count=1"], "index '9' is not allowed"),
    ],
    ids=["missing_file", "unknown_key", "bad_index"],
)
def test_other_subcommands_reject_bad_config(
    command, extra, config, overrides, needle, tmp_path, capsys
):
    extra = [str(tmp_path / "out") if a == "OUT" else a for a in extra]
    code = main([command, config, *overrides, *extra])
    _, err = capsys.readouterr()
    _check_one_error_line(code, err, needle)
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_real_process_prints_one_line_and_exits_2():
    cmd = [sys.executable, "-m", "leolink.cli", "validate", PAPER, "--set", "link.bandwith_hz=1"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
    _check_one_error_line(proc.returncode, proc.stderr, "link.bandwith_hz is not a known key")
    assert proc.stdout == ""


def test_real_process_validates_paper_config():
    cmd = [sys.executable, "-m", "leolink.cli", "validate", "configs/paper.toml"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert "leaves gaps" in proc.stdout


def _coverage_value(rx_km, ry_km, n_planes=83, n_sats=53, inclination_deg=53.0, radius_km=6371.0):
    """Sec. 3.1: (pi R / N_s / rx)^2 + (pi R sin(i) / N_p / ry)^2, typed from the paper."""
    dx = math.pi * radius_km / n_sats
    dy = math.pi * radius_km * math.sin(math.radians(inclination_deg)) / n_planes
    return (dx / rx_km) ** 2 + (dy / ry_km) ** 2


def test_validate_paper_table_roi_leaves_gaps(capsys):
    assert main(["validate", PAPER]) == 0
    out = capsys.readouterr().out
    value = _coverage_value(534.1, 170.5)
    assert f"{value:.2f}" == "1.78"  # the Table ROI fails the paper's own condition
    assert "534.1 x 170.5 km leaves gaps" in out
    assert f"condition {value:.2f} > 1" in out


def test_validate_derived_roi_covers_but_the_papers_codebook_cannot(capsys):
    """The ROI of Sec. 3.1 closes the coverage condition, but 15 beams of the paper's
    12 x 24 subarrays cannot cover it: validate builds the codebook and says so (it used
    to pass a config that ``run`` refused)."""
    derived = ["--set", "roi.semi_axis_y_m=272400"]
    assert main(["validate", PAPER, *derived]) == 2
    err = capsys.readouterr().err
    assert "gives 21 beams over the 534.1 x 272.4 km ROI, but 15 RF chains" in err
    auto = ["--set", 'satellite_array.oversampling="auto"']
    assert main(["validate", PAPER, *derived, *auto]) == 2
    assert "a codebook without holes needs 21 beams" in capsys.readouterr().err
    holes = ["--set", "satellite_array.allow_holes=true"]
    assert main(["validate", PAPER, *derived, *auto, *holes]) == 0
    out = capsys.readouterr().out
    assert _coverage_value(534.1, 272.4) <= 1.0
    assert "534.1 x 272.4 km covers the Earth" in out
    assert "13 beams for 15 RF chains (2 idle)" in out


def test_the_command_is_console_and_exits_with_mains_code_collector_frozen():
    """The installed ``leolink`` script is :func:`leolink.cli.console`: main's exit code,
    with the collector's objects frozen for the interpreter's teardown (the exit's speed,
    README "Speed")."""
    import tomllib

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["leolink"] == "leolink.cli:console"
    probe = (
        "import atexit, gc, sys\n"
        "atexit.register(lambda: print('frozen', gc.get_freeze_count() > 0))\n"
        "from leolink.cli import console\n"
        "console(sys.argv[1:])\n"
    )
    cmd = [sys.executable, "-c", probe, "validate", PAPER, "--set", "link.bandwith_hz=1"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
    _check_one_error_line(proc.returncode, proc.stderr, "link.bandwith_hz is not a known key")
    assert proc.stdout.strip() == "frozen True"


@pytest.mark.parametrize(
    ("given", "expected"),
    [({}, "1"), ({"OMP_NUM_THREADS": "2"}, None), ({"OPENBLAS_NUM_THREADS": "4"}, "4")],
)
def test_the_command_gives_blas_one_thread_unless_the_environment_says(given, expected):
    """OpenBLAS's idle threads spin on the cores leolink's kernels use (README "Speed"):
    ``console`` sets ``OPENBLAS_NUM_THREADS=1`` before numpy loads, and leaves a count the
    user chose (by any of the variables BLAS reads) alone."""
    from leolink.compiled import BLAS_THREAD_VARIABLES

    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    probe = (  # (numpy is not loaded yet when console starts: OpenBLAS reads it then)
        "import atexit, os, sys\n"
        "atexit.register(lambda: print('blas', os.environ.get('OPENBLAS_NUM_THREADS')))\n"
        "from leolink.cli import console\n"
        "assert 'numpy' not in sys.modules\n"
        "console(sys.argv[1:])\n"
    )
    cmd = [sys.executable, "-c", probe, "validate", PAPER]
    proc = subprocess.run(
        cmd, capture_output=True, text=True, timeout=120, cwd=ROOT, env=env | given
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1].split() == ["blas", str(expected)]


def _console(probe, *args, env=None):
    base = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # as a shell's
    cmd = [sys.executable, "-c", probe, *args]
    return subprocess.run(
        cmd, capture_output=True, text=True, timeout=120, cwd=ROOT, env=base | (env or {})
    )


def test_the_command_ends_with_its_output_whole_and_its_threads_done(tmp_path):
    """console ends the process with Python's own exit: buffered output reaches a pipe,
    exit functions run (test above), and a thread still running
    (here one that finishes a file after main returned) is waited for as Python would."""
    probe = "import sys\nfrom leolink.cli import console\nconsole(sys.argv[1:])\n"
    proc = _console(probe, "budget", PAPER, "--elevation-deg", "70", "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["elevation_deg"] == 70.0
    done = tmp_path / "done"
    late = (
        "import sys, threading, time\n"
        "def finish():\n"
        "    time.sleep(0.3)\n"
        f"    open({str(done)!r}, 'w').write('ok')\n"
        "threading.Thread(target=finish).start()\n"
        "from leolink.cli import console\n"
        "console(sys.argv[1:])\n"
    )
    proc = _console(late, "validate", PAPER, "--set", "link.bandwith_hz=1")
    assert proc.returncode == 2, proc.stderr
    assert done.read_text() == "ok"


CONSOLE = "import sys\nfrom leolink.cli import console\nconsole(sys.argv[1:])\n"


def test_the_command_says_when_its_output_could_not_be_written():
    """A full disk under a redirection (/dev/full): one line and the environment's exit
    code, not a silent success; a closed standard output (>&-) is no error."""
    cmd = f"exec {shlex.quote(sys.executable)} -c {shlex.quote(CONSOLE)} validate {PAPER}"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    full = subprocess.run(["sh", "-c", cmd + " > /dev/full"], capture_output=True,
                          text=True, timeout=120, cwd=ROOT, env=env)  # fmt: skip
    _check_one_error_line(full.returncode, full.stderr, "cannot write the standard output")
    closed = subprocess.run(["sh", "-c", cmd + " >&-"], capture_output=True, text=True,
                            timeout=120, cwd=ROOT, env=env)  # fmt: skip
    assert (closed.returncode, closed.stderr) == (0, "")


def test_a_profiler_gets_the_commands_end(tmp_path):
    """Under ``python -m cProfile -o FILE`` the process ends as Python's does, so the
    profiler writes its file."""
    out = tmp_path / "run.prof"
    cmd = [sys.executable, "-m", "cProfile", "-o", str(out), "-m", "leolink.cli", "validate",
           str(PAPER)]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert out.stat().st_size > 0


def test_the_command_builds_its_models_as_a_library_does():
    """No deferred pydantic builds (issue 43: not thread-safe, no measurable gain): the
    command's models are built when made, whatever the environment says."""
    probe = (
        "import atexit, sys\n"
        "def report():\n"
        "    from leolink.registry import Params\n"
        "    print('deferred', Params.model_config.get('defer_build', False))\n"
        "atexit.register(report)\n" + CONSOLE
    )
    proc = _console(probe, "validate", PAPER, env={"LEOLINK_MODELS_ON_FIRST_USE": "1"})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1] == "deferred False"
