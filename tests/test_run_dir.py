"""Output folders: another run's files are refused unless --overwrite, which removes exactly
them; ``run.json`` (written last) lists every file with its size and checksum; a folder
without it is not finished; ``Result.trace`` reads only the files its run wrote."""

import hashlib
import json
import shutil
import subprocess
import sys

import pandas as pd
import pytest

from leolink.app.run import run
from leolink.cli import EXIT_USAGE, main
from leolink.config import load_config
from leolink.io.run_dir import OutputFolderError, claim_out_dir
from report_helpers import PAPER, REPO

SHORT = ["--set", "run.duration_s=10", "--set", "output.plots.enabled=false"]
N_UT = 7  # the paper config's UTs


def _leolink(*args):
    return main([str(a) for a in args])


def _files(folder):
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture(scope="module")
def parquet_run(tmp_path_factory):
    """``leolink run --parquet`` over the whole 120 s pass: 840 trace rows."""
    out = tmp_path_factory.mktemp("parquet")
    assert _leolink("run", PAPER, "--out", out, "--quiet", "--parquet") == 0
    return out


def test_manifest_lists_every_file_with_its_size_and_sha256(parquet_run):
    manifest = json.loads((parquet_run / "run.json").read_text())
    listed = {f["path"]: f for f in manifest["files"]}
    assert set(listed) == _files(parquet_run) - {"run.json"}
    for name, entry in listed.items():
        data = (parquet_run / name).read_bytes()
        assert entry["bytes"] == len(data) and entry["sha256"] == hashlib.sha256(data).hexdigest()
    config = (parquet_run / "config.resolved.toml").read_bytes()
    assert manifest["config_sha256"] == hashlib.sha256(config).hexdigest()
    assert manifest["command"] == "run"
    version = subprocess.run(
        [sys.executable, "-m", "leolink.cli", "--version"], capture_output=True, text=True
    ).stdout.strip()
    assert version == f"leolink {manifest['leolink_version']}"
    assert (parquet_run / "run.json").stat().st_mtime_ns >= max(
        (parquet_run / n).stat().st_mtime_ns for n in listed
    )  # written last


def test_a_rerun_into_a_finished_run_is_refused_and_changes_nothing(parquet_run, capsys):
    before = {n: (parquet_run / n).read_bytes() for n in _files(parquet_run)}
    assert _leolink("run", PAPER, "--out", parquet_run, "--quiet", *SHORT) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.startswith(f"leolink: error: --out {parquet_run} holds the files of a finished")
    assert "--overwrite" in err and len(err.strip().splitlines()) == 1
    assert {n: (parquet_run / n).read_bytes() for n in _files(parquet_run)} == before


def test_overwrite_replaces_the_old_run_and_keeps_the_users_files(parquet_run, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(parquet_run, out)
    (out / "notes.txt").write_text("mine")
    (out / "mine").mkdir()
    (out / "mine" / "trace.csv").write_text("not leolink's: in a sub-folder")
    assert _leolink("run", PAPER, "--out", out, "--quiet", "--overwrite", *SHORT) == 0
    assert not (out / "trace.parquet").exists()  # the old run's, not this one's
    assert (out / "notes.txt").read_text() == "mine" and (out / "mine" / "trace.csv").exists()
    listed = {f["path"] for f in json.loads((out / "run.json").read_text())["files"]}
    assert listed == _files(out) - {"run.json", "notes.txt", "mine/trace.csv"}
    assert "trace.parquet" not in listed


def test_result_trace_reads_only_what_its_run_wrote(parquet_run, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(parquet_run, out)
    cfg = load_config(PAPER, ["run.duration_s=10", "output.plots.enabled=false"])
    res = run(cfg, out_dir=out, overwrite=True)
    shutil.copy(parquet_run / "trace.parquet", out / "trace.parquet")  # a stale file is back
    assert len(res.trace) == res.summary["overall"]["n_ut_epochs"] == N_UT * 10
    assert res.trace["time_s"].max() == 9.0
    assert len(res.events) == sum(1 for _ in (out / "events.csv").open()) - 1


def test_a_folder_of_other_files_is_used_and_left_alone(tmp_path):
    (tmp_path / "README.txt").write_text("a user's folder")
    assert _leolink("run", PAPER, "--out", tmp_path, "--quiet", *SHORT) == 0
    assert (tmp_path / "README.txt").read_text() == "a user's folder"
    assert (tmp_path / "run.json").exists()


def _interrupted_run(out, monkeypatch):
    """A run stopped after its files were written, before the manifest (Ctrl-C)."""
    import leolink.app.run as app_run

    def stop(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(app_run, "write_manifest", stop)
    args = ["--parquet", "--set", "run.duration_s=10"]  # every output, plots and report too
    assert _leolink("run", PAPER, "--out", out, "--quiet", *args) == 130
    monkeypatch.undo()
    (out / "trace.csv.1a2b3c4d.partial").write_text("left by a killed writer")


def test_an_interrupted_run_is_not_finished_and_is_cleared_by_overwrite(
    tmp_path, monkeypatch, capsys
):
    _interrupted_run(tmp_path, monkeypatch)
    assert (tmp_path / "trace.csv").exists() and not (tmp_path / "run.json").exists()
    capsys.readouterr()
    assert _leolink("report", tmp_path) == EXIT_USAGE
    assert "is not a finished leolink run (no run.json" in capsys.readouterr().err
    assert _leolink("run", PAPER, "--out", tmp_path, "--quiet", *SHORT) == EXIT_USAGE
    err = capsys.readouterr().err
    assert "files of an unfinished leolink run (no run.json: " in err
    lean = [*SHORT, "--set", "output.report.enabled=false"]  # writes fewer files
    assert _leolink("run", PAPER, "--out", tmp_path, "--quiet", "--overwrite", *lean) == 0
    assert not list(tmp_path.glob("*.partial")) and not list(tmp_path.glob("*.png"))
    assert not {"trace.parquet", "report.html", "footprint.gif"} & _files(tmp_path)
    listed = {f["path"] for f in json.loads((tmp_path / "run.json").read_text())["files"]}
    assert listed == _files(tmp_path) - {"run.json"}


def test_a_manifest_naming_a_file_outside_its_folder_removes_nothing(tmp_path):
    outside = tmp_path / "precious.txt"
    outside.write_text("keep")
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text("{}")
    entry = {"path": "../precious.txt", "bytes": 4, "sha256": ""}
    (out / "run.json").write_text(json.dumps({"command": "run", "files": [entry]}))
    with pytest.raises(OutputFolderError, match=r"lists '\.\./precious\.txt', which is outside"):
        claim_out_dir(out, overwrite=True)
    assert outside.read_text() == "keep" and (out / "summary.json").exists()


def test_leolink_report_rebuilds_the_page_and_updates_the_manifest(parquet_run, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(parquet_run, out)
    (out / "report.html").unlink()
    assert _leolink("report", out, "--uts", "2", "--no-animation", "--exports", "--quiet") == 0
    page = (out / "report.html").read_text()
    assert page.count("<img") == 9  # the figures and the run's animation, kept
    per_ut = page.split("<summary>Per UT</summary>", 1)[1]
    assert per_ut.split("<tr><td>", 2)[1].startswith("2</td>")  # the chosen UT first
    manifest = {f["path"]: f for f in json.loads((out / "run.json").read_text())["files"]}
    assert {"report.html", "run.geojson", "run.czml"} <= set(manifest)
    for name in ("report.html", "run.geojson"):
        digest = hashlib.sha256((out / name).read_bytes()).hexdigest()
        assert manifest[name]["sha256"] == digest


def test_coverage_writes_a_report_and_a_manifest_and_refuses_a_rerun(tmp_path, capsys):
    args = ["coverage", PAPER, "--out", tmp_path, "--grid", "21", "--quiet"]
    assert _leolink(*args) == 0
    manifest = json.loads((tmp_path / "run.json").read_text())
    assert manifest["command"] == "coverage" and manifest["arguments"]["n_grid"] == 21
    assert {f["path"] for f in manifest["files"]} == _files(tmp_path) - {"run.json"}
    page = (tmp_path / "report.html").read_text()
    assert page.count("<img") == len(list(tmp_path.glob("*.png"))) == 7  # every map, embedded
    grid = pd.read_csv(tmp_path / "coverage.csv")
    snr = grid.loc[grid["in_roi"], "snr_db"]
    row = f"<td>snr_db</td><td>{snr.min():.4g}</td>"  # min, then p5, median, mean, p95, max
    assert row in page and f"<td>{snr.mean():.4g}</td><td>{snr.quantile(0.95):.4g}</td>" in page
    assert _leolink(*args) == EXIT_USAGE
    assert "finished 'leolink coverage'" in capsys.readouterr().err
    assert _leolink(*args, "--overwrite", "--no-plots") == 0
    assert not list(tmp_path.glob("*.png"))  # the old run's maps went with it


def test_sweep_writes_a_report_and_a_manifest_and_resumes(tmp_path, capsys):
    args = ["sweep", PAPER, "--param", "link.ptx_dbw=12,15", *SHORT, "--out", tmp_path]
    assert _leolink(*args, "--quiet") == 0
    manifest = json.loads((tmp_path / "run.json").read_text())
    listed = {f["path"] for f in manifest["files"]}
    assert {"sweep.csv", "sweep.json", "report.html", "sweep_link_ptx_dbw.png"} <= listed
    assert sum(p.endswith("/run.json") for p in listed) == 2  # each point's own manifest
    assert "<td>0001_link.ptx_dbw=15</td>" in (tmp_path / "report.html").read_text()
    assert _leolink(*args, "--quiet") == EXIT_USAGE
    assert "--resume" in capsys.readouterr().err
    assert _leolink(*args, "--quiet", "--resume") == 0
    assert _leolink(*args, "--quiet", "--overwrite") == 0


def test_version_flag(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    text = (REPO / "pyproject.toml").read_text()
    version = text.split('version = "', 1)[1].split('"', 1)[0]
    assert capsys.readouterr().out.strip() == f"leolink {version}"


@pytest.mark.parametrize(
    "command",
    [
        ["run", PAPER, *SHORT],
        ["coverage", PAPER, "--grid", "11", "--no-plots"],
        ["sweep", PAPER, "--param", "link.ptx_dbw=12,15", *SHORT],
        ["compare", PAPER, "--policies", "max_snr,a3", "--seeds", "1", *SHORT],
    ],
    ids=lambda c: c[0],
)
def test_a_relative_output_folder_works_as_the_readme_writes_it(command, tmp_path, monkeypatch):
    """README's first command, ``leolink run configs/paper.toml --out out/paper``: an output
    folder relative to the current directory (every other test passes an absolute one)."""
    monkeypatch.chdir(tmp_path)
    assert _leolink(*command, "--out", "out/x", "--quiet") == 0
    folder = tmp_path / "out" / "x"
    listed = {f["path"] for f in json.loads((folder / "run.json").read_text())["files"]}
    written = {p for p in _files(folder) if p.count("/") == 0} - {"run.json"}
    assert written and written <= listed  # every file of the folder (sweeps: and each run's)
    if command[0] == "run":
        assert _leolink("report", "out/x", "--no-animation", "--quiet") == 0


def test_the_manifest_takes_a_known_digest_only_for_a_file_of_that_size(tmp_path):
    """``write_manifest(digests=...)``: a writer's digest stands for a file that still has
    its size; a file that changed size since is hashed again."""
    from leolink.io.run_dir import write_manifest

    kept, grown = tmp_path / "kept.csv", tmp_path / "grown.csv"
    kept.write_bytes(b"a,b\n1,2\n")
    grown.write_bytes(b"a,b\n1,2\n3,4\n")
    told = {kept: (kept.stat().st_size, "k" * 64), grown: (9, "g" * 64)}
    path = write_manifest(tmp_path, [kept, grown], "run", "x = 1", version="0", digests=told)
    files = {f["path"]: f for f in json.loads(path.read_text())["files"]}
    assert files["kept.csv"]["sha256"] == "k" * 64  # taken as told (the size matches)
    assert files["grown.csv"]["sha256"] == hashlib.sha256(grown.read_bytes()).hexdigest()
    assert files["grown.csv"]["bytes"] == 12
