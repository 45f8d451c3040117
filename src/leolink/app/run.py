"""``leolink.run(config) -> Result``: build the scenario, wire the sinks, run, write.

The default sinks: the summary statistics (always), and the enabled ``[output.*]``
sinks (trace and event files, plots, the report) when there is an output folder; without
one the trace and events are kept in memory (and the report's statistics, for the
notebook views). An output folder holding another run's files is refused unless
``overwrite`` (:func:`leolink.io.run_dir.claim_out_dir`); ``summary.json`` and
``config.resolved.toml`` are written after the stream (with more than
``PER_UT_IN_JSON_MAX`` UTs the per-UT statistics and the dwells go to ``per_ut.parquet``
and ``dwells.parquet`` instead of ``summary.json``), then the report page, and the
manifest ``run.json`` last: a folder without it is not a finished run.
"""

from __future__ import annotations

import contextlib
import dataclasses
from datetime import UTC
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING

import leolink
from leolink.app.codebook import codebook_design_from_config
from leolink.app.guard import raise_pending
from leolink.app.heap import fix_heap_thresholds
from leolink.app.multibeam import is_multibeam, run_multibeam
from leolink.app.notes import track_coverage, track_notes
from leolink.app.orbits import earth_orientation, roi_frame, tle_time_zero_utc
from leolink.app.split import run_split, split_workers
from leolink.app.validate import checked_scenario, ephemeris_health
from leolink.config import dump_toml
from leolink.errors import LeolinkError
from leolink.io.atomic import write_json_atomic, write_parquet_atomic, write_text_atomic
from leolink.io.notebook import ResultViews
from leolink.io.report.headline import config_description
from leolink.io.run_dir import UNFINISHED, claim_out_dir, held_out_dirs, write_manifest
from leolink.io.sinks import SINKS, MemorySink
from leolink.io.summary.accumulator import SummaryAccumulator
from leolink.sim.runner import run_simulation

if TYPE_CHECKING:  # pandas is imported when a table is asked for (~0.5 s of start-up)
    import pandas as pd

__all__ = ["Result", "run", "run_notes"]


@dataclasses.dataclass(repr=False)  # ResultViews.__repr__: one line, not the summary
class Result(ResultViews):
    """What a run produced: the summary, the trace and events (in memory, or read back from
    the files this run wrote, never from another run's files in the same folder), and the
    notebook views (``plot_sinr(ut_ids=...)``, ``plot_map()``, ``plot_dwell()``, ...,
    ``_repr_html_``, ``to_xarray()``; :class:`leolink.io.notebook.ResultViews`)."""

    summary: dict
    out_dir: Path | None
    files: list[Path] = dataclasses.field(default_factory=list)
    _memory: MemorySink | None = None
    report_stats: object = None  # ReportStats of the report sink, when it ran
    _per_ut: dict | None = None
    time_zero_utc: str | None = None  # ISO 8601 UTC of simulation time 0, when known

    @property
    def per_ut(self) -> pd.DataFrame:
        """Per-UT statistics, one row per UT (``SummaryAccumulator.per_ut_table``)."""
        import pandas as pd

        return pd.DataFrame(self._per_ut)

    def _written(self, stem, what):
        import pandas as pd

        names = {p.name: p for p in self.files}
        if f"{stem}.parquet" in names:  # Parquet first: faster to read
            return pd.read_parquet(names[f"{stem}.parquet"])
        if f"{stem}.csv" in names:
            return pd.read_csv(names[f"{stem}.csv"])
        raise LeolinkError(f"this run wrote no {what} (output.{what}.enabled = false)")

    @property
    def trace(self) -> pd.DataFrame:
        if self._memory is not None:
            return self._memory.trace()
        return self._written("trace", "trace")

    @property
    def events(self) -> pd.DataFrame:
        if self._memory is not None:
            return self._memory.events()
        return self._written("events", "events")


class _Position:
    """A sink that only remembers the last recorded epoch (where an interrupted run stopped)."""

    def __init__(self):
        self.n_done, self.n_epochs, self.t_s = 0, 0, None

    def start(self, info):
        self.n_epochs = info.n_epochs

    def epoch(self, frame):
        self.n_done, self.t_s = self.n_done + 1, frame.t_s

    def block(self, frame):
        self.n_done, self.t_s = self.n_done + len(frame.t_s), float(frame.t_s[-1])

    def finish(self, final):
        pass

    def abort(self):
        pass

    def where(self, out_dir):
        if self.t_s is None:
            return "the run stopped before its first recorded epoch"
        folder = f"; {out_dir} has no run.json (not a finished run)" if out_dir else ""
        return (
            f"the run stopped after t = {self.t_s:g} s (epoch {self.n_done} of "
            f"{self.n_epochs}){folder}"
        )


def time_zero_utc(cfg):
    """Aware UTC ``datetime`` of simulation time 0, by the scenario's own rule
    (:func:`~leolink.app.orbits.tle_time_zero_utc` for TLE runs); None when the run has
    no calendar time."""
    c = cfg.constellation
    return tle_time_zero_utc(cfg) if c.kind == "tle" else cfg.utc_of_time_zero()


def _epoch_utc(cfg):
    """ISO 8601 UTC (``...Z``) of simulation time 0 for the report's CZML
    (:func:`time_zero_utc`); None when the run has no calendar time (the exports then
    count from J2000)."""
    when = time_zero_utc(cfg)
    if when is None:
        return None
    return when.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _sinks(cfg, out_dir, summary, scen):
    """The sinks of a run: summary first (the plots read it), then ``[output.*]``; without
    a folder, the trace and events in memory (and the report's statistics)."""
    context = SimpleNamespace(
        out_dir=out_dir,
        summary=summary,
        ephemeris=scen.ephemeris,
        codebook=scen.engine.codebook,
        epoch_utc=_epoch_utc(cfg),
        time_zero_utc=time_zero_utc(cfg),  # the trace's time_utc
    )
    if out_dir is None:
        sinks = [summary, MemorySink(context.time_zero_utc)]
        if cfg.output.report.enabled:
            sinks.append(SINKS.build("report", cfg.output.report, context))
        return sinks
    return [summary, *(SINKS.build(name, p, context) for name, p in cfg.output.enabled())]


def run_notes(cfg, scen):
    """The notes of a run (:mod:`leolink.app.notes`) and its track coverage."""
    design = codebook_design_from_config(cfg)
    notes = [f"codebook: {design.describe()}"]
    frame = scen.roi_frame if scen.roi_frame is not None else roi_frame(cfg, scen.ephemeris)
    notes.append(frame.describe(scen.ephemeris.names))
    orientation = earth_orientation(cfg)
    if orientation is not None:
        notes.append(orientation.note)
    times = scen.times_s
    notes += ephemeris_health(cfg, scen.ephemeris, times)
    coverage = track_coverage(scen.populations, times, scen.n_warmup, scen.epoch_s)
    notes += track_notes(coverage, float(times[scen.n_warmup]), float(times[-1]))
    return notes, coverage, design


def _run_section(cfg, scen, stats):
    info = stats.info
    notes, coverage, design = run_notes(cfg, scen)
    source = Path(cfg.source) if cfg.source else None
    return {
        "scenario": source.stem if source else None,
        "description": config_description(source) if source else "",
        "config_file": cfg.source or None,
        "leolink_version": leolink.__version__,
        "n_ut": info.n_ut,
        "n_epochs": info.n_epochs,
        "epoch_s": info.epoch_s,
        "start_s": info.start_s,
        "end_s": stats.end_s,
        "n_beam": info.n_beam,
        "n_sat": info.n_sat,
        "oversampling": float(scen.engine.codebook.oversampling),
        "idle_rf_chains": design.idle_rf,
        "worst_roi_loss_db": design.loss.loss_db,
        "start_utc": cfg.run.start_utc or None,
        "earth_model": cfg.earth.model,
        "track_coverage": coverage,
        "notes": notes,
        "wall_time_s": stats.wall_time_s,
        **({"split": stats.split} if stats.split is not None else {}),
    }


def _summary(cfg):
    """The run's summary accumulator with the ``[kpi]`` and ``[cells]`` settings."""
    satellites = cfg.cells.per == "satellite"
    return SummaryAccumulator(
        ping_pong_s=cfg.kpi.ping_pong_s,
        mro_window_s=cfg.kpi.mro_window_s,
        mro_level="satellite" if satellites else "cell",
        beam_switch_s=cfg.cells.beam_switch_s if satellites else None,
    )


def run(cfg, out_dir=None, progress=None, overwrite=False, workers=1, parts=None):
    """Run the simulation of ``cfg``.

    Parameters
    ----------
    cfg : leolink.config.ConfigBase
    out_dir : path or None
        Where to write the enabled outputs (``trace.csv``/``trace.parquet``,
        ``events.csv``/``events.parquet``, plots, ``report.html`` and its files),
        ``summary.json``, ``config.resolved.toml`` and, last, ``run.json``. None keeps the
        trace and events in memory (``Result.trace`` is then built at the end).
    progress : callable, optional
        ``progress(done_epochs, n_epochs)``, called about 200 times.
    overwrite : bool
        Replace the files of an earlier run in ``out_dir`` (only leolink's files); without
        it such a folder raises :class:`~leolink.io.run_dir.OutputFolderError`.
    workers : int or str
        Split the run into parts of its UTs on this many local processes, or on the dask
        cluster of ``"dask://ADDRESS"`` (:mod:`leolink.app.split`: the same outputs); 1
        runs in this process.
    parts : int or None
        Parts of the split (None: :data:`~leolink.app.split.PARTS_PER_WORKER` per local
        worker, :data:`~leolink.app.split.SCHEDULER_PARTS` on a cluster); with one
        worker, the parts run one after the other in this process.

    Returns
    -------
    Result

    Notes
    -----
    On glibc the process's mmap threshold is fixed at 4 MiB and its trim threshold at
    32 MiB (:func:`leolink.app.heap.fix_heap_thresholds`), unless the environment sets
    malloc's tunables: the peak memory stays flat in run length, and the temporaries of
    a few MiB reuse the heap's pages instead of faulting new ones in.
    """
    if is_multibeam(cfg):  # the circular aperture: TR 38.821's one-satellite snapshot
        return run_multibeam(cfg, out_dir, overwrite)
    split = split_workers(workers, parts)
    scen = checked_scenario(cfg, split)  # the checks of ``leolink validate``, before any file
    fix_heap_thresholds()  # memory flat in run length, few page faults (leolink.app.heap)
    with held_out_dirs():  # one command per folder (leolink.io.run_dir)
        if out_dir is not None:  # after the scenario built: a bad config removes nothing
            out_dir = claim_out_dir(out_dir, overwrite)
        return _run(cfg, scen, out_dir, progress, split)


def _run(cfg, scen, out_dir, progress, split=None):
    summary, position = _summary(cfg), _Position()
    sinks, files = _sinks(cfg, out_dir, summary, scen), []
    try:
        simulate = _simulation(cfg, scen, out_dir, split)
        where = (out_dir, files)
        return _run_and_write(cfg, scen, where, summary, [*sinks, position], simulate, progress)
    except BaseException as exc:  # Ctrl-C, a signal (leolink.app.guard), an error
        if out_dir is not None:
            _list_unfinished(out_dir, files, sinks)
        if isinstance(exc, KeyboardInterrupt):  # the sinks have aborted
            exc.add_note(position.where(out_dir))
        raise


def _list_unfinished(out_dir, files, sinks):
    """``run.unfinished.json``: the files a stopped run finished (its trace, ...), so that
    ``--overwrite`` may remove them (:func:`leolink.io.run_dir.claim_out_dir`)."""
    digests = {p: d for s in sinks for p, d in (getattr(s, "digests", None) or {}).items()}
    done = [Path(p) for p in [*files, *digests] if Path(p).is_file()]
    if done:
        with contextlib.suppress(OSError):  # the error being reported matters more
            write_manifest(out_dir, done, "run", "", version=leolink.__version__,
                           digests=digests, name=UNFINISHED)  # fmt: skip


def _simulation(cfg, scen, out_dir, split):
    """``simulate(sinks, progress) -> RunStats``: in this process, or split in parts."""
    if split is None:
        return lambda sinks, progress: run_simulation(scen, sinks, progress=progress)
    return lambda sinks, progress: run_split(cfg, scen, sinks, out_dir, split, progress)


def _run_and_write(cfg, scen, where, summary, sinks, simulate, progress):
    stats = simulate(sinks, progress)
    sinks = sinks[:-1]  # without the position
    try:  # an error or a stop in the writing: each sink drops what it still holds
        return _write(cfg, scen, where, summary, sinks, stats)
    except BaseException:
        for sink in sinks:  # a finished sink's abort only stops what still runs
            sink.abort()
        raise


def _write(cfg, scen, where, summary, sinks, stats):
    """The run's own files (appended to ``files`` of ``where = (out_dir, files)`` as they
    are finished), then the sinks' (``after_run``), then ``run.json``."""
    out_dir, files = where
    result_summary = {**summary.summary(), "run": _run_section(cfg, scen, stats)}
    report = next((s.stats for s in sinks if hasattr(s, "stats")), None)  # the report's
    per_ut = summary.per_ut_table()
    if out_dir is None:
        return Result(result_summary, None, [], sinks[1], report, per_ut, _epoch_utc(cfg))
    if "per_ut" not in result_summary:  # a large run: the tables beside summary.json
        files.append(write_parquet_atomic(per_ut, out_dir / "per_ut.parquet"))
        files.append(write_parquet_atomic(summary.dwell_table(), out_dir / "dwells.parquet"))
        result_summary["per_ut_file"], result_summary["dwells_file"] = (
            "per_ut.parquet", "dwells.parquet"
        )  # fmt: skip
    config_text = dump_toml(cfg)
    files.append(write_json_atomic(out_dir / "summary.json", result_summary))
    files.append(write_text_atomic(out_dir / "config.resolved.toml", config_text))
    for sink in sinks:
        if hasattr(sink, "after_run"):
            sink.after_run(result_summary, config_text)
    files += [p for s in sinks for p in getattr(s, "files", [])]
    digests = {p: d for s in sinks for p, d in getattr(s, "digests", {}).items()}
    raise_pending()  # a stop caught inside a library: no run.json (leolink.app.guard)
    files.append(write_manifest(out_dir, files, "run", config_text, version=leolink.__version__,
                                digests=digests))  # fmt: skip
    return Result(result_summary, out_dir, files, None, report, per_ut, _epoch_utc(cfg))
