"""Pictures drawn in the run's own process.

A run's pictures (the PNG plots, the footprint GIF, the report's figures) are drawn when a
sink calls :func:`start`, in this process and on this thread: the atomic writer, the
signals (:mod:`leolink.app.guard`) and the errors are the run's own. :meth:`Job.result`
gives the drawing's value or re-raises its error where the sink collects it.

They were drawn in children forked from the run's process, with its threads alive and
Python's warning of that silenced, to overlap them with the run's last work. Measured
before that was removed (the paper run with every picture, ``leolink run
configs/paper.toml``, 3 runs each on a loaded 2-core machine, forked vs in process):
wall 16.3 / 21.5 / 35.2 s forked, 14.3 / 28.6 / 23.1 s in process (medians 21.5 and 23.1
s, x1.07, inside the load's spread of 2x): no 5 % that a measurement can show, and it cost
a clean stop: a Ctrl-C that reached the fork printed a traceback from logging's at-fork
hook and the run waited for its child (issue 49).
"""

from __future__ import annotations

import contextlib
import signal
import sys

__all__ = ["Job", "die_with_parent", "start"]

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def die_with_parent(sig=signal.SIGTERM):
    """Have the kernel send ``sig`` to this process when its parent dies (Linux only;
    a no-op elsewhere)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, sig, 0, 0, 0)


class Job:
    """A drawing's outcome: ``("ok", value)`` or ``("error", exception)``."""

    def __init__(self, name, outcome):
        self.name = name
        self._outcome = outcome

    def result(self):
        """The function's return value; its exception, re-raised, if it failed."""
        kind, value = self._outcome
        if kind == "error":
            raise value
        return value

    def cancel(self):
        """Nothing runs any more once :func:`start` returned (kept for the sinks)."""


def start(name, func, *args, **kwargs):
    """``func(*args, **kwargs)`` now; its value (or its error) by :meth:`Job.result`.

    Parameters
    ----------
    name : str
        What the job draws, for messages (e.g. ``"plots"``).
    func : callable

    Returns
    -------
    Job
    """
    try:
        return Job(name, ("ok", func(*args, **kwargs)))
    except Exception as exc:  # raised at result(), where the sink collects its files
        return Job(name, ("error", exc))
