"""What the simulator streams out: epoch frames, to sinks that the caller supplies.

``sim`` writes no file. Every recorded epoch it hands each sink an :class:`EpochFrame`
(the trace columns of every UT, the events and the dwells closed at that epoch); at the
end a :class:`FinalFrame` (the dwells still open, censored by the end). Sinks that the
CLI and :func:`leolink.run` wire by default (trace and event files, the summary
statistics, plots) live in :mod:`leolink.io.sinks`; any object following :class:`Sink`
works.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["EpochFrame", "FinalFrame", "RunInfo", "Sink", "SinkGroup"]


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
    after the ``epoch`` call that carried it (each frame's arrays are new, or, like
    ``population``, the same constant array every epoch), so a sink may keep references
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
class FinalFrame:
    """The end of the run: ``end_s`` [s] and the dwells still open (``censored_end``)."""

    end_s: float
    dwells: dict[str, np.ndarray]


@runtime_checkable
class Sink(Protocol):
    """Receives the stream of one run: ``start``, ``epoch`` per recorded epoch, ``finish``;
    ``abort`` instead of ``finish`` when the run fails or is interrupted (a sink that
    writes files then removes what it had not finished)."""

    def start(self, info: RunInfo) -> None: ...

    def epoch(self, frame: EpochFrame) -> None: ...

    def finish(self, final: FinalFrame) -> None: ...

    def abort(self) -> None: ...


class SinkGroup:
    """Forward the stream to several sinks, in order; on error abort all of them."""

    def __init__(self, sinks):
        self.sinks = list(sinks)
        self._started: list = []
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

    def epoch(self, frame):
        for sink in self.sinks:
            sink.epoch(frame)

    def finish(self, final):
        for sink in self.sinks:
            sink.finish(final)

    def abort(self):
        """Abort every sink whose ``start`` was entered (all of them after a full start)."""
        for sink in self._started:
            sink.abort()
