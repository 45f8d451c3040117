"""Sharing a beam's time among the UTs it serves (Sec. 2.1 of [1]: "time or frequency
division multiplexing mechanisms will enable beam sharing").

A beam transmits to one UT per slot (the digital precoder of :mod:`leolink.link.precoder`
serves one UT per active beam per slot). The UTs served by the same (satellite, beam)
form a *group*; each UT gets a time share of the epoch, its throughput is its share of the
beam's rate, and the trace records how many UTs share its beam.

Schedulers:

- :func:`round_robin_share`: equal share ``1 / n`` of the epoch (fluid round robin).
- :func:`round_robin_slots`: slot by slot, the UT of the group served longest ago goes
  next (ties: lower ``ut_id``); a UT that joins a group waits behind none (it was never
  served there). Over ``n`` slots each of ``n`` UTs is served once.
- :func:`proportional_fair`: per slot and group, the UT maximizing ``r_k(t) / R_k(t)``,
  ``R_k`` its exponentially averaged served rate with window ``t_c`` slots:
  ``R_k <- (1 - 1/t_c) R_k + (1/t_c) r_k 1[k served]`` (Jalali, Padovani, Pankaj [2];
  Viswanath, Tse, Laroia [3]). With constant rates it converges to equal *time* shares,
  whatever the rates (it maximizes ``sum log(throughput)``, whose optimum under
  ``sum x_k = 1`` is ``x_k = 1/n``); with fading it serves each UT near its own peaks.

Groups are ids ``sat_idx * n_beam + beam_idx`` (``-1`` unserved), so per-group state is a
flat array of ``n_sat * n_beam`` entries. All functions are vectorized over UTs
(``bincount`` / ``lexsort``); the slot loop runs over the epoch's slots only.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] A. Jalali, R. Padovani, R. Pankaj, "Data throughput of CDMA-HDR a high efficiency-
   high data rate personal communication wireless system," IEEE VTC2000-Spring.
.. [3] P. Viswanath, D. N. C. Tse, R. Laroia, "Opportunistic beamforming using dumb
   antennas," IEEE Trans. Inf. Theory, 48(6), pp. 1277-1294, 2002.
"""

from typing import Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.arrays import nonzero_2d
from leolink.errors import ConfigError
from leolink.registry import Params, Registry

__all__ = [
    "SCHEDULERS",
    "Scheduler",
    "beam_groups",
    "delivered_rate",
    "proportional_fair",
    "round_robin_share",
    "round_robin_slots",
    "slot_shares",
]


@runtime_checkable
class Scheduler(Protocol):  # pragma: no mutate block (a contract, no code)
    """How the UTs of one beam share its time (``scheduler.kind``)."""

    #: False: no sharing, every UT of a beam at the beam's full rate (today's leolink).
    shares: bool

    def schedule(self, group, n_group, rate):
        """``(schedule (n_slots, n_group) of UT indices or -1, share (n_ut,))`` of one
        epoch; ``group (n_ut,)`` from :func:`beam_groups`, ``rate (n_ut,)`` each UT's
        rate when served [bit/s] (NaN or 0: no link)."""
        ...


#: Schedulers by config name (``scheduler.kind``).
SCHEDULERS: Registry[Scheduler] = Registry("scheduler.kind", Scheduler)


def beam_groups(sat_idx, beam_idx, n_beam):
    """Group id of each UT's (satellite, beam) and the number of UTs sharing it.

    Parameters
    ----------
    sat_idx, beam_idx : array_like of int, shape (n_ut,)
        Serving satellite and beam; ``-1`` = not served.
    n_beam : int
        Beams per satellite (codebook size).

    Returns
    -------
    group : ndarray of int, shape (n_ut,)
        ``sat_idx * n_beam + beam_idx``, ``-1`` if not served.
    n_sharing : ndarray of int, shape (n_ut,)
        UTs served by the same beam (itself included), 0 if not served.
    """
    sat_idx, beam_idx = np.asarray(sat_idx), np.asarray(beam_idx)
    served = (sat_idx >= 0) & (beam_idx >= 0)
    group = np.where(served, sat_idx * n_beam + beam_idx, -1)
    size = np.bincount(group[served], minlength=1)
    n_sharing = np.where(served, size[np.where(served, group, 0)], 0)
    return group, n_sharing


def round_robin_share(group):
    """Fluid round robin: every UT of a group gets ``1 / n`` of the epoch; 0 if unserved."""
    group = np.asarray(group)
    served = group >= 0
    size = np.bincount(group[served], minlength=1)
    return np.where(served, 1.0 / np.maximum(size[np.where(served, group, 0)], 1), 0.0)


def _winners(metric, group, n_group):
    """Per group the UT with the largest metric (ties: lower index) -> (n_group,), -1 if empty."""
    ut = np.flatnonzero(group >= 0)
    order = ut[np.lexsort((ut, -metric[ut], group[ut]))]  # by group, then metric desc, then id
    first = np.ones(order.size, bool)
    first[1:] = group[order][1:] != group[order][:-1]
    win = np.full(n_group, -1)
    win[group[order[first]]] = order[first]
    return win


def slot_shares(schedule, n_ut):
    """Time share of each UT from a schedule ``(n_slots, n_group)`` of UT indices (-1 idle)."""
    s = np.asarray(schedule)
    return np.bincount(s[s >= 0], minlength=n_ut)[:n_ut] / s.shape[0]


def round_robin_slots(group, n_group, n_slots, last_served):
    """Slot-by-slot round robin: the UT of each group served longest ago goes next.

    Parameters
    ----------
    group : array_like of int, shape (n_ut,)
        From :func:`beam_groups` (``-1`` = not served).
    n_group : int
        Number of group ids (``n_sat * n_beam``).
    n_slots : int
        Slots in this epoch.
    last_served : array_like, shape (n_ut,)
        Slot counter when each UT was last served (``-inf``: never); carried over epochs.

    Returns
    -------
    schedule : ndarray of int, shape (n_slots, n_group)
        UT served by each group in each slot, ``-1`` if the group is empty.
    share : ndarray, shape (n_ut,)
        Fraction of the epoch's slots each UT is served.
    last_served : ndarray, shape (n_ut,)
        Updated state (slots numbered from the largest finite value + 1).
    """
    group = np.asarray(group)
    last = np.array(last_served, dtype=float)
    t0 = np.max(last, initial=-1.0, where=np.isfinite(last)) + 1.0
    schedule = np.full((n_slots, n_group), -1)
    for s in range(n_slots):  # loop over slots only; each slot vectorized over UTs
        win = _winners(-last, group, n_group)
        schedule[s] = win
        last[win[win >= 0]] = t0 + s
    return schedule, slot_shares(schedule, group.size), last


def proportional_fair(group, n_group, rate, avg_rate, t_c_slots):
    """Proportional-fair scheduling over the slots of one epoch, per beam.

    Parameters
    ----------
    group : array_like of int, shape (n_ut,)
        From :func:`beam_groups` (``-1`` = not served).
    n_group : int
        Number of group ids (``n_sat * n_beam``).
    rate : array_like, shape (n_slots, n_ut)
        Rate each UT would get if served in each slot [any unit, e.g. bit/s/Hz].
    avg_rate : array_like, shape (n_ut,)
        Averaged served rate ``R_k`` carried over epochs [unit of ``rate``]; 0 for a new UT
        (it is served first).
    t_c_slots : float
        Averaging window ``t_c`` [slots], >= 1.

    Returns
    -------
    schedule : ndarray of int, shape (n_slots, n_group)
        UT served by each group in each slot, ``-1`` if empty.
    share : ndarray, shape (n_ut,)
        Fraction of the slots each UT is served.
    avg_rate : ndarray, shape (n_ut,)
        Updated ``R_k``.
    """
    if not t_c_slots >= 1.0:
        raise ConfigError(f"scheduler.t_c_slots = {t_c_slots!r} is not allowed; use >= 1 slot")
    group = np.asarray(group)
    rate = np.atleast_2d(np.asarray(rate, dtype=float))
    avg = np.array(avg_rate, dtype=float)
    n_slots = rate.shape[0]
    schedule = np.full((n_slots, n_group), -1)
    w = 1.0 / t_c_slots
    for s in range(n_slots):  # loop over slots only; each slot vectorized over UTs
        r = rate[s]
        fresh = avg <= 0.0  # never served: first in line (if it has a rate at all)
        metric = np.divide(r, avg, out=np.where(fresh & (r > 0.0), np.inf, 0.0), where=~fresh)
        win = _winners(metric, group, n_group)
        schedule[s] = win
        avg *= 1.0 - w
        won = win[win >= 0]
        avg[won] += w * r[won]
    return schedule, slot_shares(schedule, group.size), avg


def delivered_rate(schedule, rate):
    """Per-UT rate averaged over the epoch: ``(1 / n_slots) sum_s r_k(s) 1[k served in s]``.

    Parameters
    ----------
    schedule : array_like of int, shape (n_slots, n_group)
    rate : array_like, shape (n_slots, n_ut) or (n_ut,)
        Rate of each UT when served [e.g. bit/s].

    Returns
    -------
    ndarray, shape (n_ut,)
    """
    s = np.asarray(schedule)
    rate = np.broadcast_to(np.asarray(rate, dtype=float), (s.shape[0], np.shape(rate)[-1]))
    slot, _ = nonzero_2d(s >= 0)
    ut = s[s >= 0]
    return np.bincount(ut, weights=rate[slot, ut], minlength=rate.shape[1]) / s.shape[0]


@SCHEDULERS.register("none")
class NoSharing:
    """No sharing: every UT of a beam gets the beam's full rate (today's leolink)."""

    shares = False

    def schedule(self, group, n_group, rate):
        raise NotImplementedError("scheduler 'none' shares nothing")


def _rank_in_group(group):
    """Rank of each served UT within its group by ``ut_id`` (0, 1, ...), -1 unserved."""
    group = np.asarray(group)
    ut = np.flatnonzero(group >= 0)
    order = ut[np.lexsort((ut, group[ut]))]
    first = np.r_[True, group[order][1:] != group[order][:-1]]
    start = np.maximum.accumulate(np.where(first, np.arange(order.size), 0))
    rank = np.full(group.size, -1)
    rank[order] = np.arange(order.size) - start
    return rank


@SCHEDULERS.register("round_robin")
class RoundRobin:
    """Fluid round robin: each of the n UTs of a beam gets 1/n of the epoch."""

    shares = True

    def schedule(self, group, n_group, rate):
        """Share ``1 / n``; the slots (for the precoder) are ``L`` = the largest group:
        slot ``s`` serves the member of rank ``s mod n`` (by ``ut_id``) of each group."""
        group = np.asarray(group)
        share = round_robin_share(group)
        size = np.bincount(group[group >= 0], minlength=n_group)
        n_slots = max(int(size.max(initial=0)), 1)
        rank = _rank_in_group(group)
        schedule = np.full((n_slots, n_group), -1)
        ut = np.flatnonzero(group >= 0)
        for s in range(n_slots):  # loop over slots only (at most the largest group)
            on = ut[rank[ut] == s % size[group[ut]]]
            schedule[s, group[on]] = on
        return schedule, share


class ProportionalFairConfig(Params):
    slots_per_epoch: int = Field(10, ge=1, le=10_000, description="scheduling slots per epoch")
    t_c_slots: float = Field(
        100.0, ge=1.0, le=1e9, description="averaging window of the served rate [slots]"
    )


@SCHEDULERS.register("proportional_fair", config=ProportionalFairConfig)
class ProportionalFair:
    """Proportional fair per beam over slots_per_epoch slots, averaged rate kept over epochs."""

    shares = True

    def __init__(self, slots_per_epoch=10, t_c_slots=100.0):
        self.n_slots, self.t_c_slots = int(slots_per_epoch), float(t_c_slots)
        self.avg_rate = None

    def schedule(self, group, n_group, rate):
        rate = np.nan_to_num(np.asarray(rate, dtype=float), nan=0.0)
        if self.avg_rate is None or self.avg_rate.size != rate.size:
            self.avg_rate = np.zeros(rate.size)
        slots = np.broadcast_to(rate, (self.n_slots, rate.size))
        sched, share, self.avg_rate = proportional_fair(
            group, n_group, slots, self.avg_rate, self.t_c_slots
        )
        return sched, share
