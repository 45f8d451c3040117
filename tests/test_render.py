"""Pictures drawn in the run's own process (the sinks' ``finish``, issues 43 and 49):
no fork, errors re-raised in the run, and a failed run leaves no temporary file."""

from __future__ import annotations

import os

import pytest

from leolink.config import load_config
from leolink.io import plots
from reliability_helpers import PAPER, files_in

#: A short pass with every picture: plots, report page and animation.
SHORT = ["run.duration_s=40", "output.report.max_frames=8"]


def test_a_run_with_every_picture_never_forks(tmp_path, monkeypatch):
    from leolink.app.run import run

    def no_fork():
        raise AssertionError("leolink forked")

    monkeypatch.setattr(os, "fork", no_fork)
    out = tmp_path / "run"
    run(load_config(PAPER, overrides=SHORT), out)
    assert {"snr_time.png", "footprint.gif", "report.html", "run.json"} <= set(files_in(out))


def test_a_failing_picture_fails_the_run_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    from leolink.app.run import run

    def broken(*args, **kwargs):
        raise RuntimeError("the SNR panel cannot be drawn")

    monkeypatch.setattr(plots, "_snr_time", broken)
    out = tmp_path / "run"
    with pytest.raises(RuntimeError, match="the SNR panel cannot be drawn"):
        run(load_config(PAPER, overrides=SHORT), out)
    left = files_in(out)
    assert not [f for f in left if ".partial" in f]
    assert "run.json" not in left and "snr_time.png" not in left


def test_an_error_after_the_pictures_leaves_no_temporary_file(tmp_path, monkeypatch):
    from leolink.app import run as app_run

    def no_space(path, obj):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(app_run, "write_json_atomic", no_space)
    out = tmp_path / "run"
    with pytest.raises(OSError, match="No space left"):
        app_run.run(load_config(PAPER, overrides=SHORT), out)
    assert not [f for f in files_in(out) if ".partial" in f]
