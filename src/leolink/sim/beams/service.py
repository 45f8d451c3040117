"""Beam sharing and precoding of one epoch's served UTs: the monitor's post-processing.

After the engine has each UT's link on its serving beam (with only the lit beams as
interference), :class:`BeamService` applies what issue 14 adds on top:

- ``n_sharing``: how many UTs the UT's (satellite, beam) serves this epoch (handover rows
  count for their serving beam, outage rows are 0);
- the scheduler (:mod:`leolink.sim.beams.scheduler`): each UT's time share of its beam; its
  throughput (and mean spectral efficiency over the epoch) is its share of the beam's;
- the precoder (:mod:`leolink.engine.precoded`): per slot of the schedule, the scheduled
  UTs of each satellite (one per beam) get ``F_BB``; a UT's spectral efficiency is the
  mean ``log2(1 + SINR)`` over the slots it is scheduled in, its ``sinr_db`` the SINR of
  that mean (``2^SE - 1``). Lit beams without a scheduled UT in a slot are idle (no data
  to precode), whereas without precoder every lit beam interferes all the time (the
  paper's full-buffer model). A UT the scheduler leaves out of every slot of an epoch
  (proportional fair, more UTs than slots) keeps the analog SINR and gets throughput 0.

``snr_db`` and ``gain_tx_db`` stay the analog beam's (the controller's quantities).
"""

from __future__ import annotations

import numpy as np

from leolink.arrays import nonzero_2d
from leolink.engine import precoded
from leolink.geometry import direction_cosines
from leolink.link.budget import spectral_efficiency_bps_hz
from leolink.sim.beams.active import assign_chains
from leolink.sim.beams.scheduler import beam_groups

__all__ = ["BeamService"]


class BeamService:
    """Sharing and precoding of served UTs (module docstring).

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    scheduler : leolink.sim.beams.scheduler.Scheduler
    precoder : leolink.link.precoder.Precoder
    array : leolink.antenna.array.HybridArray
        The satellite array (subarray phase centres of the precoder's channel).
    """

    def __init__(self, engine, scheduler, precoder, array):
        self.engine, self.scheduler, self.precoder, self.array = engine, scheduler, precoder, array
        self.precodes = precoder.kind != "none"

    def apply(self, cols, sat_id, beam_id, served, lit, rows):
        """Update one epoch's link columns in place and add ``n_sharing``.

        Parameters
        ----------
        cols : dict of ndarray, shape (n_ut,)
            :meth:`~leolink.engine.LinkEngine.serve_pairs` of the epoch's UTs.
        sat_id, beam_id : ndarray of int, shape (n_ut,)
            Serving cell (-1: none).
        served : ndarray of bool, shape (n_ut,)
            UTs with service (served or in handover) this epoch.
        lit : ndarray of bool, shape (n_sat, n_beam), or None (every beam lit)
        rows : callable or None
            ``rows() -> dict`` of the per-UT inputs of the precoder (``ut_pos_m``,
            ``sat_pos_m``, ``sat_vel_m_s``, ``path_snr_lin``, ``i_other``, and
            optionally ``sat_pos_est_m`` and ``sat_vel_est_m``: the satellite state it believes,
            from which the precoder's channel is computed while the signal goes through
            the true one — the seam of the ephemeris-error model, issue 15); None without.

        Returns
        -------
        ndarray, shape (n_ut,), or None
            Each UT's time share of its beam (1 where not served); None without sharing.
        """
        nb = self.engine.n_beam
        sat = np.where(served, sat_id, -1)
        group, n_sharing = beam_groups(sat, np.where(served, beam_id, -1), nb)
        cols["n_sharing"] = n_sharing.astype(np.int64)
        if not self.scheduler.shares:
            return None
        ids, compact = np.unique(group[group >= 0], return_inverse=True)
        g = np.full(group.size, -1)
        g[group >= 0] = compact
        schedule, share = self.scheduler.schedule(g, ids.size, cols["throughput_bps"])
        se = cols["se_bps_hz"]
        if self.precodes and ids.size:
            se = self._precoded_se(schedule, ids, sat_id, beam_id, lit, rows(), se, cols)
        bw = self.engine.bandwidth_hz
        cols["se_bps_hz"] = np.where(served, se * share, cols["se_bps_hz"])
        cols["throughput_bps"] = np.where(served, se * share * bw, cols["throughput_bps"])
        return np.where(served, share, 1.0)

    def _precoded_se(self, schedule, ids, sat_id, beam_id, lit, inp, se_analog, cols):
        """Mean SE over each UT's scheduled slots after precoding (analog where never)."""
        eng, nb = self.engine, self.engine.n_beam
        gsat = ids // nb
        slot, gi = nonzero_2d(schedule >= 0)
        ut = schedule[slot, gi]
        usat, sat_c = np.unique(gsat[gi], return_inverse=True)
        key = slot * usat.size + sat_c  # one problem per (slot, satellite)
        order = np.lexsort((ut, key))
        key, ut = key[order], ut[order]
        first = np.r_[True, key[1:] != key[:-1]]
        start = np.maximum.accumulate(np.where(first, np.arange(key.size), 0))
        rank = np.arange(key.size) - start
        prob = np.cumsum(first) - 1
        n_prob, width = int(prob[-1]) + 1, int(rank.max()) + 1
        member = np.full((n_prob, width), -1)
        member[prob, rank] = ut
        ok = member >= 0
        m = np.where(ok, member, 0)
        s, b = sat_id[m], beam_id[m]
        chain = self._chains(s, b, lit)
        u = direction_cosines(inp["sat_pos_m"][m], inp["sat_vel_m_s"][m], inp["ut_pos_m"][m])
        path = np.where(ok, np.nan_to_num(inp["path_snr_lin"][m]), 0.0)
        beam_u = np.asarray(eng.codebook.u_xy, float)[b]
        h = precoded.channel(u, path, beam_u, np.where(ok, chain, -1), eng.colors[b], ok,
                             self.array)  # fmt: skip
        i_other = 0.0 if inp["i_other"] is None else inp["i_other"][m]
        h_est = None
        if inp.get("sat_pos_est_m") is not None:  # seam of the ephemeris-error model
            vel_est = inp.get("sat_vel_est_m")
            vel_est = inp["sat_vel_m_s"] if vel_est is None else vel_est
            u_est = direction_cosines(inp["sat_pos_est_m"][m], vel_est[m],
                                      inp["ut_pos_m"][m])  # fmt: skip
            h_est = precoded.channel(u_est, path, beam_u, np.where(ok, chain, -1),
                                     eng.colors[b], ok, self.array)  # fmt: skip
        sinr = precoded.precoded_sinr(self.precoder, h, ok, i_other, h_est)
        rate = spectral_efficiency_bps_hz(np.where(ok, sinr, 0.0))
        n_ut = sat_id.size
        total = np.bincount(member[ok], weights=rate[ok], minlength=n_ut)
        count = np.bincount(member[ok], minlength=n_ut)
        se = np.where(count > 0, total / np.maximum(count, 1), se_analog)
        with np.errstate(divide="ignore"):
            cols["sinr_db"] = np.where(count > 0, 10.0 * np.log10(np.expm1(se * np.log(2.0))),
                                       cols["sinr_db"])  # fmt: skip
        return se

    def _chains(self, sat, beam, lit):
        """RF chain of each (satellite, beam): lit beams by ascending id take 0, 1, ..."""
        if lit is None:  # every beam lit (beams <= chains): beam m on chain m
            return beam
        return assign_chains(lit, self.array.n_rf)[sat, beam]
