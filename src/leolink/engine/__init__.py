"""The link engine: vectorized link evaluation for all UTs, satellites and beams.

:meth:`LinkEngine.evaluate_pairs` turns positions and velocities of ``m`` (UT, satellite)
pairs into their geometry, path SNR and beam kernels (:class:`~leolink.engine.links.Links`);
:meth:`LinkEngine.evaluate` does it for the full ``n_ut x n_sat`` grid (a
:class:`~leolink.engine.links.Snapshot`, arrays ``(n_ut, n_sat, n_beam)``).
:meth:`LinkEngine.serve_pairs` (and ``serve`` on a snapshot) then gives, per UT, everything
about its serving link: gains, losses, SNR, SINR with the serving satellite's other beams
as interference, spectral efficiency, throughput, Doppler and angular speed.

Beam gains are kept beam-major, ``(n_beam, m)``, so every numpy loop runs over the long
pair axis; a DFT beam's gain is a product of an along-track and a cross-track Dirichlet
kernel (paper Sec. 3.2), so only ``n_x + n_y`` kernels are evaluated per direction, not
``2 n_beam``. Every quantity of a pair is an element-wise function of that pair's inputs:
a pair gives bit-for-bit the same numbers whichever other pairs share the call.
No Python loop over UTs, satellites or beams.
"""

from __future__ import annotations

import collections
import functools

import numpy as np

from leolink import compiled
from leolink.antenna.array import dirichlet_coefficients
from leolink.antenna.panel import panel_basis, panel_direction_cosines
from leolink.constants import SPEED_OF_LIGHT_M_S
from leolink.engine import interference
from leolink.engine.links import (
    LinkParams,
    Links,
    Snapshot,
    group_constants_db,
    pair_geometry,
    panel_elevation_of_pairs,
    reuse_colors,
    rows_gain_db,
)
from leolink.engine.steered import kernel_rows, per_beam_steering
from leolink.geometry import azimuth_deg, azimuth_in_frame_deg, azimuth_on_sphere_deg
from leolink.kinematics import kinematics_terms, link_kinematics
from leolink.link.budget import (
    fspl_db,
    noise_power_dbw,
    sinr_lin,
    spectral_efficiency_bps_hz,
    throughput_bps,
)

__all__ = ["SERVE_COLUMNS", "SERVE_GEOMETRY_COLUMNS", "LinkEngine", "LinkParams", "Links"]
__all__ += ["Snapshot", "reuse_colors"]

#: Columns of :meth:`LinkEngine.serve`, one value per UT.
SERVE_COLUMNS = (
    "elevation_deg",
    "slant_range_m",
    "gain_tx_db",
    "gain_rx_db",
    "fspl_db",
    "atm_db",
    "snr_db",
    "sinr_db",
    "se_bps_hz",
    "throughput_bps",
    "doppler_hz",
    "doppler_sat_hz",
    "doppler_ut_hz",
    "doppler_rate_hz_s",
    "angular_speed_deg_s",
)
#: Further per-UT columns of :meth:`LinkEngine.serve`: the satellite's azimuth from the
#: UT, from north clockwise [deg], in the UT's local frame.
SERVE_GEOMETRY_COLUMNS = ("azimuth_deg",)


class LinkEngine:
    """Vectorized link evaluation for one codebook and one terminal antenna.

    Parameters
    ----------
    codebook : leolink.antenna.codebook.Codebook
        Beams (direction cosines in the satellite body frame); all active, each fed
        ``params.ptx_dbw``.
    terminal : leolink.antenna.terminal.TerminalAntenna
        UT antenna, steered at the serving satellite (paper Sec. 4.1).
    params : LinkParams
    atmosphere : leolink.link.atmosphere.AtmosphereModel
        ``atmosphere(elevation_rad) -> loss_db``, broadcasting.
    colors : ndarray of int, shape (n_beam,), optional
        Reuse colour per beam; only beams of the serving beam's colour interfere.
    other_satellites : bool
        Add the beams of every other satellite above the horizon as interference,
        through ``terminal.pattern_lin`` (which must not be None).
    steering : leolink.antenna.steering.SteeringMode, optional
        None (or ideal body-fixed beams): the codebook's lattice; beams that move or have
        quantized phases: one kernel row per beam (:mod:`leolink.engine.steered`).
    """

    def __init__(self, codebook, terminal, params, atmosphere, colors=None, other_satellites=False,
                 steering=None):  # fmt: skip
        self.other_satellites = bool(other_satellites)
        self.codebook, self.terminal = codebook, terminal
        self.params, self.atmosphere = params, atmosphere
        u = np.asarray(codebook.u_xy, dtype=float)
        self.beam_ux, self.beam_ix = np.unique(u[:, 0], return_inverse=True)
        self.beam_uy, self.beam_iy = np.unique(u[:, 1], return_inverse=True)
        n_beam = len(u)
        self.steering = per_beam_steering(steering)
        self.beam_ix, self.beam_iy = kernel_rows(self.steering, self.beam_ix, self.beam_iy)
        self.colors = np.zeros(n_beam, np.int64) if colors is None else np.asarray(colors)
        self.n_colors = int(self.colors.max()) + 1
        # Each colour has 1/n_colors of the band: less noise, less throughput.
        self.bandwidth_hz = params.bandwidth_hz / self.n_colors
        self.noise_dbw = float(noise_power_dbw(params.noise_temp_dbk, self.bandwidth_hz))
        # SNR per unit TX gain = K / rho^2 x G_rx / L_atm (Eq. of RSS and FSPL, in watts).
        k_db = params.ptx_dbw - params.cable_loss_db - params.other_loss_db - self.noise_dbw
        self._k_lin = (
            10.0 ** (k_db / 10.0) / (4.0 * np.pi * params.freq_hz / SPEED_OF_LIGHT_M_S) ** 2
        )
        self._rx_const = self._rx_groups = None
        if terminal.elevation_independent:
            self._rx_const = float(terminal.gain_db(np.pi / 2))
        elif getattr(terminal, "group", None) is not None:  # per-population antennas
            self._rx_groups = group_constants_db(terminal)
        self._atm_const = atmosphere.constant_db

    @property
    def n_beam(self) -> int:
        return len(self.beam_ix)

    @property
    def k_lin(self) -> float:
        """SNR per unit TX gain at 1 m, before ``G_rx / L_atm``: ``SNR = k_lin G_tx G_rx /
        (L_atm rho^2)`` (linear; the candidate pruning's bound)."""
        return self._k_lin

    @functools.cached_property
    def kernel_coefficients(self):
        """:func:`~leolink.antenna.array.dirichlet_coefficients` of the x and y beam cosines
        (the compiled pair loop's, :func:`leolink.engine.links._pair_rows`)."""
        cb = self.codebook
        cx = dirichlet_coefficients(self.beam_ux, cb.n_sub_x)
        return cx, dirichlet_coefficients(self.beam_uy, cb.n_sub_y)

    def evaluate(self, ut_pos_m, sat_pos_m, sat_vel_m_s, ut_enu=None, ut_panel=None,
                 sat_id=None):  # fmt: skip
        """Geometry, gains and SNR for every (UT, satellite, beam).

        Parameters
        ----------
        ut_pos_m : ndarray, shape (n_ut, 3)
        sat_pos_m, sat_vel_m_s : ndarray, shape (n_sat, 3)
            Same Earth-centred frame as ``ut_pos_m``.
        ut_enu : ndarray, shape (n_ut, 3, 3), optional
            Each UT's local east, north, up rows (the WGS 84 frame of geodetic UTs):
            elevations, azimuths and panel frames use them. None: the sphere's radial up.
        sat_id : ndarray of int, shape (n_sat,), optional
            Global satellite ids (cells of re-steered beams); None: row = id.
        ut_panel : ndarray, shape (n_ut, 3, 3), optional
            Turned or tilted panels (rows x, y, normal): terminal gains take the angle above
            the panel plane, other satellites' cosines these rows. None: flat, x east.

        Returns
        -------
        Snapshot
        """
        n_ut, n_sat = len(ut_pos_m), len(sat_pos_m)
        ut = np.tile(np.arange(n_ut), n_sat)  # satellite-major grid: p = s n_ut + u
        sat = np.repeat(np.arange(n_sat), n_ut)
        up = None if ut_enu is None else ut_enu[:, 2, :]
        normal = None if ut_panel is None else ut_panel[:, 2, :]
        links = self.evaluate_pairs(ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, up, None, normal,
                                    sat_id=sat_id)  # fmt: skip
        snap = Snapshot(self, links, n_ut, n_sat, ut_pos_m, ut_enu)
        if self.other_satellites:
            # Any satellite above the horizon interferes, usable or not: its path without
            # the UT gain, and its direction in the UT panel frame.
            el, rel, rho = snap.elevation_rad, snap.rel_m, snap.slant_range_m
            snap.path_no_rx_lin = np.where(
                el > 0.0, snap.path_lin / 10.0 ** (snap.rx_db / 10.0), 0.0
            )
            basis = panel_basis(ut_pos_m) if ut_enu is None else ut_enu
            basis = basis if ut_panel is None else ut_panel
            snap.u_panel = panel_direction_cosines(basis, -rel / rho[..., None])
        return snap

    def evaluate_pairs(self, ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up=None, ut_id=None,
                       ut_normal=None, sat_id=None, steer=None):  # fmt: skip
        """Geometry, path SNR and beam kernels of the pairs ``(ut[p], sat[p])``.

        Parameters
        ----------
        ut_pos_m : ndarray, shape (n_u, 3)
        sat_pos_m, sat_vel_m_s : ndarray, shape (n_s, 3)
            Same Earth-centred frame as ``ut_pos_m``.
        ut, sat : ndarray of int, shape (m,)
            Rows of the UT and satellite arrays of each pair.
        ut_up : ndarray, shape (n_u, 3), optional
            Each UT row's local up (the WGS 84 normal); None: the sphere's radial up.
        ut_id : ndarray of int, shape (n_u,), optional
            The UT of each UT row, for per-population terminals; None: row = UT.
        ut_normal : ndarray, shape (n_u, 3), optional
            Each UT row's panel normal: the terminal gain takes the angle above the panel
            plane (visibility and atmosphere the elevation). None: panels lying flat.
        sat_id, steer : ndarray of int (n_s,), and (pos, vel) each (n_s, 3), optional
            Global satellite ids (None: row = id); the states re-steered beams are steered
            by (None: the true ones).

        Returns
        -------
        Links
        """
        rel, rho2, rho, elevation, visible, kx, ky = pair_geometry(
            self, ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up, sat_id, steer
        )
        rx_db = self._rx_const
        if rx_db is None:
            rows = ut if ut_id is None else ut_id[ut]
            el_rx = elevation
            if ut_normal is not None:  # tilted panels: the angle above the panel plane
                el_rx = panel_elevation_of_pairs(rel, rho, ut_normal, ut)
            rx_db = rows_gain_db(self.terminal, el_rx, rows, self._rx_groups)
        atm_db = self._atm_const
        if atm_db is None:
            atm_db = self.atmosphere(np.maximum(elevation, 0.0))
        path = self._k_lin / rho2 * 10.0 ** ((rx_db - atm_db) / 10.0)
        return Links(ut, sat, rel, rho, elevation, visible, path, kx, ky, rx_db)

    def serve(
        self,
        snap,
        sat_idx,
        beam_idx,
        ut_vel_m_s,
        ut_acc_m_s2,
        sat_vel_m_s,
        sat_acc_m_s2,
        rx_fading_lin=None,
    ):
        """Per-UT link on its serving (satellite, beam) of a :class:`Snapshot`.

        Parameters
        ----------
        snap : Snapshot
        sat_idx, beam_idx : ndarray of int, shape (n_ut,)
            Serving satellite (index into this epoch's satellites) and beam; -1 = none.
        ut_vel_m_s, ut_acc_m_s2 : ndarray, shape (n_ut, 3)
        sat_vel_m_s, sat_acc_m_s2 : ndarray, shape (n_sat, 3)
        rx_fading_lin : ndarray, shape (n_ut,), optional
            Multiplies the receive power (signal and interference alike): instantaneous
            Rician draw over its mean. None = the paper's mean gain.

        Returns
        -------
        dict of ndarray, shape (n_ut,)
            :meth:`serve_pairs`; NaN where ``sat_idx < 0``.
        """
        n_ut, n_sat = snap.n_ut, snap.n_sat
        if n_sat == 0:
            return self.serve_pairs(None, np.full(n_ut, -1), beam_idx, ut_vel_m_s)
        served = sat_idx >= 0
        u = np.arange(n_ut)
        s = np.where(served, sat_idx, 0)
        b = np.where(served, beam_idx, 0)
        i_other = None
        if self.other_satellites and n_sat > 1:
            i_other = self.other_satellites_interference(snap, s, b, u)
        return self.serve_pairs(
            snap.links,
            np.where(served, s * n_ut + u, -1),
            beam_idx,
            ut_vel_m_s,
            ut_acc_m_s2,
            sat_vel_m_s[s],
            sat_acc_m_s2[s],
            rx_fading_lin=rx_fading_lin,
            i_other=i_other,
            ut_pos_m=snap.ut_pos_m,
            ut_enu=snap.ut_enu,
        )

    def serve_pairs(
        self,
        links,
        pair,
        beam_idx,
        ut_vel_m_s,
        ut_acc_m_s2=None,
        sat_vel_m_s=None,
        sat_acc_m_s2=None,
        rx_fading_lin=None,
        i_other=None,
        ut_pos_m=None,
        ut_enu=None,
        lit=None,
    ):
        """Link figures of ``n`` rows, row ``i`` served by pair ``pair[i]``, beam ``beam_idx[i]``.

        Parameters
        ----------
        links : Links or None
        pair : ndarray of int, shape (n,)
            Pair of each row; -1 = no link (every column NaN).
        beam_idx : ndarray of int, shape (n,)
        ut_vel_m_s, ut_acc_m_s2 : ndarray, shape (n, 3)
            Each row's UT velocity and acceleration.
        sat_vel_m_s, sat_acc_m_s2 : ndarray, shape (n, 3)
            Each row's satellite velocity and acceleration.
        rx_fading_lin : ndarray, shape (n,), optional
            Multiplies the receive power (signal and interference alike).
        i_other : ndarray, shape (n,), optional
            Interference from other satellites, over the noise (linear).
        ut_pos_m, ut_enu : ndarray, shapes (n, 3) and (n, 3, 3)
            Each row's UT position, and its local east, north, up rows (None: the
            sphere's, from the position): the azimuth.
        lit : ndarray of bool, shape (n, n_beam), optional
            The beams the row's satellite lights (active beams): only they interfere.
            None: every beam (the default path, and the fused kernel's).

        Returns
        -------
        dict of ndarray, shape (n,)
            ``SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS`` (SI, dB; angular speed in deg/s).
        """
        n = pair.shape[0]
        served = pair >= 0
        if links is None or links.n_pair == 0:
            return {name: np.full(n, np.nan) for name in SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS}
        pr = np.where(served, pair, 0)
        b = np.where(served, beam_idx, 0)
        if lit is None and self._full_reuse_lattice and compiled.use(n):
            rows = _ServeRows(served, pr, b, ut_vel_m_s, sat_vel_m_s, sat_acc_m_s2 - ut_acc_m_s2,
                              rx_fading_lin, i_other, ut_pos_m, ut_enu)  # fmt: skip
            return self._serve_compiled(links, rows)
        # Flat gathers: several times faster than fancy indexing with 3 index arrays.
        kx, ky = links.kx[:, pr], links.ky[:, pr]
        g_sig = kx[self.beam_ix[b], np.arange(n)] * ky[self.beam_iy[b], np.arange(n)]
        g_int = self._same_colour_total(kx, ky, b, lit) - g_sig
        path = links.path_snr_lin[pr]
        if rx_fading_lin is not None:
            path = path * rx_fading_lin
        snr = g_sig * path
        # Eqs. (18)-(19) in units of the noise: I = same-colour beams + other satellites
        sinr = sinr_lin(snr, g_int * path + (0.0 if i_other is None else i_other), 1.0)
        se = spectral_efficiency_bps_hz(sinr)

        rho, elevation = links.slant_range_m[pr], links.elevation_rad[pr]
        los = -links.rel_m[pr]  # UT -> satellite
        kin = link_kinematics(
            los, sat_vel_m_s, ut_vel_m_s, sat_acc_m_s2 - ut_acc_m_s2, self.params.freq_hz
        )
        nan = 1.0 if served.all() else np.where(served, 1.0, np.nan)
        rx_db, atm_db = self._rx_atm_db(links, pr)
        with np.errstate(divide="ignore", invalid="ignore"):
            return {
                "elevation_deg": np.degrees(elevation) * nan,
                "slant_range_m": rho * nan,
                "gain_tx_db": 10.0 * np.log10(g_sig) * nan,
                "gain_rx_db": rx_db * nan,
                "fspl_db": fspl_db(rho, self.params.freq_hz) * nan,
                "atm_db": atm_db * nan,
                "snr_db": 10.0 * np.log10(snr) * nan,
                "sinr_db": 10.0 * np.log10(sinr) * nan,
                "se_bps_hz": se * nan,
                "throughput_bps": throughput_bps(se, self.bandwidth_hz) * nan,
                "doppler_hz": kin["doppler_hz"] * nan,
                "doppler_sat_hz": kin["doppler_sat_hz"] * nan,
                "doppler_ut_hz": kin["doppler_ut_hz"] * nan,
                "doppler_rate_hz_s": kin["doppler_rate_hz_s"] * nan,
                "angular_speed_deg_s": np.degrees(kin["angular_speed_rad_s"]) * nan,
                "azimuth_deg": azimuth_deg(los, ut_pos_m, ut_enu) * nan,
            }

    def _rx_atm_db(self, links, pr):
        """Receive gain and atmospheric loss [dB] of the pairs ``pr`` (n,): the run's
        constants where they are constant; new arrays (the callers write NaN into them)."""
        n = pr.shape[0]
        rx_db = np.full(n, self._rx_const) if self._rx_const is not None else links.rx_db[pr]
        if self._atm_const is not None:
            return rx_db, np.full(n, self._atm_const)
        return rx_db, self.atmosphere(np.maximum(links.elevation_rad[pr], 0.0))

    def _serve_compiled(self, links, rows):
        """:meth:`serve_pairs` of a full-reuse lattice by the compiled :func:`_serve_rows`:
        each row's gathers, gains, SINR, spectral efficiency, kinematics, azimuth and their
        dB and degree columns in one pass (the same physics functions); the receive gain
        and the atmosphere by numpy."""
        n, pr = rows.pair.shape[0], rows.pair
        # (the loop is typed for all cases: an empty array stands for an absent one)
        fading = np.zeros(0) if rows.fading is None else rows.fading
        i_other = np.zeros(n) if rows.i_other is None else np.broadcast_to(rows.i_other, (n,))
        pos = rows.ut_pos_m if rows.ut_enu is None else np.zeros((0, 3))
        enu = np.zeros((0, 3, 3)) if rows.ut_enu is None else rows.ut_enu
        out = np.empty((len(_SERVE_ROWS), n))
        args = ((links.kx, links.ky, self.beam_ix, self.beam_iy),
                (links.path_snr_lin, links.rel_m, links.slant_range_m, links.elevation_rad),
                (rows.served, pr, rows.beam, fading, i_other),
                (rows.sat_vel, rows.ut_vel, rows.rel_acc, pos, enu),
                (float(self.params.freq_hz), float(self.bandwidth_hz)))  # fmt: skip
        compiled.run_rows(_serve_rows, n, *args, out)
        cols = dict(zip(_SERVE_ROWS, out, strict=True))
        cols["gain_rx_db"], cols["atm_db"] = self._rx_atm_db(links, pr)
        if not rows.served.all():
            for name in ("gain_rx_db", "atm_db"):
                cols[name][~rows.served] = np.nan
        return {name: cols[name] for name in SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS}

    @property
    def _full_reuse_lattice(self):
        """Every beam of the lattice, one colour (the same-colour sum's shortcut)."""
        lattice = self.n_beam == len(self.beam_ux) * len(self.beam_uy)
        return self.n_colors == 1 and lattice and self.steering is None

    def other_satellites_interference(self, snap, s, b, u, lit=None):
        """:func:`leolink.engine.interference.other_satellites` of this engine."""
        return interference.other_satellites(self, snap, s, b, u, lit)

    def _same_colour_total(self, kx, ky, b, lit=None):
        return interference.same_colour_total(self, kx, ky, b, lit)


#: :meth:`LinkEngine.serve_pairs`' per-row inputs (n rows): whether served, the pair and
#: beam (0 where not served), the velocities, the relative acceleration, the fading and
#: other-satellite interference (or None), the UT positions and local frames (or None).
_ServeRows = collections.namedtuple("_ServeRows", "served pair beam ut_vel sat_vel rel_acc "
                                    "fading i_other ut_pos_m ut_enu")  # fmt: skip


#: The columns :func:`_serve_rows` writes, in the order of its ``out`` rows.
_SERVE_ROWS = ("gain_tx_db", "snr_db", "sinr_db", "se_bps_hz", "doppler_sat_hz",
               "doppler_ut_hz", "doppler_hz", "doppler_rate_hz_s", "angular_speed_deg_s",
               "azimuth_deg", "elevation_deg", "slant_range_m", "fspl_db",
               "throughput_bps")  # fmt: skip


@compiled.jit
def _serve_rows(kernels, pairs, rows, motion, radio, out, lo, hi):
    """Rows ``lo .. hi - 1`` of :meth:`LinkEngine._serve_compiled` into ``out``
    (:data:`_SERVE_ROWS`, n): TX gain, SNR, SINR (:func:`~leolink.link.budget.sinr_lin`,
    the other beams of the full-reuse lattice ``(sum k_x)(sum k_y) - g`` and the other
    satellites as interference) in dB, spectral efficiency,
    :func:`~leolink.kinematics.kinematics_terms` but the range rate (Doppler of the
    satellite and the UT, total, rate; angular speed [deg/s]), the azimuth (in the ENU rows
    ``enu`` (n, 3, 3), or if empty the sphere's frame at the positions ``pos`` (n, 3)),
    the pair's elevation [deg], slant range, :func:`~leolink.link.budget.fspl_db` and the
    throughput (``radio``: carrier frequency and bandwidth [Hz]); NaN where not served.
    ``fading`` empty: none."""
    kx, ky, beam_ix, beam_iy = kernels
    path_snr_lin, rel_m, slant_range_m, elevation_rad = pairs
    served, pair, beam, fading, i_other = rows
    sat_vel, ut_vel, rel_acc, pos, enu = motion
    freq_hz, bandwidth_hz = radio
    los = np.empty(3)  # UT -> satellite, one row at a time
    for i in range(lo, hi):
        if not served[i]:
            out[:, i] = np.nan
            continue
        p, b = pair[i], beam[i]
        path = path_snr_lin[p] * fading[i] if fading.size else path_snr_lin[p]
        for c in range(3):
            los[c] = -rel_m[p, c]
        g_sig = kx[beam_ix[b], p] * ky[beam_iy[b], p]
        g_all = kx[:, p].sum() * ky[:, p].sum()
        snr = g_sig * path
        sinr = sinr_lin(snr, (g_all - g_sig) * path + i_other[i], 1.0)
        d_sat, d_ut, d, rate, _, angular = kinematics_terms(
            los, sat_vel[i], ut_vel[i], rel_acc[i], freq_hz
        )
        if enu.shape[0] == 0:
            azimuth = azimuth_on_sphere_deg(los, pos[i])
        else:
            azimuth = azimuth_in_frame_deg(los, enu[i])
        se = spectral_efficiency_bps_hz(sinr)
        out[0, i], out[1, i] = 10.0 * np.log10(g_sig), 10.0 * np.log10(snr)
        out[2, i], out[3, i] = 10.0 * np.log10(sinr), se
        out[4, i], out[5, i], out[6, i], out[7, i] = d_sat, d_ut, d, rate
        out[8, i], out[9, i] = np.degrees(angular), azimuth
        out[10, i], out[11, i] = np.degrees(elevation_rad[p]), slant_range_m[p]
        out[12, i] = fspl_db(slant_range_m[p], freq_hz)
        out[13, i] = throughput_bps(se, bandwidth_hz)
