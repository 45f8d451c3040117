"""``leolink.run(config) -> Result``: build the scenario, wire the sinks, run, write.

The default sinks: the summary statistics (always), and the enabled ``[output.*]``
sinks (trace and event files, plots) when there is an output folder; without one the
trace and events are kept in memory. ``summary.json`` and ``config.resolved.toml`` are
written last; with more than ``PER_UT_IN_JSON_MAX`` UTs the per-UT statistics and the
dwells go to ``per_ut.parquet`` and ``dwells.parquet`` instead of ``summary.json``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import pandas as pd

from leolink.app.codebook import codebook_design_from_config
from leolink.app.notes import track_coverage, track_notes
from leolink.app.orbits import earth_orientation, roi_frame
from leolink.app.scenario import build_scenario
from leolink.config import dump_toml
from leolink.io.atomic import write_json_atomic, write_text_atomic
from leolink.io.sinks import SINKS, MemorySink
from leolink.io.summary import SummaryAccumulator
from leolink.io.tables import write_parquet_atomic
from leolink.sim.runner import run_simulation

__all__ = ["Result", "run", "run_notes"]


@dataclasses.dataclass
class Result:
    """What a run produced: the summary, and the trace and events (in memory, or read back
    from the files this run wrote)."""

    summary: dict
    out_dir: Path | None
    files: list[Path] = dataclasses.field(default_factory=list)
    _memory: MemorySink | None = None
    _per_ut: dict | None = None

    @property
    def per_ut(self) -> pd.DataFrame:
        """Per-UT statistics, one row per UT (``SummaryAccumulator.per_ut_table``)."""
        return pd.DataFrame(self._per_ut)

    @property
    def trace(self) -> pd.DataFrame:
        if self._memory is not None:
            return self._memory.trace()
        for path in self.files:  # Parquet first: faster to read
            if path.name == "trace.parquet":
                return pd.read_parquet(path)
        return pd.read_csv(self.out_dir / "trace.csv")

    @property
    def events(self) -> pd.DataFrame:
        if self._memory is not None:
            return self._memory.events()
        return pd.read_csv(self.out_dir / "events.csv")


def _sinks(cfg, out_dir, summary):
    """The sinks of a run: summary first (the plots read it), then ``[output.*]``."""
    if out_dir is None:
        return [summary, MemorySink()]
    context = SimpleNamespace(out_dir=out_dir, summary=summary)
    return [summary, *(SINKS.build(name, p, context) for name, p in cfg.output.enabled())]


def run_notes(cfg, scen):
    """The notes of a run (:mod:`leolink.app.notes`) and its track coverage."""
    design = codebook_design_from_config(cfg)
    notes = [f"codebook: {design.describe()}"]
    notes.append(roi_frame(cfg, scen.ephemeris).describe(scen.ephemeris.names))
    orientation = earth_orientation(cfg)
    if orientation is not None:
        notes.append(orientation.note)
    times = scen.times_s
    coverage = track_coverage(scen.populations, times, scen.n_warmup, scen.epoch_s)
    notes += track_notes(coverage, float(times[scen.n_warmup]), float(times[-1]))
    return notes, coverage, design


def _run_section(cfg, scen, stats):
    info = stats.info
    notes, coverage, design = run_notes(cfg, scen)
    return {
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
    }


def run(cfg, out_dir=None, progress=None):
    """Run the simulation of ``cfg``.

    Parameters
    ----------
    cfg : leolink.config.ConfigBase
    out_dir : path or None
        Where to write the enabled outputs (``trace.csv``/``trace.parquet``,
        ``events.csv``, plots), ``summary.json`` and ``config.resolved.toml``. None keeps
        the trace and events in memory (``Result.trace`` is then built at the end).
    progress : callable, optional
        ``progress(done_epochs, n_epochs)``, called about 200 times.

    Returns
    -------
    Result
    """
    scen = build_scenario(cfg)
    if out_dir is not None:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
    summary = SummaryAccumulator()
    sinks = _sinks(cfg, out_dir, summary)
    stats = run_simulation(scen, sinks, progress=progress)
    result_summary = {**summary.summary(), "run": _run_section(cfg, scen, stats)}
    memory = sinks[1] if out_dir is None else None
    per_ut = summary.per_ut_table()
    if out_dir is None:
        return Result(result_summary, None, [], memory, per_ut)
    files = [p for s in sinks for p in getattr(s, "files", [])]
    if "per_ut" not in result_summary:  # a large run: the tables beside summary.json
        files.append(write_parquet_atomic(per_ut, out_dir / "per_ut.parquet"))
        files.append(write_parquet_atomic(summary.dwell_table(), out_dir / "dwells.parquet"))
        result_summary["per_ut_file"], result_summary["dwells_file"] = (
            "per_ut.parquet", "dwells.parquet"
        )  # fmt: skip
    files.append(write_json_atomic(out_dir / "summary.json", result_summary))
    files.append(write_text_atomic(out_dir / "config.resolved.toml", dump_toml(cfg)))
    return Result(result_summary, out_dir, files, None, per_ut)
