"""The end of the ``leolink`` process (:func:`leolink.cli.console`): without the
interpreter's teardown.

What the teardown would free one object at a time, the end of the process frees at once:
a 10-UT run's exit took 106-136 ms with the collector's last passes over every object,
21-32 ms with them frozen, and ~10 ms less without the teardown (the run 0.393 -> 0.382 s,
side by side, ``benchmarks/bench_small.py``'s command). Outputs are closed before they are
renamed into place; what the teardown would do besides is done here: the exit functions
(logging's, multiprocessing's for its children, weakref finalizers, the caller's) and the
streams' last bytes. A thread still running is waited for, as Python would.
"""

from __future__ import annotations

import atexit
import gc
import os
import sys
import threading

__all__ = ["end"]


def end(code):
    """End the process with exit status ``code`` (int); never returns."""
    gc.freeze()  # (the teardown, when a thread makes it run, skips the collector's passes)
    if threading.active_count() > 1:  # a thread still runs: the teardown waits for it
        sys.exit(code)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # its reader is gone (| head), or it was closed
            pass
    os._exit(code)
