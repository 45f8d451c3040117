"""leolink.compiled.run_rows: every row once, in bounded pieces, and a stop that cancels
the pieces not begun (issue 49: a stop waits for a piece, not for a whole call); the
switch itself (issue 45): the environment's words, the threads, the split, the
compilation."""

import importlib.util
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from leolink import compiled

CASES = [(0, 1, 2), (10, 1, 1), (300_001, 1, 2), (5_000, 100, 3), (7, 40_000, 2)]


@pytest.mark.parametrize(("n", "row_size", "threads"), CASES)
def test_rows_are_covered_once_in_pieces_of_bounded_work(monkeypatch, n, row_size, threads):
    monkeypatch.setattr(compiled, "n_threads", lambda: threads)
    seen, lock = [], threading.Lock()

    def kernel(tag, lo, hi):
        with lock:
            seen.append((lo, hi))

    compiled.run_rows(kernel, n, "tag", row_size=row_size)
    seen.sort()
    assert seen[0][0] == 0 and seen[-1][1] == n
    assert all(a[1] == b[0] for a, b in zip(seen, seen[1:], strict=False))  # no gap, no overlap
    assert all(hi > lo for lo, hi in seen) or seen == [(0, 0)]  # (no rows: one empty call)
    # at most PIECE_ROWS pairs a piece (a single row may hold more)
    assert max(hi - lo for lo, hi in seen) <= max(1, -(-compiled.PIECE_ROWS // row_size))


class _Stop(BaseException):
    """What a signal's handler raises in the main thread (leolink.app.guard.Stopped)."""


def test_a_stop_in_this_threads_piece_cancels_the_pieces_not_begun(monkeypatch):
    monkeypatch.setattr(compiled, "n_threads", lambda: 2)
    n = 64 * compiled.PIECE_ROWS  # 64 pieces: 32 here, 32 for the pool's threads
    in_pool, release, begun = threading.Event(), threading.Event(), []

    def kernel(lo, hi):
        if threading.current_thread() is threading.main_thread():
            in_pool.wait(5.0)  # a pool thread holds a piece
            raise _Stop
        begun.append(lo)
        in_pool.set()
        release.wait(5.0)

    with pytest.raises(_Stop):
        compiled.run_rows(kernel, n)
    release.set()
    compiled._pool().submit(lambda: None).result()  # queued after every piece
    assert 1 <= len(begun) < 32  # those in hand (one per pool thread); the rest cancelled


@pytest.mark.parametrize(("n_calls", "threads"), [(0, 2), (1, 2), (5, 1), (7, 2), (9, 3)])
def test_calls_return_in_order_each_in_one_thread(monkeypatch, n_calls, threads):
    monkeypatch.setattr(compiled, "n_threads", lambda: threads)
    where = {}

    def fn(i, j):
        where[i] = threading.current_thread() is threading.main_thread()
        return i * 10 + j

    out = compiled.run_calls(fn, [(i, 1) for i in range(n_calls)])
    assert out == [i * 10 + 1 for i in range(n_calls)]
    k = min(threads, n_calls)
    # every k-th call here, the others in the pool's threads (all here without a split)
    assert where == {i: k <= 1 or i % k == 0 for i in range(n_calls)}


def test_use_takes_the_loops_for_every_non_empty_call_when_enabled(monkeypatch):
    for on in (True, False):
        monkeypatch.setattr(compiled, "enabled", lambda on=on: on)
        assert [compiled.use(n) for n in (0, 1, 2, 10**6)] == [False, on, on, on]


def test_jitable_registers_the_function_and_returns_it(monkeypatch):
    monkeypatch.setattr(compiled, "_JITABLE", [])

    def f(x):
        return x

    assert compiled.jitable(f) is f
    assert compiled._JITABLE == [f]


def test_select_chooses_element_by_element():
    cond = np.array([True, False, True, False])
    out = compiled.select(cond, np.array([1.0, 2.0, 3.0, 4.0]), -1.0)
    np.testing.assert_array_equal(out, [1.0, -1.0, 3.0, -1.0])
    assert compiled.select(False, 5.0, 7.0) == 7.0


def _add(a, b):
    return a + b


def test_jit_without_numba_is_the_python_function(monkeypatch):
    monkeypatch.setattr(compiled, "_numba_present", lambda: False)
    monkeypatch.setattr(compiled, "_compile", lambda fn: pytest.fail("compiled"))
    loop = compiled.jit(_add)
    assert loop(2, 3) == 5 and loop("a", "b") == "ab"
    assert loop.__name__ == "_add" and loop.__wrapped__ is _add


def test_jit_compiles_once_when_threads_arrive_together(monkeypatch):
    made = []

    def fake_compile(fn):
        made.append(fn)
        return lambda *args: ("compiled", args)

    monkeypatch.setattr(compiled, "_numba_present", lambda: True)
    monkeypatch.setattr(compiled, "_compile", fake_compile)
    loop = compiled.jit(_add)
    start, out = threading.Barrier(4), {}

    def call(i):
        start.wait(5.0)
        out[i] = loop(i, 0)

    threads = [threading.Thread(target=call, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(10.0)
    assert made == [_add]  # once, from the Python function
    assert out == {i: ("compiled", (i, 0)) for i in range(4)}
    assert loop(7, 1) == ("compiled", (7, 1)) and made == [_add]


def _half(x):
    return 0.5 * x


def _halve_or_divide_by_zero(x, halve):
    return compiled.select(halve, _half(x), x / 0.0)


def _positive_part(x):
    return compiled.select(x > 0.0, x, 0.0 * x)


FRESH_PROCESS = """
import sys
from pathlib import Path

import numpy as np

from leolink import compiled

compiled._cache_dir = lambda: Path(sys.argv[1])


@compiled.jitable
def half(x):
    return 0.5 * x


def halve_or_divide_by_zero(x, halve):
    return compiled.select(halve, half(x), x / 0.0)


def positive_or_ten(x):
    return compiled.select(x > 0.0, x, 10.0 + 0.0 * x)


loop = compiled._compile(halve_or_divide_by_zero)
positive = compiled._compile(positive_or_ten)
print(loop(3.0, True), loop(3.0, False), positive(np.array([-2.0, 3.0, -1.0])).tolist())
"""


def _compile_in_a_fresh_process(tmp_path):
    """What the first loop's compilation in a process registers with numba (``select`` for
    scalars and arrays, the jitable functions), in a fresh process: numba keeps the types
    it worked out for the process (an earlier test's loop would hide a change)."""
    probe = tmp_path / "probe.py"  # (numba caches only functions defined in a file)
    probe.write_text(FRESH_PROCESS)
    src = Path(compiled.__file__).resolve().parents[1]  # this leolink, not an installed one
    env = {**os.environ, "PYTHONPATH": str(src)}
    env.pop("NUMBA_DISABLE_JIT", None)
    cmd = [sys.executable, str(probe), str(tmp_path / "numba-fresh")]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split(None, 2) == ["1.5", "inf", "[10.0, 3.0, 10.0]\n"]


def test_compile_gives_a_numba_loop_that_calls_the_jitable_functions(monkeypatch, tmp_path):
    """numba (not the Python function): ``select`` on scalars and on arrays, a registered
    physics function, numpy's x / 0 (inf, not ZeroDivisionError), the GIL released, cached
    in the folder :func:`~leolink.compiled._cache_dir` names (here a new one: a loop found
    in the cache would not be compiled again), numba's own folder setting left as it
    was."""
    numba = pytest.importorskip("numba")
    from numba.core import config

    monkeypatch.setattr(compiled, "_JITABLE", [])
    monkeypatch.setattr(compiled, "_cache_dir", lambda: tmp_path / "numba-test")
    compiled.jitable(_half)
    saved = config.CACHE_DIR
    loop = compiled._compile(_halve_or_divide_by_zero)
    assert config.CACHE_DIR == saved and compiled._JITABLE == []
    assert isinstance(loop, numba.core.registry.CPUDispatcher)
    assert loop(3.0, True) == 1.5
    assert loop(3.0, False) == np.inf
    assert loop.targetoptions["nogil"] is True
    assert tmp_path / "numba-test" in Path(loop._cache._cache_path).parents
    positive = compiled._compile(_positive_part)
    np.testing.assert_array_equal(positive(np.array([-2.0, 3.0, 0.0, 5.0])), [0, 3, 0, 5])
    _compile_in_a_fresh_process(tmp_path)


def test_select_in_numba_is_the_scalar_choice_or_numpys_where():
    types = pytest.importorskip("numba").types
    f64 = types.float64
    scalar = compiled._select_overload(types.boolean, f64, f64)
    assert (scalar(True, 1.0, 2.0), scalar(False, 1.0, 2.0)) == (1.0, 2.0)
    array = compiled._select_overload(types.Array(types.boolean, 1, "C"), f64, f64)
    np.testing.assert_array_equal(array(np.array([True, False]), 1.0, 2.0), [1.0, 2.0])


def test_threads_unset_are_the_cpus_and_a_number_is_capped_at_them(monkeypatch):
    cpus = len(os.sched_getaffinity(0))
    monkeypatch.delenv("LEOLINK_THREADS", raising=False)
    assert compiled.n_threads.__wrapped__() == cpus
    for asked, threads in [(" 1 ", 1), (str(cpus + 1), cpus), ("9" * 19, cpus)]:
        monkeypatch.setenv("LEOLINK_THREADS", asked)
        assert compiled.n_threads.__wrapped__() == threads, asked


@pytest.mark.parametrize("word", ["abc", "2.5", "+2", "1e3", "two", "0", "0" * 25, "-1"])
def test_threads_other_than_a_whole_number_are_refused_in_one_line(monkeypatch, word):
    from leolink.errors import ConfigError

    monkeypatch.setenv("LEOLINK_THREADS", word)
    with pytest.raises(ConfigError) as err:
        compiled.check_environment()
    assert str(err.value).startswith(f"LEOLINK_THREADS = {word!r} is not allowed")
    assert "\n" not in str(err.value)


def test_jit_unset_is_on(monkeypatch):
    monkeypatch.delenv("LEOLINK_JIT", raising=False)
    compiled.check_environment()  # not refused
    assert compiled.enabled.__wrapped__() is (importlib.util.find_spec("numba") is not None)


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ({}, {"OPENBLAS_NUM_THREADS": "1"}),
        ({"OPENBLAS_NUM_THREADS": ""}, {"OPENBLAS_NUM_THREADS": "1"}),  # empty: unset
        ({"OMP_NUM_THREADS": "3"}, {"OMP_NUM_THREADS": "3"}),
        ({"MKL_NUM_THREADS": "2"}, {"MKL_NUM_THREADS": "2"}),
        ({"GOTO_NUM_THREADS": "4", "X": "y"}, {"GOTO_NUM_THREADS": "4", "X": "y"}),
    ],
)
def test_blas_gets_one_thread_unless_a_count_is_set(given, expected):
    environ = dict(given)
    compiled.single_threaded_blas(environ)
    assert environ == expected


S = compiled.SPLIT_MIN_ROWS


# (rows, row size, threads, whether the call is split): a thread takes at least
# SPLIT_MIN_ROWS pairs, so a call is split only over twice that, and never over more
# threads than asked.
SPLITS = [
    (10, None, 2, False),
    (S * 3 // 2, None, 2, False),  # 1.5 threads' worth (row size 1, the default)
    (2 * S, None, 2, True),
    (4 * S, None, 1, False),  # one thread asked
    (4, S, 2, True),  # 4 rows of S pairs each
    (1, 4 * S, 2, False),  # one row: one thread
]


@pytest.mark.parametrize(("n", "row_size", "threads", "split"), SPLITS)
def test_a_call_is_split_only_when_each_thread_gets_its_share(
    monkeypatch, n, row_size, threads, split
):
    monkeypatch.setattr(compiled, "n_threads", lambda: threads)
    seen, lock = [], threading.Lock()

    def kernel(lo, hi):
        with lock:
            seen.append((lo, hi, threading.current_thread() is threading.main_thread()))

    if row_size is None:
        compiled.run_rows(kernel, n)
    else:
        compiled.run_rows(kernel, n, row_size=row_size)
    here = {h for _, _, h in seen}
    assert here == ({True, False} if split else {True})
    assert all(type(lo) is int and type(hi) is int for lo, hi, _ in seen)  # row indices
    assert sum(hi - lo for lo, hi, _ in seen) == n


def test_threads_with_leading_zeros_are_read_by_value(monkeypatch):
    """A word is read by its value, leading zeros and all (twenty zeros and a 1 is one
    thread, twenty zeros alone are refused elsewhere); more than 19 significant digits is
    more threads than any machine has (all its CPUs)."""
    cpus = len(os.sched_getaffinity(0))
    cases = [("0" * 18 + "1", 1), ("0" * 20 + "1", 1), ("0" * 18 + "10", min(10, cpus)),
             ("9" * 25, cpus)]  # fmt: skip
    for asked, threads in cases:
        monkeypatch.setenv("LEOLINK_THREADS", asked)
        assert compiled.n_threads.__wrapped__() == threads, asked
