"""Radio link failure in a run: each epoch's serving SINR drives :mod:`leolink.sim.handover.rlf`.

Once per epoch, after the serving links are computed, :meth:`RlfRun.after_links` gives
the RLF state machine (TS 38.331 5.3.10) one indication per UT: the epoch's serving SINR
against Q_out/Q_in, for UTs with service (no indication in outage, nor during a
handover's execution: 38.331 ignores out-of-sync while T304 runs). A UT whose serving
cell changed this epoch (handover, outage start or end) has its T310 stopped and its
counters cleared first (reconfiguration with sync).

An RLF declared at epoch ``t`` (T310 expired) takes effect at once:

- an ``rlf`` event at ``t`` (``from_*`` the failed cell, ``to_*`` -1); the dwell on the
  failed cell ends at ``t``;
- the UT loses its serving cell: the trace row of ``t`` is an outage with
  ``outage_reason = "rlf"`` (link columns NaN), and so is every row until the UT is
  re-established;
- re-establishment: at the first epoch ``t' >= t + reestablishment_s`` the controller
  serves the UT again (its best usable cell: an ``outage_end`` event, like the end of
  any outage). Until then :meth:`RlfRun.blocked` masks the UT's candidates. Outage time
  is counted in whole epochs, so an RLF costs at least one epoch of service.

With the handover procedure on (:mod:`leolink.sim.handover.procedure`, ``procedure``), a
handover failure is handled the same way: a ``handover_failure`` event (``from_*`` the
source, ``to_*`` the target) at its own time, the dwell on the target closed then, and
re-establishment from that time; the failed procedure's completion events are dropped.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.sim.handover import rlf
from leolink.sim.handover.controller import SERVICE_OUTAGE, SERVICE_SERVED
from leolink.sim.handover.events import kind_column, sorted_events

__all__ = ["RLF_REASON", "RlfRun"]

#: Trace ``outage_reason`` name of a UT that lost its link by RLF (re-establishing).
RLF_REASON = "rlf"
# The link columns of an outage row: NaN (the link figures of sim/service_link.py too; the
# MODCOD -1, none), as the monitor leaves them in any outage.
_LINK = ("snr_db", "sinr_db", "se_bps_hz", "throughput_bps", "cn0_dbhz", "esn0_db",
         "margin_db", "throughput_dvbs2x_bps", "throughput_shannon_bps")  # fmt: skip
_SERVING_CHANGES = ("beam_handover", "sat_handover", "outage_start", "outage_end")
_COMPLETIONS = ("service_resumed", "handover_complete")
# Epoch times accumulate float rounding; 1 ns is far below any timer value.
TIME_TOL_S = 1e-9


class RlfRun:
    """RLF bookkeeping of one run (module docstring).

    ``params``: :class:`~leolink.sim.handover.rlf.RlfParams`; ``reason_code``: the trace code of
    the ``rlf`` outage reason.
    """

    def __init__(self, params, n_ut, n_beam, reason_code):
        self.params, self.n_beam, self.reason_code = params, int(n_beam), int(reason_code)
        self.state = rlf.RlfState.initial(n_ut)
        self.procedure = None  # the handover procedure (leolink.sim.handover.procedure), if on

    def blocked(self, t_s):
        """bool (n_ut,): UTs still re-establishing at ``t_s`` (no service yet)."""
        waited = t_s - self.state.rlf_at_s
        with np.errstate(invalid="ignore"):
            return self.state.reestablishing & (waited < self.params.reestablishment_s - TIME_TOL_S)

    def after_links(self, t_s, controller, events, columns, blocked):
        """One indication per UT at ``t_s``; returns ``(controller, rlf_events, dwells)``.

        ``controller``: the ControllerState after this epoch's decision; ``events``: this
        epoch's events; ``columns``: the trace columns (modified in place for UTs that
        fail now or are re-establishing); ``blocked``: :meth:`blocked` at ``t_s``.
        """
        kind = np.asarray(events["kind"])
        changed = np.zeros(controller.n_ut, bool)
        changed[np.asarray(events["ut_id"], np.int64)[np.isin(kind, _SERVING_CHANGES)]] = True
        state = rlf.reset(self.state, changed)
        monitored = np.asarray(columns["service"]) == SERVICE_SERVED
        state, failed, _ = rlf.step(state, t_s, columns["sinr_db"], self.params, monitored)
        hof, hof_events = np.zeros_like(failed), None
        if self.procedure is not None:  # handover failures re-establish as an RLF does
            hof, hof_s, hof_events = self.procedure.failures(
                t_s, columns["sinr_db"], self.params.q_out_db
            )
            state = rlf.declare(state, hof, hof_s)
        self.state = state
        rlf_events, dwells = self._failed(t_s, controller, columns, failed)
        if hof.any():
            hof_dwells = self._failed(hof_s, controller, columns, hof)[1]
            dwells = {k: np.concatenate([dwells[k], hof_dwells[k]]) for k in dwells}
            rlf_events = {k: np.concatenate([rlf_events[k], hof_events[k]]) for k in rlf_events}
        self._outage_rows(columns, failed | blocked | hof)
        return _drop_serving(controller, failed | hof), rlf_events, dwells

    def _failed(self, t_s, controller, columns, failed):
        """The ``rlf`` events and the closed dwells of the UTs ``failed`` at ``t_s`` (a
        float, or per UT)."""
        ut = np.flatnonzero(failed)
        t_s = np.broadcast_to(np.asarray(t_s, float), failed.shape)[ut]
        serving = controller.serving[ut]
        sat, beam = np.divmod(serving, self.n_beam)
        none = np.full(ut.size, -1, np.int64)
        rlf_events = {
            "time_s": t_s.copy(),
            "ut_id": ut.astype(np.int64),
            "kind": kind_column("rlf", ut.size),
            "from_sat": sat,
            "from_beam": beam,
            "to_sat": none,
            "to_beam": none.copy(),
            "snr_before_db": np.asarray(columns["snr_db"], float)[ut],
            "snr_after_db": np.full(ut.size, np.nan),
        }
        dwells = {
            "ut_id": ut.astype(np.int64),
            "sat_id": sat,
            "beam_id": beam,
            "start_s": controller.serving_since_s[ut],
            "end_s": t_s.copy(),
            "censored_start": controller.dwell_censored_start[ut].copy(),
            "censored_end": np.zeros(ut.size, bool),
        }
        return rlf_events, dwells

    def merge(self, state, columns, events, dwells):
        """:meth:`after_links` on a :class:`~leolink.sim.processes.SimState`; returns
        ``(controller, events, dwells)`` with the RLF events and dwells merged in (events
        sorted by time, then UT, as the controller emits them)."""
        blocked = state.rlf_blocked
        if blocked is None:
            blocked = np.zeros(state.controller.n_ut, bool)
        controller, rlf_events, rlf_dwells = self.after_links(
            state.t_s, state.controller, events, columns, blocked
        )
        if rlf_events["ut_id"].size == 0:
            return controller, events, dwells
        failed = rlf_events["ut_id"][rlf_events["kind"] == "handover_failure"]
        if failed.size:  # a failed procedure does not complete
            kind, ut = np.asarray(events["kind"]), np.asarray(events["ut_id"])
            keep = ~(np.isin(ut, failed) & np.isin(kind, _COMPLETIONS))
            events = {k: np.asarray(v)[keep] for k, v in events.items()}
        joined = sorted_events({k: np.concatenate([events[k], rlf_events[k]]) for k in events})
        both = {k: np.concatenate([np.asarray(dwells[k]), rlf_dwells[k]]) for k in dwells}
        return controller, joined, both

    def _outage_rows(self, columns, rows):
        if not rows.any():
            return
        columns["service"] = np.where(rows, SERVICE_OUTAGE, columns["service"]).astype(np.int8)
        columns["outage_reason"] = np.where(rows, self.reason_code, columns["outage_reason"])
        columns["outage_reason"] = columns["outage_reason"].astype(np.int8)
        for name in ("sat_id", "beam_id"):
            columns[name] = np.where(rows, -1, columns[name])
        for name in _LINK:
            if name in columns:
                columns[name] = np.where(rows, np.nan, columns[name])
        if "modcod" in columns:
            columns["modcod"] = np.where(rows, -1, columns["modcod"])
        columns["interruption_s"] = np.where(rows, 0.0, columns["interruption_s"])


def _drop_serving(c, failed):
    """The controller state with the serving cell of ``failed`` UTs cleared (in outage)."""
    if not failed.any():
        return c
    return dataclasses.replace(
        c,
        serving=np.where(failed, -1, c.serving),
        pending=np.where(failed, -1, c.pending),
        pending_since_s=np.where(failed, np.nan, c.pending_since_s),
        interrupted_until_s=np.where(failed, -np.inf, c.interrupted_until_s),
        serving_since_s=np.where(failed, np.nan, c.serving_since_s),
        in_outage=c.in_outage | failed,
        dwell_censored_start=np.where(failed, False, c.dwell_censored_start),
        serving_snr_db=None
        if c.serving_snr_db is None
        else np.where(failed, np.nan, c.serving_snr_db),
    )
