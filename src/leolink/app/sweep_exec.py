"""Where a sweep's points run: this process, local worker processes, or a dask cluster.

Each executor takes ``jobs`` (``[(index, args of run_point)]``) and returns ``{index:
row}``. A point that fails with a :class:`~leolink.errors.LeolinkError` gives a row with
its ``error`` (the others go on); anything else stops the sweep. Local workers die with
their parent (:func:`leolink.app.guard.worker_init`); when the sweep is stopped (Ctrl-C,
SIGTERM, an error) the parent sends each worker SIGTERM, so that the point it runs aborts
its sinks (no ``.partial`` file is left), and waits for them.
"""

from __future__ import annotations

import os
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from leolink.errors import ConfigError, LeolinkError

__all__ = ["DASK_CONNECT_TIMEOUT_S", "check_workers", "run_jobs"]

#: How long to wait for a dask scheduler before saying it is unreachable [s].
DASK_CONNECT_TIMEOUT_S = 5.0
_WORKER_EXIT_S = 30.0  # how long a stopped worker may take to abort its point


def _safe(fn, args):
    """``fn(*args)``, or ``{"error": message}`` for an error leolink raises on purpose
    (the table has an ``error`` column only when a point failed)."""
    try:
        return fn(*args)
    except LeolinkError as exc:
        return {"error": str(exc)}


def _serial(fn, jobs, done):
    rows = {}
    for i, args in jobs:
        rows[i] = _safe(fn, args)
        done(i)
    return rows


def _stop_workers(procs):
    """SIGTERM every live process of ``procs`` and wait for it (each aborts its point)."""
    for proc in procs:
        if proc.is_alive():
            # terminate(), not os.kill(): a worker that exits between the two calls (the
            # pool's own shutdown of a broken pool stops them too) is not an error
            proc.terminate()
    for proc in procs:
        proc.join(_WORKER_EXIT_S)
        if proc.is_alive():
            proc.kill()


def _processes(fn, jobs, done, workers):
    """Run the jobs on ``workers`` processes; on any error or signal stop every worker."""
    import multiprocessing

    from leolink.app.guard import in_worker, worker_init

    rows = {}
    # the pool's workers are the children started after this point (the executor does not
    # name them in its public interface before Python 3.14's terminate_workers)
    before = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(
        max_workers=workers, initializer=worker_init, initargs=(os.getpid(),)
    )
    try:
        pending = {pool.submit(in_worker, _safe, fn, args): i for i, args in jobs}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                i = pending.pop(fut)
                rows[i] = fut.result()
                done(i)
    except BaseException:
        _stop_workers([p for p in multiprocessing.active_children() if p not in before])
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return rows


def _dask(fn, jobs, done, address):
    """Run the jobs on a ``dask.distributed`` cluster (only if dask is installed)."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise ConfigError(
            f"workers = 'dask://{address}' needs dask.distributed, which is not installed; "
            "give a number of local processes instead"
        ) from None
    try:
        client = Client(address, timeout=f"{DASK_CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError) as exc:
        raise LeolinkError(
            f"--workers dask://{address}: no dask scheduler answered within "
            f"{DASK_CONNECT_TIMEOUT_S:g} s ({type(exc).__name__}); start one "
            "(dask scheduler) or check the address"
        ) from None
    rows = {}
    with client:
        futures = {client.submit(_safe, fn, args, pure=False): i for i, args in jobs}
        for fut in as_completed(list(futures)):
            rows[futures[fut]] = fut.result()
            done(futures[fut])
    return rows


def check_workers(workers):
    """The dask scheduler address of ``"dask://ADDRESS"``, None for a number of processes."""
    if isinstance(workers, str) and workers.startswith("dask://"):
        return _dask_address(workers)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(
            f"workers = {workers!r} is not allowed; use an integer >= 1 (local processes) "
            "or 'dask://<scheduler address>'"
        )
    return None


#: The most runs one sweep or compare makes (each a folder of files; split a larger study).
MAX_RUNS = 100_000


def check_runs(n_runs, what):
    """Refuse a study of more than :data:`MAX_RUNS` runs before anything is built."""
    if n_runs > MAX_RUNS:
        raise ConfigError(
            f"{what} makes {n_runs:,} runs, which is not allowed; use at most {MAX_RUNS:,} "
            "(split the study)"
        )


def _dask_address(url):
    """The scheduler address ``[PROTOCOL://]HOST:PORT`` of ``dask://ADDRESS`` (an IPv6 host
    in brackets), checked here: an address that cannot be one is a bad argument, not an
    error of the network."""
    from urllib.parse import urlsplit

    address = url.removeprefix("dask://")
    protocol, sep, rest = address.rpartition("://")
    try:
        parts = urlsplit(f"//{rest}")
        ok = bool(parts.hostname) and parts.port is not None and not parts.path
        ok = ok and (not sep or protocol.isalpha())
    except ValueError:  # a port that is not a number in 0..65535, an unclosed bracket
        ok = False
    if not ok:
        raise ConfigError(
            f"--workers {url!r} is not allowed; use dask://HOST:PORT, e.g. "
            "dask://127.0.0.1:8786 (an IPv6 host in brackets: dask://[::1]:8786)"
        )
    return address


def run_jobs(fn, jobs, done, workers):
    """``{index: row}`` of ``fn(*args)`` for every ``(index, args)`` of ``jobs``;
    ``done(index)`` after each."""
    address = check_workers(workers)
    if address is not None:
        return _dask(fn, jobs, done, address)
    if workers == 1 or len(jobs) <= 1:
        return _serial(fn, jobs, done)
    return _processes(fn, jobs, done, min(workers, len(jobs)))
