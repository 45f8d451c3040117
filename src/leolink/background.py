"""One worker thread that handles items in order (the writers' chunks, the sinks' frames).

``put`` hands an item over and returns at once unless one item already waits: at most
two are alive, the one in hand and the one waiting, so memory stays bounded. An error on
the thread is raised by the next ``put`` or by ``close``; ``cancel`` (a run that stops)
drops what waits and returns once the item in hand is done.
"""

from __future__ import annotations

import queue
import threading

__all__ = ["BackgroundWorker"]


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
        self._queue: queue.Queue = queue.Queue(maxsize=1)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self):
        while (item := self._queue.get()) is not None:
            if self._error is None and not self._cancelled:
                try:
                    self._handle(item)
                except BaseException as exc:  # handed to the caller's thread
                    self._error = exc

    def put(self, item):
        """Hand ``item`` over (blocks while another one waits); raises the thread's error."""
        self._raise()
        self._queue.put(item)

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
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()

    def _raise(self):
        if self._error is not None:
            error, self._error = self._error, None
            raise error
