"""The monitor's side of an epoch: every UT's serving link, streamed to the sinks.

:class:`Monitor` is what :func:`~leolink.sim.processes.link_monitor` calls once per
epoch. It keeps the epoch's decision and, at the end of each motion block
(:mod:`leolink.sim.motion`), evaluates the links of all the block's recorded epochs in
one engine call (the pairs the controller's search evaluated are reused) and hands the
sinks the block's epochs in one :class:`~leolink.sim.streams.BlockFrame`, its trace
columns assembled for all of them at once. Sinks see the same rows as if each epoch were
sent at its time, up to one block later.

In outage rows where a satellite is above the minimum elevation, the geometry and budget
columns are those of the best candidate (``best_snr_db``); the link columns (SNR, SINR,
SE, throughput) are NaN. In a handover epoch SE and throughput are the epoch's means:
the link's, times the part of the epoch with service.

With radio link failure monitoring (:mod:`leolink.sim.handover.rlf_run`) the next decision needs
this epoch's serving SINR, so the links are evaluated every epoch (warm-up included) and
the RLF state machine may end a UT's service before the frame is sent; without it,
recording waits for the end of the block.

Timing: ``delay_s`` is the link's slant range / c, ``delay_rate_s_s`` its rate, the
range rate / c (from the link's total Doppler, :mod:`leolink.kinematics`); in outage rows
those of the best candidate, as the geometry. With ``[timing]`` (``timing``), the NTN
columns of :mod:`leolink.timing` (``ta_s``, ``common_ta_s``, ``k_offset_ms``,
``doppler_residual_hz``) of the same link, from the satellite state the UT believes
(NaN without a link).

Beyond the engine's columns (:class:`~leolink.sim.service_link.ServiceLink`): the link
figures (EIRP, C/N0, Es/N0, margin, MODCOD, ACM throughput), and with a SINR service
threshold the served rows below it turned to outage (``below_threshold``, no interruption).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.arrays import take_rows
from leolink.engine.links import Links
from leolink.kinematics import delay_rate_from_doppler_s_s, propagation_delay_s
from leolink.link.acm import LinkFigureParams
from leolink.link.fading import mean_rician_gain_lin, rician_gain_from_draws_lin
from leolink.rng import complex_normal
from leolink.sim.handover.controller import SERVICE_HANDOVER, SERVICE_OUTAGE, interruption_s
from leolink.sim.service_link import ServiceLink
from leolink.sim.streams import BlockFrame, EpochFrame, deliver
from leolink.timing import TIMING_COLUMNS, timing_columns

__all__ = ["FadingDraws", "Monitor"]

_LINK = ("snr_db", "sinr_db", "se_bps_hz", "throughput_bps")


@dataclasses.dataclass
class PairLinks:
    """The links of the monitored rows, and their satellites' states (each (n, 3))."""

    links: Links
    pair: np.ndarray  # (n,) each row's pair in ``links``, -1 without a link
    sat_pos_m: np.ndarray
    sat_vel_m_s: np.ndarray
    sat_acc_m_s2: np.ndarray
    rx_lin: np.ndarray | None = None  # a receive-power factor of each row (None: 1)
    sat_pos_est_m: np.ndarray | None = None  # the state the satellite believes
    sat_vel_est_m: np.ndarray | None = None
    extra: dict = dataclasses.field(default_factory=dict)  # for :meth:`Monitor._finish`


@dataclasses.dataclass
class _Record:
    """What the monitor keeps of one recorded epoch until its block is flushed."""

    k: int
    t_s: float
    decision: object  # StepResult
    geo_sat: np.ndarray  # (n_ut,) the link's satellite: serving, or best in outage (-1)
    geo_beam: np.ndarray
    gap_s: np.ndarray  # (n_ut,) interrupted part of the epoch [s]
    n_visible: np.ndarray
    best_snr_db: np.ndarray
    cone: np.ndarray  # the satellites of the other-satellite interference
    channel: object = None  # EpochChannel of the UTs' environments (None: open country)
    env_cols: dict | None = None  # the environment columns of each UT's link (geo_sat)
    open_snr_db: np.ndarray | None = None  # best SNR without the environment [dB]
    lit: np.ndarray | None = None  # (n_sat, n_beam) lit beams (active beams), None: all
    share: np.ndarray | None = None  # (n_ut,) time share of the UT's beam (sharing on)


@dataclasses.dataclass(frozen=True)
class FadingDraws:
    """Random Rician fading of the serving links: the factor ``k`` (linear) and the UTs'
    random keys (``ut_keys``, (n_ut,) uint64) of the counter-based draws."""

    k: float
    ut_keys: np.ndarray


class Monitor:
    """Serving links of every UT -> block (or epoch) frames for the sinks (module docstring).

    Parameters
    ----------
    sink : Sink
    decider : leolink.sim.decide.Decider
        Whose block candidates (and evaluated pairs) the links are read from; its engine,
        epoch and radio link failure bookkeeping (``rlf``, None: off; module docstring)
        are the monitor's.
    fading : FadingDraws or None
        Random fading draws (None: the mean gain).
    population : sequence of str
        The population name of every UT.
    link : ServiceLink or None
        The link figures and the SINR service threshold (None: the default figures of the
        engine's power and bandwidth, service as the controller judged it).
    service : leolink.sim.beams.service.BeamService, optional
        Beam sharing and precoding (adds the ``n_sharing`` column); None: today's links.
    timing : leolink.timing.TimingParams, optional
        Adds the NTN timing columns (module docstring); None: without them.
    """

    def __init__(self, sink, decider, fading=None, population=(), link=None, service=None,
                 timing=None):  # fmt: skip
        self.engine, self.sink, self.decider = decider.engine, sink, decider
        self.timing = timing
        self.rlf, self.epoch_s = decider.rlf, decider.epoch_s
        self.service, self.fading = service, fading
        self.freq_hz = float(self.engine.params.freq_hz)
        self.population = np.asarray(population, dtype=object)
        self._tiled = {}
        self.pending = []
        if link is None:
            p = self.engine.params
            link = ServiceLink(
                LinkFigureParams(p.ptx_dbw, p.cable_loss_db, self.engine.bandwidth_hz)
            )
        self.link = link

    def __call__(self, state):
        if self.rlf is not None:
            self._per_epoch(state)
            return
        if state.recording:
            self.pending.append(self._record(state))
        block = self.decider.mb
        if state.k == block.k1 - 1 or state.k == len(state.times_s) - 1:
            self.flush(state)

    def _per_epoch(self, state):
        """This epoch's links, then RLF (which may drop serving cells), then its frame."""
        rec = self._record(state)
        cols = self._columns([rec], self._links([rec]))
        res = rec.decision
        state.controller, events, dwells = self.rlf.merge(state, cols, res.events, res.dwells)
        if state.recording:
            self._send(state, rec, cols, events, dwells)

    def _send(self, state, rec, cols, events, dwells):
        start_s = state.times_s[state.n_warmup]
        frame = EpochFrame(rec.k - state.n_warmup, rec.t_s, cols, events,
                           _warmup_censored(dwells, start_s))  # fmt: skip
        self.sink.epoch(frame)

    def _record(self, state):
        res, nb = state.decision, self.engine.n_beam
        geo_sat, geo_beam = res.sat_id.copy(), res.beam_id.copy()
        unserved, best = state.best_unserved
        if unserved.size:  # outage rows: the best candidate's geometry, where there is one
            geo_sat[unserved] = np.where(best >= 0, best // nb, -1)
            geo_beam[unserved] = np.where(best >= 0, best % nb, -1)
        gap_s = interruption_s(state.t_s, self.epoch_s, res.state)
        rec = _Record(state.k, state.t_s, res, geo_sat, geo_beam, gap_s, state.n_visible,
                      state.best_snr_db, state.cand_sats)  # fmt: skip
        rec.lit = getattr(state, "lit", None)
        if state.channel is not None:
            rec.channel, rec.open_snr_db = state.channel, state.open_snr_db
            rec.env_cols = state.channel.columns(geo_sat)
        return rec

    def flush(self, state):
        """Evaluate the kept epochs (all in the current motion block) and send them as one
        :class:`~leolink.sim.streams.BlockFrame`."""
        if not self.pending:
            return
        recs, self.pending = self.pending, []
        cols = self._columns(recs, self._links(recs))
        start_s = state.times_s[state.n_warmup]
        events = [r.decision.events for r in recs]
        dwells = [r.decision.dwells for r in recs]
        frame = BlockFrame(recs[0].k - state.n_warmup, np.array([r.t_s for r in recs], float),
                           len(recs[0].geo_sat), cols, _joined(events),
                           _warmup_censored(_joined(dwells), start_s), _ends(events),
                           _ends(dwells))  # fmt: skip
        deliver(self.sink, frame)

    def _links(self, recs):
        """``serve_pairs`` of every UT of every kept epoch, in one call."""
        eng, dec, mb = self.engine, self.decider, self.decider.mb
        n_ut = len(recs[0].geo_sat)
        epochs = np.array([r.k - mb.k0 for r in recs])
        rows = (epochs[:, None] * n_ut + np.arange(n_ut)).reshape(-1)

        def per_row(x):  # a block array's rows (n, ...): all of them, if every epoch is kept
            flat = x.reshape(-1, *x.shape[2:])
            return flat if epochs.size == mb.n_k else take_rows(flat, rows)

        geo_sat = np.concatenate([r.geo_sat for r in recs])
        geo_beam = np.concatenate([r.geo_beam for r in recs])
        served = geo_sat >= 0
        if not served.any():  # no satellite above the mask for any UT of the block
            none = eng.serve_pairs(None, np.full(rows.size, -1), geo_beam, None)
            if self.service is not None:  # the trace's column, as for unserved rows
                none["n_sharing"] = np.zeros(rows.size, np.int64)
            if self.timing is not None:
                none.update({name: np.full(rows.size, np.nan) for name in TIMING_COLUMNS})
            return self._finish(none, geo_beam)
        pl = self._pair_links(rows, geo_sat, served, n_ut)
        up_enu = None if dec.enu is None else per_row(dec.enu)
        lit = None
        if recs[0].lit is not None:  # active beams: the lit beams of each row's satellite
            lit = np.concatenate([r.lit[np.maximum(r.geo_sat, 0)] for r in recs])
            # an outage row's geometry beam (its best, maybe dark) counts as its signal
            lit[np.arange(rows.size), np.maximum(geo_beam, 0)] = True
        rx = self._rx_factor(recs, pl.links, pl.pair)  # fading, the environment's loss
        if pl.rx_lin is not None:
            rx = pl.rx_lin if rx is None else rx * pl.rx_lin
        i_other = self._other_satellites(recs, geo_sat, geo_beam)
        ut_pos = per_row(mb.ut_pos_m)
        cols = eng.serve_pairs(
            pl.links,
            pl.pair,
            geo_beam,
            per_row(mb.ut_vel_m_s),
            per_row(mb.ut_acc_m_s2),
            pl.sat_vel_m_s,
            pl.sat_acc_m_s2,
            rx_fading_lin=rx,
            i_other=i_other,
            ut_pos_m=ut_pos,
            ut_enu=up_enu,
            lit=lit,
        )
        if self.service is not None:
            path = pl.links.path_snr_lin[np.maximum(pl.pair, 0)] * (1.0 if rx is None else rx)
            inputs = dict(ut_pos_m=ut_pos, sat_pos_m=pl.sat_pos_m, sat_vel_m_s=pl.sat_vel_m_s,
                          path_snr_lin=path, i_other=i_other,
                          sat_pos_est_m=pl.sat_pos_est_m,
                          sat_vel_est_m=pl.sat_vel_est_m)  # fmt: skip
            self._share(recs, cols, inputs)
        if self.timing is not None:
            cols.update(self._timing(pl, ut_pos, per_row(mb.ut_vel_m_s), cols["doppler_hz"]))
        return self._finish(cols, geo_beam, pl)

    def _timing(self, pl, ut_pos, ut_vel, doppler):
        """The NTN timing columns of the rows (:mod:`leolink.timing`), NaN without a link."""
        pos = pl.sat_pos_m if pl.sat_pos_est_m is None else pl.sat_pos_est_m
        vel = pl.sat_vel_m_s if pl.sat_vel_est_m is None else pl.sat_vel_est_m
        nan = np.where(pl.pair >= 0, 1.0, np.nan)[:, None]
        return timing_columns(self.timing, ut_pos, ut_vel, (pos * nan, vel * nan), doppler)

    def _pair_links(self, rows, geo_sat, served, n_ut):
        """The links of the rows' (UT, satellite) pairs: those the controller's search
        evaluated, and the rest (e.g. below the mask) evaluated now."""
        dec, mb = self.decider, self.decider.mb
        blk = dec.block
        pair = np.where(served, blk.find_pairs(rows, geo_sat), -1)
        links = blk.links
        miss = np.flatnonzero(served & (pair < 0))
        if miss.size:
            links = Links.concat([links, dec.evaluate(rows[miss], geo_sat[miss])])
            pair[miss] = blk.links.n_pair + np.arange(miss.size)
        epoch, s = rows // n_ut, np.where(served, geo_sat, 0)
        states = (take_rows(x, epoch, s) for x in (mb.sat_pos_m, mb.sat_vel_m_s, mb.sat_acc_m_s2))
        return PairLinks(links, pair, *states)

    def _finish(self, cols, geo_beam, pair_links=None):
        """The columns of the rows (``pair_links`` None: no row has a link)."""
        del geo_beam, pair_links
        return cols

    def _interferer_states(self, j):
        """Position and velocity of every satellite at the block's epoch ``j``."""
        mb = self.decider.mb
        return mb.sat_pos_m[j], mb.sat_vel_m_s[j]

    def _share(self, recs, cols, inputs):
        """Beam sharing and precoding, epoch by epoch (:mod:`leolink.sim.beams.service`)."""
        n_ut = len(recs[0].geo_sat)
        cols["n_sharing"] = np.zeros(len(recs) * n_ut, np.int64)
        for i, rec in enumerate(recs):
            sl = slice(i * n_ut, (i + 1) * n_ut)
            part = {name: v[sl].copy() for name, v in cols.items()}
            res = rec.decision
            served = (res.sat_id >= 0) & (res.service != SERVICE_OUTAGE)
            rec.share = self.service.apply(part, res.sat_id, res.beam_id, served, rec.lit,
                                           lambda sl=sl: {k: None if v is None else v[sl]
                                                          for k, v in inputs.items()})  # fmt: skip
            for name, v in part.items():
                cols[name][sl] = v

    def _rx_factor(self, recs, links, pair):
        """Receive-power factor of each row's path: fading and the environment's loss."""
        fading = self._fading(recs, links, pair)
        if recs[0].env_cols is None:
            return fading
        loss_db = np.concatenate([r.env_cols["extra_loss_db"] for r in recs])
        env_lin = 10.0 ** (-loss_db / 10.0)
        return env_lin if fading is None else fading * env_lin

    def _fading(self, recs, links, pair):
        if self.fading is None or not (pair >= 0).any():
            return None
        rx = np.broadcast_to(links.rx_db, links.ut.shape)[np.maximum(pair, 0)]
        n_lin = 10.0 ** (rx / 10.0)
        # Instantaneous over mean gain (mean 1); the mean receive gain stands in for the
        # LoS gain N, which is off by 1/K = 0.1 in N = 576 for the paper's UPA.
        g = np.concatenate([complex_normal(self.fading.ut_keys, r.k) for r in recs])
        k = self.fading.k
        with np.errstate(divide="ignore", invalid="ignore"):
            return rician_gain_from_draws_lin(n_lin, k, g) / mean_rician_gain_lin(n_lin, k)

    def _other_satellites(self, recs, geo_sat, geo_beam):
        """Interference of the other satellites above the horizon, per row (or None)."""
        eng, mb = self.engine, self.decider.mb
        if not eng.other_satellites:
            return None
        n_ut, out = len(recs[0].geo_sat), []
        u = np.arange(n_ut)
        for i, rec in enumerate(recs):  # one dense snapshot per epoch
            cone, j = rec.cone, rec.k - mb.k0
            sl = slice(i * n_ut, (i + 1) * n_ut)
            if len(cone) <= 1:
                out.append(np.zeros(n_ut))
                continue
            enu = None if self.decider.enu is None else self.decider.enu[j]
            panel = None if self.decider.panel is None else self.decider.panel[j]
            pos, vel = self._interferer_states(j)
            snap = eng.evaluate(mb.ut_pos_m[j], pos[cone], vel[cone], ut_enu=enu,
                                ut_panel=panel, sat_id=cone)  # fmt: skip
            s = np.where(geo_sat[sl] >= 0, np.searchsorted(cone, geo_sat[sl]), 0)
            b = np.where(geo_sat[sl] >= 0, geo_beam[sl], 0)
            if rec.channel is not None:  # each interfering path with its own state
                loss_db = rec.channel.loss_db(np.broadcast_to(cone, (n_ut, len(cone))))
                snap.path_no_rx_lin = snap.path_no_rx_lin * 10.0 ** (-loss_db / 10.0)
            lit = None if rec.lit is None else rec.lit[cone]
            out.append(eng.other_satellites_interference(snap, s, b, u, lit))
        return np.concatenate(out)

    def _columns(self, recs, cols):
        """The trace columns of the kept epochs ``recs`` from their links ``cols`` (rows
        of every UT of each epoch, epoch after epoch)."""
        n_ut, dec = len(recs[0].geo_sat), self.decider
        res = _Joined([r.decision for r in recs], ("service", "sat_id", "beam_id"))
        rec = _Joined(recs, ("gap_s", "n_visible", "best_snr_db", "open_snr_db", "share"))
        service = self.link.service(res.service, cols)
        gap_s = rec.gap_s
        if service is not res.service:  # rows turned to outage (low SINR) lose no time
            gap_s = np.where(service != res.service, 0.0, gap_s)
        outage = service == SERVICE_OUTAGE
        if outage.any():
            for name in _LINK:
                cols[name] = np.where(outage, np.nan, cols[name])
        handover = service == SERVICE_HANDOVER
        served = 1.0 - gap_s / self.epoch_s
        if handover.any():  # the served part of the epoch only
            for name in ("se_bps_hz", "throughput_bps"):
                cols[name] = np.where(handover, cols[name] * served, cols[name])
        # the ACM throughput too is the UT's share of its beam's time
        self.link.add_figures(cols, served if rec.share is None else served * rec.share)
        reason = service.astype(np.int8)  # served -> none, handover -> handover
        reason[outage] = np.where(rec.n_visible[outage] > 0, 3, 2)
        if recs[0].env_cols is not None:
            env = _joined([r.env_cols for r in recs])
            cols.update({k: v for k, v in env.items() if k != "extra_loss_db"})
            # In open country the best beam would have served: the environment blocked it.
            open_ok = rec.open_snr_db >= dec.min_snr_db
            blocked = (res.service == SERVICE_OUTAGE) & open_ok
            reason[blocked] = 4
        mb, n = dec.mb, len(recs)
        j = np.array([r.k for r in recs]) - mb.k0
        cols.update(
            time_s=np.repeat(np.array([r.t_s for r in recs], float), n_ut),
            ut_id=np.tile(np.arange(n_ut, dtype=np.int64), n),
            sat_id=res.sat_id,
            beam_id=res.beam_id,
            lat_deg=np.degrees(mb.ut_lat_rad[j]).reshape(-1),
            lon_deg=np.degrees(mb.ut_lon_rad[j]).reshape(-1),
            service=service,
            outage_reason=reason,
            n_visible=rec.n_visible.astype(np.int64),
            best_snr_db=rec.best_snr_db,
            alt_m=mb.ut_alt_m[j].reshape(-1),
            population=self._population(n),
            interruption_s=gap_s,
            delay_s=propagation_delay_s(cols["slant_range_m"]),
            delay_rate_s_s=delay_rate_from_doppler_s_s(cols["doppler_hz"], self.freq_hz),
        )
        return cols

    def _population(self, n_epoch):
        """The population of every row of ``n_epoch`` epochs: the same array for the same
        length (the writers' codes of a string column are kept for the array last seen)."""
        if n_epoch not in self._tiled:
            self._tiled[n_epoch] = np.tile(self.population, n_epoch)
        return self._tiled[n_epoch]


class _Joined:
    """The named per-UT arrays of several epochs' records, joined epoch after epoch (an
    attribute that is None in the records is None)."""

    def __init__(self, items, names):
        for name in names:
            if getattr(items[0], name) is None:
                setattr(self, name, None)
                continue
            setattr(self, name, np.concatenate([getattr(item, name) for item in items]))


def _joined(tables):
    """Dicts of 1-D arrays with the same keys, joined in order (the empty ones left out:
    most epochs have no event; the empty tables have the dtypes of full ones)."""
    full = [t for t in tables if len(next(iter(t.values())))] or tables[:1]
    return {k: np.concatenate([np.asarray(t[k]) for t in full]) for k in tables[0]}


def _ends(tables):
    """End of each table's rows in :func:`_joined` ``(tables)``."""
    return np.cumsum([len(next(iter(t.values()))) for t in tables], dtype=np.int64)


def _warmup_censored(dwells, record_start_s):
    """Dwells that began before recording (in the warm-up) are cut by the start: censored."""
    return {
        **dwells,
        "censored_start": dwells["censored_start"] | (dwells["start_s"] < record_start_s),
    }
