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
  that mean (``2^SE - 1``). A lit beam without a scheduled UT in a slot is silent by
  default (``[link.<precoder>] idle_beams = "silent"``: no data to precode, its chain off),
  whereas without precoder every lit beam interferes all the time (the paper's full-buffer
  model); ``idle_beams = "transmit"`` gives the precoder that full buffer too: each idle lit
  beam carries a stream to its cell centre, precoded with the scheduled UTs' over all lit
  chains (:data:`leolink.link.precoder.IDLE_BEAMS`). A UT the scheduler leaves out of
  every slot of an epoch (proportional fair, more UTs than slots) keeps the analog SINR and
  gets throughput 0.

``snr_db`` and ``gain_tx_db`` stay the analog beam's (the controller's quantities).
"""

from __future__ import annotations

import dataclasses

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
        u = direction_cosines(inp["sat_pos_m"][m], inp["sat_vel_m_s"][m], inp["ut_pos_m"][m])
        path = np.where(ok, np.nan_to_num(inp["path_snr_lin"][m]), 0.0)
        u_est = None
        if inp.get("sat_pos_est_m") is not None:  # seam of the ephemeris-error model
            vel_est = inp.get("sat_vel_est_m")
            vel_est = inp["sat_vel_m_s"] if vel_est is None else vel_est
            u_est = direction_cosines(inp["sat_pos_est_m"][m], vel_est[m],
                                      inp["ut_pos_m"][m])  # fmt: skip
        i_other = np.zeros(ok.shape) if inp["i_other"] is None else inp["i_other"][m]
        rows = _Rows(ok, b, u, u_est, path, i_other)
        if self.precoder.idle_beams == "transmit":
            rows = rows.with_idle_beams(s[:, 0], lit, eng.codebook.u_xy)
        width = ok.shape[1]  # the scheduled UTs' columns; the idle beams' follow
        sinr = self._precoded_sinr(rows, s[:, :1], lit)[:, :width]
        rate = spectral_efficiency_bps_hz(np.where(ok, sinr, 0.0))
        n_ut = sat_id.size
        total = np.bincount(member[ok], weights=rate[ok], minlength=n_ut)
        count = np.bincount(member[ok], minlength=n_ut)
        se = np.where(count > 0, total / np.maximum(count, 1), se_analog)
        with np.errstate(divide="ignore"):
            cols["sinr_db"] = np.where(count > 0, 10.0 * np.log10(np.expm1(se * np.log(2.0))),
                                       cols["sinr_db"])  # fmt: skip
        return se

    def _precoded_sinr(self, rows, sat, lit):
        """SINR of every row of the padded problems after the precoder (NaN on padding)."""
        eng, ok, b = self.engine, rows.ok, rows.beam
        chain = np.where(ok, self._chains(np.broadcast_to(sat, b.shape), b, lit), -1)
        beam_u = np.asarray(eng.codebook.u_xy, float)[b]
        h = precoded.channel(rows.u, rows.path, beam_u, chain, eng.colors[b], ok, self.array)
        h_est = None
        if rows.u_est is not None:
            h_est = precoded.channel(rows.u_est, rows.path, beam_u, chain, eng.colors[b], ok,
                                     self.array)  # fmt: skip
        return precoded.precoded_sinr(self.precoder, h, ok, rows.i_other, h_est)

    def _chains(self, sat, beam, lit):
        """RF chain of each (satellite, beam): lit beams by ascending id take 0, 1, ..."""
        if lit is None:  # every beam lit (beams <= chains): beam m on chain m
            return beam
        return assign_chains(lit, self.array.n_rf)[sat, beam]


@dataclasses.dataclass(frozen=True)
class _Rows:
    """The rows of the padded precoding problems (P, W): who receives a stream.

    ``ok`` (False on padding), ``beam`` (the row's beam), ``u`` and ``u_est`` (true and
    believed direction cosines, (P, W, 2); ``u_est`` None without an ephemeris error),
    ``path`` (SNR per unit TX gain), ``i_other`` (other satellites' interference / noise).
    """

    ok: np.ndarray
    beam: np.ndarray
    u: np.ndarray
    u_est: np.ndarray | None
    path: np.ndarray
    i_other: np.ndarray

    def with_idle_beams(self, sat, lit, beam_u_xy):
        """These rows and one per idle lit beam of the problem's satellite ``sat (P,)``:
        a stream to its cell centre (its boresight, true and believed alike), with the mean
        path of the problem's scheduled UTs and no other interference
        (:data:`leolink.link.precoder.IDLE_BEAMS`)."""
        n_beam = beam_u_xy.shape[0]
        lit_p = np.ones((sat.size, n_beam), bool) if lit is None else lit[sat]
        busy = np.zeros_like(lit_p)
        prob = np.broadcast_to(np.arange(sat.size)[:, None], self.ok.shape)
        busy[prob[self.ok], self.beam[self.ok]] = True
        idle = lit_p & ~busy
        width = int(idle.sum(axis=1).max(initial=0))
        order = np.argsort(~idle, axis=1, kind="stable")[:, :width]
        ok = np.take_along_axis(idle, order, axis=1)
        beam = np.where(ok, order, 0)
        u = np.where(ok[..., None], np.asarray(beam_u_xy, float)[beam], 0.0)
        mean_path = np.sum(self.path, axis=1) / np.maximum(self.ok.sum(axis=1), 1)
        path = np.where(ok, mean_path[:, None], 0.0)

        def cat(a, extra):
            return np.concatenate([a, extra], axis=1)

        u_est = None if self.u_est is None else cat(self.u_est, u)
        zeros = np.zeros(ok.shape)
        return _Rows(cat(self.ok, ok), cat(self.beam, beam), cat(self.u, u), u_est,
                     cat(self.path, path), cat(self.i_other, zeros))  # fmt: skip
