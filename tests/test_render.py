"""Pictures drawn in forked children (:mod:`leolink.io.render`): the same bytes as drawn
in the run's own process, errors re-raised in the run, and a stopped run or job leaves no
temporary file and no child behind."""

from __future__ import annotations

import json
import os
import re
import signal
import sys
import time

import numpy as np
import pytest

from leolink import compiled
from leolink.config import load_config
from leolink.errors import LeolinkError
from leolink.io import plots, render
from leolink.io.atomic import PendingFiles
from reliability_helpers import PAPER, ROOT, files_in
from test_signals import _alive, _children, _kill_left, _start, _wait_for

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="fork: Linux and macOS")
#: A short pass with every picture: plots, report page and animation.
SHORT = ["run.duration_s=40", "output.report.max_frames=8"]


def _run(tmp_path, name, monkeypatch, fork):
    from leolink.app.run import run

    monkeypatch.setenv("LEOLINK_FORK", "1" if fork else "0")
    out = tmp_path / name
    run(load_config(PAPER, overrides=SHORT), out)
    return out


def _without_wall_time(path):
    """A file's bytes; summary.json and report.html without the run's wall time."""
    data = path.read_bytes()
    if path.name == "summary.json":
        summary = json.loads(data)
        summary["run"].pop("wall_time_s")
        return json.dumps(summary).encode()
    if path.name == "report.html":
        data = re.sub(rb'<p class="meta">[^<]*</p>', b"", data)  # run time and date
        return re.sub(rb"<td>wall_time_s</td><td>[^<]*</td>", b"", data)
    return data


def test_the_pictures_drawn_in_children_are_the_bytes_drawn_in_process(tmp_path, monkeypatch):
    inline = _run(tmp_path, "inline", monkeypatch, fork=False)
    forked = _run(tmp_path, "forked", monkeypatch, fork=True)
    names = files_in(inline)
    assert names == files_in(forked)
    pictures = {"snr_time.png", "footprint.gif", "report.html", "dwell_hist.png"}
    assert pictures <= set(names)
    for name in names:
        if name != "run.json":  # its hashes follow summary.json's wall time
            assert _without_wall_time(inline / name) == _without_wall_time(forked / name), name
    manifest = {e["path"] for e in json.loads((forked / "run.json").read_text())["files"]}
    assert manifest == set(names) - {"run.json"}


def test_a_job_gives_its_value_and_its_error(monkeypatch):
    monkeypatch.setenv("LEOLINK_FORK", "1")
    parent = os.getpid()
    job = render.start("a value", lambda n: {"pid": os.getpid(), "x": np.arange(n)}, 5)
    value = job.result()
    assert value["pid"] != parent  # computed in a child
    np.testing.assert_array_equal(value["x"], np.arange(5))
    assert job.result() is value  # collected once

    def fails():
        raise ValueError("no such beam: 17")

    with pytest.raises(ValueError, match="no such beam: 17"):
        render.start("a failure", fails).result()


def test_an_error_that_cannot_be_pickled_arrives_as_its_text(monkeypatch):
    monkeypatch.setenv("LEOLINK_FORK", "1")

    class Local(Exception):  # a local class: pickle cannot find it by name
        pass

    def fails():
        raise Local("drawn badly")

    with pytest.raises(LeolinkError, match="Local: drawn badly"):
        render.start("a failure", fails).result()


def test_a_killed_child_is_an_error_that_says_so(monkeypatch):
    monkeypatch.setenv("LEOLINK_FORK", "1")
    job = render.start("a killed job", time.sleep, 60)
    os.kill(job._pid, signal.SIGKILL)
    with pytest.raises(LeolinkError, match=r"a killed job: .*killed by signal 9"):
        job.result()


def test_without_fork_the_job_runs_at_start_in_this_process(monkeypatch):
    monkeypatch.setenv("LEOLINK_FORK", "0")
    assert not render.forking()
    job = render.start("inline", os.getpid)
    assert job._pid is None and job.result() == os.getpid()


def test_cancel_stops_the_child_and_removes_its_temporary_file(tmp_path, monkeypatch):
    monkeypatch.setenv("LEOLINK_FORK", "1")

    def draws_slowly():
        with PendingFiles() as pending:
            pending.open(tmp_path / "slow.png").write(b"half a picture")
            time.sleep(60)

    job = render.start("a slow picture", draws_slowly)
    pid = job._pid
    _wait_for(lambda: any(".partial" in f for f in files_in(tmp_path)), "the partial file")
    job.cancel()
    assert not _alive(pid)
    assert files_in(tmp_path) == []  # the child's atomic writer removed it
    with pytest.raises(LeolinkError, match="a slow picture: stopped"):
        job.result()


def test_a_child_splits_kernel_calls_over_its_own_threads(monkeypatch):
    """The parent's kernel thread pool has no thread in a forked child: the child starts
    its own (the pool is dropped at fork), instead of waiting forever on the parent's."""
    monkeypatch.setenv("LEOLINK_FORK", "1")
    monkeypatch.setenv("LEOLINK_THREADS", "2")
    compiled.n_threads.cache_clear()
    monkeypatch.setattr(compiled, "SPLIT_MIN_ROWS", 4)

    def fill(out, lo, hi):
        out[lo:hi] = np.arange(lo, hi)

    def split():
        out = np.zeros(64)
        compiled.run_rows(fill, 64, out)
        return out

    def deadlocked(signum, frame):
        raise TimeoutError("the child waits on the parent's kernel threads")

    previous = signal.signal(signal.SIGALRM, deadlocked)
    try:
        np.testing.assert_array_equal(split(), np.arange(64))  # the parent's pool starts
        signal.alarm(30)  # a deadlocked child would hang the suite: fail instead
        np.testing.assert_array_equal(render.start("split", split).result(), np.arange(64))
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
        compiled.n_threads.cache_clear()


def test_a_failing_picture_fails_the_run_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    from leolink.app.run import run

    monkeypatch.setenv("LEOLINK_FORK", "1")

    def broken(*args, **kwargs):
        raise RuntimeError("the SNR panel cannot be drawn")

    monkeypatch.setattr(plots, "_snr_time", broken)  # inherited by the forked child
    out = tmp_path / "run"
    with pytest.raises(RuntimeError, match="the SNR panel cannot be drawn"):
        run(load_config(PAPER, overrides=SHORT), out)
    left = files_in(out)
    assert not [f for f in left if ".partial" in f]
    assert "run.json" not in left and "snr_time.png" not in left


def test_an_error_after_the_run_stops_the_children(tmp_path, monkeypatch):
    """The pictures are still drawn when summary.json fails to be written: the run stops
    its children (their temporary files removed) and raises the error."""
    from leolink.app import run as app_run

    monkeypatch.setenv("LEOLINK_FORK", "1")
    pids = []
    fork = os.fork

    def counted_fork():
        pid = fork()
        if pid:
            pids.append(pid)
        return pid

    def no_space(path, obj):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(os, "fork", counted_fork)
    monkeypatch.setattr(app_run, "write_json_atomic", no_space)
    out = tmp_path / "run"
    with pytest.raises(OSError, match="No space left"):
        app_run.run(load_config(PAPER, overrides=SHORT), out)
    assert len(pids) == 3  # plots, animation, page figures
    assert not [p for p in pids if _alive(p)]
    assert not [f for f in files_in(out) if ".partial" in f]


@pytest.mark.skipif(sys.platform != "linux", reason="/proc")
def test_sigterm_while_the_pictures_are_drawn_stops_them_cleanly(tmp_path):
    out = tmp_path / "run"
    sets = ["run.duration_s=600", "output.report.max_frames=600"]
    argv = [a for s in sets for a in ("--set", s)]
    proc = _start("run", PAPER, *argv, "--out", out, "--quiet")
    kids = []
    try:
        _wait_for(lambda: (out / "report_stats.npz").exists(), "the end of the simulation")
        _wait_for(lambda: len(_children(proc.pid)) >= 2, "the drawing children")
        kids = _children(proc.pid)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        _kill_left([proc.pid, *kids])
    assert proc.returncode == 143, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("leolink: stopped by SIGTERM"), err
    assert f"{out} has no run.json" in lines[0]
    assert not [k for k in kids if _alive(k)]
    left = files_in(out)
    assert not [f for f in left if ".partial" in f], left
    assert "run.json" not in left and "footprint.gif" not in left


_ORPHAN = """
import sys, time
from pathlib import Path
from leolink.io import render
from leolink.io.atomic import PendingFiles

def slow(folder):
    with PendingFiles() as pending:
        pending.open(Path(folder) / "slow.png").write(b"half a picture")
        time.sleep(60)

job = render.start("a slow picture", slow, sys.argv[1])
print(job._pid, flush=True)
time.sleep(60)
"""


@pytest.mark.skipif(sys.platform != "linux", reason="prctl(PR_SET_PDEATHSIG)")
def test_a_child_stops_cleanly_when_the_run_is_killed(tmp_path):
    """SIGKILL of the run's process (no cleanup of its own): the kernel sends its drawing
    child SIGTERM, and the child removes its temporary file."""
    import subprocess

    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "LEOLINK_FORK": "1"}
    cmd = [sys.executable, "-c", _ORPHAN, str(tmp_path)]
    parent = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
    child = None
    try:
        child = int(parent.stdout.readline())
        _wait_for(lambda: any(".partial" in f for f in files_in(tmp_path)), "the partial file")
        parent.kill()
        parent.wait(timeout=30)
        _wait_for(lambda: not _alive(child), "the child to stop")
    finally:
        _kill_left([parent.pid] + ([child] if child else []))
    assert files_in(tmp_path) == []
