"""The C heap of a run's process: large blocks straight from the kernel (glibc).

glibc's ``malloc`` serves a block at or above its *mmap threshold* with its own ``mmap``
and returns it to the kernel on ``free``; smaller blocks come from the heap, whose freed
space is reused imperfectly. By default the threshold is dynamic: each time a mapped block
is freed it rises to that block's size (up to 32 MiB on 64-bit, ``mallopt(3)``), so after
the first block of epochs the simulator's temporaries of a few MiB (a block's pair and
table arrays) all come from the heap, and the heap's resident size creeps up with the run.
Measured on the Walker example (1,000 UTs, plots off, ``benchmarks/bench_memory.py``): a
30-minute run's peak RSS was 17.6 % above a 5-minute run's, though its Python and numpy
allocations (``tracemalloc``) were only 7 % above. A fixed threshold of 4 MiB: 9.6 %, at
no speed cost measured (``bench_sim.py``: 26.8 s vs 25.8 s, within the machine's noise).
A fixed 128 KiB threshold (what ``MALLOC_TRIM_THRESHOLD_`` alone implies) is flatter
(4.9 %) but 30 % slower: every array of more than 16,000 floats is then mapped anew.
"""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["MMAP_THRESHOLD_BYTES", "fix_mmap_threshold"]

#: The fixed mmap threshold of a run [bytes].
MMAP_THRESHOLD_BYTES = 4 * 2**20
M_MMAP_THRESHOLD = -3  # <malloc.h>
#: The environment's own malloc settings (glibc reads them at start-up): left alone.
_TUNABLES = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_",
             "MALLOC_MMAP_MAX_")  # fmt: skip


def fix_mmap_threshold(nbytes=MMAP_THRESHOLD_BYTES):
    """Fix glibc's mmap threshold at ``nbytes`` for this process (``mallopt``).

    Nothing is done off Linux, with another C library (whose ``mallopt`` returns 0 or is
    missing), or where the environment sets glibc's malloc tunables (``MALLOC_*_`` or a
    ``glibc.malloc.*`` in ``GLIBC_TUNABLES``: the user's choice wins). Process-wide and
    harmless to call again.

    Returns
    -------
    bool
        Whether glibc's allocator took the threshold (meaningless under an allocator
        preloaded with ``LD_PRELOAD``, e.g. jemalloc).
    """
    own = any(k in os.environ for k in _TUNABLES)
    if own or "glibc.malloc." in os.environ.get("GLIBC_TUNABLES", ""):
        return False
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, int(nbytes)))
