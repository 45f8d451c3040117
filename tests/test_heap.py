"""The fixed mmap threshold of a run (leolink.app.heap), seen through glibc's own counters.

``mallinfo2().hblks`` counts the blocks glibc has mapped with ``mmap``. By default an
8 MiB block is mapped, and once freed the dynamic threshold rises to 8 MiB, so the next
one comes from the heap; with the threshold fixed at 4 MiB every 8 MiB block is mapped.
Each case runs in a fresh interpreter (the threshold is process-wide).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux") or os.confstr("CS_GNU_LIBC_VERSION") is None,
    reason="glibc only",
)

CHILD = r"""
import ctypes, sys
from leolink.app.heap import fix_mmap_threshold

class Mallinfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks",
                 "uordblks", "fordblks", "keepcost")]

libc = ctypes.CDLL(None)
libc.mallinfo2.restype = Mallinfo2
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, (ctypes.c_size_t,)
libc.free.argtypes = (ctypes.c_void_p,)
fixed = fix_mmap_threshold() if sys.argv[1] == "fix" else False
if sys.argv[1] == "run":  # a short run of the paper's pass, its outputs in memory
    from leolink.app.run import run
    from leolink.config import load_config
    run(load_config("configs/paper.toml", ["run.duration_s=2"]), None)
mapped = []
for _ in range(3):
    before = libc.mallinfo2().hblks
    p = libc.malloc(8 * 2**20)
    mapped.append(libc.mallinfo2().hblks - before)
    libc.free(p)
print(fixed, *mapped)
"""


def _child(mode, **env):
    out = subprocess.run([sys.executable, "-c", CHILD, mode], capture_output=True, text=True,
                         env={**os.environ, **env}, check=True)  # fmt: skip
    return out.stdout.split()


def test_default_glibc_serves_the_second_large_block_from_the_heap():
    # The behaviour the module works around: what makes the test below able to fail.
    assert _child("default") == ["False", "1", "0", "0"]


def test_a_fixed_threshold_maps_every_large_block():
    assert _child("fix") == ["True", "1", "1", "1"]


def test_the_environment_s_malloc_settings_are_left_alone():
    # A user's glibc tunable (here one with no effect on mapping) wins: nothing is set.
    tunables = "glibc.malloc.tcache_count=7"
    assert _child("fix", GLIBC_TUNABLES=tunables) == ["False", "1", "0", "0"]


def test_a_run_fixes_the_threshold():
    assert _child("run")[1:] == ["1", "1", "1"]
