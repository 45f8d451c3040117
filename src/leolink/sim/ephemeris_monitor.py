"""The monitor of a run with ephemeris errors: links on the true states, choices on the estimate.

With an estimated ephemeris (:mod:`leolink.ephemeris_error`), the controller's candidate
tables (:class:`~leolink.sim.decide.Decider`) are computed from the satellite states it
believes; :class:`TrueLinkMonitor` evaluates each UT's chosen (satellite, beam) on the true
states instead of reusing the controller's pairs:

- the satellite's beams are where they are in its true body frame; re-steered beams are
  steered by the believed state (``LinkEngine.evaluate_pairs(..., steer=...)``): the
  satellite mispoints them;
- the UT's antenna points at the believed satellite position: the angle between the
  believed and the true directions is its pointing error, whose loss
  ``G(el, 0) - G(el, error, azimuth)`` through the terminal pattern multiplies the receive
  power (signal and the same satellite's interference alike) and is in ``gain_rx_db``;
- Doppler and angular speed are the true ones.

Extra frame columns (not in the trace; :mod:`leolink.io.ephemeris_sink` writes them):
``true_best_beam_id`` (the best beam of the chosen satellite on the true geometry),
``wrong_beam`` (1.0 where it is not the chosen beam, NaN without a link),
``snr_loss_db`` (the true best beam's SNR with ideal pointing minus the served SNR),
``pointing_error_deg``, ``pointing_loss_db`` and ``position_error_m`` (believed minus true
satellite position).
"""

from __future__ import annotations

import numpy as np

from leolink.engine.links import panel_elevation_of_pairs
from leolink.sim.monitor import Monitor, PairLinks

__all__ = ["EPHEMERIS_COLUMNS", "TrueLinkMonitor", "pointing_error"]

EPHEMERIS_COLUMNS = (
    "true_best_beam_id",
    "wrong_beam",
    "snr_loss_db",
    "pointing_error_deg",
    "pointing_loss_db",
    "position_error_m",
)


def pointing_error(ut_pos_m, ut_up, true_sat_m, est_sat_m):
    """Angle between the UT's believed and true satellite directions, and its azimuth.

    Parameters
    ----------
    ut_pos_m, ut_up, true_sat_m, est_sat_m : ndarray, shape (n, 3)
        UT position, its local up (unit), true and believed satellite positions [m].

    Returns
    -------
    off_rad, psi_rad : ndarray, shape (n,)
        The angle [rad], and its direction around the true direction (0: towards higher
        elevation, pi/2: to the left seen from the UT; the convention of
        :func:`leolink.antenna.panel.pointing_offsets`).
    """
    t = true_sat_m - ut_pos_m
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    e = est_sat_m - ut_pos_m
    e /= np.linalg.norm(e, axis=-1, keepdims=True)
    off = np.arctan2(np.linalg.norm(np.cross(e, t), axis=-1), np.einsum("nk,nk->n", e, t))
    e_el = ut_up - np.einsum("nk,nk->n", ut_up, t)[:, None] * t
    e_el /= np.linalg.norm(e_el, axis=-1, keepdims=True)
    e_left = np.cross(e_el, t)
    d = e - t
    psi = np.arctan2(np.einsum("nk,nk->n", d, e_left), np.einsum("nk,nk->n", d, e_el))
    return off, psi


def _terminal_gain_db(terminal, elevation, off, psi, ut_id):
    """``terminal.gain_db(el, off, psi)`` of rows of UTs ``ut_id`` (per-population too)."""
    groups = getattr(terminal, "group", None)
    if groups is None:
        return terminal.gain_db(elevation, off, psi)
    out, group = np.empty(elevation.shape), groups[ut_id]
    for g, term in enumerate(terminal.terminals):
        rows = group == g
        out[rows] = term.gain_db(elevation[rows], off[rows], psi[rows])
    return out


class TrueLinkMonitor(Monitor):
    """:class:`~leolink.sim.monitor.Monitor` whose links are evaluated on the true states.

    ``true_ephemeris``: ``t -> (pos, vel, acc)`` of the true satellites (the decider's
    motion blocks carry the believed ones).
    """

    def __init__(self, *args, true_ephemeris, **kw):
        super().__init__(*args, **kw)
        self.true_ephemeris = true_ephemeris
        self._true = (None, None)

    def _true_block(self, mb):
        """True satellite states (pos, vel, acc), each (n_k, n_sat, 3), of the block."""
        if self._true[0] != mb.k0:
            self._true = (mb.k0, self.true_ephemeris(self.decider.motion.times_s[mb.k0 : mb.k1]))
        return self._true[1]

    def _pair_links(self, rows, geo_sat, served, n_ut):
        """The rows' links on the true states, beams steered and the UT antenna pointed
        by the believed ones; the pointing loss is the rows' receive factor."""
        eng, dec = self.engine, self.decider
        mb = dec.mb
        t_pos, t_vel, t_acc = self._true_block(mb)
        epoch, s = rows // n_ut, np.where(served, geo_sat, 0)
        pos = mb.ut_pos_m.reshape(-1, 3)[rows]
        enu = None if dec.enu is None else dec.enu.reshape(-1, 3, 3)[rows]
        up = pos / np.linalg.norm(pos, axis=-1, keepdims=True) if enu is None else enu[:, 2]
        est_pos, est_vel = mb.sat_pos_m[epoch, s], mb.sat_vel_m_s[epoch, s]
        n, ut_id = rows.size, rows % n_ut
        normal = None if dec.panel is None else dec.panel.reshape(-1, 3, 3)[rows][:, 2]
        links = eng.evaluate_pairs(
            pos, t_pos[epoch, s], t_vel[epoch, s], np.arange(n), np.arange(n),
            ut_up=None if enu is None else up, ut_id=ut_id, ut_normal=normal, sat_id=s,
            steer=(est_pos, est_vel),
        )  # fmt: skip
        off, psi = pointing_error(pos, up, t_pos[epoch, s], est_pos)
        el = links.elevation_rad  # the terminal's angle: above the panel plane if tilted
        if normal is not None:
            el = panel_elevation_of_pairs(links.rel_m, links.slant_range_m, normal, np.arange(n))
        with np.errstate(invalid="ignore", divide="ignore"):
            g0 = _terminal_gain_db(eng.terminal, el, np.zeros(n), np.zeros(n), ut_id)
            loss_db = g0 - _terminal_gain_db(eng.terminal, el, off, psi, ut_id)
        pair = np.where(served, np.arange(n), -1)
        extra = dict(served=served, off=off, loss_db=loss_db, dpos=est_pos - t_pos[epoch, s])
        return PairLinks(links, pair, t_pos[epoch, s], t_vel[epoch, s], t_acc[epoch, s],
                         rx_lin=10.0 ** (-loss_db / 10.0), sat_pos_est_m=est_pos,
                         sat_vel_est_m=est_vel, extra=extra)  # fmt: skip

    def _finish(self, cols, geo_beam, pair_links=None):
        if pair_links is None:
            return cols | {name: np.full(cols["snr_db"].size, np.nan) for name in EPHEMERIS_COLUMNS}
        x = pair_links.extra
        cols["gain_rx_db"] = cols["gain_rx_db"] - x["loss_db"]
        return cols | self._diagnostics(pair_links.links, geo_beam, cols, **x)

    def _interferer_states(self, j):
        t_pos, t_vel, _ = self._true_block(self.decider.mb)
        return t_pos[j], t_vel[j]

    def _diagnostics(self, links, beam, cols, served, off, loss_db, dpos):
        """The :data:`EPHEMERIS_COLUMNS` of the rows (NaN without a link)."""
        eng = self.engine
        snr_bm = links.snr_db_bm(eng.beam_ix, eng.beam_iy)  # true, ideal pointing
        with np.errstate(invalid="ignore"):
            best = np.argmax(np.where(np.isnan(snr_bm), -np.inf, snr_bm), axis=0)
        best_db = snr_bm[best, np.arange(best.size)]
        nan = np.where(served, 1.0, np.nan)
        return {
            "true_best_beam_id": np.where(served, best, -1).astype(float),
            "wrong_beam": (best != beam).astype(float) * nan,
            "snr_loss_db": (best_db - cols["snr_db"]) * nan,
            "pointing_error_deg": np.degrees(off) * nan,
            "pointing_loss_db": loss_db * nan,
            "position_error_m": np.linalg.norm(dpos, axis=-1) * nan,
        }
