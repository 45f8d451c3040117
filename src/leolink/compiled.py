"""Whether the compiled kernels (``leolink._kernels``, C) run, and on how many threads: one
answer for every layer (:mod:`leolink.engine.jit` for the engine, :mod:`leolink.visibility`).

The extension is built when leolink is installed (``setup.py``; optional: without a C
compiler leolink installs without it). ``LEOLINK_JIT=0`` in the environment turns every
kernel off (the numpy code then runs everywhere); ``LEOLINK_THREADS=N`` sets the threads a
large call is split over.
"""

from __future__ import annotations

import functools
import os

__all__ = ["enabled", "n_threads"]


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
