"""The candidate tables of a block of epochs: every cell a policy can need, evaluated exactly.

:class:`CandidateSearch` turns the geometry of a block of epochs
(:class:`~leolink.sim.motion.MotionBlock`) into one
:class:`~leolink.sim.candidates.table.Candidates` row per UT and epoch, plus the trace's per-UT
diagnostics (satellites above the mask, the best cell and its SNR). Rows are
``r = (k - k0) n_ut + u``; every engine call covers many epochs at once.

Pairs evaluated, per epoch, among the satellites of the epoch's cone
(:func:`~leolink.sim.processes.candidate_satellites`):

- few satellites (at most ``DENSE_CONE``), or ``prune=False`` (the reference): every pair;
- otherwise (pruned): :func:`leolink.engine.screening.screen` classifies every pair
  (visible, uncertain, below the mask) and bounds the SNR of every beam of the pair from
  above. Each UT's pair with the largest bound, and every uncertain pair, are evaluated
  first: their best beam gives ``L``, an SNR the UT certainly reaches. Then every pair
  above the mask whose bound is at least ``max(L - window, floor)``: ``window`` the
  policy's ``neighbour_window_db``, ``floor`` the service threshold for a policy that
  declares ``usable_cells_only`` (else no floor).

Every pair whose bound reaches ``L`` is evaluated too, below the floor as well: one of them
holds the row's best cell (the outage rows' geometry).

With the UTs' environments (``loss``: each path's extra loss of the epoch, drawn before the
search by :class:`~leolink.sim.decide.Decider`) the bounds, ``L``, the window, the floor
and the best cell are those of each pair's SNR after its own loss: a bound of the linear
SNR times ``10^(-loss/10)`` bounds it after the loss, so the same argument holds, with no
margin. Every pair whose bound without the loss reaches ``L`` without it is evaluated too:
the row's best SNR in open country (``open_snr_db``, the ``blocked`` outage reason).

A pair left out has a bound below ``L - window`` or below the floor: none of its cells can
be within the window of the best cell and at or above the floor. So a row holds exactly
the cells within the window of the UT's best cell and at or above the floor, pruned or
not; the serving cell is added at decision time (:meth:`Decider._with_serving
<leolink.sim.decide.Decider>`), from the evaluated pairs or evaluated then. The
diagnostics (``n_visible``, the best cell and its SNR) do not depend on the floor.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink import compiled
from leolink.arrays import nonzero_2d, take_rows, unique_inverse
from leolink.engine.links import Links, beam_snr_db
from leolink.engine.screening import UNCERTAIN, VISIBLE, screen, screen_ragged
from leolink.geometry import body_frame, earth_central_angle_rad
from leolink.sim.candidates.table import Candidates
from leolink.sim.candidates.tiles import Caps, choose_groups, group_cones

__all__ = ["DENSE_CONE", "BlockCandidates", "CandidateSearch"]

#: UT x satellite pairs screened at once (bounds the temporaries to a few MiB each; a
#: group's UTs with their caps, one call of the compiled loop per so many pairs).
SCREEN_PAIRS = 1 << 18
#: Evaluated pairs turned into table entries at once (bounds the (pairs, beams)
#: temporaries: ~4 MiB each with 16 beams).
TABLE_PAIRS = 1 << 15
#: Cones of at most this many satellites are evaluated whole (screening would not pay).
DENSE_CONE = 2
#: UT-epochs of one block's tables when the window is infinite (every cell above the mask
#: or the floor: ~50 cells per UT-epoch on configs/constellation.toml, ~5 KiB with their
#: pairs' links): the block's epochs are searched in runs this long (at least one epoch),
#: so a run's memory does not grow with the motion block.
WIDE_UT_EPOCHS = 8192


@dataclasses.dataclass
class BlockCandidates:
    """Candidates of the epochs ``k0 ..`` of a block (rows ``r = (k - k0) n_ut + u``).

    Attributes
    ----------
    k0, n_ut, n_beam : int
    table : Candidates
        Cells within the window of each row's best cell (global ids), (n_rows, n_slot).
    n_visible, best_cell, best_snr_db : ndarray, shape (n_rows,)
        Satellites above the mask; the best cell (-1 for none) and its SNR (NaN).
    links : Links
        Every evaluated pair, sorted by (row, satellite); ``links.ut`` is the row,
        ``links.sat`` the global satellite id.
    """

    k0: int
    n_ut: int
    n_beam: int
    table: Candidates
    n_visible: np.ndarray
    best_cell: np.ndarray
    best_snr_db: np.ndarray
    links: Links

    beam_ix: np.ndarray
    beam_iy: np.ndarray
    #: Each row's best SNR without the environment [dB] (NaN: none); ``best_snr_db`` with
    #: it. None: no environment (the same as ``best_snr_db``).
    open_snr_db: np.ndarray | None = None

    def __post_init__(self):
        self.n_key = int(self.links.sat.max(initial=0)) + 1
        self.pair_key = self.links.ut * self.n_key + self.links.sat  # sorted
        # Each row's first pair and its number of pairs: a row of one pair is found
        # without a search (one satellite: every row).
        count = np.bincount(self.links.ut, minlength=self.n_visible.size)
        self.row_pairs = (np.cumsum(count) - count, count)

    def rows(self, k):
        """Rows of epoch ``k``."""
        lo = (k - self.k0) * self.n_ut
        return slice(lo, lo + self.n_ut)

    def find_pairs(self, rows, sats):
        """Index into ``links`` of the pairs ``(rows[i], sats[i])``, -1 if not evaluated."""
        n = self.links.n_pair
        if n == 0:
            return np.full(np.shape(rows), -1, np.int64)
        ok = (sats >= 0) & (sats < self.n_key)
        key = rows * self.n_key + np.where(ok, sats, 0)
        first, count = self.row_pairs
        i = np.minimum(first[rows], n - 1)  # (a row without pairs: the next row's, no match)
        several = np.flatnonzero(count[rows] > 1)
        if several.size:
            i[several] = np.minimum(np.searchsorted(self.pair_key, key[several]), n - 1)
        ok &= self.pair_key[i] == key
        return np.where(ok, i, -1)

    def snr_db_of(self, pair, beam):
        """SNR [dB] of beam ``beam[i]`` of evaluated pair ``pair[i]``, and whether the
        pair is above the mask."""
        snr = self.links.snr_db_bm(self.beam_ix, self.beam_iy, pair)
        return snr[beam, np.arange(pair.size)], self.links.visible[pair]


class CandidateSearch:
    """Candidate tables of the blocks of a run (module docstring).

    Parameters
    ----------
    engine : leolink.engine.LinkEngine
    window_db : float
        The policy's ``neighbour_window_db`` [dB] (``inf``: every cell above the mask).
    prune : bool
        Screen the pairs (default); False evaluates every pair (the reference).
    floor_db : float
        Cells below this SNR [dB] are left out of the tables (``-inf``: none).
    """

    def __init__(self, engine, window_db, prune=True, floor_db=-np.inf):
        self.engine, self.window_db, self.prune = engine, float(window_db), bool(prune)
        self.floor_db = float(floor_db)
        #: UT-epochs a block may hold (None: the caller's motion block, whole).
        self.block_ut_epochs = WIDE_UT_EPOCHS if self.window_db == np.inf else None

    def block(self, k0, ut_pos_m, ut_up, sat_pos_m, sat_vel_m_s, cones, normal=None, loss=None):
        """The candidates of the epochs ``k0 .. k0 + n_k - 1``.

        Parameters
        ----------
        k0 : int
        ut_pos_m : ndarray, shape (n_k, n_ut, 3)
        ut_up : ndarray, shape (n_k, n_ut, 3), or None
            Local up of each UT (WGS 84); None: the sphere's.
        sat_pos_m, sat_vel_m_s : ndarray, shape (n_k, n_sat, 3)
            Every satellite of the run.
        cones : list of ndarray of int
            Per epoch, the global ids (ascending) of the satellites that may be above the
            mask for some UT.
        normal : ndarray, shape (n_k, n_ut, 3), optional
            Panel normal of each UT (tilted panels, ``LinkEngine.evaluate_pairs``).
        loss : callable, optional
            ``loss(i) -> (n_ut, len(cones[i]))``: the extra loss [dB] of each path of the
            block's epoch ``i`` (the UTs' environments; 0 without one), drawn before the
            search: the window, the floor and the best cell are those of the SNRs after
            it, and the pruning stays exact (module docstring). None: no environment.

        Returns
        -------
        BlockCandidates
        """
        n_k, n_ut = len(cones), ut_pos_m.shape[1]
        pos = ut_pos_m.reshape(-1, 3)
        up = None if ut_up is None else ut_up.reshape(-1, 3)
        nrm = None if normal is None else normal.reshape(-1, 3)
        widest = max((len(c) for c in cones), default=0)
        step = int(np.clip(SCREEN_PAIRS // max(n_ut * widest, 1), 1, n_k))
        # (no groups where every epoch's pairs are evaluated whole: a cone of a few)
        dense = not self.prune or all(len(c) <= DENSE_CONE for c in cones)
        groups = None if dense else self._groups(ut_pos_m[0], sat_pos_m[0])
        geo = (pos, up, sat_pos_m, sat_vel_m_s)
        parts = []
        for lo in range(0, n_k, step):  # chunks of epochs: bounded temporaries
            ks = range(lo, min(lo + step, n_k))
            parts.append(self._chunk(ks, n_ut, geo, cones, (nrm, groups), loss))
        links = Links.concat([part for p in parts for part in p[0]])  # (one copy of each)
        sure = np.concatenate([p[1] for p in parts])
        pair_loss = None if loss is None else np.concatenate([p[2] for p in parts])
        del parts  # (the parts' links are copied: not kept with the sorted ones)
        order = np.lexsort((links.sat, links.ut))
        if (order != np.arange(order.size)).any():  # (often sorted already: no copy)
            links = links.take(order)
            pair_loss = None if loss is None else pair_loss[order]
        return self._tables(k0, n_ut, n_k, links, sure, pair_loss)

    def _groups(self, ut_pos_m, sat_pos_m):
        """The UTs' screening groups of a block, from its first epoch (the caps are each
        epoch's own: the groups only decide how UTs share a cap)."""
        r_ut = float(np.mean(np.linalg.norm(ut_pos_m, axis=1)))
        r_sat = float(np.mean(np.linalg.norm(sat_pos_m, axis=1)))
        el = self.engine.params.min_elevation_rad
        return choose_groups(
            ut_pos_m, len(sat_pos_m), earth_central_angle_rad(el, r_sat - r_ut, r_ut)
        )

    def _chunk(self, ks, n_ut, geo, cones, screening, loss=None):
        """Evaluated pairs of the epochs ``ks`` (a list of :class:`Links`, joined by the
        caller once for the whole block: ``links.ut`` the row, ``links.sat`` the global
        id), the rows' visible satellites that were not evaluated, and the pairs'
        environment loss [dB] (None without ``loss``). ``geo``: the block's UT rows, their
        up, the satellites' positions and velocities; ``screening``: the rows' panel
        normals (or None) and the UTs' screening groups
        (:func:`~leolink.sim.candidates.tiles.choose_groups`)."""
        nrm, groups = screening
        n_rows = len(ks) * n_ut
        grids = {} if loss is None else {k: loss(k) for k in ks}
        if not self.prune or all(len(cones[k]) <= DENSE_CONE for k in ks):  # every pair
            rows, sats = _dense_pairs(ks, n_ut, cones)
            links = self.evaluate(*geo, n_ut, rows, sats, nrm)
            return [links], np.zeros(n_rows, np.int64), _pair_loss(grids, n_ut, cones, links)
        if len(groups) == 1 or loss is not None:  # one region, or environments: by cones
            return self._chunk_one_cone(ks, n_ut, geo, cones, nrm, grids)
        row, sat, code, bound, top = self._screened(ks, n_ut, geo, nrm, groups)
        chosen = _first_pairs(code, bound, top)
        links1 = self.evaluate(*geo, n_ut, row[chosen], sat[chosen], nrm)
        more = _more_pairs(code, bound, self._low(geo[0].shape[0], links1)(row), chosen)
        links2 = self.evaluate(*geo, n_ut, row[more], sat[more], nrm)
        unseen = row[_unseen_pairs(code, chosen, more)] - ks.start * n_ut
        sure = np.bincount(unseen, minlength=n_rows)
        return [links1, links2], sure, None

    def _chunk_one_cone(self, ks, n_ut, geo, cones, nrm, grids):
        """:meth:`_chunk` by each epoch's cone (every UT with every satellite of the cone,
        screened as dense matrices; ``grids``: each epoch's path losses [dB], empty without
        an environment): the same pairs as by tiles, evaluated alike."""
        pos, up, sat_pos_m, sat_vel_m_s = geo
        sure = np.zeros(len(ks) * n_ut, np.int64)
        rows1, sats1, rows2, sats2, screened = [], [], [], [], []
        ut_id = np.arange(n_ut)
        for i, k in enumerate(ks):
            rows, cone = k * n_ut + ut_id, cones[k]
            axes = body_frame(sat_pos_m[k][cone], sat_vel_m_s[k][cone])
            code, bound = self._screen(pos, up, rows, sat_pos_m[k][cone], axes, ut_id, nrm, cone)
            # Each path's bound after its environment (the loss is known: an exact bound).
            env = bound if not grids else bound * 10.0 ** (-grids[k] / 10.0)
            chosen = _first_pairs(code, env, np.max(env, axis=1, initial=-1.0)[:, None])
            r, s = nonzero_2d(chosen)
            rows1.append(rows[r])
            sats1.append(cone[s])
            screened.append((i, rows, cone, code, bound, env, chosen))
        links1 = self.evaluate(*geo, n_ut, rows1, sats1, nrm)
        loss1 = _pair_loss(grids, n_ut, cones, links1)
        reach, reach_open = self._reach(pos.shape[0], links1, loss1)
        for i, rows, cone, code, bound, env, chosen in screened:
            # the window's and the floor's cells, and every pair that may hold the best
            # cell (the diagnostics', below the floor too)
            more = _more_pairs(code, env, self._low_of(reach[rows])[:, None], chosen)
            if reach_open is not None:  # and every pair that may hold the open best
                more |= _more_pairs(code, bound, reach_open[rows][:, None], chosen)
            r, s = nonzero_2d(more)
            rows2.append(rows[r])
            sats2.append(cone[s])
            sure[i * n_ut : (i + 1) * n_ut] = _unseen_pairs(code, chosen, more).sum(axis=1)
        links2 = self.evaluate(*geo, n_ut, rows2, sats2, nrm)
        pair_loss = None if not grids else np.r_[loss1, _pair_loss(grids, n_ut, cones, links2)]
        return [links1, links2], sure, pair_loss

    def _reach(self, n_rows, links, pair_loss):
        """Per row, the largest linear SNR of its evaluated pairs' best beams: after the
        environment (``pair_loss`` [dB]), and without it (None without an environment)."""
        gain = links.gain_tx_bm(self.engine.beam_ix, self.engine.beam_iy).max(axis=0)
        lin = np.where(links.visible, gain, 0.0) * links.path_lin
        reach = np.zeros(n_rows)
        if pair_loss is None:
            np.maximum.at(reach, links.ut, lin)
            return reach, None
        reach_open = np.zeros(n_rows)
        np.maximum.at(reach_open, links.ut, lin)
        np.maximum.at(reach, links.ut, lin * 10.0 ** (-pair_loss / 10.0))
        return reach, reach_open

    def _low_of(self, reach):
        """The bound below which a pair of a row whose best SNR is ``reach`` can be left
        out: ``max(reach - window, floor)``, at most ``reach`` (the best cell's pairs)."""
        factor = 10.0 ** (-self.window_db / 10.0)
        floor_lin = 10.0 ** (self.floor_db / 10.0)  # 0 without a floor
        return np.minimum(np.maximum(reach * factor, floor_lin), reach)

    def _low(self, n_rows, links1):
        """``low(rows)``: :meth:`_low_of` of each row's best SNR among ``links1``."""
        reach, _ = self._reach(n_rows, links1, None)
        return lambda rows: self._low_of(reach[rows])

    def _screened(self, ks, n_ut, geo, nrm, groups):
        """The pairs of the epochs ``ks`` above the mask or near it, each group of UTs
        screened against its cap (:func:`~leolink.sim.candidates.tiles.group_cones`):
        their rows, satellites (global ids), codes, bounds and their UT's largest bound
        (NaN if any is), flat."""
        pos, up, sat_pos_m, sat_vel_m_s = geo
        label = np.empty(n_ut, np.int64)
        for g, members in enumerate(groups):
            label[members] = g
        min_el = self.engine.params.min_elevation_rad
        parts = []
        for k in ks:
            rows = k * n_ut + np.arange(n_ut)
            ut_up = None if up is None else up[rows]
            caps = group_cones(sat_pos_m[k], pos[rows], ut_up, min_el, label, len(groups))
            # the caps' satellites (ascending) and each cap entry's row among them, by a
            # mask over the constellation (np.unique's sort cost ~1 ms an epoch here)
            seen = np.zeros(len(sat_pos_m[k]), bool)
            seen[caps.sat] = True
            union = np.flatnonzero(seen)
            axes = body_frame(sat_pos_m[k][union], sat_vel_m_s[k][union])
            local = Caps((np.cumsum(seen) - 1)[caps.sat], caps.start, caps.group)
            sats = (sat_pos_m[k][union], axes, union)
            u, s, code, bound, top = self._screen_caps(pos, up, rows, sats, local, groups, nrm)
            parts.append((rows[u], union[s], code, bound, top))
        return tuple(np.concatenate(p) for p in zip(*parts, strict=True))

    def _screen_caps(self, pos, up, rows, sats, caps, groups, nrm):
        """One epoch's UT rows ``rows`` screened against their caps (``sats``: positions,
        body frames and global ids of the satellites ``caps`` index): the pairs above the
        mask or near it, flat (UT, satellite, code, bound, the UT's largest bound), by the
        compiled loop in one call where it runs, else by :func:`screen` per group."""
        sat_pos_m, axes, sat_id = sats
        n_ut = len(rows)
        ut_id = np.arange(n_ut)
        parts = []
        if compiled.use(caps.sat.size) and self.engine.steering is None:
            for lo, hi in _ut_chunks(np.diff(caps.start)[caps.group], SCREEN_PAIRS):
                part = Caps(caps.sat, caps.start, caps.group[lo:hi])
                r = rows[lo:hi]
                code, bound, start = screen_ragged(
                    self.engine, pos[r], sat_pos_m, axes, part, None if up is None else up[r],
                    ut_id[lo:hi], None if nrm is None else nrm[r],
                )  # fmt: skip
                flat = np.flatnonzero(code > 0)
                u, s = part.pairs(start, flat)
                top = np.full(hi - lo, -1.0)
                has = np.flatnonzero(start[1:] > start[:-1])
                if has.size:
                    top[has] = np.maximum.reduceat(bound, start[has])
                parts.append((u + lo, s, code[flat], bound[flat], top[u]))
            return tuple(np.concatenate(p) for p in zip(*parts, strict=True))
        for g, members in enumerate(groups):
            cap = caps.of(g)
            if cap.size == 0:
                continue
            code, bound = self._screen(pos, up, rows[members], sat_pos_m[cap], axes[cap],
                                       members, nrm, sat_id[cap])  # fmt: skip
            flat = np.flatnonzero(code > 0)
            i, j = np.divmod(flat, cap.size)
            top = bound.max(axis=1)
            parts.append((members[i], cap[j], code.reshape(-1)[flat], bound.reshape(-1)[flat],
                          top[i]))  # fmt: skip
        if not parts:
            empty = np.zeros(0, np.int64)
            return empty, empty, np.zeros(0, np.int8), np.zeros(0), np.zeros(0)
        return tuple(np.concatenate(p) for p in zip(*parts, strict=True))

    def _screen(self, pos, up, rows, sat_pos_m, axes, ut_id, nrm, sat_id):
        """:func:`screen` of the UT rows ``rows`` (UTs ``ut_id``) against the satellites at
        ``sat_pos_m`` (body frames ``axes``, global ids ``sat_id``), in blocks of UTs."""
        n_ut = len(rows)
        n_part = -(-n_ut * len(sat_id) // SCREEN_PAIRS)
        step = -(-n_ut // max(n_part, 1))
        parts = [
            screen(
                self.engine,
                pos[rows[lo : lo + step]],
                sat_pos_m,
                axes,
                None if up is None else up[rows[lo : lo + step]],
                ut_id[lo : lo + step],
                None if nrm is None else nrm[rows[lo : lo + step]],
                sat_id,
            )  # fmt: skip
            for lo in range(0, n_ut, step)
        ]
        if len(parts) == 1:
            return parts[0]
        return (np.concatenate([p[j] for p in parts]) for j in (0, 1))

    def evaluate(self, pos, up, sat_pos_m, sat_vel_m_s, n_ut, rows, sats, nrm=None):
        """The engine's links of the pairs ``(rows, global satellite ids)`` of a block, in
        one call (``pos``, ``up``, ``nrm`` (panel normals or None): (n_k n_ut, 3) rows;
        ``sat_*``: (n_k, n_sat, 3)); lists of index arrays are joined."""
        if isinstance(rows, list):
            rows = np.concatenate(rows) if rows else np.zeros(0, np.int64)
            sats = np.concatenate(sats) if sats else np.zeros(0, np.int64)
        n_sat = sat_pos_m.shape[1]
        key, inverse = unique_inverse((rows // n_ut) * n_sat + sats)
        flat_pos = take_rows(sat_pos_m.reshape(-1, 3), key)
        flat_vel = take_rows(sat_vel_m_s.reshape(-1, 3), key)
        ut_id = np.arange(pos.shape[0]) % n_ut
        links = self.engine.evaluate_pairs(
            pos, flat_pos, flat_vel, rows, inverse.reshape(-1), ut_up=up, ut_id=ut_id,
            ut_normal=nrm, sat_id=key % n_sat,
        )  # fmt: skip
        links.sat = sats  # global ids from here on
        return links

    def _tables(self, k0, n_ut, n_k, links, sure, pair_loss=None):
        """Window tables and diagnostics of the sorted evaluated pairs, in chunks of whole
        rows (:data:`TABLE_PAIRS` pairs): the (pairs, beams) temporaries stay bounded
        however many satellites a block sees; every value is one row's, so the tables do
        not depend on the chunks."""
        eng, nb, n_rows = self.engine, self.engine.n_beam, n_k * n_ut
        vis = np.flatnonzero(links.visible)
        rows_vis = links.ut[vis]
        n_visible = sure + np.bincount(rows_vis, minlength=n_rows)
        best_db = np.full(n_rows, np.nan)
        best_cell = np.full(n_rows, -1, np.int64)
        every = vis.size == links.n_pair  # every pair visible: slices, not gathers
        open_db = None if pair_loss is None else np.full(n_rows, np.nan)
        chunks = [slice(lo, hi) for lo, hi in _row_chunks(rows_vis, TABLE_PAIRS)]
        pairs = [chunk if every else vis[chunk] for chunk in chunks]
        # (the diagnostics' best cell does not see the floor: kept here when it has one)
        best = (best_db, None if self.floor_db == -np.inf else best_cell)
        if pair_loss is None:
            # No (nb, m) matrix: the window's and the floor's beams only; the chunks (whole
            # rows, each writing its own rows' best) split over threads.
            _ = links.path_snr_lin  # (cached here, not raced for by the threads)
            beams, limits = (eng.beam_ix, eng.beam_iy), (self.window_db, self.floor_db)
            calls = [(links, p, beams, rows_vis[c], links.sat[p], limits, best)
                     for c, p in zip(chunks, pairs, strict=True)]  # fmt: skip
            entries = compiled.run_calls(link_window_entries, calls)
        else:
            entries = [self._matrix_entries(links, p, rows_vis[c], pair_loss, best, open_db)
                       for c, p in zip(chunks, pairs, strict=True)]  # fmt: skip
        ut, cell, snr = (np.concatenate(e) for e in zip(*entries, strict=True))
        table = Candidates.from_entries(n_rows, ut, cell, snr)
        if self.floor_db == -np.inf:
            best_cell, _ = table.best()
        return BlockCandidates(k0, n_ut, nb, table, n_visible, best_cell, best_db, links,
                               eng.beam_ix, eng.beam_iy, open_db)  # fmt: skip

    def _matrix_entries(self, links, pairs, rows, pair_loss, best, open_db):
        """:func:`window_entries` of the evaluated ``pairs`` (their sorted ``rows``) from
        their (n_beam, m) SNR matrix, each lowered by its pair's environment loss
        ``pair_loss`` [dB] (None: no environment; else each row's best before it is
        written into ``open_db``). ``best``: as :func:`window_entries` takes it."""
        eng = self.engine
        snr_bm = links.snr_db_bm(eng.beam_ix, eng.beam_iy, pairs)  # (nb, m)
        if pair_loss is not None:  # the open best, then every SNR after the environment
            _row_best(rows, snr_bm.T, open_db)
            snr_bm = snr_bm - pair_loss[pairs][None, :]
        limits = (self.window_db, self.floor_db)
        return window_entries(snr_bm, rows, links.sat[pairs], limits, best)


def _first_pairs(code, bound, top):
    """The pairs evaluated first (module docstring), from their screening ``code`` and
    ``bound`` (linear SNR) and their row's largest bound ``top`` (broadcast): every
    uncertain pair, and the pairs of the row's largest bound (none where it is NaN or
    negative: no pair above the mask)."""
    return (code == UNCERTAIN) | ((bound == top) & (top >= 0.0))


def _more_pairs(code, bound, low, first):
    """The pairs evaluated next: above the mask, not among ``first``, their bound at least
    ``low`` (their row's :meth:`CandidateSearch._low_of`, broadcast; NaN keeps none)."""
    with np.errstate(invalid="ignore"):
        return (code > 0) & (bound >= low) & ~first


def _unseen_pairs(code, first, more):
    """The visible pairs left out (counted in ``n_visible``, never evaluated)."""
    return (code == VISIBLE) & ~first & ~more


def _row_best(rows, snr, out):
    """Write into ``out`` each of the sorted ``rows``' largest SNR of ``snr (m, nb)``
    (NaN ignored; NaN where all are)."""
    if rows.size:
        start = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
        with np.errstate(invalid="ignore"):
            pair_best = np.fmax.reduce(snr, axis=1)
            out[rows[start]] = np.fmax.reduceat(pair_best, start)


def _pair_loss(grids, n_ut, cones, links):
    """The environment loss [dB] of each pair of ``links`` (rows ``k n_ut + u``) from the
    epochs' ``(n_ut, n_cone)`` grids (``{k: grid}``); None without grids."""
    if not grids:
        return None
    out = np.zeros(links.n_pair)
    epoch = links.ut // n_ut
    for k, grid in grids.items():
        at = np.flatnonzero(epoch == k)
        if at.size:
            slot = np.searchsorted(cones[k], links.sat[at])  # every pair's satellite is in it
            out[at] = grid[links.ut[at] - k * n_ut, slot]
    return out


def window_entries(snr_bm, rows, sat, limits, best):
    """The window's entries of pairs of the sorted ``rows`` (each row's pairs together):
    every cell whose SNR is at least the row's best minus the window and at least the
    floor, in (pair, beam) order, ``(ut, cell, snr)``; each row's best (NaN ignored; NaN
    where all are) written into ``best_db``. ``snr_bm``: (n_beam, m) [dB]; ``sat``: each
    pair's satellite; ``limits``: ``(window_db, floor_db)`` [dB] (a float: the window,
    no floor); ``best``: ``best_db``, or ``(best_db, best_cell)`` to write each row's best
    cell too (:func:`_best_cells`' rule; None: not). By the compiled
    :func:`_window_rows` where it runs, else numpy (the same entries)."""
    window_db, floor_db = limits if isinstance(limits, tuple) else (limits, -np.inf)
    best_db, best_cell = best if isinstance(best, tuple) else (best, None)
    nb, m = snr_bm.shape
    if compiled.use(m):
        ut, cell, snr = np.empty(m * nb, np.int64), np.empty(m * nb, np.int64), np.empty(m * nb)
        out = (ut, cell, snr)
        cells_out = np.full(0, -1, np.int64) if best_cell is None else best_cell
        n = _window_rows(snr_bm, rows, np.asarray(sat, np.int64),
                         (float(window_db), float(floor_db)), (best_db, cells_out),
                         out)  # fmt: skip
        return ut[:n].copy(), cell[:n].copy(), snr[:n].copy()
    snr = snr_bm.T  # (m, nb)
    _row_best(rows, snr, best_db)
    with np.errstate(invalid="ignore"):
        keep = (snr >= (best_db[rows] - window_db)[:, None]) & (snr >= floor_db)
    if best_cell is not None:
        _best_cells(rows, sat[:, None] * nb + np.arange(nb)[None, :], snr, best_db, best_cell)
    # the kept entries in (pair, beam) order, as boolean indexing gives them
    pair, beam = np.divmod(np.flatnonzero(keep), nb)
    return rows[pair], sat[pair] * nb + beam, snr[pair, beam]


@compiled.jit
def _window_rows(snr_bm, rows, sat, limits, best, out):
    """:func:`window_entries` row by row: the row's best (``numpy.fmax``'s rule) and its
    first cell in (pair, beam) order holding it (written where it is finite and
    ``best[1]`` has room), then its entries at or above best - window and the floor (a
    NaN best keeps none); returns their count."""
    ut, cell, snr = out
    window_db, floor_db = limits
    best_db, best_cell = best
    nb, m = snr_bm.shape
    n, lo = 0, 0
    while lo < m:
        hi, top, top_cell = lo, np.nan, -1
        while hi < m and rows[hi] == rows[lo]:
            for b in range(nb):
                v = snr_bm[b, hi]
                if v > top or (np.isnan(top) and not np.isnan(v)):
                    top, top_cell = v, sat[hi] * nb + b
            hi += 1
        best_db[rows[lo]] = top
        if best_cell.size and np.isfinite(top):
            best_cell[rows[lo]] = top_cell
        for p in range(lo, hi):
            for b in range(nb):
                v = snr_bm[b, p]
                if v >= top - window_db and v >= floor_db:
                    ut[n], cell[n], snr[n] = rows[p], sat[p] * nb + b, v
                    n += 1
        lo = hi
    return n


#: Relative margin of :func:`link_window_entries`' linear pre-selection: a beam whose
#: linear SNR is below the row's largest times ``10^(-window/10) (1 - WINDOW_GAP)`` is
#: out of the window in dB too, and one below ``10^(floor/10) (1 - WINDOW_GAP)`` under the
#: floor (the dB sums err by < 1e-12 dB, 2.3e-13 relative).
WINDOW_GAP = 1e-9


def link_window_entries(links, pairs, beams, rows, sat, limits, best):
    """:func:`window_entries` of :meth:`Links.snr_db_bm <leolink.engine.links.Links.
    snr_db_bm>` ``(*beams, pairs)`` (``pairs``: a slice or indices of the sorted
    ``rows``' pairs; ``limits`` and ``best`` as :func:`window_entries` takes them), without
    the (n_beam, m) matrix: by the compiled :func:`_link_window_rows` where it runs (the
    same entries, row bests and best cells, each dB value the same sum), else by numpy on
    the matrix."""
    beam_ix, beam_iy = beams
    if not compiled.use(len(rows)):
        snr_bm = links.snr_db_bm(beam_ix, beam_iy, pairs)
        return window_entries(snr_bm, rows, sat, limits, best)
    window_db, floor_db = limits if isinstance(limits, tuple) else (limits, -np.inf)
    best_db, best_cell = best if isinstance(best, tuple) else (best, None)
    idx = np.arange(links.n_pair)[pairs] if isinstance(pairs, slice) else pairs
    m, nb = len(rows), len(beam_ix)
    out = (np.empty(m * nb, np.int64), np.empty(m * nb, np.int64), np.empty(m * nb))
    beams = np.stack([beam_ix, beam_iy]).astype(np.int64)
    kernels = (links.kx, links.ky, links.path_snr_lin, beams)
    cells_out = np.full(0, -1, np.int64) if best_cell is None else best_cell
    n = _link_window_rows(kernels, np.asarray(idx, np.int64), rows, np.asarray(sat, np.int64),
                          (float(window_db), float(floor_db)), (best_db, cells_out),
                          out)  # fmt: skip
    return out[0][:n].copy(), out[1][:n].copy(), out[2][:n].copy()


@compiled.jit
def _link_window_rows(kernels, idx, rows, sat, limits, best, out):
    """:func:`_window_rows` of the pairs ``idx`` from their kernels: each row's largest
    linear SNR ``k_x k_y p`` first; only the beams within :data:`WINDOW_GAP` of the window
    below it, or of the floor where that is lower, and those within it of the largest
    itself (the row's best in dB is among them) get their dB value
    (:func:`~leolink.engine.links.beam_snr_db`); the row's best among them
    (``numpy.fmax``'s rule) and its first cell (written as :func:`_window_rows` does),
    then the entries at or above best - window and the floor."""
    kx, ky, path_snr_lin, beams = kernels
    beam_ix, beam_iy = beams[0], beams[1]
    window_db, floor_db = limits
    best_db, best_cell = best
    ut, cell, snr = out
    nb, m = beam_ix.size, idx.size
    factor = 10.0 ** (-window_db / 10.0)
    floor_lin = 10.0 ** (floor_db / 10.0)  # 0 without a floor
    n, lo = 0, 0
    while lo < m:
        hi, top = lo, -1.0
        while hi < m and rows[hi] == rows[lo]:
            p = idx[hi]
            for b in range(nb):
                g = kx[beam_ix[b], p] * ky[beam_iy[b], p] * path_snr_lin[p]
                if g > top:  # (a NaN path, below the mask: never the largest)
                    top = g
            hi += 1
        low = min(max(top * factor, floor_lin), top) * (1.0 - WINDOW_GAP)
        best, top_cell, first = np.nan, -1, n
        for q in range(lo, hi):  # the candidates, kept for now
            p = idx[q]
            for b in range(nb):
                if kx[beam_ix[b], p] * ky[beam_iy[b], p] * path_snr_lin[p] >= low:
                    v = beam_snr_db(kx, ky, path_snr_lin, p, beam_ix[b], beam_iy[b])
                    if v > best or (np.isnan(best) and not np.isnan(v)):
                        best, top_cell = v, sat[q] * nb + b
                    ut[n], cell[n], snr[n] = rows[q], sat[q] * nb + b, v
                    n += 1
        best_db[rows[lo]] = best
        if best_cell.size and np.isfinite(best):
            best_cell[rows[lo]] = top_cell
        last, n = n, first
        for e in range(first, last):  # those in the window and at or above the floor, in order
            if snr[e] >= best - window_db and snr[e] >= floor_db:
                ut[n], cell[n], snr[n] = ut[e], cell[e], snr[e]
                n += 1
        lo = hi
    return n


def _dense_pairs(ks, n_ut, cones):
    """Every (row, satellite) pair of the epochs ``ks`` (a range): each UT of an epoch with
    each satellite of its cone, epoch after epoch, UT after UT (rows ``k n_ut + u``)."""
    if len({len(cones[k]) for k in ks}) == 1:  # one cone size (the usual): at once
        cone = np.array([cones[k] for k in ks])  # (n_k, n_cone)
        rows = np.arange(ks.start * n_ut, ks.stop * n_ut)
        sats = np.broadcast_to(cone[:, None, :], (len(ks), n_ut, cone.shape[1]))
        return np.repeat(rows, cone.shape[1]), sats.reshape(-1)
    rows = [np.repeat(k * n_ut + np.arange(n_ut), len(cones[k])) for k in ks]
    sats = [np.tile(cones[k], n_ut) for k in ks]
    return np.concatenate(rows), np.concatenate(sats)


def _ut_chunks(size, pairs):
    """``(lo, hi)`` ranges of UTs whose ``size`` (pairs each) add up to about ``pairs``
    (at least one UT each; one empty range for no UT)."""
    total = np.cumsum(size)
    cuts = np.searchsorted(total, np.arange(pairs, total[-1] if total.size else 0, pairs))
    edges = np.unique(np.concatenate(([0], cuts + 1, [size.size])))
    edges = edges[edges <= size.size]
    if edges.size == 1:
        return [(0, 0)]
    return list(zip(edges[:-1].tolist(), edges[1:].tolist(), strict=True))


def _row_chunks(rows, size):
    """``(lo, hi)`` slices of the sorted ``rows``, each of at least ``size`` entries (the
    last may have fewer) and ending at the end of a row; one empty slice if none."""
    lo, n = 0, rows.size
    while True:
        hi = n if lo + size >= n else int(np.searchsorted(rows, rows[lo + size - 1], "right"))
        yield lo, hi
        if hi >= n:
            return
        lo = hi


def _best_cells(rows, cell, snr, best_db, out):
    """Write into ``out`` each of ``rows``' best cell (left as is where its best SNR is
    not finite), ties to the lowest id, as :meth:`Candidates.best` of the whole table,
    without building it.

    ``rows`` (m,) sorted, with the pairs of a row by ascending satellite, so that the
    entries ``(pair, beam)`` of a row, flattened, are in ascending cell id: the first
    entry equal to the row's best is the lowest tied cell.
    """
    best = best_db[rows]
    with np.errstate(invalid="ignore"):
        tied = (snr == best[:, None]) & np.isfinite(best)[:, None]
    flat = np.flatnonzero(tied)
    row_of = rows[flat // snr.shape[1]]
    first = np.flatnonzero(np.r_[True, row_of[1:] != row_of[:-1]]) if flat.size else flat
    out[row_of[first]] = cell.reshape(-1)[flat[first]]
    return out
