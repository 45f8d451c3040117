"""The controller's side of an epoch: candidate tables, then ``controller.step``.

:class:`Decider` is what :func:`~leolink.sim.processes.beam_controller` calls once per
epoch. When an epoch opens a new motion block (:mod:`leolink.sim.motion`) it finds the
candidates of the whole block in a few vectorized engine calls
(:class:`~leolink.sim.candidates.search.CandidateSearch`); every epoch it adds each UT's serving
cell to its row (from the pairs already evaluated, or evaluated then), evaluates the
table at ``t + lookahead`` if the policy asks, and runs the controller.

A policy with per-cell state (the 3GPP triggers of :mod:`leolink.sim.handover.trigger_policies`)
has a ``run(...)`` method: its :class:`~leolink.sim.handover.trigger_run.TriggerRun` picks the
target from the epoch's table and the controller executes it. With radio link failure
monitoring (:mod:`leolink.sim.handover.rlf_run`), the candidates of UTs still re-establishing are
masked (NaN) so that the controller leaves them unserved.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from leolink.geometry import enu_basis
from leolink.sim.beams.selectors import restrict
from leolink.sim.candidates.search import CandidateSearch
from leolink.sim.candidates.table import Candidates
from leolink.sim.handover.cells import beam_switches
from leolink.sim.handover.controller import concat_events, resumed_events, step
from leolink.sim.handover.events import sorted_events
from leolink.sim.handover.policies import neighbour_window_db

__all__ = ["Decider", "Rules", "Sky"]


@dataclass(frozen=True)
class Rules:
    """What the controller decides by.

    Parameters
    ----------
    policy : Policy
    min_snr_db, handover_time_s : float
        The controller's service threshold [dB] and handover execution time [s].
    selector : leolink.sim.beams.selectors.BeamSelector, optional
        Active beams: the controller chooses among the lit beams of each epoch, and every
        visible cell is a candidate (a lit neighbour may be further down than the
        policy's window). None: every beam lit (today's run, untouched).
    prune : bool
        Screen the (UT, satellite) pairs before evaluating them (the same tables,
        :mod:`leolink.sim.candidates.search`); False evaluates every pair (the reference).
    """

    policy: object
    min_snr_db: float
    handover_time_s: float
    selector: object = None
    prune: bool = True


@dataclass(frozen=True)
class Sky:
    """How the UTs see the satellites.

    Parameters
    ----------
    min_elevation_rad, radius_m : float
        The mask [rad] and the Earth radius [m] (the satellite cone).
    ellipsoidal : bool
        The UTs' latitudes are geodetic (WGS 84) and their local frame is the ellipsoid's,
        handed to the engine; otherwise the engine takes the sphere's radial up.
    panels : leolink.antenna.panel.PanelOrientation or None
        The UTs' turned or tilted panels (None: lying flat, x east): their rows per epoch
        of the block are ``Decider.panel`` (n_k, n_ut, 3, 3), handed to the engine.
    """

    min_elevation_rad: float
    radius_m: float
    ellipsoidal: bool = False
    panels: object = None


class Decider:
    """Finds every UT's candidate cells and runs ``controller.step`` on them.

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    rules : Rules
    sky : Sky
    motion : leolink.sim.motion.MotionBlocks
    future_state : callable
        ``t -> (ut_pos, sat_pos, sat_vel)`` of every UT and satellite (prediction).
    epoch_s : float
    rlf : leolink.sim.handover.rlf_run.RlfRun or None
        Radio link failure bookkeeping (None: off).
    """

    def __init__(self, engine, rules, sky, motion, future_state, epoch_s=1.0, rlf=None):
        policy, min_snr_db, selector = rules.policy, rules.min_snr_db, rules.selector
        self.engine, self.policy, self.rlf = engine, policy, rlf
        run = getattr(policy, "run", None)  # per-cell state: the policy's own run
        radius_m = sky.radius_m
        self.trigger = run(engine, min_snr_db, radius_m, future_state, epoch_s) if run else None
        self.min_snr_db, self.handover_time_s = min_snr_db, rules.handover_time_s
        # With interference from other satellites, every satellite above the horizon counts.
        self.min_el = 0.0 if engine.other_satellites else sky.min_elevation_rad
        self.future_state, self.motion = future_state, motion
        self.epoch_s, self.ellipsoidal = float(epoch_s), bool(sky.ellipsoidal)
        self.selector = selector
        # Active beams: the best lit cell may be far below the best cell, so no window.
        self.window_db = neighbour_window_db(policy) if selector is None else np.inf
        self.prune = rules.prune
        # A policy blind to cells below the service threshold needs none of them.
        self.floor_db = min_snr_db if getattr(policy, "usable_cells_only", False) else -np.inf
        self.search = CandidateSearch(engine, self.window_db, self.prune, self.floor_db)
        self.panels = sky.panels
        self.block = self.mb = self.cones = self.enu = self.panel = None
        self.channel = None  # ChannelTracker of the UTs' environments (None: open country)
        self.channels = []  # its EpochChannel of each epoch of the current block
        self.procedure = None  # the handover procedure (leolink.sim.handover.procedure), if on
        self.beam_switch_s = None  # cells are satellites: a beam change is a beam_switch

    def with_channel(self, tracker):
        """Decide on SNRs with each path's environment loss (:mod:`leolink.sim.environment`).

        The channel of a block's epochs is drawn when the block opens, before its search:
        the search prunes on each path's SNR after its own loss (an exact bound, neither
        a margin nor a tail probability), so the window and the floor stay the policy's."""
        self.channel = tracker

    def _open(self, k):
        """The candidates of the motion block of epoch ``k`` (computed once per block)."""
        from leolink.sim.processes import candidate_satellites

        mb = _epochs_of(self.motion.block_of(k), k, self.search.block_ut_epochs)
        if self.block is not None and self.block.k0 == mb.k0:
            return self.block
        self.block = None  # (its tables and links go before the next block's are built)
        self.enu = enu_basis(mb.ut_lat_rad, mb.ut_lon_rad) if self.ellipsoidal else None
        up = None if self.enu is None else self.enu[..., 2, :]
        none = np.zeros(0, np.int64)
        self.cones = [
            candidate_satellites(
                mb.sat_pos_m[i], mb.ut_pos_m[i], self.min_el, none, None if up is None else up[i]
            )
            for i in range(mb.n_k)
        ]
        self.panel = self._panels(mb)
        normal = None if self.panel is None else self.panel[..., 2, :]
        self.mb = mb
        loss = None
        if self.channel is not None:  # every epoch's paths, in order, before the search
            self.channels = []  # (the last block's go first: one block's at a time)
            self.channels = [self._channel(mb, i) for i in range(mb.n_k)]
            loss = lambda i: self.channels[i].loss_grid()  # noqa: E731
        self.block = self.search.block(mb.k0, mb.ut_pos_m, up, mb.sat_pos_m, mb.sat_vel_m_s,
                                       self.cones, normal, loss)  # fmt: skip
        return self.block

    def _channel(self, mb, i):
        """The UTs' environment at the block's epoch ``i`` (the tracker steps to it)."""
        enu = self.enu[i] if self.enu is not None else enu_basis(mb.ut_lat_rad[i], mb.ut_lon_rad[i])
        return self.channel.step(mb.k0 + i, mb.ut_pos_m[i], enu, mb.sat_pos_m[i], self.cones[i])

    def _panels(self, mb):
        """Panel rows of the block's epochs (n_k, n_ut, 3, 3), or None (flat panels). On
        the sphere the local frame is the ENU of the geocentric latitude (radial up)."""
        if self.panels is None:
            return None
        enu = self.enu if self.enu is not None else enu_basis(mb.ut_lat_rad, mb.ut_lon_rad)
        return np.stack([self.panels.basis(enu[i], mb.ut_vel_m_s[i]) for i in range(mb.n_k)])

    def __call__(self, state):
        k, nb = state.k, self.engine.n_beam
        blk = self._open(k)
        c = state.controller
        rows = blk.rows(k)
        ch = self.channels[k - blk.k0] if self.channel is not None else None
        table = self._with_serving(blk.table.rows(rows), rows, c.serving, ch)
        state.best_snr_db, state.n_visible = blk.best_snr_db[rows], blk.n_visible[rows]
        best_cell = blk.best_cell[rows]
        future = None
        if self.policy.lookahead_s > 0.0:
            # The UTs' frames of now: over a lookahead they turn by (distance / R), 0.02 deg
            # for an aircraft over 10 s.
            future = self._future(table, state.t_s + self.policy.lookahead_s, k)
        if self.channel is not None:
            self._environment(state, ch)
            future = None if future is None else ch.apply(future, nb)
        if self.selector is not None:
            table, future = self._lit_only(state, table, future, best_cell, k)
        t = state.t_s
        decided, target = self._masked(state, table), None
        if self.trigger is not None:
            j, mb = k - blk.k0, self.mb
            up = None if self.enu is None else self.enu[j][:, 2, :]
            target = self.trigger.target(t, decided, c.serving, mb.ut_pos_m[j],
                                         mb.sat_pos_m[j], mb.sat_vel_m_s[j], up)  # fmt: skip
        res = step(t, decided, c, self.policy, self.min_snr_db, self.handover_time_s, nb,
                   future, target)  # fmt: skip
        if self.beam_switch_s is not None:
            beam_switches(t, res, self.beam_switch_s)
        steps = None
        if self.procedure is not None:  # signalling: the handovers' interruption and steps
            j = k - blk.k0
            steps = self.procedure.after_step(t, res, self.mb.ut_pos_m[j], self.mb.sat_pos_m[j])
        resumed = resumed_events(t, self.epoch_s, res.state, table)
        if resumed["ut_id"].size:  # (both tables have the same dtypes: nothing to join)
            res.events = concat_events(res.events, resumed)
        if steps is not None and steps["ut_id"].size:
            res.events = sorted_events(concat_events(res.events, steps))
        unserved = np.flatnonzero(res.sat_id < 0)
        state.best_unserved = (unserved, best_cell[unserved])
        cone = self.cones[k - blk.k0]
        if self.engine.other_satellites:  # the satellites of the interference sum
            cone = np.union1d(cone, np.unique(c.serving[c.serving >= 0] // nb))
        state.cand_sats, state.decision = cone, res
        state.enu = None if self.enu is None else self.enu[k - blk.k0]
        state.controller = res.state

    def _environment(self, state, ch):
        """The epoch's environment ``ch`` (its paths' losses are in the block's tables and
        best cells already) and each UT's best SNR without it (open country)."""
        state.channel = ch
        state.open_snr_db = self.block.open_snr_db[self.block.rows(state.k)]

    def _masked(self, state, table):
        """``table`` with the candidates of UTs re-establishing after an RLF masked."""
        if self.rlf is None:
            return table
        state.rlf_blocked = self.rlf.blocked(state.t_s)
        if not state.rlf_blocked.any():
            return table
        return table.like(np.where(state.rlf_blocked[:, None], np.nan, table.snr_db))

    def _lit_only(self, state, table, future, best_cell, k):
        """The tables restricted to this epoch's lit beams (``state.lit`` set)."""
        sel = self.selector
        state.lit = np.asarray(sel.lit(k, best_cell, self.mb.sat_pos_m.shape[1]), bool)
        table = restrict(table, state.lit, best_cell, sel.dark_fallback)
        if future is not None:  # the beams lit now (the future's are not decided yet)
            future = restrict(future, state.lit, best_cell, sel.dark_fallback)
        return table, future

    def _with_serving(self, table, rows, serving, channel=None):
        """``table`` with each UT's serving cell added where it is missing and above the
        mask (an extra column; -1/NaN elsewhere), lowered by its path's loss in
        ``channel`` (the epoch's :class:`~leolink.sim.environment.EpochChannel`, if any:
        the table's cells have theirs)."""
        nb, blk = self.engine.n_beam, self.block
        need = np.flatnonzero((serving >= 0) & (table.slot_of(serving) < 0))
        if need.size == 0:
            return table
        r = rows.start + need
        sat, beam = serving[need] // nb, serving[need] % nb
        val, vis = np.full(need.size, np.nan), np.zeros(need.size, bool)
        pair = blk.find_pairs(r, sat)
        hit = pair >= 0
        val[hit], vis[hit] = blk.snr_db_of(pair[hit], beam[hit])
        miss = np.flatnonzero(~hit)
        if miss.size:  # pairs the search left out: evaluated now
            val[miss], vis[miss] = self._evaluated_snr_db(r[miss], serving[need[miss]])
        cell, snr_db = np.full(table.n_ut, -1, np.int64), np.full(table.n_ut, np.nan)
        cell[need[vis]], snr_db[need[vis]] = serving[need[vis]], val[vis]
        if channel is not None:
            sat = np.where(cell >= 0, cell // self.engine.n_beam, -1)
            snr_db = snr_db - channel.loss_db(sat[:, None])[:, 0]
        return Candidates(np.column_stack([table.cell, cell]),
                          np.column_stack([table.snr_db, snr_db]))  # fmt: skip

    def _evaluated_snr_db(self, rows, cells):
        """The SNR [dB] of the cells ``cells`` of the block rows ``rows`` from their pairs
        evaluated now, and whether each pair is above the mask."""
        nb = self.engine.n_beam
        links = self.evaluate(rows, cells // nb)
        snr = links.snr_db_bm(self.engine.beam_ix, self.engine.beam_iy)
        return snr[cells % nb, np.arange(rows.size)], links.visible

    def evaluate(self, rows, sats):
        """The engine's links of pairs (block rows, global satellite ids) of this block."""
        mb = self.mb
        up = None if self.enu is None else self.enu[..., 2, :].reshape(-1, 3)
        nrm = None if self.panel is None else self.panel[..., 2, :].reshape(-1, 3)
        n_ut = mb.ut_pos_m.shape[1]
        pos = mb.ut_pos_m.reshape(-1, 3)
        return self.search.evaluate(pos, up, mb.sat_pos_m, mb.sat_vel_m_s, n_ut, rows, sats, nrm)

    def _future(self, table, t_s, k):
        """The table's cells at ``t_s`` (the same cells; NaN where not visible then)."""
        eng, nb = self.engine, self.engine.n_beam
        ut_f, sat_pos_f, sat_vel_f = self.future_state(t_s)
        j = k - self.block.k0
        up = None if self.enu is None else self.enu[j][:, 2, :]
        nrm = None if self.panel is None else self.panel[j][:, 2, :]
        rows = np.broadcast_to(np.arange(table.n_ut)[:, None], table.shape)
        valid = table.cell >= 0
        key = rows[valid] * len(sat_pos_f) + table.cell[valid] // nb
        pairs, inverse = np.unique(key, return_inverse=True)
        ut, sat = np.divmod(pairs, len(sat_pos_f))
        links = eng.evaluate_pairs(ut_f, sat_pos_f, sat_vel_f, ut, sat, ut_up=up, ut_normal=nrm)
        snr = links.snr_db_bm(eng.beam_ix, eng.beam_iy)  # (n_beam, n_pair)
        out = np.full(table.shape, np.nan)
        out[valid] = snr[table.cell[valid] % nb, inverse.reshape(-1)]
        return table.like(out)


def _epochs_of(mb, k, ut_epochs):
    """The part of motion block ``mb`` whose candidates are found together with epoch
    ``k``'s: the whole block, or ``mb``'s epochs in runs of ``ut_epochs // n_ut`` (at
    least one) where the search bounds its block (a wide table); a view, no copy."""
    n_ut = mb.ut_pos_m.shape[1]
    span = max(1, ut_epochs // max(n_ut, 1)) if ut_epochs else mb.n_k
    if span >= mb.n_k:
        return mb
    lo = (k - mb.k0) // span * span
    hi = min(lo + span, mb.n_k)
    arrays = {f.name: getattr(mb, f.name)[lo:hi] for f in dataclasses.fields(mb)
              if f.name not in ("k0", "k1")}  # fmt: skip
    return dataclasses.replace(mb, k0=mb.k0 + lo, k1=mb.k0 + hi, **arrays)
