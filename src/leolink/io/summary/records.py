"""The layout of ``summary.json``: per-UT records from the accumulator's columns.

Formatting only (Python lists and dicts); the statistics are computed, vectorized, by
:class:`leolink.io.summary.accumulator.SummaryAccumulator`.
"""

from __future__ import annotations

import numpy as np

from leolink.sim.handover.controller import EVENT_KINDS

__all__ = ["STAT_KEYS", "by_reason", "handover_counts", "nanmax", "per_ut_records"]

#: The keys of an SNR / SINR block.
STAT_KEYS = ("mean", "p5", "p50", "p95")


def per_ut_records(table, d, complete, link=None, kpi=None):
    """The ``per_ut`` list of summary.json from :meth:`SummaryAccumulator.per_ut_table`
    (and each UT's ``link`` block, :class:`leolink.io.summary.link.LinkStats`, and ``kpi``
    dict, :class:`leolink.io.summary.kpi.KpiAccumulator`)."""
    n_ut = table["ut_id"].size
    ut = d["ut_id"].astype(np.int64)
    n_complete = np.bincount(ut[complete], minlength=n_ut)
    complete_lists = np.split(d["duration_s"][complete], np.cumsum(n_complete)[:-1])
    records = _dwell_records(d, d["duration_s"], ~complete)
    bounds = np.concatenate(([0], np.cumsum(np.bincount(ut[~complete], minlength=n_ut))))
    cols = {k: np.asarray(v).tolist() for k, v in table.items()}
    rows = [dict(zip(cols, r, strict=True)) for r in zip(*cols.values(), strict=True)]
    out = []
    for i, r in enumerate(rows):  # output formatting only; statistics are vectorized
        out.append(
            {
                "ut_id": i,
                "n_epochs": r["n_epochs"],
                "handovers": handover_counts({k: r[f"n_{k}"] for k in EVENT_KINDS}),
                "dwell": {
                    "n_complete": r["n_dwell_complete"],
                    "mean_s": r["dwell_mean_s"],
                    "median_s": r["dwell_median_s"],
                    "complete_s": complete_lists[i],
                    "censored": records[bounds[i] : bounds[i + 1]],
                },
                "outage_fraction": r["outage_fraction"],
                "outage_fraction_by_reason": by_reason(
                    r["outage_fraction_no_satellite"],
                    r["outage_fraction_below_threshold"],
                    r["handover_interruption_fraction"],
                    r["outage_fraction_rlf"],
                ),
                "handover_interruption_fraction": r["handover_interruption_fraction"],
                "snr_db": {k: r[f"snr_{k}_db"] for k in STAT_KEYS},
                "sinr_db": {k: r[f"sinr_{k}_db"] for k in STAT_KEYS},
                "mean_throughput_bps": r["mean_throughput_bps"],
                "max_abs_doppler_hz": r["max_abs_doppler_hz"],
                "max_angular_speed_deg_s": r["max_angular_speed_deg_s"],
            }
        )
        if link is not None:
            out[-1]["link"] = link[i]
        if kpi is not None:
            out[-1]["kpi"] = kpi[i]
    return out


def by_reason(no_satellite, below_threshold, handover, rlf):
    return {
        "no_satellite": no_satellite,
        "below_threshold": below_threshold,
        "handover": handover,
        "rlf": rlf,
    }


def nanmax(x):
    return float(np.nanmax(x)) if np.isfinite(x).any() else None


def handover_counts(by_kind):
    out = {k: int(v) for k, v in by_kind.items()}
    out["handovers_total"] = out["beam_handover"] + out["sat_handover"]
    return out


def _dwell_records(d, duration, mask):
    """Dwell records (list of dicts) of the rows in ``mask``."""
    cols = {k: d[k][mask].tolist() for k in ("sat_id", "beam_id", "start_s", "end_s")}
    cols["duration_s"] = duration[mask].tolist()
    cols["censored_start"] = d["censored_start"][mask].tolist()
    cols["censored_end"] = d["censored_end"][mask].tolist()
    return [dict(zip(cols, row, strict=True)) for row in zip(*cols.values(), strict=True)]
