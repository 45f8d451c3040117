"""Issue 49: every stop is clean at any point. SIGINT, SIGTERM, SIGHUP (a closed terminal),
SIGXCPU (``RLIMIT_CPU``) and a second Ctrl-C, each at observable points of a real run
(its output folder locked; its sinks streaming): exit code 128 + the signal's number,
one line and no traceback, no ``*.partial`` file, no lock file left."""

from __future__ import annotations

import signal
import sys

import pytest

from reliability_helpers import files_in
from test_signals import LONG_RUN, PAPER, WAIT_S, _partials, _sets, _start, _wait_for

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="POSIX signals")
STOPS = ["SIGINT", "SIGTERM", "SIGHUP", "SIGXCPU"]


def _locked(out):
    return lambda: (out / ".leolink.lock").exists()


def _streaming(out):
    return lambda: len(_partials(out)) >= 3  # trace.csv, events.csv, events.parquet


def _stopped(tmp_path, point, signals):
    out = tmp_path / "run"
    proc = _start("run", PAPER, *_sets(LONG_RUN), "--out", out, "--quiet")
    _wait_for(point(out), point.__name__)
    for name in signals:
        proc.send_signal(getattr(signal, name))
    _, err = proc.communicate(timeout=WAIT_S)
    return proc.returncode, err, out


@pytest.mark.parametrize("point", [_locked, _streaming])
@pytest.mark.parametrize("name", STOPS)
def test_each_stop_signal_is_clean_at_each_point(tmp_path, name, point):
    code, err, out = _stopped(tmp_path, point, [name])
    assert code == 128 + getattr(signal, name), err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"leolink: stopped by {name}: "), err
    assert _partials(out) == [] and ".leolink.lock" not in files_in(out)
    assert "run.json" not in files_in(out)


def test_a_second_ctrl_c_does_not_interrupt_the_cleanup(tmp_path):
    code, err, out = _stopped(tmp_path, _streaming, ["SIGINT", "SIGINT"])
    assert code == 130, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert _partials(out) == [] and files_in(out) == []


@pytest.mark.parametrize("name", STOPS)
def test_a_stop_before_the_command_starts_is_one_line(name):
    """Between the console script's start and the command's own handlers (imports, the
    parser): one line and 128 + N, not a KeyboardInterrupt traceback, never lost (a run
    stopped there went on for minutes)."""
    import subprocess

    code = (
        "import os, signal, time; from leolink.cli import _exit_on_stop_signals; "
        f"_exit_on_stop_signals(); os.kill(os.getpid(), signal.{name}); time.sleep(30)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 128 + getattr(signal, name), proc.stderr
    assert proc.stderr == f"leolink: stopped by {name} before the command started\n"
