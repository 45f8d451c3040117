"""Radio link failure (TS 38.331 5.3.10) per UT, vectorized: N310/T310/N311, then re-establishment.

Indications (TS 38.213 clause 5, TS 38.133 8.1). Layer 1 compares the serving link
quality with Q_out and Q_in once per indication period and tells RRC "out-of-sync" when
it is worse than Q_out and "in-sync" when it is better than Q_in; between the two it
says nothing. The standard's thresholds are block error rates of a hypothetical PDCCH,
BLER_out = 10 % and BLER_in = 2 % (TS 38.133 Table 8.1.1-1, configuration 0); the SINR
that gives them depends on the receiver, so leolink takes SINR thresholds. The defaults
-8 dB / -6 dB are the values of 3GPP-style mobility studies (the HetNet mobility model
of TR 36.839 and the conditional-handover studies that reuse it); they are not
TS 38.133 values. ns-3 LTE uses -5 dB / -3.9 dB (LteUePhy Qout/Qin, from TS 36.133 7.6).

Indication period. In non-DRX operation the period is the larger of 10 ms and the
shortest radio-link-monitoring reference-signal period (TS 38.213 5); 38.133 evaluates
Q_out over 200 ms and Q_in over 100 ms (FR1, SSB-based). leolink gives one indication
per simulator epoch: the epoch *is* the indication period, and the SINR of the epoch
stands for the evaluation window (a leolink simplification; with 1 s epochs N310 = 1 is
one second of bad link, not 10 ms).

RRC (TS 38.331 5.3.10.1-5.3.10.3):
- T310 starts upon N310 consecutive out-of-sync indications (while no T310 runs);
- while T310 runs, N311 consecutive in-sync indications stop it;
- an in-sync indication breaks the out-of-sync run and vice versa; a missing indication
  (SINR between Q_out and Q_in) breaks neither (consecutive among received indications);
- T310 expiry declares radio link failure. Expiry at ``t_start + T310`` is checked
  before that epoch's indication, so an in-sync at the expiry instant comes too late.
Then the UT re-establishes (TS 38.331 5.3.7), which takes ``reestablishment_s``; the UT
is without service meanwhile and ``recovered_now`` is set at the first epoch with
``t >= t_rlf + reestablishment_s`` (at the earliest the epoch after the RLF; that epoch
gives no indication, the next one is the first on the new link). A handover
(reconfiguration with sync) stops T310 and clears the counters: :func:`reset`.

Defaults of TS 38.331 9.2.3 (default values timers and constants): T310 = 1000 ms,
N310 = 1, N311 = 1 (T311 = 30 000 ms is not modelled).

References
----------
.. [1] 3GPP TS 38.331, 5.3.10 Radio link failure related actions; 7.1 timers; 7.3
   constants; 9.2.3 default values; 6.3.2 RLF-TimersAndConstants (t310 ms0..ms6000,
   n310 n1..n20, n311 n1..n10).
.. [2] 3GPP TS 38.133, 8.1 Radio link monitoring, Table 8.1.1-1.
.. [3] 3GPP TS 38.213, 5 Radio link monitoring.
.. [4] 3GPP TR 36.839 V11.1.0, 5.2.1.2 RLF modelling.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from leolink.errors import ConfigError, require_at_least

# Epoch times accumulate float rounding; 1 ns is far below any timer value.
TIME_TOL_S = 1e-9


@dataclasses.dataclass(frozen=True)
class RlfParams:
    """RLF parameters; the defaults are TS 38.331 9.2.3 (timers) and study SINR thresholds.

    ``q_out_db``, ``q_in_db``: SINR thresholds [dB], ``q_in_db >= q_out_db``;
    ``t310_s`` [s]; ``n310``, ``n311``: counts >= 1; ``reestablishment_s`` [s]: time from
    RLF to service on the re-established cell. Its 0.2 s default is a leolink placeholder,
    not a 3GPP value (the re-establishment delay of TS 38.133 depends on search, SI
    reading and random access).
    """

    q_out_db: float = -8.0
    q_in_db: float = -6.0
    t310_s: float = 1.0
    n310: int = 1
    n311: int = 1
    reestablishment_s: float = 0.2

    def __post_init__(self):
        for name in ("q_out_db", "q_in_db", "t310_s", "reestablishment_s"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigError(f"rlf.{name} = {getattr(self, name)!r} is not allowed; finite")
        require_at_least("rlf.q_in_db", self.q_in_db, self.q_out_db, "Q_in >= Q_out [dB]")
        require_at_least("rlf.t310_s", self.t310_s, 0.0, "timer T310 [s]")
        require_at_least("rlf.n310", self.n310, 1, "consecutive out-of-sync indications")
        require_at_least("rlf.n311", self.n311, 1, "consecutive in-sync indications")
        require_at_least("rlf.reestablishment_s", self.reestablishment_s, 0.0, "[s]")


@dataclasses.dataclass(frozen=True)
class RlfState:
    """Per-UT state, shape (n_ut,) each.

    ``n_oos``, ``n_is``: running counts of consecutive out-of-sync / in-sync indications;
    ``t310_start_s``: start of T310 (NaN: not running); ``rlf_at_s``: time of the last RLF
    while re-establishing (NaN: connected).
    """

    n_oos: np.ndarray
    n_is: np.ndarray
    t310_start_s: np.ndarray
    rlf_at_s: np.ndarray

    @classmethod
    def initial(cls, n_ut):
        zeros = np.zeros(n_ut, np.int64)
        return cls(zeros, zeros.copy(), np.full(n_ut, np.nan), np.full(n_ut, np.nan))

    @property
    def t310_running(self):
        return ~np.isnan(self.t310_start_s)

    @property
    def reestablishing(self):
        """bool (n_ut,): after an RLF, before service is back."""
        return ~np.isnan(self.rlf_at_s)


def reset(state, ut_mask):
    """Stop T310 and clear both counters for ``ut_mask`` (a handover: TS 38.331 7.1 stops
    T310 upon reconfiguration with sync)."""
    m = np.asarray(ut_mask, bool)
    return RlfState(
        np.where(m, 0, state.n_oos),
        np.where(m, 0, state.n_is),
        np.where(m, np.nan, state.t310_start_s),
        state.rlf_at_s,
    )


def step(state, t_s, sinr_db, params, monitored=None):
    """One indication period at epoch ``t_s``; returns ``(state, rlf_now, recovered_now)``.

    Parameters
    ----------
    state : RlfState
    t_s : float [s]
    sinr_db : ndarray (n_ut,) [dB], serving-link SINR; NaN (no link) is out-of-sync.
    params : RlfParams
    monitored : bool (n_ut,) or None
        UTs whose link is monitored now; others (no serving cell, handover execution:
        38.331 ignores out-of-sync while T304 runs) give no indication. Default all.

    Returns
    -------
    (RlfState, rlf_now bool (n_ut,), recovered_now bool (n_ut,))
    """
    sinr_db = np.asarray(sinr_db, float)
    on = np.ones(sinr_db.shape, bool) if monitored is None else np.asarray(monitored, bool)
    waited_s = t_s - state.rlf_at_s
    recovered = state.reestablishing & (waited_s >= params.reestablishment_s - TIME_TOL_S)
    connected = ~state.reestablishing
    expired = (
        connected & state.t310_running & (t_s - state.t310_start_s >= params.t310_s - TIME_TOL_S)
    )
    live = connected & ~expired & on
    oos = live & ~(sinr_db >= params.q_out_db)  # worse than Q_out, or no link at all
    ins = live & (sinr_db > params.q_in_db)
    running = state.t310_running
    # T310 not running: count out-of-sync; T310 running: count in-sync (5.3.10.1, 5.3.10.2).
    n_oos = np.where(ins, 0, np.where(oos & ~running, state.n_oos + 1, state.n_oos))
    n_is = np.where(oos, 0, np.where(ins & running, state.n_is + 1, state.n_is))
    start = ~running & (n_oos >= params.n310)
    stop = running & (n_is >= params.n311)
    t310 = np.where(start, t_s, np.where(stop, np.nan, state.t310_start_s))
    # T310 = 0 (ms0) expires the moment it starts.
    rlf = expired | (start & (params.t310_s <= TIME_TOL_S))
    clear = rlf | start | stop | recovered
    new = RlfState(
        n_oos=np.where(clear, 0, n_oos),
        n_is=np.where(clear, 0, n_is),
        t310_start_s=np.where(rlf | recovered, np.nan, t310),
        rlf_at_s=np.where(rlf, t_s, np.where(recovered, np.nan, state.rlf_at_s)),
    )
    return new, rlf, recovered


def declare(state, ut_mask, t_s):
    """Start re-establishment at ``t_s`` (n_ut,) [s] for ``ut_mask`` without an RLF of
    this module (a handover failure, :mod:`leolink.sim.handover.procedure`): T310 stopped,
    counters cleared, as after an RLF (TS 38.331 5.3.7 follows either)."""
    m = np.asarray(ut_mask, bool)
    if not m.any():
        return state
    return RlfState(
        np.where(m, 0, state.n_oos),
        np.where(m, 0, state.n_is),
        np.where(m, np.nan, state.t310_start_s),
        np.where(m, t_s, state.rlf_at_s),
    )
