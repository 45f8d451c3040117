"""One worker thread that handles items in order (the writers' chunks, the sinks' frames).

``put`` hands an item over and returns at once unless one item already waits: at most
two are alive, the one in hand and the one waiting, so memory stays bounded. An error on
the thread is raised by the next ``put`` or by ``close``; ``cancel`` (a run that stops)
drops what waits and returns once the item in hand is done. A long item is cut short:
its handler asks :func:`cancelled` between bounded pieces of work (a writer's slices of
rows, a sink group's sinks) and returns early once its worker is cancelled, since what it
makes is dropped: a stop waits for one piece, not for the whole item (issue 49).

The caller's side is safe to interrupt: a signal handler that raises (Ctrl-C, SIGTERM in
:mod:`leolink.app.guard`) may do so between any two bytecodes of the main thread, also
inside ``put`` or ``close``. ``queue.Queue`` is not: interrupted inside its
``Condition.notify``, it leaves the worker asleep beside a full queue, and the ``cancel``
that follows waits for ever. Nor is ``Thread.join`` (CPython 3.11): interrupted, it may
mark a running thread stopped; nor ``threading.Event`` (interrupted inside its ``with``,
it keeps its lock). The channels here are C ``queue.SimpleQueue`` s, whose ``put`` is one
step and whose blocking ``get`` takes nothing when a signal interrupts it.
"""

from __future__ import annotations

import queue
import threading

__all__ = ["BackgroundWorker", "cancelled"]

_STOP = object()  # after the items: the thread ends
_here = threading.local()  # .worker: the BackgroundWorker whose thread this is


def cancelled():
    """True on a worker's thread once its worker is cancelled (its item in hand may stop
    early: what it makes is dropped); always False on any other thread."""
    worker = getattr(_here, "worker", None)
    return worker is not None and worker._cancelled


class BackgroundWorker:
    """Runs ``handle(item)`` for each item ``put``, on one thread, in the order given.

    Parameters
    ----------
    handle : callable
        Called on the worker thread, one item at a time.
    name : str
        The thread's name.
    """

    def __init__(self, handle, name="leolink-worker"):
        self._handle, self._error, self._cancelled = handle, None, False
        self._items: queue.SimpleQueue = queue.SimpleQueue()
        self._room: queue.SimpleQueue = queue.SimpleQueue()  # one token: one item may wait
        self._room.put(None)
        self._ended: queue.SimpleQueue = queue.SimpleQueue()  # the thread's last word
        self._finished = False  # set by the thread before it says so: read without waiting
        threading.Thread(target=self._run, name=name, daemon=True).start()

    def _run(self):
        _here.worker = self
        try:
            while (item := self._items.get()) is not _STOP:
                self._room.put(None)  # taken in hand: the next one may wait
                if self._error is None and not self._cancelled:
                    try:
                        self._handle(item)
                    except BaseException as exc:  # handed to the caller's thread
                        self._error = exc
        finally:
            self._finished = True
            self._ended.put(None)

    def put(self, item):
        """Hand ``item`` over (blocks while another one waits); raises the thread's error."""
        self._raise()
        self._room.get()
        self._items.put(item)

    def close(self):
        """Handle every item given, stop the thread, raise its error if it had one."""
        self._stop()
        self._raise()

    def cancel(self):
        """Drop the items still waiting and stop the thread once the one in hand is done;
        its error, if any, is dropped (the caller is stopping already)."""
        self._cancelled = True
        self._stop()
        self._error = None

    def _stop(self):
        if not self._finished:  # again after an interrupted stop: one _STOP ends it
            self._items.put(_STOP)  # never blocks: the end needs no room
            self._ended.get()

    def _raise(self):
        if self._error is not None:
            error, self._error = self._error, None
            raise error
