"""The sinks' background thread: leolink.background.BackgroundWorker, and a run whose sinks
take each block on that thread while the simulator computes the next one."""

import contextlib
import queue
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from frame_helpers import BlockCapture
from leolink.background import BackgroundWorker, cancelled
from leolink.config import load_config

ROOT = Path(__file__).resolve().parents[1]
# The paper's pass at 0.5 s for 70 s: 140 epochs, blocks of 64, 64 and 12 epochs (with
# conftest.blocks_of_64; 7 UTs alone would take one block).
SETS = ["run.epoch_s=0.5", "run.duration_s=70.0"]


def test_a_worker_handles_every_item_in_order_on_its_own_thread():
    seen, threads = [], set()

    def handle(item):
        seen.append(item)
        threads.add(threading.current_thread().name)

    worker = BackgroundWorker(handle, "test-worker")
    for i in range(50):
        worker.put(i)
    worker.close()  # waits for all of them
    assert seen == list(range(50)) and threads == {"test-worker"}


def test_a_workers_error_is_raised_on_the_callers_thread_and_stops_its_work():
    seen, gate = [], threading.Event()

    def handle(item):
        if item == 3:
            gate.wait(5.0)  # item 4 waits in the queue meanwhile: it must not be handled
            raise ValueError("item 3 is bad")
        seen.append(item)

    worker = BackgroundWorker(handle)
    with pytest.raises(ValueError, match="item 3 is bad"):
        for i in range(10):
            worker.put(i)
            if i == 4:
                gate.set()
        worker.close()
    worker.cancel()
    assert seen == [0, 1, 2]


def test_cancel_drops_what_waits_once_the_item_in_hand_is_done():
    seen, started, release = [], threading.Event(), threading.Event()

    def handle(item):
        started.set()
        release.wait(5.0)
        seen.append(item)

    worker = BackgroundWorker(handle)
    worker.put("in hand")
    started.wait(5.0)
    worker.put("waiting")  # the queue holds one
    threading.Timer(0.05, release.set).start()
    worker.cancel()
    assert seen == ["in hand"]


def test_cancel_cuts_the_item_in_hand_short_where_it_asks():
    """Issue 49: a long item asks :func:`cancelled` between its pieces and returns at the
    first piece after ``cancel`` (a stop waits for one piece, not the whole item); the
    caller's thread is never "cancelled"."""
    pieces, started, tokens = [], threading.Event(), queue.SimpleQueue()
    n_pieces = 100  # each waits for a token, 5 s at most: a cancel unseen reaches the end

    def handle(item):
        started.set()
        for _ in range(n_pieces):
            if cancelled():
                return
            with contextlib.suppress(queue.Empty):
                tokens.get(timeout=0.05)
            pieces.append(item)

    worker = BackgroundWorker(handle)
    worker.put("long")
    started.wait(5.0)
    worker.cancel()
    assert len(pieces) < n_pieces  # it stopped at the piece after the cancel
    assert not cancelled()


class _Interrupt(BaseException):
    """What a signal handler raises (Ctrl-C, SIGTERM: leolink.app.guard.Stopped)."""


def _interrupted_at(k, call, *args):
    """``call(*args)`` with :class:`_Interrupt` raised at its ``k``-th bytecode (in every
    Python frame it enters: queue, threading); True if ``call`` ran fewer."""
    count = 0

    def trace(frame, event, arg):
        nonlocal count
        frame.f_trace_opcodes = True
        if event == "opcode":
            count += 1
            if count == k:
                raise _Interrupt
        return trace

    sys.settrace(trace)
    try:
        call(*args)
    except _Interrupt:
        return False
    finally:
        sys.settrace(None)
    return True


def test_an_interrupted_put_never_keeps_cancel_from_returning():
    """A signal handler that raises may do so between any two bytecodes of the caller,
    also inside ``put``: ``cancel`` must still return (with ``queue.Queue`` it waited for
    ever when ``Condition.notify`` was interrupted before it woke the worker, and a
    stopped sweep worker was killed with its partial files left)."""
    for k in range(1, 1000):
        seen = []
        worker = BackgroundWorker(seen.append)
        worker.put("before")
        while not seen:  # the worker is done with it and waits for the next item
            threading.Event().wait(0.001)
        ran_whole = _interrupted_at(k, worker.put, "interrupted")
        stopper = threading.Thread(target=worker.cancel, daemon=True)
        stopper.start()
        stopper.join(5.0)
        assert not stopper.is_alive(), f"cancel hangs after put was interrupted at bytecode {k}"
        assert seen in (["before"], ["before", "interrupted"])
        if ran_whole:  # every bytecode of put was tried
            return
    raise AssertionError("put takes more than 1000 bytecodes")


class _ThreadLog(BlockCapture):
    """BlockCapture that also notes the thread of each call and what finish saw."""

    def start(self, info):
        super().start(info)
        self.threads = {"start": threading.current_thread().name}

    def block(self, frame):
        super().block(frame)
        self.threads.setdefault("block", set()).add(threading.current_thread().name)

    def finish(self, final):
        super().finish(final)
        self.threads["finish"] = threading.current_thread().name
        self.blocks_at_finish = len(self.blocks)


def _run(sinks, background=True, monkeypatch=None):
    from leolink.app.scenario import build_scenario
    from leolink.sim import runner, streams

    if not background:  # the same run with the sinks on the simulator's thread
        monkeypatch.setattr(runner, "SinkGroup", lambda s, background: streams.SinkGroup(s))
    cfg = load_config(ROOT / "configs/paper.toml", SETS)
    return runner.run_simulation(build_scenario(cfg), sinks)


def test_a_runs_sinks_take_its_blocks_on_one_other_thread_in_order(monkeypatch, blocks_of_64):
    log = _ThreadLog()
    _run([log])
    main = threading.current_thread().name
    assert log.threads["start"] == log.threads["finish"] == main
    assert log.threads["block"] == {"leolink-sinks"}
    assert [len(b.t_s) for b in log.blocks] == [64, 64, 12]  # all of them before finish
    assert log.blocks_at_finish == 3
    times = np.concatenate([b.t_s for b in log.blocks])
    np.testing.assert_array_equal(np.diff(times), 0.5)  # in order

    same = BlockCapture()
    _run([same], background=False, monkeypatch=monkeypatch)
    for a, b in zip(log.blocks, same.blocks, strict=True):
        assert a.columns.keys() == b.columns.keys()
        for name in a.columns:
            np.testing.assert_array_equal(a.columns[name], b.columns[name], err_msg=name)


class _Fails(BlockCapture):
    def block(self, frame):
        if self.blocks:
            raise RuntimeError("the second block is bad")
        super().block(frame)


class _Aborts(BlockCapture):
    aborted = finished = False

    def finish(self, final):
        self.finished = True

    def abort(self):
        self.aborted = True


def test_a_sinks_error_on_the_thread_fails_the_run_and_aborts_every_sink(blocks_of_64):
    other = _Aborts()
    with pytest.raises(RuntimeError, match="the second block is bad"):
        _run([_Fails(), other])
    assert other.aborted and not other.finished


class _Slow(BlockCapture):
    """Takes 2 ms a block; notes whether ``abort`` came while a block was in hand."""

    busy = aborted_while_busy = False

    def block(self, frame):
        self.busy = True
        threading.Event().wait(0.002)
        self.busy = False

    def abort(self):
        self.aborted_while_busy |= self.busy


def test_an_interrupted_finish_leaves_abort_to_stop_the_thread_first():
    """A signal during ``finish`` (waiting for the frames in flight): the ``abort`` that
    follows must wait for the block in hand before any sink aborts."""
    from leolink.sim.streams import SinkGroup

    real = BlockCapture()
    _run([real])
    for k in range(1, 2000):
        slow = _Slow()
        group = SinkGroup([slow], background=True)
        group.start(real.info)
        for frame in real.blocks:
            group.block(frame)
        ran_whole = _interrupted_at(k, group.finish, real.final)
        if not ran_whole:
            group.abort()
        assert not slow.aborted_while_busy, f"a sink aborted during a block (bytecode {k})"
        if ran_whole:
            return
    raise AssertionError("finish takes more than 2000 bytecodes")


class _Ordered(BlockCapture):
    """Notes its ``flush_pending`` and ``finish`` calls in a list shared by the sinks."""

    def __init__(self, name, calls):
        super().__init__()
        self.name, self.calls = name, calls

    def flush_pending(self):
        self.calls.append(("flush", self.name))

    def finish(self, final):
        self.calls.append(("finish", self.name))


def test_every_sink_starts_writing_before_the_first_finishes():
    """``SinkGroup.finish``: every sink's ``flush_pending`` (its files start being written
    on their threads), then the ``finish`` of each in order; a sink without one is fine."""
    from leolink.sim.streams import SinkGroup

    real = BlockCapture()
    _run([real])
    calls = []
    group = SinkGroup([_Ordered("a", calls), BlockCapture(), _Ordered("b", calls)], True)
    group.start(real.info)
    for frame in real.blocks:
        group.block(frame)
    group.finish(real.final)
    assert calls == [("flush", "a"), ("flush", "b"), ("finish", "a"), ("finish", "b")]
