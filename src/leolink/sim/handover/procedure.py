"""The handover procedure in simulated time: report, command, execution (T304), access.

With ``[controller.signalling]`` on, a handover that the controller decides at epoch
``t_r`` (the trigger) is not instantaneous. Per UT, vectorized over the UTs that hand over:

1. **measurement report** at ``t_r``, sent to the source over the service link;
2. **handover command** (RRCReconfiguration with reconfigurationWithSync) received at
   ``t_c = t_r + d_s / c + network_processing_s + d_s / c``: the report's uplink and the
   command's downlink each take the one-way delay of the source link, ``d_s`` its slant
   range at ``t_r``;
3. **execution**: T304 starts at ``t_c`` (TS 38.331 7.1.1); the UE applies the
   configuration in ``ue_processing_s`` (the RRC procedure delay, 10 ms in TS 38.133
   A.14.2.1.1.3), then accesses the target:

   - ``access = "rach"``: ``rach_attempts`` four-step random accesses, each
     Msg1 -> Msg2 and Msg3 -> Msg4 over the target link (two round trips, ``4 d_t / c``)
     plus ``rach_processing_s``;
   - ``access = "rach_less"`` (Rel-18, TS 38.300 16.14.3.2.1): the first uplink on the
     configured grant, ``d_t / c``;

4. **handover complete** at ``t_d = t_c + ue_processing_s + access``, the end of the
   interruption (``service_resumed`` at the same instant).

A conditional handover (CHO) has no report and no command at execution: its command was
received at preparation, so execution starts at the trigger (``t_c = t_r``).

Interruption (a leolink choice, documented in docs/handover_notes.md): the controller
moves the UT to the target at the trigger, so the UT has no service from ``t_r`` to
``t_d``: round trip to the source + processing + access. In NR the source keeps serving
until the command; leolink charges the whole procedure, an upper bound.

Failure (handover failure, HOF): T304 expires before the access completes
(``ue_processing_s + access > t304_s``: at ``t_c + t304_s``), or the target's SINR sampled
at an epoch of the procedure is below Q_out of ``[controller.rlf]`` (the access would not
complete; declared at ``max(t_c, epoch)``, without waiting for T304). The UT then
re-establishes as after a radio link failure (:mod:`leolink.sim.handover.rlf_run`).

The geometry is the decision epoch's: over a procedure of tens of ms a LEO slant range
changes by less than 200 m (0.7 us of delay).

References
----------
.. [1] 3GPP TS 38.331, 5.3.5.5 reconfiguration with sync, 7.1.1 T304
   (ms50 ... ms10000), 5.3.5.13 conditional reconfiguration.
.. [2] 3GPP TS 38.300, 9.2.3.2 handover (RACH, RACH-less), 16.14.3.2 NTN mobility.
.. [3] 3GPP TS 38.133, A.14.2.1.1.3 (RRC procedure delay 10 ms).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.errors import ConfigError, require_at_least
from leolink.kinematics import propagation_delay_s as one_way_delay_s
from leolink.sim.handover.events import (
    EVENT_COLUMNS,
    kind_column,
    no_events,
    sorted_events,
    split_cells,
)

__all__ = ["T304_VALUES_S", "Procedure", "SignallingParams", "timeline"]

#: T304 values of ReconfigurationWithSync (TS 38.331 6.3.2): ms50 ... ms10000, nothing else.
T304_VALUES_S = (0.05, 0.1, 0.15, 0.2, 0.5, 1.0, 2.0, 10.0)
ACCESS = ("rach", "rach_less")
# Event times are sums of float seconds; 1 ns is far below any delay modelled here.
TIME_TOL_S = 1e-9
_HANDOVERS = ("beam_handover", "sat_handover")


@dataclasses.dataclass(frozen=True)
class SignallingParams:
    """``[controller.signalling]`` (module docstring). Times [s]."""

    network_processing_s: float = 0.01
    ue_processing_s: float = 0.01
    t304_s: float = 1.0
    access: str = "rach"
    rach_attempts: int = 1
    rach_processing_s: float = 0.0

    def __post_init__(self):
        for name in ("network_processing_s", "ue_processing_s", "rach_processing_s"):
            require_at_least(f"controller.signalling.{name}", getattr(self, name), 0.0, "[s]")
        require_at_least("controller.signalling.rach_attempts", self.rach_attempts, 1, "tries")
        if not any(abs(self.t304_s - v) <= TIME_TOL_S for v in T304_VALUES_S):
            raise ConfigError(
                f"controller.signalling.t304_s = {self.t304_s!r} is not allowed: use one of "
                f"{', '.join(map(str, T304_VALUES_S))} (TS 38.331 t304)"
            )
        if self.access not in ACCESS:
            raise ConfigError(
                f"controller.signalling.access = {self.access!r} is not allowed: use one of "
                f"{', '.join(map(repr, ACCESS))}"
            )


def access_s(target_range_m, params):
    """Time of the access to the target after the UE has applied the command [s]."""
    d_t = one_way_delay_s(target_range_m)
    if params.access == "rach_less":
        return d_t
    return params.rach_attempts * (4.0 * d_t + params.rach_processing_s)


def timeline(t_r, source_range_m, target_range_m, params, conditional=False):
    """The procedure's instants of handovers triggered at ``t_r`` (module docstring).

    Parameters
    ----------
    t_r : float or ndarray (n,) [s], trigger (measurement report) times.
    source_range_m, target_range_m : ndarray (n,) [m], slant ranges at ``t_r``.
    params : SignallingParams
    conditional : bool, CHO: the command was received at preparation (``t_c = t_r``).

    Returns
    -------
    (t_c, t_d, t_fail) : ndarrays (n,) [s]: command received, access complete, and the
        T304 expiry ``t_c + t304_s`` where the access cannot complete in time (inf else).
    """
    t_r = np.broadcast_to(np.asarray(t_r, float), np.shape(source_range_m))
    rtt = 0.0 if conditional else 2.0 * one_way_delay_s(source_range_m)
    t_c = t_r + rtt + (0.0 if conditional else params.network_processing_s)
    execution = params.ue_processing_s + access_s(target_range_m, params)
    late = execution > params.t304_s + TIME_TOL_S
    return t_c, t_c + execution, np.where(late, t_c + params.t304_s, np.inf)


class Procedure:
    """The signalling state of every UT of a run (arrays ``(n_ut,)``), advanced once per epoch.

    :meth:`after_step` takes the controller's decision of an epoch, times the procedure of
    its new handovers, sets their interruption and emits the step events that fall in the
    epoch; :meth:`failures` (called with the epoch's serving SINR) says which fail now.
    """

    def __init__(self, params, n_ut, n_beam, epoch_s, conditional=False):
        self.params, self.n_beam, self.conditional = params, int(n_beam), bool(conditional)
        self.epoch_s = float(epoch_s)
        self.source = np.full(n_ut, -1, np.int64)
        self.target = np.full(n_ut, -1, np.int64)
        self.t_r, self.t_c = np.full(n_ut, np.nan), np.full(n_ut, np.nan)
        self.t_d, self.t_fail = np.full(n_ut, np.nan), np.full(n_ut, np.inf)
        self.active = np.zeros(n_ut, bool)

    def after_step(self, t_s, res, ut_pos_m, sat_pos_m):
        """Time the handovers of ``res`` (a StepResult at ``t_s``, modified: interruption,
        service codes) and return the step events of the epoch ``[t_s, t_s + epoch_s)``
        (completion: ``(t_s, t_s + epoch_s]``, as ``service_resumed``). ``ut_pos_m`` (n_ut, 3),
        ``sat_pos_m`` (n_sat, 3): the epoch's positions [m]."""
        from leolink.sim.handover.controller import service_codes

        ev, st = res.events, res.state
        new = np.isin(np.asarray(ev["kind"]), _HANDOVERS)
        # a serving change not planned here (outage, RLF, another handover) ends a procedure
        self.active &= (st.serving == self.target) & (st.interrupted_until_s > t_s)
        if new.any():
            u = np.asarray(ev["ut_id"], np.int64)[new]
            src = np.asarray(ev["from_sat"])[new] * self.n_beam + np.asarray(ev["from_beam"])[new]
            d_s = np.linalg.norm(sat_pos_m[np.asarray(ev["from_sat"])[new]] - ut_pos_m[u], axis=-1)
            d_t = np.linalg.norm(sat_pos_m[np.asarray(ev["to_sat"])[new]] - ut_pos_m[u], axis=-1)
            t_c, t_d, t_fail = timeline(t_s, d_s, d_t, self.params, self.conditional)
            self.source[u], self.target[u], self.t_r[u] = src, st.serving[u], t_s
            self.t_c[u], self.t_d[u], self.t_fail[u], self.active[u] = t_c, t_d, t_fail, True
            st.interrupted_until_s = st.interrupted_until_s.copy()
            st.interrupted_until_s[u] = np.minimum(t_d, t_fail)
            res.service = service_codes(t_s, st)
        return self._events(t_s)

    def _events(self, t_s):
        """The step events of the active procedures that fall in this epoch."""
        end = t_s + self.epoch_s
        a = self.active
        within = lambda t: a & (t >= t_s - TIME_TOL_S) & (t < end - TIME_TOL_S)  # noqa: E731
        report = within(self.t_r) if not self.conditional else np.zeros_like(a)
        command = within(self.t_c)
        done = a & ~np.isfinite(self.t_fail) & (self.t_d > t_s + TIME_TOL_S)
        done &= self.t_d <= end + TIME_TOL_S
        parts = [self._table(m, t, kind) for m, t, kind in (
            (report, self.t_r, "measurement_report"), (command, self.t_c, "handover_command"),
            (done, self.t_d, "handover_complete"))]  # fmt: skip
        return sorted_events({k: np.concatenate([p[k] for p in parts]) for k in EVENT_COLUMNS})

    def _table(self, mask, time_s, kind):
        """Events ``kind`` of the UTs ``mask`` at their ``time_s``: source -> target."""
        ut = np.flatnonzero(mask)
        if ut.size == 0:
            return no_events()
        (fs, fb), (ts, tb) = (
            split_cells(self.source[ut], self.n_beam),
            split_cells(self.target[ut], self.n_beam),
        )
        nan = np.full(ut.size, np.nan)
        return {"time_s": time_s[ut].astype(float), "ut_id": ut.astype(np.int64),
                "kind": kind_column(kind, ut.size), "from_sat": fs, "from_beam": fb, "to_sat": ts,
                "to_beam": tb, "snr_before_db": nan, "snr_after_db": nan.copy()}  # fmt: skip

    def failures(self, t_s, sinr_db, q_out_db):
        """Handover failures at the epoch ``t_s``: ``(failed bool (n_ut,), time_s (n_ut,),
        events)``. ``sinr_db`` (n_ut,): the serving (target) link's SINR this epoch [dB]."""
        end = t_s + self.epoch_s
        running = self.active & (self.t_r <= t_s + TIME_TOL_S)
        t304 = running & (self.t_fail < end - TIME_TOL_S)
        with np.errstate(invalid="ignore"):
            weak = running & ~(np.asarray(sinr_db, float) >= q_out_db)
        weak &= self.t_c < end - TIME_TOL_S  # the command has arrived within this epoch
        failed = t304 | weak
        time_s = np.where(t304, self.t_fail, np.maximum(self.t_c, t_s))
        time_s = np.where(weak & ~t304, np.minimum(time_s, self.t_fail), time_s)
        events = self._table(failed, time_s, "handover_failure")
        self.active &= ~failed
        return failed, np.where(failed, time_s, np.nan), events
