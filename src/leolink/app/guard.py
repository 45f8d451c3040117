"""What the command line wraps around every command: signals, library warnings, and the
environment's errors turned into one line.

- SIGINT, SIGTERM, SIGHUP (a closed terminal or SSH session) and SIGXCPU (``RLIMIT_CPU``'s
  soft limit) raise :class:`Stopped` (a ``KeyboardInterrupt``) in the main thread, once:
  the stream's sinks abort (:func:`leolink.sim.runner.run_simulation`), the atomic writer
  removes its temporary files, the command adds a note saying where it stopped and exits
  with 128 + the signal's number; a second signal (a second Ctrl-C) during that cleanup
  is ignored so that the cleanup finishes. A signal that lands while LLVM calls back into
  Python (numba compiling or loading a cached kernel) is sent again a moment later: an
  exception cannot unwind through C, ctypes drops it and LLVM goes on with a broken buffer.
- Sweep workers (:func:`worker_init`) die with their parent: ``prctl(PR_SET_PDEATHSIG)``
  on Linux (also after SIGKILL of the parent), and a watchdog thread on the parent's pid
  elsewhere; they ignore SIGINT and SIGHUP (the parent stops them with SIGTERM, so a Ctrl-C
  or a hang-up, sent to the whole process group, stops each point once, cleanly) and stop
  their point on SIGTERM or SIGXCPU.
- Library warnings are shown as one line each, once (:func:`quiet_warnings`), or silenced
  where the reason is known (:data:`SILENCED`).
"""

from __future__ import annotations

import _thread
import contextlib
import errno
import math
import os
import signal
import sys
import threading
import warnings

__all__ = [
    "SILENCED",
    "Stopped",
    "environment_error",
    "interruptible",
    "out_of_memory",
    "quiet_warnings",
    "raise_pending",
    "worker_init",
]

_SIGNALS = {
    getattr(signal, name): name
    for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGXCPU")
    if hasattr(signal, name)  # (Windows has SIGINT and SIGTERM only)
}
_WATCHDOG_S = 0.5
_AGAIN_S = 0.05  # a signal that landed in LLVM's callback is sent again after this [s]
_LLVMLITE = f"{os.sep}llvmlite{os.sep}"
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>

#: (message regex, category, module regex, why it is silenced).
SILENCED = (
    (
        r".*non-interactive.*cannot be shown",
        UserWarning,
        r"matplotlib.*",
        "leolink draws on the Agg canvas and writes files; it never shows a window",
    ),
    (
        r".*Tight layout not applied.*",
        UserWarning,
        r"matplotlib.*",
        "a figure too small for its labels is still drawn; the PNG stays readable",
    ),
    (
        r".*",
        DeprecationWarning,
        r"",
        "a library's deprecations (itur's use of numpy and scipy, ...) are for its "
        "developers; a leolink user can do nothing about them",
    ),
    (r".*", PendingDeprecationWarning, r"", "as DeprecationWarning"),
)


class Stopped(KeyboardInterrupt):
    """The command was stopped by a signal (``signal_name``: ``"SIGINT"``, ``"SIGTERM"``,
    ``"SIGHUP"``, ``"SIGXCPU"``); ``exit_code`` is 128 + its number, as a shell reports."""

    def __init__(self, signal_name: str):
        super().__init__(signal_name)
        self.signal_name = signal_name
        self.exit_code = 128 + int(getattr(signal, signal_name, signal.SIGINT))


#: The stop a signal raised, kept until it reaches the command: library code may catch the
#: exception where the handler raised it (pydantic's serializer does, inside its union
#: discriminator callback, and only warns), so the command checks again.
_pending: list[Stopped] = []


def _in_llvm(frame) -> bool:
    """Whether the main thread runs inside llvmlite (numba's compiler or its cache): LLVM
    calls back into Python through ctypes there, where an exception raised by a signal
    handler is printed and dropped, and LLVM then crashes (SIGSEGV, seen under load)."""
    while frame is not None:
        if _LLVMLITE in frame.f_code.co_filename:
            return True
        frame = frame.f_back
    return False


#: Timers of the signals sent again (:func:`_later`): stopped when :func:`interruptible`'s
#: block ends, so that none reaches the handlers it puts back.
_again: list[threading.Timer] = []


def _later(signum, frame) -> bool:
    """If ``signum`` landed in LLVM (:func:`_in_llvm`): keep its stop in :data:`_pending`
    (raised where the command commits, or at the block's end if that comes first) and send
    the signal to the main thread again in :data:`_AGAIN_S`; True if so, and the handler
    must return without raising."""
    if not _in_llvm(frame):
        return False
    _pending[:] = [Stopped(_SIGNALS.get(signum, str(signum)))]
    if hasattr(signal, "pthread_kill"):  # a real signal: it also ends a blocking call
        args = (threading.main_thread().ident, signum)
        timer = threading.Timer(_AGAIN_S, signal.pthread_kill, args)
    else:  # (Windows)
        timer = threading.Timer(_AGAIN_S, _thread.interrupt_main, (signum,))
    _again.append(timer)
    timer.start()
    return True


def _stop_again():
    """Cancel the signals :func:`_later` would still send, and wait for one being sent."""
    while _again:
        timer = _again.pop()
        timer.cancel()
        timer.join()


def _raise_stopped(signum, frame):
    if _later(signum, frame):
        return
    for sig in _SIGNALS:  # a second signal must not interrupt the cleanup
        signal.signal(sig, signal.SIG_IGN)
    stop = Stopped(_SIGNALS.get(signum, str(signum)))
    _pending[:] = [stop]
    raise stop


def raise_pending():
    """Raise again, once, the stop of a signal whose exception library code caught
    (:data:`_pending`): where a command commits its work (a run folder's ``run.json``)
    and at the end of :func:`interruptible`."""
    if _pending:
        raise _pending.pop()


@contextlib.contextmanager
def interruptible():
    """SIGINT and SIGTERM raise :class:`Stopped` inside the block (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.getsignal(sig) for sig in _SIGNALS}
    _pending.clear()
    for sig in _SIGNALS:
        signal.signal(sig, _raise_stopped)
    try:
        yield
        raise_pending()  # a stop caught on the way still stops the command
    finally:
        _stop_again()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _show(message, category, filename, lineno, file=None, line=None):
    if _pending:  # after a stop, the line that says where it stopped is the last word
        return
    text = str(message).strip().splitlines()[0] if str(message).strip() else ""
    print(f"leolink: warning: {category.__name__}: {text}", file=sys.stderr)


@contextlib.contextmanager
def quiet_warnings():
    """Each library warning as one line, once; the :data:`SILENCED` ones not at all."""
    with warnings.catch_warnings():
        warnings.simplefilter("once")
        for message, category, module, _why in SILENCED:
            warnings.filterwarnings("ignore", message, category, module)
        warnings.showwarning = _show
        yield


def environment_error(exc: OSError, out=None) -> str:
    """One line for an error of the file system or the network: what, where."""
    where = exc.filename or out or "the output"
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"no space left on the device writing {where} (free some space or use another --out)"
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return f"cannot write {where}: {exc.strerror} (choose a folder you can write)"
    if exc.errno == errno.ENOTDIR:
        return f"cannot use {where}: a part of the path is a file, not a folder"
    if exc.errno == errno.EISDIR:
        return f"cannot write {where}: it is a folder"
    return f"{where}: {exc.strerror or type(exc).__name__}"


def out_of_memory(exc: MemoryError) -> str:
    """One line for a MemoryError, with the size of the array that did not fit when numpy
    says it (its ``shape`` and ``dtype``)."""
    try:
        gib = math.prod(exc.shape) * exc.dtype.itemsize / 2**30  # type: ignore[attr-defined]
        needs = f"needs about {max(gib, 0.1):.1f} GiB more; "
    except (TypeError, AttributeError):
        needs = ""
    return f"out of memory ({needs}reduce UTs/epochs or use --workers)"


def die_with_parent(sig=signal.SIGTERM):
    """Have the kernel send ``sig`` to this process when its parent dies (Linux only;
    a no-op elsewhere)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, sig, 0, 0, 0)


def _parent_gone(parent_pid):
    return os.getppid() != parent_pid


def _watchdog(parent_pid):
    """Stop this worker when its parent is gone (where prctl is not available)."""
    event = threading.Event()
    while not event.wait(_WATCHDOG_S):
        if _parent_gone(parent_pid):
            os.kill(os.getpid(), signal.SIGTERM)
            return


_busy = False  # a worker is running a point (SIGTERM raises) or idle (SIGTERM exits)


_WORKER_STOPS = [s for s in _SIGNALS if _SIGNALS[s] in ("SIGTERM", "SIGXCPU")]


def _worker_term(signum, frame):
    if _busy and _later(signum, frame):
        return
    for sig in _WORKER_STOPS:
        signal.signal(sig, signal.SIG_IGN)
    if not _busy:
        os._exit(128 + signum)
    raise Stopped("SIGTERM")


def worker_init(parent_pid: int):
    """Initializer of a sweep's worker process (``ProcessPoolExecutor(initializer=...)``)."""
    for sig in _SIGNALS:
        signal.signal(sig, _worker_term if sig in _WORKER_STOPS else signal.SIG_IGN)
    die_with_parent(signal.SIGTERM)
    if _parent_gone(parent_pid):  # the parent died before prctl took effect
        os._exit(128 + signal.SIGTERM)
    threading.Thread(target=_watchdog, args=(parent_pid,), daemon=True).start()


def in_worker(fn, *args):
    """Run ``fn(*args)`` in a worker: SIGTERM now stops the point cleanly, then the worker
    exits (a pool would otherwise hand it the next point)."""
    global _busy
    _busy = True
    try:
        return fn(*args)
    except Stopped:
        os._exit(128 + signal.SIGTERM)  # the point's sinks have aborted: nothing is left
    finally:
        _busy = False
