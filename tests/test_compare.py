"""``leolink compare``: every policy on the same seeds, KPIs tabulated with their spread."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from leolink.app.compare import parse_policy, policy_twins, run_compare
from leolink.app.sweep import Execution
from leolink.cli import main
from leolink.errors import ConfigError

PAPER = str(Path(__file__).resolve().parents[1] / "configs" / "paper.toml")
BASE = ["run.duration_s=20", "link.fading=rician", 'output.trace.formats=["csv"]']


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    table = run_compare(
        PAPER, ["max_snr", "a3,hysteresis_db=3"], out, BASE, seeds=2, how=Execution(progress=False)
    )
    return out, table


def test_policies_see_the_same_uts_and_fading_on_each_seed(compared):
    out, _ = compared
    runs = pd.read_csv(out / "compare_runs.csv")
    assert list(runs.seed) == [20201, 20202, 20201, 20202]  # paper.toml: run.seed = 20201
    traces = {(r.policy, r.seed): pd.read_csv(Path(r.run) / "trace.csv") for r in runs.itertuples()}
    same_cells = 0
    for seed in (20201, 20202):
        a, b = traces[("max_snr", seed)], traces[("a3,hysteresis_db=3", seed)]
        np.testing.assert_array_equal(a[["lat_deg", "lon_deg"]], b[["lat_deg", "lon_deg"]])
        same = (a.sat_id == b.sat_id) & (a.beam_id == b.beam_id)
        np.testing.assert_array_equal(a.snr_db[same], b.snr_db[same])  # the same fading draw
        same_cells += same.sum()
    assert same_cells > 100
    a, b = traces[("max_snr", 20201)], traces[("max_snr", 20202)]
    assert not np.allclose(a.snr_db, b.snr_db)  # another seed draws other fading


def test_the_table_is_the_mean_and_spread_of_the_runs(compared):
    out, table = compared
    assert list(table.policy) == ["max_snr", "a3,hysteresis_db=3"]
    assert (table.n_seeds == 2).all()
    disk = pd.read_csv(out / "compare.csv")
    assert list(disk.policy) == list(table.policy)
    runs = pd.read_csv(out / "compare_runs.csv")
    for policy, group in runs.groupby("policy"):
        values = [
            json.loads((Path(r) / "summary.json").read_text())["overall"]["kpi"][
                "handover_rate_per_ut_min"
            ]
            for r in group.run
        ]
        row = disk[disk.policy == policy].iloc[0]
        assert row.kpi_handover_rate_per_ut_min == pytest.approx(np.mean(values))
        assert row.kpi_handover_rate_per_ut_min_std == pytest.approx(np.std(values, ddof=1))
    hyst = disk[disk.policy == "a3,hysteresis_db=3"].iloc[0]
    plain = disk[disk.policy == "max_snr"].iloc[0]
    assert hyst.handovers_total <= plain.handovers_total
    for name in ("compare_kpis.png", "compare_tradeoff.png", "compare_sinr_cdf.png", "compare.md"):
        assert (out / name).stat().st_size > 0
    assert "| a3,hysteresis_db=3 |" in (out / "compare.md").read_text()


def test_the_report_names_its_columns_and_the_policies_conditions(compared):
    """compare.md: a legend (rates, counts and fractions named as such), served-only SINR,
    each policy's parameters in effect; no column empty for every policy anywhere."""
    out, table = compared
    md = (out / "compare.md").read_text()
    head = md.splitlines()[0]
    for heading in ("handovers /UT-min", "ping-pongs (cell)", "ping-pong fraction (cell)",
                    "served SINR p5 [dB]"):  # fmt: skip
        assert f"| {heading} |" in head and f"- **{heading}**: " in md
    assert "a count per run" in md and "a fraction in [0, 1]" in md
    assert "mean ± sample standard deviation over 2 seed(s)" in md
    mine = md.split("- **a3,hysteresis_db=3**: `")[1].split("`")[0]
    assert mine.startswith("a3 {") and '"hysteresis_db": 3.0' in mine
    assert '"offset_db": 0.0' in mine and '"time_to_trigger_s": 0.0' in mine
    disk = pd.read_csv(out / "compare.csv")
    assert disk.notna().any().all()  # no empty column
    assert (table.kpi_sinr_db_percentiles_served_p5 >= table.kpi_sinr_db_percentiles_p5).all()


def test_one_seed_leaves_out_the_spreads_and_empty_kpis():
    from leolink.app.compare import _aggregate, report_table

    runs = pd.DataFrame({"policy": ["a", "b"], "seed": [1, 1], "run": ["x", "y"],
                         "kpi_handover_rate_per_ut_min": [1.5, 2.0],
                         "kpi_ping_pong_fraction_satellite": [np.nan, np.nan],
                         "kpi_rlf_count": [np.nan, 2.0]})  # fmt: skip
    table = _aggregate(runs)
    assert list(table.columns) == ["policy", "n_seeds", "kpi_handover_rate_per_ut_min",
                                   "kpi_rlf_count"]  # fmt: skip
    md = report_table(table, {"a": "a3 {}", "b": "max_snr {}"})
    assert md.splitlines()[0] == "| policy | handovers /UT-min | RLFs |"
    assert md.splitlines()[2] == "| a | 1.500 |  |" and "±" not in md
    assert "one run per policy, 1 seed(s)" in md and "- **b**: `max_snr {}`" in md


def test_the_manifest_lists_every_file_and_every_run(compared):
    """run.json, written last, hashes the tables and plots and each run's own manifest."""
    import hashlib

    from leolink.io.run_dir import read_manifest

    out, _ = compared
    data = read_manifest(out)
    assert data["command"] == "compare" and data["arguments"]["seeds"] == 2
    listed = {f["path"]: f for f in data["files"]}
    runs = pd.read_csv(out / "compare_runs.csv")
    expected = {"compare.csv", "compare_runs.csv", "compare.md", "compare_kpis.png",
                "compare_tradeoff.png", "compare_sinr_cdf.png"}  # fmt: skip
    expected |= {(Path(r) / "run.json").relative_to(out).as_posix() for r in runs.run}
    assert set(listed) == expected
    for rel, entry in listed.items():
        body = (out / rel).read_bytes()
        assert entry["bytes"] == len(body) and entry["sha256"] == hashlib.sha256(body).hexdigest()


def test_policy_specs_and_mistakes():
    assert parse_policy("cho,prepare.offset_db=-2,kpi.ping_pong_s=3")[1] == [
        "controller.policy=cho",
        "controller.cho.prepare.offset_db=-2",
        "kpi.ping_pong_s=3",
    ]
    with pytest.raises(ConfigError, match="is not KEY=VALUE"):
        parse_policy("a3,hysteresis_db")
    with pytest.raises(ConfigError, match=r"policy a3,hysteresis_db=-1: .*hysteresis_db = -1"):
        run_compare(
            PAPER,
            ["a3,hysteresis_db=-1"],
            "/nonexistent/never",
            BASE,
            how=Execution(progress=False),
        )


def test_cli_compare(tmp_path, capsys):
    code = main(["compare", PAPER, "--policies", "max_snr,a3", "--out", str(tmp_path),
                 "--set", "run.duration_s=5", "--set", "output.trace.enabled=false"])  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    assert "| a3 |" in out and out == (tmp_path / "compare.md").read_text(encoding="utf-8")
    assert len(pd.read_csv(tmp_path / "compare.csv")) == 2


def test_policies_that_parameters_make_identical_are_named():
    twins = policy_twins(PAPER, ["max_snr", "hysteresis", "a3", "a3,hysteresis_db=0", "a4"])
    assert twins == [
        "policy hysteresis is identical to max_snr (the same parameters in effect): its rows "
        "will repeat max_snr's",
        "policy a3,hysteresis_db=0 is identical to a3 (the same parameters in effect): its "
        "rows will repeat a3's",
    ]
    assert policy_twins(PAPER, ["hysteresis"]) == [
        "policy hysteresis with these parameters is max_snr: its rows will be max_snr's"
    ]
    # a margin, a time-to-trigger or another base config: no twin
    assert policy_twins(PAPER, ["max_snr", "hysteresis,margin_db=1", "a3,hysteresis_db=1"]) == []
    assert policy_twins(PAPER, ["max_snr", "hysteresis,time_to_trigger_s=0.5"]) == []
    assert policy_twins(PAPER, ["a3", "a3,kpi.ping_pong_s=3"]) == []


def test_cli_compare_warns_of_twins_and_its_progress_is_compare(tmp_path, capsys):
    code = main(["compare", PAPER, "--policies", "max_snr,hysteresis", "--out", str(tmp_path),
                 "--set", "run.duration_s=20", "--set", "output.trace.enabled=false"])  # fmt: skip
    assert code == 0
    err = capsys.readouterr().err
    warned = [line for line in err.splitlines() if "warning" in line]
    assert len(warned) == 1 and "hysteresis is identical to max_snr" in warned[0]
    assert "leolink compare" in err and "leolink sweep" not in err
    # the warning is true: the two rows agree on every KPI
    table = pd.read_csv(tmp_path / "compare.csv").drop(columns="policy")
    pd.testing.assert_series_equal(table.iloc[0], table.iloc[1], check_names=False)
