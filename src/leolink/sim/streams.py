"""What the simulator streams out: epoch frames, to sinks that the caller supplies.

``sim`` writes no file. Every recorded epoch reaches each sink, as an :class:`EpochFrame`
(the trace columns of every UT, the events and the dwells closed at that epoch) or within
a :class:`BlockFrame` (below); at the end a :class:`FinalFrame` (the dwells still open,
censored by the end). Sinks that the CLI and :func:`leolink.run` wire by default (trace
and event files, the summary statistics, plots) live in :mod:`leolink.io.sinks`; any
object following :class:`Sink` works.

The simulator evaluates the links of a motion block's epochs at once and hands them over
as one :class:`BlockFrame` (consecutive epochs, in order). A sink with a ``block`` method
takes it whole (one call per block instead of one per epoch: the fixed cost of an epoch);
:class:`SinkGroup` splits it into the same :class:`EpochFrame` s, in order, for the others.
A sink's ``block(frame)`` must leave it in the state that ``epoch`` over
``frame.frames()`` would. In a run the frames reach the sinks on a background thread
(:class:`SinkGroup` with ``background``): the simulator computes the next block meanwhile.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

import numpy as np

from leolink.background import BackgroundWorker, cancelled

__all__ = ["BlockFrame", "EpochFrame", "FinalFrame", "RunInfo", "Sink", "SinkGroup", "deliver"]


@dataclasses.dataclass(frozen=True)
class RunInfo:
    """What a sink knows before the first frame.

    Attributes
    ----------
    n_ut, n_sat, n_beam : int
    epoch_s : float [s]
    start_s : float [s], first recorded epoch (after the warm-up).
    n_epochs : int, recorded epochs.
    population : tuple of str, the population name of every UT (``n_ut``).
    environment : tuple of str, the TR 38.811 environment of every UT when the run models
        environments (the trace then has ``leolink.io.tables.ENVIRONMENT_COLUMNS``);
        empty for the paper's open-country link.
    extra_columns : tuple of str, trace columns of this run beyond ``TRACE_COLUMNS``
        (``n_sharing`` with beam sharing).
    """

    n_ut: int
    n_sat: int
    n_beam: int
    epoch_s: float
    start_s: float
    n_epochs: int
    population: tuple[str, ...]
    environment: tuple[str, ...] = ()
    extra_columns: tuple[str, ...] = ()


@dataclasses.dataclass(frozen=True)
class EpochFrame:
    """One recorded epoch.

    Attributes
    ----------
    k : int, index of the recorded epoch (0 = first after the warm-up).
    t_s : float [s]
    columns : dict of ndarray (n_ut,), the trace columns (``leolink.io.tables.TRACE_COLUMNS``
        and possibly more); ``service`` as int8 codes of ``controller.SERVICE_NAMES``.
    events : dict of 1-D arrays, ``controller.EVENT_COLUMNS``, this epoch's events.
    dwells : dict of 1-D arrays, ``controller.DWELL_COLUMNS``, dwells closed this epoch
        (``censored_start`` also set for dwells that began in the warm-up).

    Notes
    -----
    The arrays are handed over, read-only: the simulator never writes into an array
    after the call that carried it (each frame's arrays are new, or views of a new
    :class:`BlockFrame`'s, or, like ``population``, the same constant array for blocks of
    the same length), so a sink may keep references
    instead of copying (the trace writer buffers them until a chunk is written, on a
    background thread). A sink must not modify them: the other sinks see the same arrays.
    A producer of frames that reuses buffers across epochs must copy before the call.
    """

    k: int
    t_s: float
    columns: dict[str, np.ndarray]
    events: dict[str, np.ndarray]
    dwells: dict[str, np.ndarray]


@dataclasses.dataclass(frozen=True)
class BlockFrame:
    """Consecutive recorded epochs, the rows of each epoch after the previous epoch's.

    Attributes
    ----------
    k0 : int, index of the first recorded epoch.
    t_s : ndarray (n_epoch,) [s], the epochs' times.
    n_ut : int
    columns : dict of ndarray (n_epoch * n_ut,), the trace columns of every epoch, epoch
        after epoch (epoch ``i``'s rows are ``i * n_ut .. (i + 1) * n_ut - 1``, by UT).
    events, dwells : dict of 1-D arrays, the epochs' events and closed dwells, in order.
    event_end, dwell_end : ndarray (n_epoch,) of int, the end of each epoch's events
        (dwells) in ``events`` (``dwells``): epoch ``i`` has ``end[i - 1] .. end[i] - 1``.

    Notes
    -----
    Handed over read-only, as an :class:`EpochFrame`'s arrays (its Notes).
    """

    k0: int
    t_s: np.ndarray
    n_ut: int
    columns: dict[str, np.ndarray]
    events: dict[str, np.ndarray]
    dwells: dict[str, np.ndarray]
    event_end: np.ndarray
    dwell_end: np.ndarray

    def frames(self):
        """The block's :class:`EpochFrame` s, in order (their arrays are views of the
        block's: a sink that keeps a few epochs' rows should copy them)."""
        n, e0, d0 = self.n_ut, 0, 0
        for i, t_s in enumerate(self.t_s.tolist()):
            e1, d1 = int(self.event_end[i]), int(self.dwell_end[i])
            yield EpochFrame(
                self.k0 + i,
                t_s,
                {k: v[i * n : (i + 1) * n] for k, v in self.columns.items()},
                {k: v[e0:e1] for k, v in self.events.items()},
                {k: v[d0:d1] for k, v in self.dwells.items()},
            )
            e0, d0 = e1, d1


@dataclasses.dataclass(frozen=True)
class FinalFrame:
    """The end of the run: ``end_s`` [s] and the dwells still open (``censored_end``)."""

    end_s: float
    dwells: dict[str, np.ndarray]


@runtime_checkable
class Sink(Protocol):
    """Receives the stream of one run: ``start``, ``epoch`` per recorded epoch, ``finish``;
    ``abort`` instead of ``finish`` when the run fails or is interrupted (a sink that
    writes files then removes what it had not finished).

    Optionally ``block(frame)``: a :class:`BlockFrame` instead of its epochs' ``epoch``
    calls (:func:`deliver`); ``epoch`` is still needed (runs with radio link failure
    monitoring send epoch frames). Optionally ``flush_pending()``: start writing what it
    holds without waiting for it (on a writer thread), called on every sink before the
    first ``finish``, so that the writing overlaps the other sinks' finishing. Sinks get a
    block one after the other: a sink must not read another's state before ``finish``.
    The simulator's :class:`SinkGroup` calls ``epoch`` and ``block`` on a thread of its
    own (one, in order), ``start``, ``flush_pending``, ``finish`` and ``abort`` on the
    caller's.
    """

    def start(self, info: RunInfo) -> None: ...

    def epoch(self, frame: EpochFrame) -> None: ...

    def finish(self, final: FinalFrame) -> None: ...

    def abort(self) -> None: ...


def deliver(sink, frame):
    """Hand ``sink`` a :class:`BlockFrame`: whole if it has ``block``, else epoch by epoch.

    A subclass that overrides ``epoch`` but not its base's ``block`` gets epochs: its
    ``epoch`` must see every row.
    """
    whole = getattr(sink, "block", None)
    if whole is not None and _owner(sink, "block") <= _owner(sink, "epoch"):
        whole(frame)
        return
    for epoch in frame.frames():
        if cancelled():  # a stop (SinkGroup.abort): the rest is dropped
            return
        sink.epoch(epoch)


def _owner(sink, name):
    """Place in the sink's class hierarchy (0: its own class) of the class that defines
    ``name``; past the end for an attribute of the instance itself."""
    mro = type(sink).__mro__
    return next((i for i, cls in enumerate(mro) if name in vars(cls)), len(mro))


class SinkGroup:
    """Forward the stream to several sinks, in order; on error abort all of them.

    With ``background``, the frames reach the sinks on a thread of their own
    (:class:`~leolink.background.BackgroundWorker`), in order, while the simulator goes
    on with the next block: its arrays are never written after the call that carried
    them (:class:`EpochFrame`). ``start``, ``finish`` and ``abort`` stay on the caller's
    thread; ``finish`` first waits until every frame has been handed over, ``abort``
    drops the frames still waiting. A sink's error is raised by the next frame or by
    ``finish``.
    """

    def __init__(self, sinks, background=False):
        self.sinks = list(sinks)
        self.background = bool(background)
        self._started: list = []
        self._worker: BackgroundWorker | None = None
        for sink in self.sinks:
            if not isinstance(sink, Sink):
                raise TypeError(f"{type(sink).__name__} does not follow the Sink protocol")

    def start(self, info):
        """Start the sinks in order; a sink is counted started (``abort`` reaches it) as
        soon as its ``start`` is entered, so a failure or a signal in the middle of a later
        sink's start still lets the earlier ones remove the files they opened."""
        self._started = []
        for sink in self.sinks:
            self._started.append(sink)
            sink.start(info)
        if self.background:
            self._worker = BackgroundWorker(self._hand, "leolink-sinks")

    def epoch(self, frame):
        self._send((False, frame))

    def block(self, frame):
        """A :class:`BlockFrame` to each sink, in order (:func:`deliver`)."""
        self._send((True, frame))

    def _send(self, item):
        if self._worker is None:
            self._hand(item)
        else:
            self._worker.put(item)

    def _hand(self, item):
        whole, frame = item
        for sink in self.sinks:
            if cancelled():  # a stop: the frame is dropped, the sinks abort next
                return
            if whole:
                deliver(sink, frame)
            else:
                sink.epoch(frame)

    def finish(self, final):
        if self._worker is not None:  # kept until closed: an abort must still stop it
            self._worker.close()
            self._worker = None
        for sink in self.sinks:  # their files start being written, then each finishes
            flush = getattr(sink, "flush_pending", None)
            if flush is not None:
                flush()
        for sink in self.sinks:
            sink.finish(final)

    def abort(self):
        """Abort every sink whose ``start`` was entered (all of them after a full start),
        once the sink in hand has done with its frame, which it cuts short
        (:func:`~leolink.background.cancelled`; the frames still waiting are dropped)."""
        if self._worker is not None:
            worker, self._worker = self._worker, None
            worker.cancel()
        for sink in self._started:
            sink.abort()
