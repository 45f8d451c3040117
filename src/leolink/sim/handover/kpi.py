"""Handover KPIs from the event and dwell tables (the streaming percentiles over UT-epochs:
:mod:`leolink.sim.histograms`).

Tables are dicts of equal-length 1-D arrays, as :mod:`leolink.sim.handover.controller` emits them:
events ``time_s, ut_id, kind, from_sat, from_beam, to_sat, to_beam`` (kinds
``beam_handover``, ``sat_handover``, ``outage_start``, ``outage_end``, ``rlf``, ...);
dwells ``ut_id, sat_id, beam_id, start_s, end_s, censored_start, censored_end``.

Definitions
-----------
Handover rate: handovers per UT-minute of observation, overall and by kind.

Ping-pong (after TR 36.839 5.2.2, "ping-pong modelling", and the time-of-stay of
5.4.3): a handover ``B -> A`` is a ping-pong when the UT's previous serving change was
the handover ``A -> B`` and it came less than ``ping_pong_s`` earlier (the time of stay in
``B`` is shorter than the minimum time of stay, 1 s by default). At cell level a cell is
``(sat, beam)`` and every event of the UT (handover, outage, RLF) is a serving change; at
satellite level only satellite handovers, outages and RLFs are, so beam handovers inside
``B`` do not break the pair. Each return counts once, so ``A -> B -> A -> B`` has two
ping-pongs. ``ping_pong_fraction`` = ping-pongs / handovers (of the same level).

Time of stay: the duration of a dwell (beam level: one serving cell; satellite level:
consecutive dwells on one satellite joined where one ends as the next starts). A stay cut
by the start or end of the run (``censored_*``) is not complete: it is excluded from the
mean and the distribution and counted apart.

Mobility robustness (TS 38.300 15.5.2.2.2, "Connection failure due to intra-system
mobility"). A connection failure is an ``rlf`` or a ``handover_failure`` (HOF); the cell
the UT re-establishes in is the ``to_*`` cell of its next ``outage_end`` (a failure whose
re-establishment the run does not reach is not classified). With ``S -> T`` the UT's last
handover before the failure, initiated at ``t_h`` (the trigger: 38.300 times "since the
last handover initialisation"), and the failure at ``t_f``:

- *too early*: an HOF, or an RLF with ``t_f - t_h < mro_window_s``, re-established in
  ``S``;
- *wrong cell*: the same, re-established in a cell other than ``S``, ``T`` and the cell
  that failed;
- *too late*: an RLF without a handover in the window, re-established in a cell other
  than the one that failed.

The window stands for Tstore_UE_cntxt, which OAM sets (38.300 15.5.2.5 gives no value;
leolink's default is 1 s). An HOF re-established in its target is counted as a handover
failure of no class. Cells are ``(sat, beam)``, or satellites at ``level="satellite"``.

References
----------
.. [1] 3GPP TR 36.839 V11.1.0, "E-UTRA; Mobility enhancements in heterogeneous
   networks", 5.2.2 Ping-pong modelling, 5.4.2 handover performance metrics, 5.4.3
   short time-of-stay.
.. [2] 3GPP TS 38.300 V18.6.0, 15.5.2.2.2 connection failure due to intra-system
   mobility, 15.5.2.5 (Tstore_UE_cntxt).
"""

from __future__ import annotations

import math

import numpy as np

from leolink.sim.histograms import (  # noqa: F401  (re-exported: the KPIs' percentiles)
    PERCENTILES,
    GroupedPercentileHistogram,
    PercentileHistogram,
    interpolated_percentiles,
)

HANDOVER_KINDS = ("beam_handover", "sat_handover")
# Dwell boundaries come from the same epoch times; 1 ns absorbs float rounding.
TIME_TOL_S = 1e-9


def _ut_minutes(observed_s, n_ut):
    minutes = np.broadcast_to(np.asarray(observed_s, float), (n_ut,)) / 60.0
    if np.any(minutes <= 0):
        raise ValueError("observed_s must be > 0 for every UT")
    return minutes


def handover_rates(events, observed_s, n_ut, kinds=HANDOVER_KINDS):
    """Handovers per UT-minute, overall and by kind.

    Parameters
    ----------
    events : dict of arrays (``ut_id``, ``kind``)
    observed_s : float or (n_ut,) [s], observation time of each UT.
    n_ut : int
    kinds : the event kinds that are handovers.

    Returns
    -------
    dict
        ``overall`` (total handovers / total UT-minutes), ``by_kind`` {kind: float},
        ``per_ut`` (n_ut,) and ``per_ut_by_kind`` {kind: (n_ut,)} [1/min].
    """
    minutes = _ut_minutes(observed_s, n_ut)
    ut, kind = np.asarray(events["ut_id"], np.int64), np.asarray(events["kind"])
    per_kind = {k: np.bincount(ut[kind == k], minlength=n_ut).astype(float) for k in kinds}
    total = sum(per_kind.values(), np.zeros(n_ut))
    return {
        "overall": float(total.sum() / minutes.sum()),
        "by_kind": {k: float(c.sum() / minutes.sum()) for k, c in per_kind.items()},
        "per_ut": total / minutes,
        "per_ut_by_kind": {k: c / minutes for k, c in per_kind.items()},
    }


def ping_pong_mask(events, ping_pong_s=1.0, level="cell"):
    """bool per event: the handover is a ping-pong (module docstring).

    Parameters
    ----------
    events : dict of arrays
    ping_pong_s : float [s], minimum time of stay; a return strictly sooner is a ping-pong.
    level : "cell" or "satellite"

    Returns
    -------
    ndarray of bool, one per event row, in the table's order.
    """
    kind = np.asarray(events["kind"])
    if level == "cell":
        counted, breaks = np.isin(kind, HANDOVER_KINDS), np.ones(kind.shape, bool)
        cols = ("from_sat", "from_beam", "to_sat", "to_beam")
    elif level == "satellite":
        counted = kind == "sat_handover"
        breaks = kind != "beam_handover"  # a beam change inside the satellite is no change
        cols = ("from_sat", "from_sat", "to_sat", "to_sat")
    else:
        raise ValueError(f"level = {level!r}; use 'cell' or 'satellite'")
    idx = np.flatnonzero(breaks)
    time_s, ut_all = np.asarray(events["time_s"], float), np.asarray(events["ut_id"])
    order = idx[np.lexsort((idx, time_s[idx], ut_all[idx]))]
    t, ut = time_s[order], ut_all[order]
    fs, fb, ts, tb = (np.asarray(events[c])[order] for c in cols)
    pp = np.zeros(order.shape, bool)
    same = (ut[1:] == ut[:-1]) & counted[order][1:] & counted[order][:-1]
    chain = (fs[1:] == ts[:-1]) & (fb[1:] == tb[:-1])  # B -> A starts where A -> B ended
    back = (ts[1:] == fs[:-1]) & (tb[1:] == fb[:-1])  # ... and returns to A
    pp[1:] = same & chain & back & (t[1:] - t[:-1] < ping_pong_s - TIME_TOL_S)
    mask = np.zeros(kind.shape, bool)
    mask[order] = pp
    return mask


def ping_pong_fraction(events, ping_pong_s=1.0, level="cell"):
    """``(fraction, n_ping_pong, n_handover)``; fraction NaN without handovers."""
    kind = np.asarray(events["kind"])
    n_ho = int(np.isin(kind, HANDOVER_KINDS if level == "cell" else ("sat_handover",)).sum())
    n_pp = int(ping_pong_mask(events, ping_pong_s, level).sum())
    return (n_pp / n_ho if n_ho else math.nan), n_pp, n_ho


def stays(dwells, level="beam"):
    """Stays as a dwell table: the dwells themselves (beam) or joined per satellite.

    At satellite level, dwells of one UT on one satellite that follow each other without
    a gap (``end_s`` of one = ``start_s`` of the next) become one stay.
    """
    if level == "beam":
        return {k: np.asarray(v) for k, v in dwells.items()}
    if level != "satellite":
        raise ValueError(f"level = {level!r}; use 'beam' or 'satellite'")
    ut, sat = np.asarray(dwells["ut_id"]), np.asarray(dwells["sat_id"])
    start, end = np.asarray(dwells["start_s"], float), np.asarray(dwells["end_s"], float)
    order = np.lexsort((start, ut))
    ut, sat, start, end = ut[order], sat[order], start[order], end[order]
    touching = np.abs(start[1:] - end[:-1]) <= TIME_TOL_S
    joins = (ut[1:] == ut[:-1]) & (sat[1:] == sat[:-1]) & touching
    first = np.flatnonzero(np.concatenate(([True], ~joins))) if len(ut) else np.zeros(0, int)
    last = np.concatenate((first[1:] - 1, [len(ut) - 1])) if len(ut) else first
    cs = np.asarray(dwells["censored_start"], bool)[order]
    ce = np.asarray(dwells["censored_end"], bool)[order]
    return {
        "ut_id": ut[first],
        "sat_id": sat[first],
        "start_s": start[first],
        "end_s": end[last],
        "censored_start": cs[first],
        "censored_end": ce[last],
    }


def time_of_stay(dwells, level="beam"):
    """Distribution of complete stays [s]: ``durations_s`` (sorted), ``mean_s``,
    ``median_s``, ``p10_s``, ``p90_s``, ``n_complete``, ``n_censored`` (NaN stats if none)."""
    table = stays(dwells, level)
    dur = np.asarray(table["end_s"], float) - np.asarray(table["start_s"], float)
    censored = np.asarray(table["censored_start"], bool) | np.asarray(table["censored_end"], bool)
    done = np.sort(dur[~censored])
    stat = (lambda f: float(f(done))) if done.size else (lambda f: math.nan)
    return {
        "durations_s": done,
        "mean_s": stat(np.mean),
        "median_s": stat(np.median),
        "p10_s": stat(lambda d: np.percentile(d, 10)),
        "p90_s": stat(lambda d: np.percentile(d, 90)),
        "n_complete": int(done.size),
        "n_censored": int(censored.sum()),
    }


#: Connection failures of the MRO classes and the classes (:func:`mro_classes`).
FAILURE_KINDS = ("rlf", "handover_failure")
MRO_CLASSES = ("too_early", "too_late", "wrong_cell")


def _last_of(is_kind, ut, reverse=False):
    """Per row (in UT-then-time order) the nearest earlier (later, ``reverse``) row of its
    UT where ``is_kind``, inclusive of itself; -1 where none."""
    n = is_kind.size
    idx = np.arange(n)
    if reverse:
        found = np.minimum.accumulate(np.where(is_kind, idx, n)[::-1])[::-1]
        found = np.where(found < n, found, -1)
    else:
        found = np.maximum.accumulate(np.where(is_kind, idx, -1)) if n else idx
    ok = found >= 0
    return np.where(ok & (ut[np.maximum(found, 0)] == ut), found, -1)


def mro_classes(events, window_s=1.0, level="cell"):
    """The MRO class of every connection failure (module docstring, TS 38.300 15.5.2.2.2).

    Parameters
    ----------
    events : dict of arrays (``time_s, ut_id, kind, from_sat, from_beam, to_sat, to_beam``)
    window_s : float [s], the "shortly after" a handover (Tstore_UE_cntxt).
    level : "cell" (sat, beam) or "satellite"

    Returns
    -------
    dict of bool arrays, one per event row: ``handover_failure`` and each of
    :data:`MRO_CLASSES` (False on rows that are not failures).
    """
    kind = np.asarray(events["kind"]).astype(str)
    t_all, ut_all = np.asarray(events["time_s"], float), np.asarray(events["ut_id"], np.int64)
    order = np.lexsort((np.arange(kind.size), t_all, ut_all))
    k, t, ut = kind[order], t_all[order], ut_all[order]
    beam = (lambda c: np.asarray(events[c])[order]) if level == "cell" else (
        lambda c: np.zeros(order.size, np.int64))  # fmt: skip
    cell = {e: (np.asarray(events[f"{e}_sat"])[order], beam(f"{e}_beam")) for e in ("from", "to")}
    ho = _last_of(np.isin(k, HANDOVER_KINDS), ut)
    re = _last_of(k == "outage_end", ut, reverse=True)
    hof, failure = k == "handover_failure", np.isin(k, FAILURE_KINDS)
    h, r = np.maximum(ho, 0), np.maximum(re, 0)

    def same(a, i, b, j):  # cell a of rows i == cell b of rows j
        return (cell[a][0][i] == cell[b][0][j]) & (cell[a][1][i] == cell[b][1][j])

    rows = np.arange(k.size)
    known = failure & (re >= 0)
    recent = hof | ((ho >= 0) & (t - t[h] < window_s - TIME_TOL_S))
    # the failed cell: an RLF's from_*, an HOF's target
    failed_in = np.where(hof, same("to", r, "to", rows), same("to", r, "from", rows))
    in_source, in_target = same("to", r, "from", h), same("to", r, "to", h)
    out = {
        "handover_failure": hof,
        "too_early": known & recent & in_source,
        "wrong_cell": known & recent & ~in_source & ~in_target & ~failed_in,
        "too_late": known & ~recent & (k == "rlf") & ~failed_in,
    }
    result = {}
    for name, mask in out.items():
        result[name] = np.zeros(kind.size, bool)
        result[name][order] = mask
    return result


def mro_counts(events, window_s=1.0, level="cell"):
    """``{handover_failure_count, too_early_count, too_late_count, wrong_cell_count}``."""
    classes = mro_classes(events, window_s, level)
    return {f"{name}_count": int(mask.sum()) for name, mask in classes.items()}


def summarize(events, dwells, observed_s, n_ut, ping_pong_s=1.0, mro_window_s=1.0,
              mro_level="cell"):  # fmt: skip
    """The ``overall.kpi`` block of summary.json from the event and dwell tables.

    SINR/throughput percentiles and interruption/outage times are streamed by the caller
    (:class:`PercentileHistogram`), which adds their summaries.
    """
    rates = handover_rates(events, observed_s, n_ut)
    pp_cell, n_pp_cell, _ = ping_pong_fraction(events, ping_pong_s, "cell")
    pp_sat, n_pp_sat, _ = ping_pong_fraction(events, ping_pong_s, "satellite")
    stay = {level: time_of_stay(dwells, level) for level in ("beam", "satellite")}
    n_rlf = int(np.sum(np.asarray(events["kind"]) == "rlf"))
    minutes = _ut_minutes(observed_s, n_ut).sum()
    return {
        "handover_rate_per_ut_min": rates["overall"],
        "handover_rate_per_ut_min_by_kind": rates["by_kind"],
        "ping_pong_s": float(ping_pong_s),
        "ping_pong_fraction": pp_cell,
        "ping_pong_count": n_pp_cell,
        "ping_pong_fraction_satellite": pp_sat,
        "ping_pong_count_satellite": n_pp_sat,
        "rlf_count": n_rlf,
        **mro_counts(events, mro_window_s, mro_level),
        "mro_window_s": float(mro_window_s),
        "rlf_rate_per_ut_min": n_rlf / minutes,
        "mean_time_of_stay_s": {k: v["mean_s"] for k, v in stay.items()},
        "time_of_stay_s": {
            k: {m: v[m] for m in ("median_s", "p10_s", "p90_s", "n_complete", "n_censored")}
            for k, v in stay.items()
        },
    }
