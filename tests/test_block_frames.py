"""Block frames: a run's sinks take a motion block's epochs at once (``Sink.block``), and
must end in the state that the same epochs sent one by one give (``leolink.sim.streams``).

The reference is the epoch-by-epoch path itself: ``deliver`` patched to split every block
into its epoch frames, as it does for a sink without ``block``. Every output file of real
runs (the paper's pass, a town with environments, a Walker shell with an ephemeris error)
is compared between the two paths, and the split is checked against what an epoch frame
is (its rows are one epoch's UTs, its dwells end at that epoch).
"""

import copy
import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from frame_helpers import BlockCapture
from leolink.app.run import run
from leolink.config import load_config
from leolink.io import sinks as io_sinks
from leolink.io.summary import accumulator as io_summary
from leolink.sim import monitor, motion, streams

ROOT = Path(__file__).resolve().parents[1]
SHORT = ["run.duration_s=30.0", "run.start_s=45.0"]
# The pictures are drawn from the files compared (the plots' rows: a test below).
NO_PICTURES = ["output.plots.enabled=false", "output.report.animation=false"]
BOTH_TRACES = "output.trace.formats=['csv', 'parquet']"
RUNS = {
    # a partial first block (the warm-up), trace chunks of 100 rows
    "paper": ("configs/paper.toml",
              ["run.epoch_s=0.25", "run.warmup_s=3.5", BOTH_TRACES, "output.trace.chunk_rows=100"]),
    "town": ("configs/examples/town.toml", []),
    "walker_ephemeris": (
        "configs/examples/walker.toml",
        ["run.duration_s=40.0", "ephemeris_error.model='rtn'",
         "ephemeris_error.rtn.along_track_m=2000.0"],
    ),
}  # fmt: skip


def _split(sink, frame):
    for epoch in frame.frames():
        sink.epoch(epoch)


def _run(name, out, epoch_by_epoch, monkeypatch):
    path, sets = RUNS[name]
    with monkeypatch.context() as m:
        m.setattr(io_summary, "_POOL_BUFFER", 50)  # the summary folds its rows many times
        if epoch_by_epoch:
            m.setattr(streams, "deliver", _split)
            m.setattr(monitor, "deliver", _split)
        short = SHORT if name != "walker_ephemeris" else []
        cfg = load_config(ROOT / path, [*short, *NO_PICTURES, *sets])
        run(cfg, out_dir=out)
    return out


def _same_file(a, b):
    if a.name in ("run.json", "report.html") or a.suffix in (".png", ".gif"):
        return True  # wall times / pictures: drawn from the files compared here
    if a.name == "summary.json":
        x, y = json.loads(a.read_text()), json.loads(b.read_text())
        x["run"].pop("wall_time_s"), y["run"].pop("wall_time_s")
        return x == y
    if a.suffix == ".parquet":
        return pq.read_table(a).to_pandas().equals(pq.read_table(b).to_pandas())  # NaN == NaN
    if a.suffix == ".npz":
        x, y = np.load(a, allow_pickle=False), np.load(b, allow_pickle=False)
        return x.files == y.files and all(
            np.array_equal(x[k], y[k], equal_nan=x[k].dtype.kind == "f") for k in x.files
        )
    return a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("name", sorted(RUNS))
def test_a_run_is_the_same_sent_a_block_or_an_epoch_at_a_time(
    name, tmp_path, monkeypatch, blocks_of_64
):
    block = _run(name, tmp_path / "block", False, monkeypatch)
    epoch = _run(name, tmp_path / "epoch", True, monkeypatch)
    if name == "paper":  # 14 warm-up epochs, 120 recorded: a partial first block
        assert blocks_of_64 == [(0, 64), (64, 128), (128, 134)] * 2
    files = sorted(p.name for p in block.iterdir())
    assert files == sorted(p.name for p in epoch.iterdir())
    assert {"summary.json", "events.csv", "report_stats.npz"} <= set(files)
    if name == "walker_ephemeris":
        assert "ephemeris_errors.csv" in files
    differ = [f for f in files if not _same_file(block / f, epoch / f)]
    assert differ == []


@pytest.fixture(scope="module")
def captured():
    """The block frames of the paper's pass at 0.5 s (7 UTs, several blocks, handovers)."""
    from leolink.app.scenario import build_scenario
    from leolink.sim.runner import run_simulation

    cfg = load_config(ROOT / "configs/paper.toml", ["run.epoch_s=0.5"])
    cap = BlockCapture()
    with pytest.MonkeyPatch.context() as mp:  # blocks of 64 epochs (conftest.blocks_of_64)
        mp.setattr(motion, "MAX_BLOCK_EPOCHS", 64)
        run_simulation(build_scenario(cfg), [cap])
    assert len(cap.blocks) > 2 and len(set(cap.info.population)) > 1
    return cap


def test_epoch_frames_of_a_block_are_its_epochs(captured):
    n_ut, n_epoch = captured.info.n_ut, 0
    for block in captured.blocks:
        assert block.k0 == n_epoch  # blocks follow one another
        for i, frame in enumerate(block.frames()):
            assert frame.k == block.k0 + i and frame.t_s == block.t_s[i]
            np.testing.assert_array_equal(frame.columns["ut_id"], np.arange(n_ut))
            np.testing.assert_array_equal(frame.columns["time_s"], np.full(n_ut, frame.t_s))
            assert tuple(frame.columns["population"]) == captured.info.population
            assert np.all(frame.dwells["end_s"] == frame.t_s)  # a dwell closes at its epoch
            ev = frame.events["time_s"]
            assert np.all((ev >= frame.t_s) & (ev < frame.t_s + captured.info.epoch_s))
            n_epoch += 1
        n_ev = sum(len(f.events["ut_id"]) for f in block.frames())
        assert n_ev == len(block.events["ut_id"]) == block.event_end[-1]
    assert n_epoch == captured.info.n_epochs
    assert sum(len(b.events["ut_id"]) for b in captured.blocks) > 0  # events to split
    assert sum(len(b.dwells["ut_id"]) for b in captured.blocks) > 0


def _state(sink):
    if isinstance(sink, io_sinks.PlotSink):
        rows = pa.concat_tables([io_sinks.TRACE_SCHEMA.empty_table(), *sink._rows])
        events = pa.concat_tables([io_sinks.EVENT_SCHEMA.empty_table(), *sink._events])
        return rows, events, sink._span
    return sink.trace(), sink.events()


@pytest.mark.parametrize(
    "make",
    [lambda: io_sinks.PlotSink("unused", None, ut_ids=(0, 5, 6)), io_sinks.MemorySink],
    ids=["plots", "memory"],
)  # fmt: skip
def test_sinks_in_memory_end_the_same_by_block_or_by_epoch(captured, make):
    by_block, by_epoch = make(), make()
    for sink in (by_block, by_epoch):
        sink.start(captured.info)
    for block in captured.blocks:
        by_block.block(block)
        _split(by_epoch, block)
    a, b = _state(by_block), _state(by_epoch)
    if isinstance(by_block, io_sinks.PlotSink):
        assert a[0].num_rows == 3 * captured.info.n_epochs and a[1].num_rows > 0
        assert a[0].equals(b[0]) and a[1].equals(b[1]) and a[2] == b[2]
    else:
        assert len(a[0]) == captured.info.n_ut * captured.info.n_epochs
        assert a[0].equals(b[0]) and a[1].equals(b[1])


class _EpochsOnly:
    """A sink of the Sink protocol without ``block`` (as a user's may be)."""

    def start(self, info):
        self.frames = []

    def epoch(self, frame):
        self.frames.append(copy.deepcopy(frame))

    def finish(self, final):
        pass

    def abort(self):
        pass


def test_a_sink_without_block_gets_the_epoch_frames_in_order(captured):
    from leolink.app.scenario import build_scenario
    from leolink.sim.runner import run_simulation

    sink, memory = _EpochsOnly(), io_sinks.MemorySink()
    cfg = load_config(ROOT / "configs/paper.toml", ["run.epoch_s=0.5"])
    run_simulation(build_scenario(cfg), [sink, memory])
    n_ut, n_epoch = captured.info.n_ut, captured.info.n_epochs
    assert [f.k for f in sink.frames] == list(range(n_epoch))
    trace, events = memory.trace(), memory.events()  # the same run's rows, taken by block
    for f in sink.frames:
        rows = trace.iloc[f.k * n_ut : (f.k + 1) * n_ut]
        assert np.all(rows.time_s.to_numpy() == f.t_s)
        for name in ("ut_id", "sat_id", "beam_id", "snr_db", "sinr_db", "doppler_hz"):
            np.testing.assert_array_equal(rows[name].to_numpy(), f.columns[name])
    ev = {k: np.concatenate([f.events[k] for f in sink.frames]) for k in ("time_s", "ut_id")}
    np.testing.assert_array_equal(ev["time_s"], events.time_s.to_numpy())
    np.testing.assert_array_equal(ev["ut_id"], events.ut_id.to_numpy())
    assert len(ev["ut_id"]) > 0


def test_the_monitor_assembles_a_block_as_its_epochs_one_by_one(monkeypatch, blocks_of_64):
    """``Monitor._columns`` of a block's records equals the same function over each epoch's
    slice of the links (the monitor's code before blocks), joined: beam sharing, fading,
    a SINR service threshold and a handover time make every branch of it run."""
    calls = []
    original = monitor.Monitor._columns

    def checked(self, recs, cols):
        if len(recs) > 1:
            n = len(recs[0].geo_sat)
            cut = [
                {k: v[i * n : (i + 1) * n].copy() for k, v in cols.items()}
                for i in range(len(recs))
            ]
            parts = [original(self, [r], c) for r, c in zip(recs, cut, strict=True)]
            out = original(self, recs, {k: v.copy() for k, v in cols.items()})
            for key in out:
                joined = np.concatenate([np.asarray(p[key]) for p in parts])
                assert np.array_equal(out[key], joined, equal_nan=joined.dtype.kind == "f"), key
            calls.append(len(recs))
        return original(self, recs, cols)

    monkeypatch.setattr(monitor.Monitor, "_columns", checked)
    sets = ["run.epoch_s=0.5", "controller.handover_time_s=0.2", "controller.service_metric='sinr'",
            "link.fading='rician'", "link.interference='all_satellites'",
            "scheduler.kind='round_robin'"]  # fmt: skip
    from leolink.app.scenario import build_scenario
    from leolink.sim.runner import run_simulation

    cfg = load_config(ROOT / "configs/paper.toml", sets)
    run_simulation(build_scenario(cfg), [io_sinks.MemorySink()])
    assert len(calls) > 2


def test_an_interrupted_run_counts_the_blocks_it_finished():
    from leolink.app.run import _Position

    pos = _Position()
    pos.start(type("Info", (), {"n_epochs": 240})())
    pos.block(streams.BlockFrame(0, np.arange(64) * 0.5, 7, {}, {}, {}, np.zeros(64), np.zeros(64)))
    assert pos.where(None) == "the run stopped after t = 31.5 s (epoch 64 of 240)"


class _Counting:
    def __init__(self):
        self.n_epoch, self.n_block = 0, 0

    def epoch(self, frame):
        self.n_epoch += 1

    def block(self, frame):
        self.n_block += 1


class _OwnEpoch(_Counting):
    """Overrides ``epoch`` only: it must see every epoch."""

    def epoch(self, frame):
        self.n_epoch += 10


def test_a_subclass_overriding_epoch_only_gets_epochs(captured):
    block = captured.blocks[0]
    base, sub = _Counting(), _OwnEpoch()
    streams.deliver(base, block)
    streams.deliver(sub, block)
    assert (base.n_block, base.n_epoch) == (1, 0)
    assert (sub.n_block, sub.n_epoch) == (0, 10 * len(block.t_s))
