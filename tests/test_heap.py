"""The fixed heap thresholds of a run (leolink.app.heap), seen through glibc's own counters.

``mallinfo2().hblks`` counts the blocks glibc has mapped with ``mmap``. By default an
8 MiB block is mapped, and once freed the dynamic threshold rises to 8 MiB, so the next
one comes from the heap; with the threshold fixed at 4 MiB every 8 MiB block is mapped,
and a 3 MiB block still comes from the heap (below the threshold: not a smaller one, nor
the 128 KiB that a fixed trim threshold would leave).
``keepcost`` is the free space at the heap's top: with the trim threshold fixed at 32 MiB
the freed 3 MiB block stays there for reuse; a mmap threshold fixed alone leaves the
default trim threshold (128 KiB), and ``free`` hands the block back to the kernel.
Each case runs in a fresh interpreter (the thresholds are process-wide).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from leolink.app import heap

PAPER = Path(__file__).resolve().parents[1] / "configs" / "paper.toml"

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux") or os.confstr("CS_GNU_LIBC_VERSION") is None,
    reason="glibc only",
)

CHILD = r"""
import ctypes, sys
from leolink.app.heap import M_MMAP_THRESHOLD, fix_heap_thresholds

libc = ctypes.CDLL(None)
info = getattr(libc, "mallinfo2", None)  # glibc >= 2.33; mallinfo (int fields) before
field = ctypes.c_size_t if info is not None else ctypes.c_int
info = info if info is not None else libc.mallinfo

class Mallinfo(ctypes.Structure):
    _fields_ = [(n, field) for n in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
                 "uordblks", "fordblks", "keepcost")]

info.restype = Mallinfo
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, (ctypes.c_size_t,)
libc.free.argtypes = (ctypes.c_void_p,)
fixed = fix_heap_thresholds() if sys.argv[1] == "fix" else False
if sys.argv[1] == "mmap_only":  # the mmap threshold alone: the default trim threshold
    fixed = bool(libc.mallopt(M_MMAP_THRESHOLD, 4 * 2**20))
if sys.argv[1] == "run":  # a short run of the paper's pass, its outputs in memory
    from leolink.app.run import run
    from leolink.config import load_config
    run(load_config(sys.argv[2], ["run.duration_s=2"]), None)
mapped = []
for mib in (8, 8, 8, 3, 3):
    before = info().hblks
    p = libc.malloc(mib * 2**20)
    mapped.append(info().hblks - before)
    libc.free(p)
kept = info().keepcost >= 3 * 2**20  # the last 3 MiB block's space, kept at the top
print(fixed, *mapped, kept)
"""


def _child(mode, **env):
    # Without the caller's own malloc settings, which would decide the counts.
    base = {k: v for k, v in os.environ.items() if k not in heap._TUNABLES}
    out = subprocess.run([sys.executable, "-c", CHILD, mode, str(PAPER)], capture_output=True,
                         text=True, env={**base, **env})  # fmt: skip
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


def test_default_glibc_serves_the_second_large_block_from_the_heap():
    # The behaviour the module works around: what makes the test below able to fail.
    assert _child("default") == ["False", "1", "0", "0", "0", "0", "True"]


def test_fixed_thresholds_map_every_large_block_and_keep_freed_heap_space():
    assert _child("fix") == ["True", "1", "1", "1", "0", "0", "True"]


def test_a_fixed_mmap_threshold_alone_hands_freed_heap_space_back():
    # What the fixed trim threshold prevents: the test above able to fail.
    assert _child("mmap_only") == ["True", "1", "1", "1", "0", "0", "False"]


def test_the_environment_s_malloc_settings_are_left_alone():
    # A user's glibc tunable (here one with no effect on mapping) wins: nothing is set.
    tunables = "glibc.malloc.tcache_count=7"
    assert _child("fix", GLIBC_TUNABLES=tunables) == ["False", "1", "0", "0", "0", "0", "True"]


def test_a_run_fixes_the_thresholds():
    assert _child("run")[1:] == ["1", "1", "1", "0", "0", "True"]


def test_other_glibc_tunables_do_not_stop_the_fix():
    tunables = "glibc.pthread.rseq=0"
    assert _child("fix", GLIBC_TUNABLES=tunables) == ["True", "1", "1", "1", "0", "0", "True"]
