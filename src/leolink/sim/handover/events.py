"""The event and dwell tables of the controller: columns, kinds, and their builders.

An event table and a dwell table are dicts of equal-length 1-D arrays, one entry per
column of :data:`EVENT_COLUMNS` / :data:`DWELL_COLUMNS`, sorted by ``ut_id`` (events of
one epoch; :func:`leolink.sim.handover.controller.resumed_events` sorts by time, then UT). Empty
tables have the dtypes of non-empty ones, so that joining them changes no dtype.
"""

from __future__ import annotations

import numpy as np

#: Event kinds (new kinds are appended, never renamed). ``service_resumed``: the end of a
#: handover's execution time (``to_*`` the serving link, ``from_*`` -1).
EVENT_KINDS = (
    "beam_handover",
    "sat_handover",
    "outage_start",
    "outage_end",
    "service_resumed",
    "rlf",  # radio link failure (leolink.sim.handover.rlf_run): from_* the failed cell, to_* -1
    # the handover procedure (leolink.sim.handover.procedure): from_* source, to_* target
    "measurement_report",
    "handover_command",
    "handover_complete",
    "handover_failure",
    "beam_switch",  # cells = satellites (leolink.sim.handover.cells): a beam change inside one
)
SERVICE_RESUMED = EVENT_KINDS.index("service_resumed")
_KIND_NAMES = np.asarray(EVENT_KINDS)


def kind_column(kind, n):
    """A ``kind`` column of ``n`` events of one kind, in the dtype every event table's
    ``kind`` has (that of :data:`EVENT_KINDS`: joining tables changes no dtype)."""
    return np.full(n, kind, _KIND_NAMES.dtype)


EVENT_COLUMNS = (
    "time_s",
    "ut_id",
    "kind",
    "from_sat",
    "from_beam",
    "to_sat",
    "to_beam",
    "snr_before_db",
    "snr_after_db",
)
DWELL_COLUMNS = (
    "ut_id",
    "sat_id",
    "beam_id",
    "start_s",
    "end_s",
    "censored_start",
    "censored_end",
)
_DWELL_DTYPES = (np.int64, np.int64, np.int64, float, float, bool, bool)


def split_cells(cand, n_beam):
    """Candidate index -> (sat, beam), -1 for -1."""
    cand = np.asarray(cand, np.int64)
    sat, beam = np.divmod(cand, n_beam)
    none = cand < 0
    sat[none] = -1
    beam[none] = -1
    return sat, beam


def events_table(t_s, kind_code, old, old_split, new_split, new_db, before_db, ut_id=None):
    """Events of UTs with ``kind_code >= 0`` (at most one per UT per epoch);
    ``old_split``, ``new_split``: ``split_cells`` of the old and new serving cells (n,);
    ``new_db``, ``before_db`` (n,): the new serving cell's SNR, the old link's last;
    ``ut_id`` (n,) ascending: the UTs of the rows (default: row ``i`` is UT ``i``)."""
    ut = np.flatnonzero(kind_code >= 0)
    return {
        "time_s": np.full(ut.size, float(t_s)),
        "ut_id": (ut if ut_id is None else ut_id[ut]).astype(np.int64),
        "kind": _KIND_NAMES[kind_code[ut]],
        "from_sat": old_split[0][ut],
        "from_beam": old_split[1][ut],
        "to_sat": new_split[0][ut],
        "to_beam": new_split[1][ut],
        "snr_before_db": np.where(old[ut] >= 0, before_db[ut], np.nan),
        "snr_after_db": new_db[ut],
    }


def dwells_table(ut, cand, start_s, end_s, censored_start, censored_end, n_beam, split=None):
    """Dwell records of the UTs ``ut`` on candidates ``cand`` (``split``: their
    ``split_cells``, if known)."""
    sat, beam = split_cells(cand, n_beam) if split is None else split
    return {
        "ut_id": np.asarray(ut, np.int64),
        "sat_id": sat,
        "beam_id": beam,
        "start_s": np.asarray(start_s, float),
        "end_s": np.broadcast_to(np.asarray(end_s, float), ut.shape).copy(),
        "censored_start": np.asarray(censored_start, bool),
        "censored_end": np.full(ut.shape, censored_end, bool),
    }


def no_events():
    """An empty event table, with the dtypes of a non-empty one (a new dict of shared,
    read-only empty arrays: most epochs have no event)."""
    return dict(_NO_EVENTS)


def no_dwells():
    """An empty dwell table, with the dtypes of a non-empty one (as :func:`no_events`)."""
    return dict(_NO_DWELLS)


def _read_only(values):
    values.flags.writeable = False
    return values


def _empty_event_column(name):
    if name == "kind":
        return _KIND_NAMES[:0]
    ints = ("ut_id", "from_sat", "from_beam", "to_sat", "to_beam")
    return np.zeros(0, np.int64 if name in ints else float)


_NO_EVENTS = {k: _read_only(_empty_event_column(k)) for k in EVENT_COLUMNS}
_NO_DWELLS = {
    k: _read_only(np.zeros(0, t)) for k, t in zip(DWELL_COLUMNS, _DWELL_DTYPES, strict=True)
}


def concat_events(*tables):
    """Join event tables (dicts of ``EVENT_COLUMNS`` arrays) in the order given."""
    return {k: np.concatenate([np.asarray(t[k]) for t in tables]) for k in EVENT_COLUMNS}


def sorted_events(table):
    """An event table sorted by time, then UT (stable: rows of one instant keep their order)."""
    order = np.lexsort((table["ut_id"], table["time_s"]))
    return {k: np.asarray(v)[order] for k, v in table.items()}
