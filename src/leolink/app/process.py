"""The ``leolink`` process's start and end (:func:`leolink.cli.console`).

:func:`start` makes the settings of a process that runs one command, before numpy and
leolink's models load. :func:`end` ends it without the interpreter's teardown: what the
teardown would free one object at a time, the end of the process frees at once. A 10-UT
run's exit took 106-136 ms with the collector's last passes over every object, 21-32 ms
with them frozen, and ~10 ms less without the teardown (the run 0.393 -> 0.382 s, side by
side, ``benchmarks/bench_small.py``'s command). Outputs are closed before they are renamed
into place; what the teardown would do besides is done here: the exit functions (logging's,
multiprocessing's for its children, weakref finalizers, the caller's) and the streams' last
bytes. A thread still running is waited for, and a profiler or tracer (``python -m
cProfile``, coverage) gets its end, as Python would.
"""

from __future__ import annotations

import atexit
import gc
import os
import sys
import threading

from leolink.compiled import MODELS_ON_FIRST_USE, single_threaded_blas

__all__ = ["end", "start"]

#: The exit status of a command whose last output could not be written: an error of the
#: environment (:data:`leolink.cli.EXIT_USAGE`).
EXIT_ENVIRONMENT = 2


def start(environ=os.environ):
    """Settings of the command's process (and of the processes it starts): BLAS on one
    thread (:func:`~leolink.compiled.single_threaded_blas`), the pydantic models built at
    their first use (:func:`~leolink.compiled.models_on_first_use`: the command uses them
    on one thread), each unless the environment says otherwise."""
    single_threaded_blas(environ)
    environ.setdefault(MODELS_ON_FIRST_USE, "1")


def end(code):
    """End the process with exit status ``code`` (int); never returns."""
    gc.freeze()  # (when the teardown runs, its collector then skips every object)
    if threading.active_count() > 1 or sys.getprofile() or sys.gettrace():
        sys.exit(code)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (BrokenPipeError, ValueError):  # its reader is gone (| head); it was closed
            pass
        except OSError as exc:  # a full disk under a redirection: say so, as for a file
            if stream is sys.stdout:
                _say(f"leolink: error: cannot write the standard output: {exc.strerror}")
                code = code or EXIT_ENVIRONMENT
    os._exit(code)


def _say(line):
    try:
        os.write(2, (line + "\n").encode())
    except OSError:
        pass
