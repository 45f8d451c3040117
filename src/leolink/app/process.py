"""The ``leolink`` process's start and end (:func:`leolink.cli.console`).

:func:`start` makes the settings of a process that runs one command, before numpy loads.
:func:`end` ends it with Python's own exit (``sys.exit``: the exit functions, the
teardown), after the standard streams' last bytes: a reader that went away (``| head``)
is not an error, a full disk under a redirection is said in one line.

It ended with ``os._exit`` after the private ``atexit._run_exitfuncs``, to skip the
teardown; measured before that was removed (a 10-epoch paper run, no pictures, a fresh
process each, 5 runs on a loaded 2-core machine, together with the deferred pydantic builds
of :mod:`leolink.registry`): wall median 2.99 s, CPU median 0.96 s with them, 2.65 s and
0.84 s without. Not the 5 % that would earn a change of the process's semantics.
"""

from __future__ import annotations

import gc
import os
import sys

from leolink.compiled import single_threaded_blas

__all__ = ["end", "start"]

#: The exit status of a command whose last output could not be written: an error of the
#: environment (:data:`leolink.cli.EXIT_USAGE`).
EXIT_ENVIRONMENT = 2


def start(environ=os.environ):
    """Settings of the command's process (and of the processes it starts): BLAS on one
    thread (:func:`~leolink.compiled.single_threaded_blas`) unless the environment says
    otherwise."""
    single_threaded_blas(environ)


def end(code):
    """End the process with exit status ``code`` (int); never returns."""
    gc.freeze()  # (the teardown's collector then skips every object: ~0.1 s less)
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (BrokenPipeError, ValueError):  # its reader is gone (| head); it was closed
            _to_devnull(stream)
        except OSError as exc:  # a full disk under a redirection: say so, as for a file
            _to_devnull(stream)
            if stream is sys.stdout:
                _say(f"leolink: error: cannot write the standard output: {exc.strerror}")
                code = code or EXIT_ENVIRONMENT
    sys.exit(code)


def _to_devnull(stream):
    """Point ``stream``'s descriptor at the null device: the interpreter's last flush of
    what it still holds then succeeds, silently (Python's advice for SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, stream.fileno())
    except (OSError, ValueError):
        pass


def _say(line):
    try:
        os.write(2, (line + "\n").encode())
    except OSError:
        pass
