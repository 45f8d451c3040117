"""The examples shipped as package data (``leolink.examples``): listed, copied with their
files, usable by name wherever a config path is, and the one copy behind ``configs/``."""

import json
import tomllib
from pathlib import Path

import pytest

from leolink.cli import main
from leolink.config import load_config
from leolink.errors import ConfigError
from leolink.examples import EXAMPLES, HERE, copy_example, example_path, resolve

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "src" / "leolink" / "examples"  # HERE, unless leolink is installed (CI)


def test_every_packaged_toml_is_listed_and_every_listed_name_has_its_file():
    assert {p.stem for p in HERE.glob("*.toml")} == set(EXAMPLES)


def test_the_clone_configs_are_links_to_the_packaged_examples():
    # One copy: configs/ (the README's first command, the tests) is the package's files.
    configs = ROOT / "configs"
    data = [configs / "examples" / f for f in ("tles/iss.tle", "tracks/car.csv", "tracks/ship.csv")]
    linked = [p for p in configs.rglob("*") if p.is_file()] + data
    assert len(linked) == len(EXAMPLES) + 3
    for path in linked:
        assert path.resolve().is_relative_to(SOURCE), path
    assert (ROOT / "configs" / "paper.toml").resolve() == SOURCE / "paper.toml"


def test_the_installed_examples_are_the_source_files():
    files = [p.relative_to(SOURCE) for p in SOURCE.rglob("*") if p.is_file()]
    files = [f for f in files if "__pycache__" not in f.parts and f.suffix != ".py"]
    assert len(files) == len(EXAMPLES) + 3
    for f in files:  # a wheel that left one out, or an old install, fails here
        assert (HERE / f).read_bytes() == (SOURCE / f).read_bytes(), f


def test_pyproject_ships_every_example_file():
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))["tool"]["setuptools"]
    patterns = globs["package-data"]["leolink"]
    shipped = {p for pattern in patterns for p in SOURCE.parent.glob(pattern)}
    files = {p for p in SOURCE.rglob("*") if p.is_file() and p.suffix in {".toml", ".tle", ".csv"}}
    assert files and files <= shipped


def test_examples_command_lists_one_line_per_example(capsys):
    assert main(["examples"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in lines] == list(EXAMPLES)


def test_init_copies_the_config_with_its_tle_and_the_copy_loads(tmp_path, capsys):
    assert main(["init", "tle", str(tmp_path / "x")]) == 0
    assert (tmp_path / "x" / "tle.toml").read_bytes() == example_path("tle").read_bytes()
    assert (tmp_path / "x" / "tles" / "iss.tle").read_bytes() == (
        HERE / "tles/iss.tle"
    ).read_bytes()
    cfg = load_config(tmp_path / "x" / "tle.toml")
    assert Path(cfg.constellation.tle_file) == tmp_path / "x" / "tles" / "iss.tle"
    assert "x/tle.toml" in capsys.readouterr().out


def test_init_copies_a_track_file(tmp_path):
    written = copy_example("ship", tmp_path)
    assert [p.relative_to(tmp_path).as_posix() for p in written] == ["ship.toml", "tracks/ship.csv"]


def test_init_refuses_to_overwrite_and_writes_nothing(tmp_path, capsys):
    (tmp_path / "tles").mkdir()
    (tmp_path / "tles" / "iss.tle").write_text("mine\n")
    assert main(["init", "tle", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "iss.tle exists already" in err
    assert not (tmp_path / "tle.toml").exists()
    assert (tmp_path / "tles" / "iss.tle").read_text() == "mine\n"


def test_init_of_an_unknown_name_lists_the_examples(tmp_path, capsys):
    assert main(["init", "papr", str(tmp_path)]) == 2
    assert "'papr' is not an example; use one of paper, " in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def test_a_name_runs_the_example(tmp_path):
    out = tmp_path / "o"
    assert (
        main(
            [
                "run",
                "paper",
                "--out",
                str(out),
                "--quiet",
                "--set",
                "run.duration_s=3",
                "--set",
                "output.plots.enabled=false",
            ]
        )
        == 0
    )
    assert (out / "run.json").is_file()
    resolved = tomllib.loads((out / "config.resolved.toml").read_text("utf-8"))
    assert resolved["roi"]["semi_axis_y_m"] == 170500.0 and len(resolved["population"]) == 4


def test_a_file_of_that_path_wins_over_the_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("paper").write_text("[run]\nduration_s = 7.0\n", encoding="utf-8")
    assert load_config("paper").run.duration_s == 7.0
    assert resolve("car") == example_path("car")


def test_a_bare_unknown_name_says_it_is_neither_file_nor_example(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError, match="'papr' is neither a config file nor an example"):
        load_config("papr")
    assert main(["validate", "nope.toml"]) == 2
    assert "config file 'nope.toml' does not exist" in capsys.readouterr().err


def test_an_all_defaults_config_runs_the_papers_pass(tmp_path, capsys):
    config = tmp_path / "m.toml"
    config.write_text("[run]\nduration_s = 60.0\n", encoding="utf-8")
    out = tmp_path / "o"
    assert main(["run", str(config), "--out", str(out), "--quiet"]) == 0
    resolved = tomllib.loads((out / "config.resolved.toml").read_text("utf-8"))
    assert (resolved["roi"]["semi_axis_x_m"], resolved["roi"]["semi_axis_y_m"]) == (
        534.1e3,
        170.5e3,
    )
    summary = json.loads((out / "summary.json").read_text("utf-8"))
    assert (summary["run"]["oversampling"], summary["run"]["n_beam"]) == (1.2, 15)
    assert summary["run"]["n_epochs"] == 60
    assert summary["overall"]["outage_fraction"] == 0.0


def test_sweep_and_compare_take_a_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no file named "paper" here: the example
    short = ["--set", "run.duration_s=2", "--set", "output.plots.enabled=false", "--quiet"]
    assert main(["sweep", "paper", "--param", "run.seed=1,2", "--out", "sw", *short]) == 0
    assert main(["compare", "paper", "--policy", "max_snr", "--out", "cmp", *short]) == 0
    import pandas as pd

    sweep = pd.read_csv("sw/sweep.csv", keep_default_na=False)
    assert len(sweep) == 2 and not (sweep.get("error", pd.Series([""])) != "").any()
    assert pd.read_csv("cmp/compare.csv")["policy"].tolist() == ["max_snr"]
