"""One run split over parts of its UTs: ``leolink run CONFIG --workers N`` (local processes)
or ``--scheduler ADDRESS`` (a dask cluster), on the executors of ``leolink sweep``
(:func:`leolink.app.sweep_exec.run_jobs`).

- **Parts by region** (:func:`regions`): the UTs, by where they are at the first epoch,
  are cut into parts of nearly equal counts by recursive bisection along the longer side
  (north-south or east-west) of each region: a part's UTs are close together, so its
  satellite cone (:func:`leolink.sim.processes.candidate_satellites`) and screening hold
  only the satellites over its region.
- **Seeds per UT**: every part builds the whole run's scenario from the same config (the
  same placements and headings, drawn from ``run.seed``), keeps its UTs
  (:func:`leolink.sim.mobility.models.take_uts`) and their random keys of the whole run
  (:func:`leolink.rng.ut_keys` with ``ut_ids``): a UT's draws do not depend on the part.
- **Parts on workers**: each part streams to its own Parquet files
  (:class:`leolink.io.parts.PartWriter`, in ``OUT/.parts-<random>.partial/`` while the run runs) and
  returns a few numbers (its UTs' populations, wall time, peak memory); the parent reads
  the parts back a window of epochs at a time (:func:`leolink.io.parts.merged_blocks`)
  into the run's own sinks: the trace, events, summary, plots and report of a
  single-process run, in bounded memory.
- **Coupled UTs are refused** (:func:`check_split`): active beams chosen by demand or
  hopping, beam sharing (schedulers) and digital precoders make a UT's link depend on
  other UTs, possibly in other parts. Interference from other satellites
  (``link.interference = "all_satellites"``) with every beam lit depends on no UT: it
  is split exactly.
- **Worker loss**: dask hands a lost worker's part to another worker (up to its
  ``allowed-failures``); a local process that dies, or a part that fails, stops the
  run with one line: the parts are removed and no output of the run is written.
"""

from __future__ import annotations

import math
import os
import resource
import shutil
import socket
import time

import numpy as np

from leolink.errors import ConfigError, LeolinkError

__all__ = [
    "PARTS_PER_WORKER",
    "SCHEDULER_PARTS",
    "check_split",
    "regions",
    "run_part",
    "run_split",
    "split_flag",
    "split_workers",
]

#: Parts per local worker by default: the last parts to finish then keep every worker busy.
PARTS_PER_WORKER = 4
#: Parts on a dask cluster by default (its size is not known before it answers).
SCHEDULER_PARTS = 16


def split_workers(workers, parts):
    """``(workers, n_parts or None)`` checked, or None when the run is not split.

    ``workers``: an int >= 1 or ``"dask://ADDRESS"`` (as ``leolink sweep``); ``parts``:
    None (the default count) or an int >= 1. One local worker splits only if ``parts``
    is given (the parts then run one after the other, in this process).
    """
    from leolink.app.sweep_exec import check_workers

    check_workers(workers)
    if parts is not None and (isinstance(parts, bool) or not isinstance(parts, int) or parts < 1):
        raise ConfigError(f"--parts {parts!r} is not allowed; use an integer >= 1")
    if workers == 1 and parts is None:
        return None
    return workers, parts


def split_flag(workers, parts):
    """How the command line asks for this split (for messages)."""
    asked = f"--scheduler {workers.removeprefix('dask://')}" if isinstance(workers, str) else (
        f"--workers {workers}")  # fmt: skip
    return asked + (f" --parts {parts}" if parts is not None else "")


def check_split(cfg, scen, flag):
    """Refuse to split a run whose UTs' links depend on each other.

    Raises
    ------
    ConfigError
        One line naming the key (``flag``: how the user asked for the split).
    """
    coupled = []
    if scen.selector is not None:
        coupled.append(
            f"satellite_array.active_beams = {cfg.satellite_array.active_beams!r} "
            "(a satellite lights beams by the demand of all the UTs it covers)"
        )
    if scen.service is not None and cfg.link.precoder != "none":
        coupled.append(
            f"link.precoder = {cfg.link.precoder!r} (a satellite's precoder serves all its "
            "UTs at once)"
        )
    if scen.service is not None and cfg.scheduler.kind != "none":
        coupled.append(
            f"scheduler.kind = {cfg.scheduler.kind!r} (the UTs of a beam share its time)"
        )
    if coupled:
        raise ConfigError(
            f"{flag} splits the UTs into parts, but {coupled[0]} couples them; run it "
            "without the split (--workers 1), or without that feature"
        )


def regions(lat_rad, lon_rad, n_parts):
    """Cut UTs into ``n_parts`` compact regions of nearly equal counts.

    Recursive bisection: a region is cut at the quantile of its latitude or longitude
    (the longer side in arc, longitude counted at ``cos(median latitude)``) that gives
    its two halves their share of the parts.

    Parameters
    ----------
    lat_rad, lon_rad : ndarray (n_ut,)
        Where the UTs are [rad].
    n_parts : int
        Parts wanted (at most ``n_ut`` are made).

    Returns
    -------
    list of ndarray of int
        Each part's UT indices, increasing; together every UT once.
    """
    lat, lon = np.asarray(lat_rad, float), np.asarray(lon_rad, float)
    return _bisect(np.arange(lat.size), lat, lon, max(1, min(int(n_parts), lat.size)))


def _bisect(index, lat, lon, n_parts):
    if n_parts == 1:
        return [np.sort(index)]
    la, lo = lat[index], lon[index]
    north_south = np.ptp(la)
    east_west = np.ptp(lo) * math.cos(float(np.median(la)))
    key = la if north_south >= east_west else lo
    order = index[np.argsort(key, kind="stable")]
    half = n_parts // 2
    cut = round(len(index) * half / n_parts)
    return _bisect(order[:cut], lat, lon, half) + _bisect(order[cut:], lat, lon, n_parts - half)


def _start_positions(scen):
    """Latitude and longitude [rad] of every UT at the run's first epoch."""
    from leolink.sim.mobility.models import concat_states

    t0 = float(scen.times_s[0])
    first = concat_states([model.state(t0) for _, model in scen.populations])
    return first.lat_rad, first.lon_rad


def _peak_rss_mib():
    """This process's peak resident memory [MiB] (Linux counts ``ru_maxrss`` in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_part(config, source, ut_ids, folder):
    """Simulate the UTs ``ut_ids`` of a config into ``folder`` (on a worker).

    Parameters
    ----------
    config : dict, the validated config (``cfg.model_dump(mode="json")``); ``source`` its file.
    ut_ids : ndarray of int, the part's run-wide UT ids (increasing).
    folder : str, where :class:`~leolink.io.parts.PartWriter` writes.

    Returns
    -------
    dict
        Bounded by the part's UT count: its UTs' ``population`` and ``environment``, the
        run's ``info`` numbers, ``end_s``, ``wall_s``, ``peak_rss_mib`` and ``worker``.
    """
    from leolink.app.scenario import build_scenario
    from leolink.config import parse_config
    from leolink.io.parts import PartWriter
    from leolink.sim.runner import run_simulation

    t_wall = time.perf_counter()
    scen = build_scenario(parse_config(config, source), ut_ids=np.asarray(ut_ids, np.int64))
    stats = run_simulation(scen, [PartWriter(folder)])
    i = stats.info
    return {
        "population": i.population,
        "environment": i.environment,
        "info": (i.n_sat, i.n_beam, i.epoch_s, i.start_s, i.n_epochs, i.extra_columns),
        "end_s": stats.end_s,
        "wall_s": time.perf_counter() - t_wall,
        "peak_rss_mib": _peak_rss_mib(),
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }


def _run_parts(cfg, ids, root, workers, progress):
    """Every part on the workers; their result dicts, in part order."""
    from concurrent.futures.process import BrokenProcessPool

    from leolink.app.sweep_exec import run_jobs

    config = cfg.model_dump(mode="json", exclude_none=True)
    jobs = [(p, (config, cfg.source, i, str(root / f"part-{p:05d}"))) for p, i in enumerate(ids)]
    n_epochs, finished = int(round(cfg.run.duration_s / cfg.run.epoch_s)), []

    def done(p):
        finished.append(p)
        if progress is not None:
            progress(n_epochs * len(finished) // len(jobs), n_epochs)

    try:
        rows = run_jobs(run_part, jobs, done, workers)
    except BrokenProcessPool:
        raise LeolinkError(_lost(len(finished), len(jobs), "a worker process died")) from None
    except Exception as exc:
        if type(exc).__name__ != "KilledWorker":  # dask's, after its retries on other workers
            raise
        raise LeolinkError(_lost(len(finished), len(jobs), f"dask lost {exc}")) from None
    failed = [(p, r["error"]) for p, r in sorted(rows.items()) if "error" in r]
    if failed:
        raise LeolinkError(f"split run: part {failed[0][0]} of {len(jobs)} failed: {failed[0][1]}")
    return [rows[p] for p in range(len(jobs))]


def _lost(n_done, n_parts, what):
    return (
        f"split run: {what} with {n_done} of {n_parts} parts finished (out of memory? try "
        "more parts or fewer workers); the parts were removed and no output written"
    )


def _run_info(results, ids):
    """The whole run's :class:`~leolink.sim.streams.RunInfo` from its parts'."""
    from leolink.sim.streams import RunInfo

    order = np.argsort(np.concatenate(ids), kind="stable")
    population = np.concatenate([np.asarray(r["population"], object) for r in results])[order]
    environment = np.concatenate([np.asarray(r["environment"], object) for r in results])
    n_sat, n_beam, epoch_s, start_s, n_epochs, extra = results[0]["info"]
    return RunInfo(
        len(order), n_sat, n_beam, epoch_s, start_s, n_epochs, tuple(population),
        tuple(environment[order]) if environment.size else (), tuple(extra),
    )  # fmt: skip


def _stream(sinks, info, end_s, root, ids):
    """Hand the parts' merged frames to ``sinks`` (a single run's stream)."""
    from leolink.io.parts import merged_blocks
    from leolink.sim.streams import FinalFrame, SinkGroup

    group = SinkGroup(sinks, background=True)
    folders = [root / f"part-{p:05d}" for p in range(len(ids))]
    try:
        group.start(info)
        for item in merged_blocks(folders, ids, info.population, info.n_epochs):
            if isinstance(item, dict):  # the last: the dwells still open at the end
                group.finish(FinalFrame(end_s, item))
            else:
                group.block(item)
    except BaseException:
        group.abort()
        raise


def run_split(cfg, scen, sinks, out_dir, split, progress=None):
    """Run ``cfg`` in parts of its UTs and stream the merged run to ``sinks``.

    Parameters
    ----------
    cfg : config; ``scen`` its whole scenario (the parent's: UT positions, checks).
    sinks : the run's sinks (:func:`leolink.sim.runner.run_simulation`'s).
    out_dir : Path or None, the run's folder (the parts go to a new folder in it, removed
        at the end; in the system's temporary folder without one); on a dask cluster it
        must be a folder every worker can write.
    split : ``(workers, n_parts or None)`` of :func:`split_workers`.
    progress : callable, optional, ``progress(done_epochs, n_epochs)`` as parts finish.

    Returns
    -------
    leolink.sim.runner.RunStats
        With ``split``: the parts' wall times and each worker's peak memory.
    """
    from leolink.io.parts import parts_folder
    from leolink.sim.runner import RunStats

    workers, n_parts = split
    if n_parts is None:
        n_parts = SCHEDULER_PARTS if isinstance(workers, str) else PARTS_PER_WORKER * workers
    t_wall = time.perf_counter()
    ids = regions(*_start_positions(scen), n_parts)
    root = parts_folder(out_dir)
    try:
        results = _run_parts(cfg, ids, root, workers, progress)
        info, end_s = _run_info(results, ids), results[0]["end_s"]
        _stream(sinks, info, end_s, root, ids)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    peaks = {}
    for r in results:
        peaks[r["worker"]] = max(peaks.get(r["worker"], 0.0), r["peak_rss_mib"])
    split_stats = {
        "workers": workers,
        "parts": len(ids),
        "part_wall_s": [round(r["wall_s"], 3) for r in results],
        "peak_rss_mib_by_worker": {w: round(m, 1) for w, m in sorted(peaks.items())},
    }
    return RunStats(info, end_s, time.perf_counter() - t_wall, split_stats)
