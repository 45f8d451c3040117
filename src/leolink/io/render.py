"""Pictures drawn in child processes while the run finishes its other work.

A run's pictures (the PNG plots, the footprint GIF, the report's figures) are CPU-bound
matplotlib work that needs nothing the run still has to do (close the trace, write
``summary.json``), and matplotlib draws one figure at a time on one core. :func:`start`
runs such a job in a child forked from the run's process: the child has the sink's
statistics without copying them (copy-on-write), writes its files through the atomic
writer as the run would, and sends back only its small result (paths, ``data:`` URIs),
pickled over a pipe; :meth:`Job.result` waits for it and re-raises the child's error. The
jobs of a run and its own last work then share the machine's cores: on two cores the
constellation's ~11 s of pictures take ~6 s of wall time.

The pictures are the same bytes as when drawn in the run's own process (a test compares
them). The run's other threads (the kernels' pool, idle then; the trace writer's, joined
before) hold nothing a child needs: the kernels' pool is dropped in a child
(:mod:`leolink.engine.jit`), and Python 3.12's warning of a fork with threads is silenced.
``LEOLINK_FORK=0`` in the environment, or a platform without ``fork``, runs every job in
the calling process at :func:`start`.

Stopping: a child ignores SIGINT (a Ctrl-C in a terminal reaches the whole process group;
the run stops its children itself) and turns SIGTERM into ``KeyboardInterrupt``, so that
its atomic writer removes its temporary files; :meth:`Job.cancel` sends SIGTERM and waits.
On Linux a child also receives SIGTERM when the run's process dies
(``prctl(PR_SET_PDEATHSIG)``), even by SIGKILL.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import sys
import time
import traceback
import warnings

from leolink.errors import LeolinkError

__all__ = ["Job", "die_with_parent", "forking", "start"]

_EXIT_WAIT_S = 30.0  # how long a stopped child may take to remove its temporary files
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def forking():
    """Whether :func:`start` forks: ``os.fork`` exists and ``LEOLINK_FORK`` is not 0."""
    off = os.environ.get("LEOLINK_FORK", "1").strip().lower() in ("0", "false", "no", "off")
    return hasattr(os, "fork") and not off


def die_with_parent(sig=signal.SIGTERM):
    """Have the kernel send ``sig`` to this process when its parent dies (Linux only;
    a no-op elsewhere)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, sig, 0, 0, 0)


class Job:
    """A function's result, computed in a child process (or already, in this one)."""

    def __init__(self, name):
        self.name = name
        self._pid = self._fd = None
        self._outcome = None  # ("ok", value) or ("error", exception), once known

    def result(self):
        """The function's return value; its exception, re-raised, if it failed."""
        if self._outcome is None:
            self._outcome = self._collect()
        kind, value = self._outcome
        if kind == "error":
            raise value
        return value

    def cancel(self):
        """Stop the child (SIGTERM: it removes its temporary files) and wait for it."""
        if self._pid is None:
            return
        os.close(self._fd)  # a child blocked on writing its result gets EPIPE and exits
        pid, self._pid, self._fd = self._pid, None, None
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGTERM)
        deadline = time.monotonic() + _EXIT_WAIT_S
        while os.waitpid(pid, os.WNOHANG) == (0, 0):
            if time.monotonic() > deadline:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                break
            time.sleep(0.01)
        self._outcome = ("error", LeolinkError(f"{self.name}: stopped"))

    def _collect(self):
        chunks = []
        try:
            while chunk := os.read(self._fd, 1 << 20):
                chunks.append(chunk)
        except BaseException:  # a signal while waiting: stop the child, then propagate
            self.cancel()
            raise
        os.close(self._fd)
        _, status = os.waitpid(self._pid, 0)
        self._pid = self._fd = None
        if chunks:
            return pickle.loads(b"".join(chunks))
        code = os.waitstatus_to_exitcode(status)
        why = f"killed by signal {-code}" if code < 0 else f"exit code {code}"
        return ("error", LeolinkError(f"{self.name}: its process ended without a result ({why})"))


#: What the picture jobs import (~1 s of CPU): imported once in the run's process
#: before the first fork, so the children share it instead of importing it each.
PRELOAD = ("matplotlib.figure", "matplotlib.backends.backend_agg", "PIL.Image", "pandas")


def _preload():
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)


def start(name, func, *args, **kwargs):
    """``func(*args, **kwargs)`` in a forked child; :meth:`Job.result` gives its value.

    Parameters
    ----------
    name : str
        What the job draws, for messages (e.g. ``"plots"``).
    func : callable
        Anything: a closure or a lambda is fine (nothing is pickled but the result).

    Returns
    -------
    Job
    """
    job = Job(name)
    if not forking():
        try:
            job._outcome = ("ok", func(*args, **kwargs))
        except Exception as exc:  # raised at result(), as from a child
            job._outcome = ("error", exc)
        return job
    _preload()
    read_fd, write_fd = os.pipe()
    with warnings.catch_warnings():  # Python >= 3.12 warns of a fork with threads: the
        warnings.simplefilter("ignore", DeprecationWarning)  # child takes none of their locks
        pid = os.fork()
    if pid == 0:  # the child: never returns into the caller's frames
        os.close(read_fd)
        _child(write_fd, func, args, kwargs)
    os.close(write_fd)
    job._pid, job._fd = pid, read_fd
    return job


def _stop(signum, frame):
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # once: the cleanup must finish
    raise KeyboardInterrupt("SIGTERM")


def _child(fd, func, args, kwargs):
    code = 1
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, _stop)
        die_with_parent()
        try:
            payload = pickle.dumps(("ok", func(*args, **kwargs)))
            code = 0
        except BaseException as exc:
            payload = _pickled_error(exc)
        with os.fdopen(fd, "wb") as out:
            out.write(payload)
    except BaseException:  # the parent is gone or stopped us: nothing more to say
        pass
    finally:
        os._exit(code)


def _pickled_error(exc):
    try:
        return pickle.dumps(("error", exc))
    except Exception:  # an exception that cannot be pickled: its text
        text = "".join(traceback.format_exception_only(type(exc), exc)).strip()
        return pickle.dumps(("error", LeolinkError(text)))
