"""Tests of leolink.sim.recorder: chunk independence, atomicity, round trips, summary."""

import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from leolink.io.atomic import write_json_atomic, write_text_atomic
from leolink.io.summary.accumulator import (
    OVERALL_RESOLUTION_DB,
    PER_UT_RESOLUTION_DB,
    SummaryAccumulator,
    grouped_percentiles,
)
from leolink.io.tables import TRACE_COLUMNS, TRACE_FLOAT64_COLUMNS, EventLog, TraceWriter
from leolink.link.modcod import modcod_table
from leolink.sim.handover.controller import (
    EVENT_COLUMNS,
    SERVICE_NAMES,
    ControllerState,
    close_dwells,
    step,
)
from leolink.sim.handover.policies import MaxSnr
from leolink.sim.processes import OUTAGE_REASONS

# Percentiles from fixed-bin histograms: within half a bin of numpy (+ float rounding).
PER_UT_DB = PER_UT_RESOLUTION_DB / 2 + 1e-9
OVERALL_DB = OVERALL_RESOLUTION_DB / 2 + 1e-9
#: The trace's MODCOD names by code; code -1 is written "none".
MODCOD_NAMES = (*modcod_table().names, "none")


def random_epoch(rng, t_s, n_ut):
    """One epoch of trace rows with NaN outages, as the runner would append it."""
    service = rng.integers(0, 3, n_ut)
    cols = {name: rng.normal(0.0, 1e3, n_ut) for name in TRACE_COLUMNS}
    cols["time_s"] = np.full(n_ut, t_s)
    cols["ut_id"] = np.arange(n_ut, dtype=np.int64)
    cols["sat_id"] = np.where(service == 2, -1, rng.integers(0, 50, n_ut))
    cols["beam_id"] = np.where(service == 2, -1, rng.integers(0, 300, n_ut))
    cols["snr_db"] = rng.normal(10.0, 6.0, n_ut)
    cols["sinr_db"] = cols["snr_db"] - rng.exponential(2.0, n_ut)
    for name in ("snr_db", "sinr_db", "throughput_bps", "doppler_hz"):
        cols[name] = np.where(service == 2, np.nan, cols[name])
    cols["throughput_bps"] = np.abs(cols["throughput_bps"]) * 1e4
    cols["angular_speed_deg_s"] = np.abs(cols["angular_speed_deg_s"]) * 1e-3
    cols["service"] = service
    # diagnostics: a reason per service (outage: either of its two reasons), counts, names
    cols["n_visible"] = np.where(service == 2, rng.integers(0, 2, n_ut), rng.integers(1, 9, n_ut))
    cols["outage_reason"] = np.where(service == 2, 3 - (cols["n_visible"] == 0), service)
    cols["population"] = np.asarray(["static", "car", "train"], dtype=object)[np.arange(n_ut) % 3]
    cols["interruption_s"] = np.where(service == 1, rng.uniform(0.0, 1.0, n_ut), 0.0)
    cols["modcod"] = np.where(service == 2, -1, rng.integers(-1, len(MODCOD_NAMES) - 1, n_ut))
    return cols


def random_trace(seed=0, n_epoch=30, n_ut=7):
    rng = np.random.default_rng(seed)
    return [random_epoch(rng, 0.1 * k, n_ut) for k in range(n_epoch)]


def as_frame(epochs):
    df = pd.DataFrame({k: np.concatenate([e[k] for e in epochs]) for k in TRACE_COLUMNS})
    df["service"] = np.asarray(SERVICE_NAMES)[df["service"]]
    df["outage_reason"] = np.asarray(OUTAGE_REASONS)[df["outage_reason"]]
    df["modcod"] = np.asarray(MODCOD_NAMES)[df["modcod"]]  # code -1: the last name, "none"
    return df


@pytest.mark.parametrize("chunk_rows", [1, 5, 7, 64, 10_000])
def test_trace_is_independent_of_chunk_size(tmp_path, chunk_rows):
    epochs = random_trace()
    ref_dir, dir_ = tmp_path / "ref", tmp_path / "x"
    with TraceWriter(ref_dir, formats=("csv", "parquet"), chunk_rows=1_000_000) as w:
        for e in epochs:
            w.append(e)
    with TraceWriter(dir_, formats=("csv", "parquet"), chunk_rows=chunk_rows) as w:
        for e in epochs:
            w.append(e)
    assert (dir_ / "trace.csv").read_bytes() == (ref_dir / "trace.csv").read_bytes()
    got, ref = pq.read_table(dir_ / "trace.parquet"), pq.read_table(ref_dir / "trace.parquet")
    assert got.schema == ref.schema
    # NaN-aware, exact: pandas treats NaN at the same place as equal, Arrow does not
    pd.testing.assert_frame_equal(got.to_pandas(), ref.to_pandas(), rtol=0, atol=0)
    n_rows = sum(len(e["ut_id"]) for e in epochs)
    assert pq.ParquetFile(dir_ / "trace.parquet").num_row_groups == -(-n_rows // chunk_rows)


def test_csv_and_parquet_round_trip_equal_the_appended_data(tmp_path):
    epochs = random_trace(seed=4)
    with TraceWriter(tmp_path, formats=("csv", "parquet"), chunk_rows=11) as w:
        for e in epochs:
            w.append(e)
    expected = as_frame(epochs)
    header = (tmp_path / "trace.csv").read_text().splitlines()[0]
    assert header == ",".join(TRACE_COLUMNS)
    from_csv = pd.read_csv(tmp_path / "trace.csv")
    from_parquet = pq.read_table(tmp_path / "trace.parquet").to_pandas()
    assert list(from_csv.columns) == list(from_parquet.columns) == list(TRACE_COLUMNS)
    # exact: the CSV float text is the shortest round-trip representation of the float64
    pd.testing.assert_frame_equal(from_csv, expected, check_dtype=False, rtol=0, atol=0)
    # Parquet: float32 but for the times and positions, each value the float64 rounded
    as32 = [c for c in TRACE_COLUMNS if expected[c].dtype == np.float64]
    as32 = [c for c in as32 if c not in TRACE_FLOAT64_COLUMNS]
    assert {str(from_parquet[c].dtype) for c in as32} == {"float32"}
    assert {str(from_parquet[c].dtype) for c in TRACE_FLOAT64_COLUMNS} == {"float64"}
    rounded = expected.astype({c: np.float32 for c in as32})
    pd.testing.assert_frame_equal(from_parquet, rounded, check_dtype=False, rtol=0, atol=0)
    assert str(from_parquet["ut_id"].dtype) == "int32"


def test_abort_and_exceptions_leave_no_final_file(tmp_path):
    epochs = random_trace(n_epoch=3)
    w = TraceWriter(tmp_path, formats=("csv", "parquet"), chunk_rows=5)
    for e in epochs:
        w.append(e)
    assert len(list(tmp_path.glob("trace.csv.*.partial"))) == 1
    assert not (tmp_path / "trace.csv").exists()
    w.abort()
    assert list(tmp_path.iterdir()) == []

    with pytest.raises(RuntimeError, match="boom"), TraceWriter(tmp_path, chunk_rows=2) as w2:
        w2.append(epochs[0])
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_bad_columns_are_rejected(tmp_path):
    e = random_trace(n_epoch=1)[0]
    with TraceWriter(tmp_path) as w:
        with pytest.raises(ValueError, match=r"missing: \['snr_db'\]"):
            w.append({k: v for k, v in e.items() if k != "snr_db"})
        with pytest.raises(ValueError, match="must be integer"):
            w.append({**e, "ut_id": e["ut_id"] + 0.5})
        with pytest.raises(ValueError, match="different lengths"):
            w.append({**e, "snr_db": e["snr_db"][:2]})
    assert (tmp_path / "trace.csv").read_text() == ",".join(TRACE_COLUMNS) + "\n"


def run_controller(snr_seq, n_beam=2):
    state = ControllerState.initial(snr_seq.shape[1])
    results = []
    for k in range(snr_seq.shape[0]):
        res = step(float(k), snr_seq[k], state, MaxSnr(), 0.0, 0.0, n_beam)
        results.append(res)
        state = res.state
    return results, close_dwells(state, float(snr_seq.shape[0]))


def test_event_log_round_trip(tmp_path):
    rng = np.random.default_rng(5)
    snr = rng.normal(5.0, 4.0, (25, 4, 4))
    results, _ = run_controller(snr)
    with EventLog(tmp_path, chunk_rows=3) as log:
        for r in results:
            log.append(r.events)
    df = pd.read_csv(tmp_path / "events.csv")
    assert list(df.columns) == list(EVENT_COLUMNS)
    expected = pd.DataFrame({k: np.concatenate([r.events[k] for r in results]) for k in df})
    assert len(df) > 5
    pd.testing.assert_frame_equal(df, expected, check_dtype=False)
    assert df.sort_values(["time_s", "ut_id"], kind="stable").index.equals(df.index)


def test_grouped_percentiles_match_numpy_per_group():
    rng = np.random.default_rng(6)
    group = rng.integers(0, 6, 500)
    group[group == 4] = 5  # group 4 empty
    values = rng.normal(0.0, 10.0, 500)
    q = [0.0, 5.0, 37.0, 50.0, 95.0, 100.0]
    got = grouped_percentiles(group, values, 6, q)
    for g in range(6):
        sel = values[group == g]
        expected = np.percentile(sel, q) if sel.size else np.full(len(q), np.nan)
        np.testing.assert_allclose(got[g], expected, rtol=0, atol=1e-12)


def test_summary_matches_pandas(tmp_path):
    epochs = random_trace(seed=7, n_epoch=40, n_ut=5)
    rng = np.random.default_rng(8)
    results, tail = run_controller(rng.normal(5.0, 4.0, (40, 5, 4)))
    acc = SummaryAccumulator(5, epoch_s=0.1)  # random_trace steps 0.1 s
    for e, r in zip(epochs, results, strict=True):
        acc.add_trace(e)
        acc.add_events(r.events)
        acc.add_dwells(r.dwells)
    acc.add_dwells(tail)
    summary = acc.summary()
    write_json_atomic(tmp_path / "summary.json", summary)
    summary = json.loads((tmp_path / "summary.json").read_text())  # what users read

    df = as_frame(epochs)
    g = df.groupby("ut_id")
    ev = pd.DataFrame({k: np.concatenate([r.events[k] for r in results]) for k in EVENT_COLUMNS})
    dw = pd.DataFrame({k: np.concatenate([r.dwells[k] for r in results] + [tail[k]]) for k in tail})
    dw["duration_s"] = dw["end_s"] - dw["start_s"]
    complete = dw[~dw["censored_start"] & ~dw["censored_end"]]
    for i, ut in enumerate(summary["per_ut"]):
        rows = g.get_group(i)
        assert ut["n_epochs"] == len(rows)
        assert ut["outage_fraction"] == pytest.approx((rows["service"] == "outage").mean())
        by_reason = ut["outage_fraction_by_reason"]
        for reason in ("no_satellite", "below_threshold"):
            assert by_reason[reason] == pytest.approx((rows["outage_reason"] == reason).mean())
        gap = rows["interruption_s"].sum() / (len(rows) * 0.1)
        assert ut["handover_interruption_fraction"] == by_reason["handover"] == pytest.approx(gap)
        assert ut["mean_throughput_bps"] == pytest.approx(rows["throughput_bps"].fillna(0).mean())
        assert ut["max_abs_doppler_hz"] == pytest.approx(rows["doppler_hz"].abs().max())
        assert ut["max_angular_speed_deg_s"] == pytest.approx(rows["angular_speed_deg_s"].max())
        for col in ("snr_db", "sinr_db"):
            s = rows[col].dropna()
            assert ut[col]["mean"] == pytest.approx(s.mean(), abs=1e-9)
            for q in (5, 50, 95):
                assert ut[col][f"p{q}"] == pytest.approx(s.quantile(q / 100), abs=PER_UT_DB)
        kinds = ev[ev["ut_id"] == i]["kind"].value_counts()
        for kind in ("beam_handover", "sat_handover", "outage_start", "outage_end"):
            assert ut["handovers"][kind] == kinds.get(kind, 0)
        mine = complete[complete["ut_id"] == i].sort_values("start_s")
        assert ut["dwell"]["complete_s"] == pytest.approx(mine["duration_s"].tolist())
        if len(mine):
            assert ut["dwell"]["mean_s"] == pytest.approx(mine["duration_s"].mean())
            assert ut["dwell"]["median_s"] == pytest.approx(mine["duration_s"].median())
        cens = dw[(dw["ut_id"] == i) & (dw["censored_start"] | dw["censored_end"])]
        assert len(ut["dwell"]["censored"]) == len(cens)
        assert all(c["censored_start"] or c["censored_end"] for c in ut["dwell"]["censored"])
    overall = summary["overall"]
    assert overall["outage_fraction"] == pytest.approx((df["service"] == "outage").mean())
    for col in ("snr_db", "sinr_db"):
        for q in (5, 50, 95):
            expected = df[col].quantile(q / 100)
            assert overall[col][f"p{q}"] == pytest.approx(expected, abs=OVERALL_DB)
    assert overall["dwell"]["median_s"] == pytest.approx(complete["duration_s"].median())
    assert overall["handovers"]["handovers_total"] == ev["kind"].str.endswith("handover").sum()


def test_summary_of_a_ut_without_samples_is_null(tmp_path):
    acc = SummaryAccumulator(2)
    e = random_epoch(np.random.default_rng(0), 0.0, 2)
    e["snr_db"][:] = np.nan
    e["sinr_db"][:] = np.nan
    acc.add_trace(e)
    path = write_json_atomic(tmp_path / "s.json", acc.summary())
    text = path.read_text()
    assert "NaN" not in text
    ut0 = json.loads(text)["per_ut"][0]
    assert ut0["snr_db"] == {"mean": None, "p5": None, "p50": None, "p95": None}
    assert ut0["dwell"]["mean_s"] is None


def test_write_text_atomic_leaves_no_partial(tmp_path):
    path = write_text_atomic(tmp_path / "a.txt", "hello\n")
    assert path.read_text() == "hello\n"
    with pytest.raises(TypeError):
        write_json_atomic(tmp_path / "b.json", {"x": object()})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]


def _leaf_pairs():
    """(value as a summary holds it, what JSON must read back): numpy and Python scalars,
    non-finite floats as null."""
    from hypothesis import strategies as st

    finite = st.floats(allow_nan=False, allow_infinity=False)
    return st.one_of(
        finite.map(lambda x: (x, x)),
        finite.map(lambda x: (np.float64(x), x)),
        st.floats(width=32, allow_nan=False, allow_infinity=False).map(
            lambda x: (np.float32(x), float(np.float32(x)))
        ),
        st.sampled_from([float("nan"), float("inf"), -float("inf"), np.float64("nan")]).map(
            lambda x: (x, None)
        ),
        st.integers(-(2**62), 2**62).map(lambda i: (np.int64(i), i)),
        st.integers(-(2**63), 2**64 - 1).map(lambda i: (i, i)),  # orjson's range
        st.booleans().map(lambda b: (np.bool_(b), b)),
        st.booleans().map(lambda b: (b, b)),
        st.none().map(lambda n: (n, n)),
        st.text(max_size=8).map(lambda s: (s, s)),
    )


def _tree_pairs():
    from hypothesis import strategies as st

    def grow(children):
        keys = st.one_of(st.text(max_size=5), st.integers(-9, 9))
        as_list = st.lists(children, max_size=4)
        return st.one_of(
            as_list.map(lambda items: ([v for v, _ in items], [e for _, e in items])),
            as_list.map(lambda items: (tuple(v for v, _ in items), [e for _, e in items])),
            st.lists(st.floats(allow_nan=False, allow_infinity=False), max_size=4).map(
                lambda xs: (np.asarray(xs, float), xs)
            ),
            st.dictionaries(keys, children, max_size=4).map(
                lambda d: (
                    {k: v for k, (v, _) in d.items()},
                    {str(k): e for k, (_, e) in d.items()},
                )
            ),
        )

    return st.recursive(_leaf_pairs(), grow, max_leaves=20)


def test_json_holds_the_plain_values(tmp_path_factory):
    """What summary.json holds: numpy scalars and arrays as numbers and lists, NaN and
    infinities as null, keys as strings, every float read back to the same bits, indented
    by two spaces; the expected values are built beside the inputs, not by the converter."""
    from hypothesis import given, settings

    folder = tmp_path_factory.mktemp("json")

    @settings(max_examples=300, deadline=None)
    @given(_tree_pairs())
    def check(pair):
        value, expected = pair
        path = write_json_atomic(folder / "s.json", {"x": value})
        text = path.read_text()
        assert json.loads(text) == {"x": expected}
        assert text.startswith('{\n  "x": ') and text.endswith("\n}\n")

    check()


def test_an_integer_beyond_64_bits_is_refused_and_nothing_is_left(tmp_path):
    with pytest.raises(TypeError):
        write_json_atomic(tmp_path / "big.json", {"n": [1, 2**64]})
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("chunk_rows", [5, 1_000_000])
def test_a_trace_flushed_before_close_is_the_same_files(tmp_path, chunk_rows):
    """``TableWriter.flush`` (the sinks' ``flush_pending``, before any sink finishes) hands
    the partial chunk that ``close`` would: byte-identical CSV and Parquet files, whether
    the chunk is partial (a flush with rows) or every chunk was written already."""
    epochs = random_trace(n_epoch=10)
    files = {}
    for flushed in (False, True):
        out = tmp_path / str(flushed)
        w = TraceWriter(out, formats=("csv", "parquet"), chunk_rows=chunk_rows)
        for e in epochs:
            w.append(e)
        if flushed:
            w.flush()
            assert w._n_filled == 0
        w.close()
        files[flushed] = [(out / f"trace.{f}").read_bytes() for f in ("csv", "parquet")]
    assert files[True] == files[False]
