"""The C heap of a run's process: large blocks straight from the kernel, freed space kept
for reuse (glibc).

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

A fixed mmap threshold also freezes the *trim threshold* at its default, 128 KiB: each
time more than that lies free at the top of the heap, ``free`` hands it back to the
kernel, and the next temporary of a few MiB faults its pages in again (zeroed by the
kernel). The run therefore fixes the trim threshold at 32 MiB too. Measured on
``bench_sim.py --epochs 1800`` (1,000 UTs): 181,600-183,300 -> 58,800-59,000 minor page
faults, system time 0.73-0.89 -> 0.32-0.43 s, 403-417 k -> 418-457 k UT-epochs/s, for
16 MiB more peak RSS (354 -> 370 MiB).
"""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["MMAP_THRESHOLD_BYTES", "TRIM_THRESHOLD_BYTES", "fix_heap_thresholds"]

#: The fixed mmap threshold of a run [bytes].
MMAP_THRESHOLD_BYTES = 4 * 2**20
#: The fixed trim threshold of a run [bytes]: free space at the heap's top kept for reuse.
TRIM_THRESHOLD_BYTES = 32 * 2**20
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # <malloc.h>
#: The environment's own malloc settings (glibc reads them at start-up): left alone.
_TUNABLES = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_",
             "MALLOC_MMAP_MAX_")  # fmt: skip


def fix_heap_thresholds(mmap_bytes=MMAP_THRESHOLD_BYTES, trim_bytes=TRIM_THRESHOLD_BYTES):
    """Fix glibc's mmap threshold at ``mmap_bytes`` and its trim threshold at ``trim_bytes``
    for this process (``mallopt``).

    Nothing is done off Linux, with another C library (whose ``mallopt`` returns 0 or is
    missing), or where the environment sets glibc's malloc tunables (``MALLOC_*_`` or a
    ``glibc.malloc.*`` in ``GLIBC_TUNABLES``: the user's choice wins). Process-wide and
    harmless to call again.

    Returns
    -------
    bool
        Whether glibc's allocator took both thresholds (meaningless under an allocator
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
    mapped = bool(mallopt(M_MMAP_THRESHOLD, int(mmap_bytes)))
    return mapped and bool(mallopt(M_TRIM_THRESHOLD, int(trim_bytes)))
