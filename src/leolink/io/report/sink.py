"""The report sink (``[output.report]``): what :class:`ReportStats` keeps, fed by the stream.

At each epoch the sink keeps the trace columns the statistics need (buffered, handed to
:meth:`ReportStats.add_trace` in chunks of ``CHUNK_ROWS`` rows), the events and the dwells
closed there; at the end the dwells still open. The satellites are not in the stream: the
sink is given the run's ephemeris and evaluates it only at the kept frame epochs and only
for the satellites that serve a sampled UT there (bounded: ``max_frames x n_serving``
states, whatever the constellation), so pass, Walker and TLE runs are drawn alike. The
codebook is the engine's.

Files, when the run has an output folder: ``report_stats.npz``, ``footprint.gif`` and
``run.geojson`` / ``run.czml`` at :meth:`finish`; ``report.html`` at :meth:`after_run`, once
``summary.json`` exists (the page shows the final summary). Without a folder nothing is
written and :attr:`stats` feeds the notebook views of ``leolink.run()``'s result.
"""

from __future__ import annotations

import gc
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from leolink.errors import ConfigError
from leolink.io.report.stats import SERIES_COLUMNS, ReportStats
from leolink.sim.handover.controller import SERVICE_NAMES
from leolink.sim.processes import OUTAGE_REASONS

__all__ = ["ReportSink", "default_series_uts", "run_heap_frozen"]

CHUNK_ROWS = 100_000  # rows handed to ReportStats at once: one call per ~100 k rows
MAX_DEFAULT_UTS = 6  # default time-plot UTs: the first of each population, at most this
EPHEMERIS_BLOCK = 16  # kept epochs evaluated per ephemeris call (bounded temporaries)
#: Trace columns sent as integer codes, and their names (decoded before counting).
CODED_COLUMNS = {"service": SERVICE_NAMES, "outage_reason": OUTAGE_REASONS}
_WANTED = (*SERIES_COLUMNS, "outage_reason", "alt_m")


def default_series_uts(population):
    """The first UT of each population (names per UT, in order), at most 6."""
    firsts = [i for i, name in enumerate(population) if i == 0 or population[i - 1] != name]
    return firsts[:MAX_DEFAULT_UTS]


def _decode(columns):
    """The columns the statistics read, integer codes turned into their names."""
    out = {}
    for name in _WANTED:
        if name not in columns:
            continue
        values = np.asarray(columns[name])
        names = CODED_COLUMNS.get(name)
        out[name] = np.asarray(names)[values] if names and values.dtype.kind in "iu" else values
    return out


@contextmanager
def run_heap_frozen():
    """The objects alive on entry (the run's, and matplotlib's and Pillow's modules,
    imported here first) left out of the cyclic collector's passes until the exit.

    Drawing the report makes ~10^5 objects, which starts two full collections; each walks
    the whole heap of the run (~190,000 objects with matplotlib's at 1,000 UTs, ~0.1 s of
    CPU apiece), though none of it can become garbage while the report is drawn. :func:`gc.freeze`
    moves the objects alive now to the permanent generation, which the collector skips;
    :func:`gc.unfreeze` at the exit (an exception included) puts them back in the oldest
    generation, so cyclic garbage among them is collected later, as before: nothing is
    kept for good, the collector is neither disabled nor re-tuned, and the objects made
    meanwhile are collected as usual. When the caller has frozen objects itself, nothing
    is done (unfreezing would release its objects too).
    """
    if gc.get_freeze_count():
        yield
        return
    import matplotlib.backends.backend_agg  # noqa: F401  # the drawing's heavy imports,
    import matplotlib.figure  # noqa: F401  # frozen with the rest
    import PIL.Image  # noqa: F401

    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


class ReportSink:
    """Streamed report statistics and, with an output folder, the report's files.

    Parameters
    ----------
    out_dir : path or None
    params : leolink.io.sinks.ReportParams
        ``uts``, ``sample_uts``, ``max_frames``, ``animation``, ``exports``.
    ephemeris : callable or None
        ``ephemeris(t_s) -> (pos_m, vel_m_s, acc)``, shapes ``(n_t, n_sat, 3)``, in the
        frame of the UT positions (:class:`leolink.orbit.Ephemeris`).
    codebook : leolink.antenna.codebook.Codebook or None
    epoch_utc : str or None
        UTC of simulation time 0, for CZML (default J2000).
    """

    def __init__(self, out_dir, params, ephemeris=None, codebook=None, epoch_utc=None):
        self.out_dir = None if out_dir is None else Path(out_dir)
        self.params, self.ephemeris, self.codebook = params, ephemeris, codebook
        self.epoch_utc = epoch_utc
        self.stats, self.files, self.animation, self._drawn = None, [], None, None

    def start(self, info):
        uts = list(self.params.uts) or default_series_uts(info.population)
        bad = [u for u in uts if not 0 <= u < info.n_ut]
        if bad:
            raise ConfigError(
                f"output.report.uts = {list(self.params.uts)!r} is not allowed; "
                f"UT ids of this run are 0 to {info.n_ut - 1}"
            )
        end_s = info.start_s + info.n_epochs * info.epoch_s
        self.stats = ReportStats(
            info.n_ut, info.start_s, end_s, info.epoch_s, uts,
            self.params.sample_uts, self.params.max_frames,
        )  # fmt: skip
        if self.epoch_utc:  # saved with the statistics: leolink report DIR --exports reads it
            self.stats.epoch_utc = np.asarray(self.epoch_utc)
        cb = self.codebook
        if cb is not None:
            if not np.array_equal(cb.beam_id, np.arange(len(cb.beam_id))):
                raise ValueError("the report needs beam ids 0 .. n_beam - 1 in codebook order")
            self.stats.set_codebook(cb.u_xy, cb.n_sub_x, cb.n_sub_y)
        self._buffer, self._n_buffered, self.files = [], 0, []

    def epoch(self, frame):
        cols = _decode(frame.columns)
        self._buffer.append(cols)
        self._n_buffered += len(cols["ut_id"])
        if self._n_buffered >= CHUNK_ROWS:
            self._flush()
        if len(frame.events["ut_id"]):
            self.stats.add_events(frame.events)
        self._add_dwells(frame.dwells)

    block = epoch  # ReportStats takes rows in any chunking

    def _flush(self):
        if self._buffer:
            names = self._buffer[0]
            self.stats.add_trace({k: np.concatenate([b[k] for b in self._buffer]) for k in names})
        self._buffer, self._n_buffered = [], 0

    def _add_dwells(self, dwells):
        if len(dwells["ut_id"]):
            duration = np.asarray(dwells["end_s"], float) - np.asarray(dwells["start_s"], float)
            censored = np.asarray(dwells["censored_start"]) | np.asarray(dwells["censored_end"])
            self.stats.add_dwells(duration, censored)

    def _add_satellites(self):
        """States at the kept epochs of the satellites serving a sampled UT there."""
        stats = self.stats
        serving = np.unique(stats.ut_sat[stats.ut_sat >= 0])
        if self.ephemeris is None or serving.size == 0:
            return
        times = stats.keep_times_s
        for lo in range(0, times.size, EPHEMERIS_BLOCK):
            pos, vel, _ = self.ephemeris(times[lo : lo + EPHEMERIS_BLOCK])
            for i in range(pos.shape[0]):  # at most max_frames kept epochs
                stats.add_satellites(times[lo + i], pos[i, serving], vel[i, serving], serving)

    def finish(self, final):
        """Complete the statistics and save them; draw the animation (and the exports)
        and the page's figures, in this process."""
        self._flush()
        self._add_dwells(final.dwells)
        self._add_satellites()
        if self.out_dir is None:
            return
        self.files = [self.stats.save(self.out_dir / "report_stats.npz")]
        with run_heap_frozen():  # no full collection walks the run's heap meanwhile
            self._drawn = self._draw_files(), self._draw_figures()

    def _draw_files(self):
        """``footprint.gif`` (and the exports): ``(animation path or None, written)``."""
        stats, animation, written = self.stats, None, []
        drawable = stats.sat_pos_m is not None and stats.beam_u_xy is not None
        if self.params.animation and drawable:
            from leolink.io.report.animation import (
                animation_frames,
                frames_from_stats,
                write_footprint_gif,
            )

            frames = frames_from_stats(stats, animation_frames(stats.keep_times_s.size))
            animation = write_footprint_gif(self.out_dir / "footprint.gif", frames)["path"]
            written.append(animation)
        if self.params.exports:
            from leolink.io.report.rebuild import write_exports

            written += write_exports(stats, self.out_dir, self.epoch_utc)
        return animation, written

    def _draw_figures(self):
        from leolink.io.report.page import rendered_figures

        return rendered_figures(self.stats)

    def after_run(self, summary, config_text):
        """Write ``report.html`` from the final summary; returns the written paths."""
        if self.out_dir is None:
            return []
        from leolink.io.report.page import build_run_report

        (self.animation, drawn), figures = self._drawn
        page = build_run_report(
            self.out_dir / "report.html",
            summary,
            self.stats,
            config_text,
            animation_path=self.animation,
            figures=figures,
        )
        self.files = [*self.files, *drawn, page]
        return [*drawn, page]

    def abort(self):
        """Drop the buffered rows and the drawings."""
        self._buffer, self._n_buffered, self._drawn = [], 0, None
