"""leolink.compiled.run_rows: every row once, in bounded pieces, and a stop that cancels
the pieces not begun (issue 49: a stop waits for a piece, not for a whole call)."""

import threading

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
