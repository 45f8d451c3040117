"""Compiled speed from the same source: numba on the physics functions and the loops that
call them, one switch for every layer, and how large calls are split over threads.

A physics function that a compiled loop calls is written once, in the module named after
its physics, with arithmetic and numpy ufuncs only, so that it takes arrays (numpy
callers) and scalars (the loops) alike; :func:`jitable` marks it. A loop is decorated with
:func:`jit`: ``numba.njit(cache=True, nogil=True)`` (numpy's error model), compiled at its
first call. With ``LEOLINK_JIT=0`` in the environment (or without numba; ``1`` or unset:
on; any other word is refused) :func:`enabled` is False: callers take their numpy code,
which calls the same physics functions on arrays, and :func:`jit` gives the loop's Python
function itself (the tests run both and compare them to a stated tolerance).
``LEOLINK_THREADS=N`` sets the threads a large call is split over (:func:`run_rows`), at
most the CPUs this process may run on. The ``leolink`` command gives BLAS one thread
(:func:`single_threaded_blas`).

numba's cache invalidates a loop when the loop's own file changes, not when a function it
calls changes in another file: the cache folder is therefore keyed by the sizes and times
of every leolink source file (:func:`_cache_dir`), so that editing a formula in its one
place recompiles every loop that calls it.
"""

from __future__ import annotations

import functools
import hashlib
import os
import threading
from pathlib import Path

__all__ = [
    "JIT_WORDS",
    "SPLIT_MIN_ROWS",
    "check_environment",
    "enabled",
    "jit",
    "jitable",
    "n_threads",
]
__all__ += ["run_calls", "run_rows", "select", "single_threaded_blas", "use"]

#: The variables BLAS libraries take their thread count from (OpenBLAS, numpy's own, reads
#: the first three in this order; MKL its own).
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS",
                         "MKL_NUM_THREADS")  # fmt: skip
#: The physics functions the compiled loops call (:func:`jitable`), registered with numba
#: when a loop is first compiled.
_JITABLE: list = []
#: Whether :func:`select`'s numba version is registered (once, at the first compilation).
_SELECT_REGISTERED: list = []
#: Held while a loop compiles (numba's cache folder is set for it: :func:`_compile`).
_COMPILE_LOCK = threading.Lock()


#: The words ``LEOLINK_JIT`` may be (any case): on, then off. Anything else is refused
#: (``maybe`` was read as on).
JIT_WORDS = (("1", "true", "yes", "on"), ("0", "false", "no", "off"))


def check_environment():
    """Refuse a ``LEOLINK_JIT`` or ``LEOLINK_THREADS`` that is not allowed, in one line
    (:class:`~leolink.errors.ConfigError`); every command calls it before it writes."""
    jit = os.environ.get("LEOLINK_JIT", "1").strip()
    if jit.lower() not in JIT_WORDS[0] + JIT_WORDS[1]:
        from leolink.errors import ConfigError

        raise ConfigError(
            f"LEOLINK_JIT = {jit!r} is not allowed: use 1 (compiled loops, the default) or 0"
        )
    _threads_asked()


@functools.cache
def enabled():
    """Whether the compiled loops run: numba installed and ``LEOLINK_JIT`` not 0."""
    check_environment()
    if os.environ.get("LEOLINK_JIT", "1").strip().lower() in JIT_WORDS[1]:
        return False
    import importlib.util

    return importlib.util.find_spec("numba") is not None


def use(n):
    """Whether a call over ``n`` pairs or rows takes a compiled loop: every non-empty call
    when :func:`enabled` (the tests turn the loops off by replacing it, so callers look it
    up here at each call)."""
    return n >= 1 and enabled()


def jitable(fn):
    """Mark a physics function as callable from the compiled loops (numba's
    ``register_jitable``, applied when a loop is first compiled); returns ``fn``."""
    _JITABLE.append(fn)
    return fn


def select(cond, a, b):
    """``a`` where ``cond``, else ``b``: :func:`numpy.where` on arrays, and in a compiled
    loop on one element's scalars (``a if cond else b``), so that a rule written with it
    runs on every UT at once in numpy and UT by UT when compiled, from one source."""
    import numpy as np  # (not at the top: the leolink command sets BLAS up before numpy)

    return np.where(cond, a, b)


def _select_overload(cond, a, b):
    """numba's :func:`select`: the scalar choice on a scalar condition, else numpy's."""
    import numpy as np
    from numba import types

    if isinstance(cond, types.Boolean):
        return lambda cond, a, b: a if cond else b
    return lambda cond, a, b: np.where(cond, a, b)


def jit(fn):
    """``numba.njit(cache=True, nogil=True)`` of the loop ``fn``, compiled at its first call
    (``fn`` itself, in Python, where numba is absent)."""
    compiled = None

    @functools.wraps(fn)
    def call(*args):
        nonlocal compiled
        if compiled is None:
            with _COMPILE_LOCK:  # the threads of a split call arrive together
                if compiled is None:
                    compiled = _compile(fn) if _numba_present() else fn
        return compiled(*args)

    return call


@functools.cache
def _numba_present():
    import importlib.util

    return importlib.util.find_spec("numba") is not None


def _compile(fn):
    """numba's dispatcher of ``fn``, its cache in :func:`_cache_dir`."""
    import numba
    from numba.core import config
    from numba.extending import register_jitable

    if not _SELECT_REGISTERED:
        from numba.extending import overload

        overload(select)(_select_overload)
        _SELECT_REGISTERED.append(True)
    while _JITABLE:
        register_jitable(_JITABLE.pop())
    saved, config.CACHE_DIR = config.CACHE_DIR, str(_cache_dir())
    try:  # numba's cache locator reads the folder when the dispatcher is made
        # numpy's error model: x / 0 is inf or NaN, as in the numpy code, not an exception
        return numba.njit(cache=True, nogil=True, error_model="numpy")(fn)
    finally:
        config.CACHE_DIR = saved


@functools.cache
def _cache_dir():
    """``__pycache__/numba-<key>`` of the package (else of the user's cache folder), ``key``
    a hash of every leolink source file's path, size and modification time."""
    root = Path(__file__).resolve().parent
    stamp = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        st = path.stat()
        stamp.update(f"{path.relative_to(root)} {st.st_size} {st.st_mtime_ns}\n".encode())
    name = f"numba-{stamp.hexdigest()[:16]}"
    for base in (root / "__pycache__", Path.home() / ".cache" / "leolink"):
        try:
            base.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(base, os.W_OK):
            return base / name
    import tempfile

    return Path(tempfile.gettempdir()) / "leolink" / name


@functools.cache
def n_threads():
    """Threads a large kernel call is split over: ``LEOLINK_THREADS`` if set, capped at the
    CPUs this process may run on, else those CPUs."""
    return _threads_asked()


def _threads_asked():
    env = os.environ.get("LEOLINK_THREADS", "").strip()
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    if not env:
        return cpus
    digits = env.lstrip("0")  # (leading zeros: the value, however many)
    if not env.isdigit() or not digits:
        from leolink.errors import ConfigError

        raise ConfigError(f"LEOLINK_THREADS = {env!r} is not allowed: a whole number >= 1")
    # no 5,000-digit int(): past 19 digits the length says it is more than the CPUs
    return min(int(digits) if len(digits) <= 19 else cpus, cpus)  # more would only queue


#: Rows per thread below which a kernel call is not split (a task costs ~50 us).
SPLIT_MIN_ROWS = 16_384
#: Most rows (in pairs, ``row_size``) of one compiled call: a signal's handler (a stop,
#: :mod:`leolink.app.guard`) runs only between two, and the pool's threads finish the
#: piece in hand before the process exits (issue 49: a stop waits for a piece, not a call).
PIECE_ROWS = 1 << 17


@functools.cache
def _pool():
    from concurrent.futures import ThreadPoolExecutor

    return ThreadPoolExecutor(max(1, n_threads() - 1), thread_name_prefix="leolink-kernel")


# A forked child (a sweep's worker) has none of the pool's threads: it starts its own.
if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_pool.cache_clear)


def run_rows(kernel, n, *args, row_size=1):
    """``kernel(*args, lo, hi)`` over the rows ``0 .. n - 1``, split over
    :func:`n_threads` threads when large (the compiled loops release the GIL). Each row is
    computed by one thread with the same operations: the bits of a single call.
    ``row_size``: the work of a row, in units of a pair (a UT's row of satellites). The
    rows go in pieces of at most :data:`PIECE_ROWS` pairs, every ``k``-th to this thread;
    on a stop the pieces not yet begun are cancelled."""
    k = min(n_threads(), n * row_size // SPLIT_MIN_ROWS, n)
    m = max(1, min(n, max(k, -(-n * row_size // PIECE_ROWS))))  # (no rows: one empty call)
    edges = [n * i // m for i in range(m + 1)]
    pieces = list(zip(edges[:-1], edges[1:], strict=True))
    _split_calls(kernel, [(*args, lo, hi) for lo, hi in pieces], k)


def run_calls(fn, calls):
    """``[fn(*args) for args in calls]``, the calls split over :func:`n_threads` threads
    (every ``k``-th in this thread, the others in the pool's): for calls that spend their
    time in compiled loops (they release the GIL), each of which writes only its own part
    of any shared array. Each call runs whole in one thread: the bits of a serial run."""
    return _split_calls(fn, list(calls), min(n_threads(), len(calls)))


def _split_calls(fn, calls, k):
    """``fn(*args)`` of each of ``calls`` (their results in order), every ``k``-th in this
    thread and the others in the pool's; on a stop the calls not yet begun are
    cancelled."""
    if k <= 1:
        return [fn(*args) for args in calls]
    pool = _pool()
    tasks = {i: pool.submit(fn, *args) for i, args in enumerate(calls) if i % k}
    try:
        mine = {i: fn(*args) for i, args in enumerate(calls) if i % k == 0}  # this thread's
        return [mine[i] if i % k == 0 else tasks[i].result() for i in range(len(calls))]
    except BaseException:
        for task in tasks.values():
            task.cancel()
        raise


def single_threaded_blas(environ=os.environ):
    """One BLAS thread for this process and its children, unless the environment sets a
    count (any of :data:`BLAS_THREAD_VARIABLES`): called by the ``leolink`` command before
    numpy is imported (OpenBLAS reads it when it loads).

    leolink's BLAS products are small (a codebook's Dirichlet coefficients, 3 x 3 frames);
    its large loops are its own kernels, split over the CPUs by :func:`n_threads`.
    OpenBLAS's threads, started with numpy, spin waiting for work after it loads and
    after each product, on the cores those loops use: a 10-UT run's CPU time 0.59 -> 0.47
    s, its wall time 0.491 -> 0.468 s (medians of 10, side by side); the constellation's
    and bench_sim's wall times 0.98 and 0.99 of those with OpenBLAS's threads.
    """
    if not any(environ.get(name) for name in BLAS_THREAD_VARIABLES):
        environ["OPENBLAS_NUM_THREADS"] = "1"
