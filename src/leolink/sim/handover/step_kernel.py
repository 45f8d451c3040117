""":func:`leolink.sim.handover.controller.step`'s rules by the compiled loop (``leolink._kernels``).

Once the policy has chosen (``policy.choose`` is any policy's Python), every rule of the
step is per UT: its time-to-trigger, handover, outage and dwell bookkeeping, the new
state and the service code. ``step_rules`` applies them UT by UT in one call, with the
numpy code's comparisons and selections (no value is rounded but ``t + handover_time_s``,
computed alike), and marks the UTs with an event or a closing dwell, whose tables are
then built here for those few. ``tests/test_controller_contracts.py`` checks both paths
against a scalar reference of the rules; ``tests/test_controller.py`` runs on both.
"""

from __future__ import annotations

import numpy as np

from leolink import _kernels
from leolink.sim.handover.events import (
    dwells_table,
    events_table,
    no_dwells,
    no_events,
    split_cells,
)

__all__ = ["compiled_step"]


def compiled_step(t_s, table, state, policy, target, min_snr_db, handover_time_s, n_beam):
    """The rules of :func:`~leolink.sim.handover.controller.step` for the policy's ``target``: its
    :class:`~leolink.sim.handover.controller.StepResult` (the same ValueError where the target is
    not usable where one is needed)."""
    from leolink.sim.handover.controller import (
        TIME_TOL_S,
        ControllerState,
        StepResult,
        _raise_unusable,
    )

    n, old = state.n_ut, np.asarray(state.serving, np.int64)
    last = state.serving_snr_db
    new = ControllerState(
        serving=np.empty(n, np.int64),
        pending=np.empty(n, np.int64),
        pending_since_s=np.empty(n),
        interrupted_until_s=np.empty(n),
        serving_since_s=np.empty(n),
        in_outage=np.empty(n, bool),
        dwell_censored_start=np.empty(n, bool),
        n_beam=int(n_beam),
        serving_snr_db=np.empty(n),
    )
    sat, beam = np.empty(n, np.int64), np.empty(n, np.int64)
    service, kind = np.empty(n, np.int8), np.empty(n, np.int8)
    new_db, last_db, closing = np.empty(n), np.empty(n), np.empty(n, bool)
    n_bad, first_bad, n_events, n_closing = _kernels.step_rules(
        np.asarray(table.cell, np.int64), np.asarray(table.snr_db, float),
        np.asarray(target, np.int64), old, np.asarray(state.pending, np.int64),
        np.asarray(state.pending_since_s, float), np.asarray(state.interrupted_until_s, float),
        np.asarray(state.serving_since_s, float), np.asarray(state.in_outage, bool),
        np.asarray(state.dwell_censored_start, bool),
        np.full(n, np.nan) if last is None else np.asarray(last, float),
        float(t_s), float(min_snr_db), float(handover_time_s),
        float(policy.time_to_trigger_s), TIME_TOL_S,
        int(n_beam), new.serving, new.pending, new.pending_since_s, new.interrupted_until_s,
        new.serving_since_s, new.in_outage, new.dwell_censored_start, new.serving_snr_db, sat,
        beam, service, kind, new_db, last_db, closing,
    )  # fmt: skip
    if n_bad:
        _raise_unusable(policy, target, n_bad, first_bad)
    events, dwells = no_events(), no_dwells()
    if n_events:
        u = np.flatnonzero(kind >= 0)
        old_split = split_cells(old[u], n_beam)
        events = events_table(t_s, kind[u].astype(np.int64), old[u], old_split,
                              (sat[u], beam[u]), new_db[u], last_db[u], ut_id=u)  # fmt: skip
    if n_closing:
        u = np.flatnonzero(closing)
        dwells = dwells_table(u, old[u], state.serving_since_s[u], t_s,
                              state.dwell_censored_start[u], False, n_beam,
                              split_cells(old[u], n_beam))  # fmt: skip
    return StepResult(new, events, dwells, service, sat, beam)
