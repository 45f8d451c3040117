"""Issue 19: files are never written through a symbolic link, a user's files are never
touched, and errors of the environment are one line with exit 2.

Each case asserts the exit code, the message and the files left (the user's files
byte for byte, no ``*.partial``, no ``run.json`` of an unfinished run).
"""

from __future__ import annotations

import errno
import io
import os
import socket
import time
import warnings

import pytest

from leolink.cli import EXIT_USAGE
from reliability_helpers import FAST, PAPER, cli, files_in

SHORT = [a for o in [*FAST, "run.duration_s=3"] for a in ("--set", o)]
VICTIM_TEXT = "a user's file that leolink must not touch\n"


@pytest.fixture
def victim(tmp_path):
    path = tmp_path / "elsewhere" / "precious.txt"
    path.parent.mkdir()
    path.write_text(VICTIM_TEXT, encoding="utf-8")
    return path


def test_a_planted_partial_symlink_is_not_followed(tmp_path, victim, capsys):
    """``trace.csv.partial`` -> the victim: the writer's temporary files have random names
    and are created with O_EXCL | O_NOFOLLOW; the planted link stays, the victim too."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "trace.csv.partial").symlink_to(victim)
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", out, "--quiet")
    assert code == 0, err
    assert victim.read_text(encoding="utf-8") == VICTIM_TEXT
    assert (out / "trace.csv.partial").is_symlink() and (out / "trace.csv").is_file()
    assert not (out / "trace.csv").is_symlink()


def test_a_symlink_at_the_final_name_is_left_alone_never_followed(tmp_path, victim, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "trace.csv").symlink_to(victim)
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", out, "--quiet")
    assert code == EXIT_USAGE and "holds files of an unfinished leolink run" in err
    assert "rerun with --overwrite" in err and err.count("\n") == 1
    assert files_in(out) == ["trace.csv"] and (out / "trace.csv").is_symlink()
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", out, "--quiet", "--overwrite")
    assert code == EXIT_USAGE and "holds trace.csv, not written by leolink" in err  # issue 49
    assert (out / "trace.csv").is_symlink() and files_in(out) == ["trace.csv"]
    assert victim.read_text(encoding="utf-8") == VICTIM_TEXT


def test_the_temporary_file_is_created_exclusively(tmp_path, victim, monkeypatch):
    """A link planted at the very name the writer picks makes it fail, not follow."""
    import leolink.io.atomic as atomic

    monkeypatch.setattr(atomic.secrets, "token_hex", lambda n: "0" * (2 * n))
    (tmp_path / "x.json.00000000.partial").symlink_to(victim)
    with pytest.raises(FileExistsError):
        atomic.write_json_atomic(tmp_path / "x.json", {"a": 1})
    assert victim.read_text(encoding="utf-8") == VICTIM_TEXT
    assert not (tmp_path / "x.json").exists()


def test_out_that_is_a_file(tmp_path, capsys):
    out = tmp_path / "notes.txt"
    out.write_text("mine\n", encoding="utf-8")
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", out, "--quiet")
    assert (code, err) == (EXIT_USAGE, f"leolink: error: --out {out} is a file; give a folder\n")
    assert out.read_text(encoding="utf-8") == "mine\n"


def test_out_below_a_file(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine\n", encoding="utf-8")
    out = tmp_path / "notes.txt" / "run"
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", out, "--quiet")
    assert code == EXIT_USAGE and err.count("\n") == 1
    assert "a part of the path is a file, not a folder" in err and "notes.txt" in err
    assert (tmp_path / "notes.txt").read_text(encoding="utf-8") == "mine\n"


def test_unwritable_out(capsys):
    """/sys (Linux, as CI) refuses new folders even to root: EPERM or EROFS. (A folder
    without write permission is the same EACCES path for a user other than root.)"""
    out = "/sys/leolink_cannot_write_here"
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", out, "--quiet")
    assert code == EXIT_USAGE and err.count("\n") == 1
    assert err.startswith(f"leolink: error: cannot write {out}: ")
    assert "choose a folder you can write" in err and not os.path.exists(out)


class _FullDisk(io.RawIOBase):
    """A file whose device fills up after ``room`` bytes (``write`` raises ENOSPC)."""

    def __init__(self, real, room):
        self.real, self.room = real, room

    def writable(self):
        return True

    def write(self, data):
        if len(data) > self.room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.room -= len(data)
        return self.real.write(data)

    def close(self):
        self.real.close()
        super().close()


def _assert_no_space_left(capsys, out):
    """A run into ``out`` stops with the one-line ENOSPC message, exit 2, nothing left."""
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", out, "--quiet")
    assert code == EXIT_USAGE and err.count("\n") == 1
    assert err == f"leolink: error: no space left on the device writing {out} (free some " \
        "space or use another --out)\n"  # fmt: skip
    assert [f for f in files_in(out) if ".partial" in f or f == "run.json"] == []


def test_full_disk(tmp_path, monkeypatch, capsys):
    """Every output file gets 4 KiB of room: the trace overflows it mid-run."""
    import leolink.io.atomic as atomic

    real_fdopen = os.fdopen
    monkeypatch.setattr(
        atomic.os, "fdopen", lambda fd, mode: _FullDisk(real_fdopen(fd, mode), room=4096)
    )
    _assert_no_space_left(capsys, tmp_path / "run")


def test_full_disk_under_pyarrows_own_file(tmp_path, monkeypatch, capsys):
    """The trace and event writers write through pyarrow's own file on the partial file
    (``PendingFiles.open_native``, no GIL per write): there the device fills up at once
    (``/dev/full``: every write is ENOSPC, raised by pyarrow, not by Python's file)."""
    import leolink.io.atomic as atomic

    assert os.path.exists("/dev/full")  # Linux's always-full device
    monkeypatch.setattr(atomic, "_reopen_path", lambda handle: "/dev/full")
    _assert_no_space_left(capsys, tmp_path / "run")


def test_a_file_that_does_not_reopen_is_written_through_python(tmp_path, monkeypatch, capsys):
    """Where the partial file cannot be reopened (a sandbox's /proc), the tables are
    written through the Python file: the run's outputs are whole."""
    import leolink.io.atomic as atomic

    monkeypatch.setattr(atomic, "_reopen_path", lambda handle: str(tmp_path / "no" / "such"))
    code, _, err = cli(capsys, "run", PAPER, *SHORT, "--out", tmp_path / "run", "--quiet")
    assert code == 0 and err == ""
    text = (tmp_path / "run" / "trace.csv").read_text()
    assert text.startswith("time_s,") and text.count("\n") > 3


def test_pyarrows_own_file_becomes_the_target_only_on_commit(tmp_path):
    """``open_native`` writes to the partial file itself (reopened through
    ``/proc/self/fd``): nothing at the target before the commit, the bytes after; an
    abort leaves nothing; a file object without a descriptor is given back as it is."""
    import pyarrow as pa

    from leolink.io.atomic import PendingFiles, _reopen_path

    target = tmp_path / "t.bin"
    pending = PendingFiles()
    f = pending.open_native(target)
    assert isinstance(f, pa.NativeFile)
    f.write(b"abc" * 1000)
    partial = [p for p in tmp_path.iterdir() if p.name.endswith(".partial")]
    assert len(partial) == 1 and partial[0].stat().st_size == 3000 and not target.exists()
    assert pending.commit() == [target] and target.read_bytes() == b"abc" * 1000
    assert f.closed and sorted(p.name for p in tmp_path.iterdir()) == ["t.bin"]

    pending = PendingFiles()
    pending.open_native(tmp_path / "u.bin").write(b"x")
    pending.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.bin"]
    assert _reopen_path(io.BytesIO()) is None


def test_unreachable_dask_scheduler(tmp_path, capsys):
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "sw"
    t0 = time.monotonic()
    code, _, err = cli(
        capsys, "sweep", PAPER, *SHORT, "--param", "link.ptx_dbw=15,14",
        "--workers", f"dask://127.0.0.1:{port}", "--out", out, "--quiet",
    )  # fmt: skip
    assert time.monotonic() - t0 < 30.0
    assert code == EXIT_USAGE and err.count("\n") == 1
    assert f"--workers dask://127.0.0.1:{port}: no dask scheduler answered within 5 s" in err
    assert [f for f in files_in(out) if not f.startswith("runs/")] == []


def test_library_warnings_are_one_line_or_silenced(monkeypatch, capsys):
    """A library's multi-line warning is one line, once; itur's DeprecationWarning is
    silenced (leolink.app.guard.SILENCED gives the reason)."""
    import leolink.app.reports as reports

    real = reports.link_budget_at_elevation

    def noisy(cfg, elevation_deg):
        for _ in range(3):
            warnings.warn_explicit(
                "a library says\nsomething long", UserWarning, "lib.py", 1, module="somelib"
            )
            warnings.warn_explicit(
                "np.x is deprecated", DeprecationWarning, "itur.py", 2, module="itur"
            )
        return real(cfg, elevation_deg)

    monkeypatch.setattr(reports, "link_budget_at_elevation", noisy)
    code, _, err = cli(capsys, "budget", PAPER, "--elevation-deg", "30")
    assert code == 0
    assert err == "leolink: warning: UserWarning: a library says\n"
