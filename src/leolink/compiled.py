"""Whether the compiled kernels (``leolink._kernels``, C) run, and on how many threads: one
answer for every layer (:mod:`leolink.engine.jit` for the engine, :mod:`leolink.visibility`).

The extension is built when leolink is installed (``setup.py``; optional: without a C
compiler leolink installs without it). ``LEOLINK_JIT=0`` in the environment turns every
kernel off (the numpy code then runs everywhere); ``LEOLINK_THREADS=N`` sets the threads a
large call is split over (:func:`run_rows`). The ``leolink`` command gives BLAS one thread
(:func:`single_threaded_blas`).
"""

from __future__ import annotations

import functools
import os

__all__ = ["SPLIT_MIN_ROWS", "enabled", "n_threads", "run_rows"]
__all__ += ["single_threaded_blas", "use"]

#: The variables BLAS libraries take their thread count from (OpenBLAS, numpy's own, reads
#: the first three in this order; MKL its own).
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS",
                         "MKL_NUM_THREADS")  # fmt: skip


@functools.cache
def enabled():
    """Whether the compiled extension is built and not turned off (``LEOLINK_JIT=0``)."""
    if os.environ.get("LEOLINK_JIT", "1").strip() in ("0", "false", "no", "off"):
        return False
    try:
        import leolink._kernels  # noqa: F401
    except ImportError:
        return False
    return True


def use(n):
    """Whether a call over ``n`` pairs or rows runs a compiled kernel: every non-empty call
    when :func:`enabled` (the one switch of every layer: the tests turn the kernels off by
    replacing it, so callers look it up here at each call)."""
    return n >= 1 and enabled()


@functools.cache
def n_threads():
    """Threads a large kernel call is split over: ``LEOLINK_THREADS`` if set, else the
    CPUs this process may run on."""
    env = os.environ.get("LEOLINK_THREADS", "").strip()
    if env:
        if not env.isdigit() or int(env) < 1:
            from leolink.errors import ConfigError

            raise ConfigError(f"LEOLINK_THREADS = {env!r} is not allowed: a whole number >= 1")
        return int(env)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


#: Rows per thread below which a kernel call is not split (a task costs ~50 us).
SPLIT_MIN_ROWS = 16_384


@functools.cache
def _pool():
    from concurrent.futures import ThreadPoolExecutor

    return ThreadPoolExecutor(max(1, n_threads() - 1), thread_name_prefix="leolink-kernel")


# A forked child (leolink.io.render) has none of the pool's threads: it starts its own.
if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_pool.cache_clear)


def run_rows(kernel, n, *args, row_size=1):
    """``kernel(*args, lo, hi)`` over the rows ``0 .. n - 1``, split over
    :func:`n_threads` threads when large (the kernels release the GIL). Each row is
    computed by one thread with the same operations: the bits of a single call.
    ``row_size``: the work of a row, in units of a pair (a UT's row of satellites)."""
    k = min(n_threads(), n * row_size // SPLIT_MIN_ROWS, n)
    if k <= 1:
        kernel(*args, 0, n)
        return
    edges = [n * i // k for i in range(k + 1)]
    pool = _pool()
    shares = zip(edges[1:-1], edges[2:], strict=True)
    tasks = [pool.submit(kernel, *args, lo, hi) for lo, hi in shares]
    kernel(*args, 0, edges[1])  # this thread's share
    for task in tasks:
        task.result()


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
