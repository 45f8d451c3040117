"""Block frames against what they mean, not against the epoch path (the sixth mutation
pass, docs/testing_log.md): a block's rows and times are its epochs' (times from the config,
not from the run), its events and dwells split at their own epochs, the warm-up's cut
dwells censored, the sinks' block methods (progress, plots, link statistics) against
sums and positions recomputed from the captured rows one epoch at a time.

The run: the paper's pass at 0.5 s after a 13.5 s warm-up (27 epochs, so recording starts
inside the first motion block of 64 epochs, the tests' block length: a run of 7 UTs
alone would take blocks of 1,024), 51 s recorded: blocks of 37, 64 and 1 epochs
(a block of one epoch is a block too).
"""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from frame_helpers import BlockCapture
from leolink.app import run as app_run
from leolink.config import load_config
from leolink.io.sinks import PlotSink
from leolink.io.summary.link import LinkStats
from leolink.io.summary.stats import DbStats
from leolink.sim import streams

ROOT = Path(__file__).resolve().parents[1]
EPOCH_S, WARMUP_S, DURATION_S = 0.5, 13.5, 51.0
SETS = [f"run.epoch_s={EPOCH_S}", f"run.warmup_s={WARMUP_S}", f"run.duration_s={DURATION_S}"]


@pytest.fixture(scope="module")
def run():
    from leolink.app.scenario import build_scenario
    from leolink.sim import motion
    from leolink.sim.runner import run_simulation

    cfg = load_config(ROOT / "configs/paper.toml", SETS)
    cap = BlockCapture()
    with pytest.MonkeyPatch.context() as mp:  # blocks of 64 epochs (conftest.blocks_of_64)
        mp.setattr(motion, "MAX_BLOCK_EPOCHS", 64)
        run_simulation(build_scenario(cfg), [cap])
    return cfg, cap


def _epochs(cap):
    return [f for b in cap.blocks for f in b.frames()]


def test_blocks_are_the_recorded_epochs_in_order_at_the_configured_times(run):
    cfg, cap = run
    n_epoch = round(DURATION_S / EPOCH_S)
    start_s = cfg.run.start_s + WARMUP_S
    assert cap.info.start_s == start_s and cap.info.n_epochs == n_epoch
    lengths = [len(b.t_s) for b in cap.blocks]
    # 27 warm-up epochs: the first block is the rest of the first 64-epoch motion block
    assert lengths == [64 - 27, 64, 1] and n_epoch == 37 + 64 + 1
    k = 0
    for b in cap.blocks:
        assert b.k0 == k and b.n_ut == cap.info.n_ut
        assert b.t_s.dtype == np.float64
        np.testing.assert_allclose(b.t_s, start_s + EPOCH_S * (k + np.arange(len(b.t_s))),
                                   rtol=0, atol=1e-9)  # fmt: skip
        for name, v in b.columns.items():
            assert len(v) == len(b.t_s) * b.n_ut, name
        k += len(b.t_s)
    assert k == n_epoch


def test_each_row_of_a_block_is_its_epoch_and_its_ut(run):
    cfg, cap = run
    n_ut = cap.info.n_ut
    for b in cap.blocks:
        rows = np.arange(len(b.t_s) * n_ut)
        c = b.columns
        np.testing.assert_array_equal(c["time_s"], b.t_s[rows // n_ut])
        np.testing.assert_array_equal(c["ut_id"], rows % n_ut)
        assert c["ut_id"].dtype == np.int64
        assert list(c["population"]) == [cap.info.population[u] for u in rows % n_ut]
    # static UTs keep their position; the car and the aircraft move by equal steps
    col = {k: np.concatenate([b.columns[k] for b in cap.blocks]).reshape(-1, n_ut)
           for k in ("lat_deg", "lon_deg", "alt_m")}  # fmt: skip
    lat, lon, alt = np.radians(col["lat_deg"]), np.radians(col["lon_deg"]), col["alt_m"]
    step = 2 * np.arcsin(
        np.sqrt(
            np.sin(np.diff(lat, axis=0) / 2) ** 2
            + np.cos(lat[1:]) * np.cos(lat[:-1]) * np.sin(np.diff(lon, axis=0) / 2) ** 2
        )
    )
    for u, name in enumerate(cap.info.population):
        if name in ("centre", "static"):
            assert np.all(step[:, u] == 0) and np.all(alt[:, u] == alt[0, u])
        else:  # haversine on a sphere: equal steps to 1e-3 of a ~1e-6 rad step
            assert step[0, u] > 0
            np.testing.assert_allclose(step[:, u], step[0, u], rtol=1e-3)


def test_events_and_dwells_belong_to_the_epoch_they_are_split_into(run):
    cfg, cap = run
    n_ev = n_dw = 0
    for b in cap.blocks:
        assert b.event_end.dtype == np.int64 and b.dwell_end.dtype == np.int64
        assert len(b.event_end) == len(b.dwell_end) == len(b.t_s)
        assert b.event_end[-1] == len(b.events["ut_id"])
        assert b.dwell_end[-1] == len(b.dwells["ut_id"])
        for frame in b.frames():
            # a dwell closes at the epoch of its frame; an event lies inside its epoch
            assert np.all(frame.dwells["end_s"] == frame.t_s)
            ev = frame.events["time_s"]
            assert np.all((ev >= frame.t_s) & (ev < frame.t_s + EPOCH_S))
            n_ev, n_dw = n_ev + len(ev), n_dw + len(frame.dwells["end_s"])
    assert n_ev > 10 and n_dw > 10


def test_dwells_begun_in_the_warm_up_and_only_those_are_censored_at_the_start(run):
    cfg, cap = run
    start_s = cap.info.start_s
    dwells = [b.dwells for b in cap.blocks] + [cap.final.dwells]
    start = np.concatenate([d["start_s"] for d in dwells])
    censored = np.concatenate([d["censored_start"] for d in dwells])
    assert (start < start_s).sum() >= cap.info.n_ut  # every UT's first dwell
    np.testing.assert_array_equal(censored, start < start_s)


def test_progress_after_each_block_is_the_last_recorded_epoch(run):
    cfg, cap = run
    pos, n = app_run._Position(), 0
    pos.start(cap.info)
    for b in cap.blocks:
        streams.deliver(pos, b)
        n += len(b.t_s)
        m = re.fullmatch(r"the run stopped after t = (\S+) s \(epoch (\d+) of (\d+)\)",
                         pos.where(None))  # fmt: skip
        assert m is not None, pos.where(None)
        t_s = cfg.run.start_s + WARMUP_S + (n - 1) * EPOCH_S
        assert math.isclose(float(m[1]), t_s, abs_tol=1e-9)
        assert (int(m[2]), int(m[3])) == (n, cap.info.n_epochs)
        assert isinstance(pos.t_s, float)


def test_plot_rows_are_the_chosen_uts_rows_and_the_span_the_recorded_time(run):
    cfg, cap = run
    chosen = (1, 4)
    sink = PlotSink("unused", None, ut_ids=chosen)
    sink.start(cap.info)
    for b in cap.blocks:
        sink.block(b)
    import pyarrow as pa

    rows = pa.concat_tables(sink._rows).to_pandas()
    events = pa.concat_tables(sink._events).to_pandas()
    n_ut = cap.info.n_ut
    want = np.concatenate([np.flatnonzero(np.isin(b.columns["ut_id"], chosen)) for b in cap.blocks])
    assert len(rows) == len(chosen) * cap.info.n_epochs == len(want)
    np.testing.assert_array_equal(rows.ut_id, np.tile(chosen, cap.info.n_epochs))
    times = cap.info.start_s + EPOCH_S * np.arange(cap.info.n_epochs)
    np.testing.assert_allclose(rows.time_s, np.repeat(times, len(chosen)), rtol=0, atol=1e-9)
    sinr = np.concatenate([b.columns["sinr_db"] for b in cap.blocks]).reshape(-1, n_ut)
    np.testing.assert_array_equal(rows.sinr_db, sinr[:, list(chosen)].reshape(-1))
    all_events = np.concatenate([b.events["ut_id"] for b in cap.blocks])
    assert len(events) == np.isin(all_events, chosen).sum() > 0
    assert set(events.ut_id) <= set(chosen)
    assert sink._span == [times[0], times[-1]]


def test_link_statistics_sum_each_uts_throughput_over_its_epochs(run):
    cfg, cap = run
    n_ut = cap.info.n_ut
    by_block, by_epoch = LinkStats(n_ut, DbStats), LinkStats(n_ut, DbStats)
    for b in cap.blocks:
        by_block.add(b.columns, b.columns["ut_id"], b.columns["service"])
        for f in b.frames():
            by_epoch.add(f.columns, f.columns["ut_id"], f.columns["service"])
    frames = _epochs(cap)
    for model, key in (("shannon", "throughput_shannon_bps"), ("dvbs2x", "throughput_dvbs2x_bps")):
        # one UT at a time, epoch after epoch, NaN (no link) counting as 0
        want = [math.fsum(0.0 if math.isnan(v) else v
                          for v in (float(f.columns[key][u]) for f in frames))
                for u in range(n_ut)]  # fmt: skip
        assert by_block.tput_seen[model]
        np.testing.assert_allclose(by_block.tput_sum[model], want, rtol=1e-12, atol=0)
        # row by row in the same order: the same bits whichever way the rows come
        np.testing.assert_array_equal(by_block.tput_sum[model], by_epoch.tput_sum[model])
        assert max(want) > 0


def test_per_ut_mean_throughput_of_a_run_is_the_mean_of_its_trace_file(tmp_path):
    """summary.json's per-UT Shannon and overall throughput means against the trace
    read back from its Parquet file (NaN rows counting as 0, over every recorded epoch)."""
    import json

    import pandas as pd

    sets = ["run.epoch_s=0.5", "run.warmup_s=13.5", "run.duration_s=40.0",
            "output.trace.formats=['parquet']", "output.plots.enabled=false",
            "output.report.enabled=false"]  # fmt: skip
    app_run.run(load_config(ROOT / "configs/paper.toml", sets), out_dir=tmp_path / "out")
    trace = pd.read_parquet(tmp_path / "out" / "trace.parquet")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    n_epoch = 80
    assert len(trace) == n_epoch * len(summary["per_ut"])
    tput = trace.throughput_bps.fillna(0.0)
    # trace.parquet keeps throughput as float32: each value, hence the mean of
    # non-negative values, within 2**-24 (6e-8) relative of the float64 sum's
    for u, block in enumerate(summary["per_ut"]):
        want = math.fsum(tput[trace.ut_id == u]) / n_epoch
        got = block["link"]["mean_throughput_bps"]
        assert math.isclose(got["shannon"], want, rel_tol=1e-7), u
        assert math.isclose(block["mean_throughput_bps"], want, rel_tol=1e-7), u
        assert got["dvbs2x"] is not None and 0 < got["dvbs2x"] < want  # ACM below Shannon


def _block_of(frames):
    """A BlockFrame put together from real epoch frames (consecutive, in order)."""
    cat = lambda part: {k: np.concatenate([getattr(f, part)[k] for f in frames])  # noqa: E731
                        for k in getattr(frames[0], part)}  # fmt: skip
    ends = lambda part: np.cumsum([len(getattr(f, part)["ut_id"]) for f in frames])  # noqa: E731
    return streams.BlockFrame(frames[0].k, np.array([f.t_s for f in frames]),
                              len(frames[0].columns["ut_id"]), cat("columns"), cat("events"),
                              cat("dwells"), ends("events"), ends("dwells"))  # fmt: skip


def test_a_block_that_begins_with_events_and_dwells_splits_back_into_its_epochs(run):
    """Each epoch's events and dwells, the first epoch's too, come back in its frame."""
    cfg, cap = run
    frames = _epochs(cap)
    starts = [i for i, f in enumerate(frames[:-3])
              if len(f.events["ut_id"]) and len(f.dwells["ut_id"])]  # fmt: skip
    assert starts
    for i in starts:
        parts = frames[i : i + 3]
        back = list(_block_of(parts).frames())
        assert [f.k for f in back] == [f.k for f in parts]
        for got, want in zip(back, parts, strict=True):
            assert got.t_s == want.t_s
            for part in ("columns", "events", "dwells"):
                a, b = getattr(got, part), getattr(want, part)
                assert a.keys() == b.keys()
                for k in a:
                    np.testing.assert_array_equal(a[k], b[k], err_msg=f"{part} {k}")
