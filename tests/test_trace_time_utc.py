"""The trace's ``time_utc`` (DESIGN output contract): present whenever a UTC start is
known, ISO 8601 text in CSV, a UTC timestamp in Parquet and in ``Result.trace``, equal to
``run.start_utc - run.start_s + time_s`` computed here with the standard library's
datetime arithmetic; absent when the run has no calendar time."""

from datetime import datetime, timedelta
from pathlib import Path

import pandas as pd
import pytest

import leolink
from leolink.config import load_config

CITIES = Path(__file__).resolve().parent / "data" / "cities_20.toml"
START = "2026-03-21T11:59:59.75+00:00"
SETS = [
    f'run.start_utc="{START}"', "run.start_s=10.5", "run.epoch_s=0.25", "run.duration_s=1.0",
    "output.trace.enabled=true", 'output.trace.formats=["csv", "parquet"]',
]  # fmt: skip


def _expected(time_s):
    zero = datetime.fromisoformat(START) - timedelta(seconds=10.5)
    return [zero + timedelta(seconds=float(t)) for t in time_s]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("utc") / "run"
    leolink.run(load_config(CITIES, SETS), out)
    return out


def test_csv_time_utc_is_iso_8601_of_start_plus_time(run_dir):
    trace = pd.read_csv(run_dir / "trace.csv")
    assert trace.columns[-1] == "time_utc"  # added after every other column
    assert trace["time_utc"].str.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z").all()
    got = [datetime.fromisoformat(s) for s in trace["time_utc"]]
    assert got == _expected(trace["time_s"])
    assert sorted(set(got))[1] - sorted(set(got))[0] == timedelta(seconds=0.25)


def test_parquet_time_utc_is_a_utc_timestamp(run_dir):
    trace = pd.read_parquet(run_dir / "trace.parquet")
    assert str(trace["time_utc"].dtype) == "datetime64[us, UTC]"
    assert [t.to_pydatetime() for t in trace["time_utc"]] == _expected(trace["time_s"])


def test_memory_trace_has_time_utc_too():
    trace = leolink.run(load_config(CITIES, SETS[:4])).trace
    assert [t.to_pydatetime() for t in trace["time_utc"]] == _expected(trace["time_s"])


def test_no_time_utc_without_a_calendar_start():
    trace = leolink.run(load_config(CITIES, ["run.duration_s=1.0"])).trace
    assert "time_utc" not in trace.columns
