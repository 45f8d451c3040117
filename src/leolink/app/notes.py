"""What a run should tell its user besides its outputs: tracks that do not cover the run,
the codebook leolink chose, the Earth orientation of TLE runs, the ROI frame.

Each note is one sentence; ``leolink run`` and ``leolink validate`` print them and
``summary.json`` keeps them under ``run.notes`` (track coverage also as numbers, under
``run.track_coverage``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["track_coverage", "track_notes"]


def track_coverage(populations, times_s, n_warmup=0, epoch_s=1.0):
    """UTs whose recorded track (or waypoints) does not cover the recorded epochs.

    Before its first fix and after its last, a track's UT holds that fix
    (:class:`leolink.sim.mobility.models.Waypoints`); this says for how long.

    Parameters
    ----------
    populations : list of (name, motion model)
    times_s : ndarray, every epoch [s]; ``n_warmup`` of them before recording.
    epoch_s : float [s]

    Returns
    -------
    list of dict
        ``ut_id``, ``population``, ``label``, ``first_s``, ``last_s`` (the track's span) and
        ``held_s`` (recorded time spent before or after it), for the UTs with ``held_s > 0``.
    """
    rec = np.asarray(times_s, float)[n_warmup:]
    out, lo = [], 0
    for name, model in populations:
        span = getattr(model, "time_span_s", None)
        if span is not None:
            span = np.asarray(span, float)
            labels = getattr(model, "ut_id", [str(i) for i in range(model.n_ut)])
            outside = (rec[None, :] < span[:, :1]) | (rec[None, :] > span[:, 1:])
            held = outside.sum(axis=1) * epoch_s
            for i in np.flatnonzero(held > 0):
                out.append(
                    {
                        "ut_id": lo + int(i),
                        "population": name,
                        "label": str(labels[i]),
                        "first_s": float(span[i, 0]),
                        "last_s": float(span[i, 1]),
                        "held_s": float(held[i]),
                    }
                )
        lo += model.n_ut
    return out


def track_notes(coverage, run_start_s, run_end_s):
    """One sentence per UT of :func:`track_coverage`."""
    return [
        f"UT {c['ut_id']} ({c['population']!r}, track {c['label']!r}) has fixes from "
        f"t = {c['first_s']:.1f} to {c['last_s']:.1f} s only; it is held at its first or last "
        f"fix for {c['held_s']:.0f} s of the recorded run ({run_start_s:.1f} to "
        f"{run_end_s:.1f} s)"
        for c in coverage
    ]
