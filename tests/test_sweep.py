"""``leolink.sweep.run_sweep``: the grid, the table, parallel runs, fail-fast validation.

The table is checked against direct ``run()`` calls of the same configs, with the metric
names mapped by hand here (not through ``flatten_summary``), so a wrong flattening or a
row matched to the wrong point fails. Runs are short (``run.duration_s`` a few seconds of
the paper's scenario, 7 UTs) to keep the file fast.
"""

import math
import re
import shutil
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import leolink.app.run as runner
from leolink.app.sweep import Execution, parse_param, point_name, run_sweep
from leolink.cli import EXIT_USAGE, main
from leolink.config import load_config
from leolink.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"
BASE = ["run.duration_s=6", 'controller.policy="hysteresis"']
PARAMS = ["controller.hysteresis.margin_db=0,3", "link.ptx_dbw=15,9.5"]

# summary["overall"] path -> table column, written out by hand (independent of the code)
METRIC_PATHS = {
    "snr_db_mean": ("snr_db", "mean"),
    "snr_db_p5": ("snr_db", "p5"),
    "sinr_db_mean": ("sinr_db", "mean"),
    "sinr_db_p5": ("sinr_db", "p5"),
    "sinr_db_p95": ("sinr_db", "p95"),
    "beam_handovers": ("handovers", "beam_handover"),
    "sat_handovers": ("handovers", "sat_handover"),
    "outage_starts": ("handovers", "outage_start"),
    "outage_fraction": ("outage_fraction",),
    "dwell_mean_s": ("dwell", "mean_s"),
    "dwell_median_s": ("dwell", "median_s"),
    "dwell_n_censored": ("dwell", "n_censored"),
    "mean_throughput_bps": ("mean_throughput_bps",),
    "max_abs_doppler_hz": ("max_abs_doppler_hz",),
    "max_angular_speed_deg_s": ("max_angular_speed_deg_s",),
}


def _get(summary, path):
    value = summary["overall"]
    for part in path:
        value = value[part]
    return math.nan if value is None else value


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep_serial")
    return out, run_sweep(
        PAPER, PARAMS, out, base_overrides=BASE, how=Execution(workers=1, progress=False)
    )


def test_one_row_per_grid_point(serial):
    out, table = serial
    assert len(table) == 4
    assert list(table.columns[:3]) == ["point", "controller.hysteresis.margin_db", "link.ptx_dbw"]
    # Cartesian product in the given order, the last parameter fastest
    pairs = list(zip(table["controller.hysteresis.margin_db"], table["link.ptx_dbw"], strict=True))
    assert pairs == [(0, 15), (0, 9.5), (3, 15), (3, 9.5)]
    assert table["point"].iloc[1] == "0001_controller.hysteresis.margin_db=0_link.ptx_dbw=9.5"
    for name in table["point"]:
        run_dir = out / "runs" / name
        assert (run_dir / "summary.json").exists()
        assert not list(run_dir.glob("*.png")), "run plots are off unless asked for"
    assert not list(out.glob("sweep_*.png")), "no sweep plot for two parameters"


def test_table_matches_direct_runs(serial):
    _, table = serial
    for row in table.itertuples(index=False):
        point = [f"controller.hysteresis.margin_db={row[1]}", f"link.ptx_dbw={row[2]}"]
        summary = runner.run(load_config(PAPER, [*BASE, *point])).summary
        for column, path in METRIC_PATHS.items():
            got, want = table.loc[table["point"] == row.point, column].item(), _get(summary, path)
            # exact: every run is deterministic from its config seed
            assert got == want or (math.isnan(got) and math.isnan(want)), (row.point, column)


def test_written_csv_and_json_match_table(serial):
    out, table = serial
    # the CSV holds repr() of each float, which pandas reads back exactly
    csv = pd.read_csv(out / "sweep.csv")
    pd.testing.assert_frame_equal(csv, table, check_dtype=False)
    import json

    doc = json.loads((out / "sweep.json").read_text())
    assert doc["params"] == ["controller.hysteresis.margin_db", "link.ptx_dbw"]
    assert [p["point"] for p in doc["points"]] == list(table["point"])


def test_two_workers_give_the_same_table(serial, tmp_path):
    _, table = serial
    parallel = run_sweep(
        PAPER, PARAMS, tmp_path, base_overrides=BASE, how=Execution(workers=2, progress=False)
    )
    pd.testing.assert_frame_equal(parallel, table)


@pytest.mark.parametrize(
    ("spec", "text"),
    [
        (
            "controller.hysteresis.margin_db",
            "--param 'controller.hysteresis.margin_db' is not allowed",
        ),
        ("=0,3", "--param '=0,3' is not allowed"),
        ("controller.hysteresis.margin_db=", "controller.hysteresis.margin_db: no values"),
        ("controller.hysteresis.margin_db=0,,3", "controller.hysteresis.margin_db: an empty value"),
        (  # every point fails: nothing runs (one bad point of several: test_reliability.py)
            "controller.hysteresis.margin_db=-2,-1",
            "controller.hysteresis.margin_db = -2 is not allowed",
        ),
        ("controller.policy=greedy", "controller.policy = 'greedy' is not allowed"),
        ("controller.hysteresys_db=1", "controller.hysteresys_db is not a known key"),
    ],
)
def test_bad_param_fails_before_any_run(tmp_path, spec, text):
    out = tmp_path / "sweep"
    with pytest.raises(ConfigError, match=re.escape(text)):
        run_sweep(
            PAPER,
            ["link.ptx_dbw=15,12", spec],
            out,
            base_overrides=BASE,
            how=Execution(progress=False),
        )
    assert not out.exists()


def test_duplicate_param_and_bad_workers(tmp_path):
    with pytest.raises(ConfigError, match="link.ptx_dbw is given twice"):
        run_sweep(
            PAPER,
            ["link.ptx_dbw=1", "link.ptx_dbw=2"],
            tmp_path / "a",
            how=Execution(progress=False),
        )
    with pytest.raises(ConfigError, match="workers = 0"):
        run_sweep(
            PAPER, ["link.ptx_dbw=1"], tmp_path / "b", how=Execution(workers=0, progress=False)
        )
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_parse_param_reads_toml_values():
    assert parse_param("controller.hysteresis.margin_db=0, 1.5,3") == (
        "controller.hysteresis.margin_db",
        [0, 1.5, 3],
    )
    assert parse_param("controller.policy=max_snr,hysteresis")[1] == ["max_snr", "hysteresis"]
    assert parse_param('population.0.name="a,b","c"')[1] == ["a,b", "c"]
    assert parse_param("earth.rotation=true,false")[1] == [True, False]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.one_of(st.text(max_size=40), st.floats(), st.integers()), min_size=1))
def test_point_names_are_safe_folder_names(values):
    name = point_name(12, {f"k{i}.v": v for i, v in enumerate(values)})
    assert re.fullmatch(r"0012_[A-Za-z0-9._=+-]*", name)
    assert len(name) <= 120


def test_one_param_plots_and_cli(tmp_path):
    out = tmp_path / "cli"
    argv = ["sweep", str(PAPER), "--param", "controller.hysteresis.margin_db=0,3"]
    argv += ["--set", 'controller.policy="hysteresis"', "--set", "run.duration_s=20"]
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    table = pd.read_csv(out / "sweep.csv")
    assert list(table["controller.hysteresis.margin_db"]) == [0, 3]
    assert (out / "sweep_controller_hysteresis_margin_db.png").stat().st_size > 0
    bad = ["sweep", str(PAPER), "--param", "controller.hysteresis.margin_db=-3", "--out", str(out)]
    assert main([*bad, "--quiet"]) == EXIT_USAGE


def _counting_run(monkeypatch, fail_at=None):
    """Patch ``runner.run`` to count calls (and raise KeyboardInterrupt at call ``fail_at``)."""
    real, calls = runner.run, []

    def fake(cfg, out_dir=None, progress=None, **kw):
        calls.append(out_dir)
        if len(calls) == fail_at:
            raise KeyboardInterrupt
        return real(cfg, out_dir=out_dir, progress=progress, **kw)

    monkeypatch.setattr(runner, "run", fake)
    return calls


def test_interrupt_keeps_finished_runs_and_writes_no_table(tmp_path, monkeypatch):
    calls = _counting_run(monkeypatch, fail_at=2)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(
            PAPER,
            PARAMS,
            tmp_path,
            base_overrides=BASE,
            how=Execution(progress=False, overwrite=True),
        )
    assert (Path(calls[0]) / "run.json").exists()  # finished
    assert not (Path(calls[1]) / "run.json").exists()
    assert not list(tmp_path.glob("sweep.*")) and not (tmp_path / "run.json").exists()


def test_resume_reuses_only_matching_runs(serial, tmp_path, monkeypatch):
    out, table = serial
    shutil.copytree(out / "runs", tmp_path / "runs")
    calls = _counting_run(monkeypatch)
    again = run_sweep(
        PAPER, PARAMS, tmp_path, base_overrides=BASE, how=Execution(progress=False, resume=True)
    )
    assert calls == []
    pd.testing.assert_frame_equal(again, table, check_dtype=False)
    changed = [*BASE, "run.seed=7"]  # same folder names, another config: run them again
    run_sweep(
        PAPER, PARAMS, tmp_path, base_overrides=changed, how=Execution(progress=False, resume=True)
    )
    assert len(calls) == 4


def test_parallel_rows_follow_the_grid_not_completion_order(tmp_path):
    # point 0 runs 10x longer than point 1, so point 1 finishes first on 2 workers
    table = run_sweep(
        PAPER,
        ["run.duration_s=40,4"],
        tmp_path,
        base_overrides=BASE[1:],
        how=Execution(workers=2, progress=False),
    )
    n_ut = 7  # the paper config's populations: 1 + 4 + 1 + 1 UTs, epoch_s = 1 s
    assert list(table["n_ut_epochs"]) == [n_ut * 40, n_ut * 4]


@pytest.mark.optional_extra("dist")
def test_dask_cluster_gives_the_same_table(tmp_path):
    """``workers="dask://ADDRESS"`` (the ``dist`` extra): same table as one process."""
    distributed = pytest.importorskip("dask.distributed")
    base = ['controller.policy="hysteresis"', "run.duration_s=10"]
    params = ["controller.hysteresis.margin_db=0,3"]
    local = run_sweep(
        PAPER, params, tmp_path / "local", base_overrides=base, how=Execution(progress=False)
    )
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
        remote = run_sweep(
            PAPER,
            params,
            tmp_path / "dask",
            base_overrides=base,
            how=Execution(workers=f"dask://{cluster.scheduler_address}", progress=False),
        )
    pd.testing.assert_frame_equal(remote, local)
