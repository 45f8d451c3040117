"""The link engine: one vectorized call per epoch for all UTs, satellites and beams.

``LinkEngine.evaluate`` turns positions and velocities into the per (UT, satellite, beam)
SNR that the beam controller needs; ``LinkEngine.serve`` then gives, per UT, everything
about its serving link: gains, losses, SNR, SINR with the serving satellite's other
beams as interference, spectral efficiency, throughput, Doppler and angular speed.

Public arrays are ``(n_ut, n_sat, n_beam)``. Inside, beam gains are kept beam-major,
``(n_beam, n_sat, n_ut)``, so every numpy loop runs over the long UT axis; a DFT beam's
gain is a product of an along-track and a cross-track Dirichlet kernel (paper Sec. 3.2),
so only ``n_x + n_y`` kernels are evaluated per direction, not ``2 n_beam``.
No Python loop over UTs, satellites or beams.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from leolink.antenna.array import dirichlet_kernels
from leolink.antenna.panel import panel_basis, panel_direction_cosines
from leolink.constants import SPEED_OF_LIGHT_M_S
from leolink.geometry import body_frame, ecef_to_geodetic, enu_basis
from leolink.kinematics import link_kinematics
from leolink.link.budget import fspl_db, noise_power_dbw

__all__ = ["SERVE_COLUMNS", "SERVE_GEOMETRY_COLUMNS", "LinkEngine", "LinkParams", "Snapshot"]
__all__ += ["reuse_colors"]

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


@dataclass(frozen=True)
class LinkParams:
    """Scalars of the link budget (paper's Table).

    ``ptx_dbw`` is the power of one beam (one RF chain), as in the paper.
    """

    freq_hz: float
    bandwidth_hz: float
    ptx_dbw: float
    cable_loss_db: float
    noise_temp_dbk: float
    min_elevation_rad: float


@dataclass
class Snapshot:
    """What :meth:`LinkEngine.evaluate` computed for one epoch.

    Attributes
    ----------
    engine : LinkEngine
        The engine that computed it (beam lattice indices).
    rel_m : ndarray, shape (n_ut, n_sat, 3)
        Satellite -> UT vector [m].
    slant_range_m, elevation_rad : ndarray, shape (n_ut, n_sat)
    visible : ndarray of bool, shape (n_ut, n_sat)
        Above the minimum elevation.
    path_snr_lin : ndarray, shape (n_ut, n_sat)
        SNR per unit transmit gain (NaN where not visible).
    kx, ky : ndarray, shapes (n_kx, n_sat, n_ut) and (n_ky, n_sat, n_ut)
        Along- and cross-track Dirichlet kernels of the distinct beam cosines.
    rx_db : ndarray, shape (n_ut, n_sat), or float
        UT receive gain towards each satellite [dB].
    path_no_rx_lin, u_panel : ndarray or None
        With other-satellite interference: the path without the UT gain, (n_ut, n_sat),
        zero below the horizon; each satellite's direction in the UT panel's cosines,
        (n_ut, n_sat, 2).
    ut_pos_m : ndarray, shape (n_ut, 3), or None
    ut_enu : ndarray, shape (n_ut, 3, 3), or None
        The UTs' local east, north, up rows when given to :meth:`LinkEngine.evaluate`
        (WGS 84); None: the sphere's, from the positions.
    """

    engine: LinkEngine = field(repr=False)
    rel_m: np.ndarray
    slant_range_m: np.ndarray
    elevation_rad: np.ndarray
    visible: np.ndarray
    path_snr_lin: np.ndarray
    kx: np.ndarray
    ky: np.ndarray
    rx_db: np.ndarray | float
    path_no_rx_lin: np.ndarray | None = None
    u_panel: np.ndarray | None = None
    ut_pos_m: np.ndarray | None = None
    ut_enu: np.ndarray | None = None

    @cached_property
    def gain_tx_bm(self):
        """Beam-major linear TX gains, shape (n_beam, n_sat, n_ut)."""
        e = self.engine
        return self.kx[e.beam_ix] * self.ky[e.beam_iy]

    @property
    def snr_lin_bm(self):
        """Beam-major linear SNR, shape (n_beam, n_sat, n_ut); NaN where not visible."""
        return self.gain_tx_bm * self.path_snr_lin.T

    @property
    def gain_tx_lin(self):
        """Linear TX gain of every beam, shape (n_ut, n_sat, n_beam)."""
        return self.gain_tx_bm.transpose(2, 1, 0)

    @cached_property
    def snr_db(self):
        """SNR of every beam [dB], shape (n_ut, n_sat, n_beam); NaN where not visible.

        ``10 log10(k_x k_y p) = 10 log10 k_x + 10 log10 k_y + 10 log10 p``: only the
        ``n_x + n_y`` kernels take a logarithm, not the ``n_beam`` products.
        """
        e = self.engine
        with np.errstate(divide="ignore"):
            lx, ly = 10.0 * np.log10(self.kx), 10.0 * np.log10(self.ky)
            path_db = 10.0 * np.log10(self.path_snr_lin.T)
        out = lx[e.beam_ix] + ly[e.beam_iy] + path_db
        return out.transpose(2, 1, 0)

    @property
    def gain_rx_db(self):
        return np.broadcast_to(self.rx_db, self.slant_range_m.shape)


def reuse_colors(lattice_ij, n_colors):
    """Frequency-reuse colour of each beam from its lattice indices (i, j).

    1 colour: full reuse (the paper). 4 colours: a 2 x 2 pattern, so that no two
    neighbours along an axis share a carrier. 3 colours: (i + 2 j) mod 3, the classic
    3-colour tiling of a lattice where no two edge neighbours share a colour.
    Each colour gets ``1 / n_colors`` of the bandwidth.
    """
    i, j = np.asarray(lattice_ij).T
    if n_colors == 1:
        return np.zeros(i.shape, dtype=np.int64)
    if n_colors == 4:
        return (i % 2) * 2 + (j % 2)
    if n_colors == 3:
        return (i + 2 * j) % 3
    raise ValueError(f"reuse_colors = {n_colors!r} is not allowed; use 1, 3 or 4")


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
    """

    def __init__(self, codebook, terminal, params, atmosphere, colors=None, other_satellites=False):
        self.other_satellites = bool(other_satellites)
        self.codebook, self.terminal = codebook, terminal
        self.params, self.atmosphere = params, atmosphere
        u = np.asarray(codebook.u_xy, dtype=float)
        self.beam_ux, self.beam_ix = np.unique(u[:, 0], return_inverse=True)
        self.beam_uy, self.beam_iy = np.unique(u[:, 1], return_inverse=True)
        n_beam = len(u)
        self.colors = np.zeros(n_beam, np.int64) if colors is None else np.asarray(colors)
        self.n_colors = int(self.colors.max()) + 1
        # Each colour has 1/n_colors of the band: less noise, less throughput.
        self.bandwidth_hz = params.bandwidth_hz / self.n_colors
        self.noise_dbw = float(noise_power_dbw(params.noise_temp_dbk, self.bandwidth_hz))
        # SNR per unit TX gain = K / rho^2 x G_rx / L_atm (Eq. of RSS and FSPL, in watts).
        k_db = params.ptx_dbw - params.cable_loss_db - self.noise_dbw
        self._k_lin = (
            10.0 ** (k_db / 10.0) / (4.0 * np.pi * params.freq_hz / SPEED_OF_LIGHT_M_S) ** 2
        )
        self._rx_const = None
        if terminal.elevation_independent:
            self._rx_const = float(terminal.gain_db(np.pi / 2))
        self._atm_const = atmosphere.constant_db

    @property
    def n_beam(self) -> int:
        return len(self.beam_ix)

    def evaluate(self, ut_pos_m, sat_pos_m, sat_vel_m_s, ut_enu=None):
        """Geometry, gains and SNR for every (UT, satellite, beam).

        Parameters
        ----------
        ut_pos_m : ndarray, shape (n_ut, 3)
        sat_pos_m, sat_vel_m_s : ndarray, shape (n_sat, 3)
            Same Earth-centred frame as ``ut_pos_m``.
        ut_enu : ndarray, shape (n_ut, 3, 3), optional
            Each UT's local east, north, up rows (the WGS 84 frame of geodetic UTs):
            elevations, azimuths and panel frames use them. None: the sphere's radial up.

        Returns
        -------
        Snapshot
        """
        p = self.params
        rel = ut_pos_m[:, None, :] - sat_pos_m[None, :, :]  # satellite -> UT, (n_ut, n_sat, 3)
        rho2 = np.einsum("usk,usk->us", rel, rel)
        rho = np.sqrt(rho2)
        if ut_enu is None:
            r_ut = np.sqrt(np.einsum("uk,uk->u", ut_pos_m, ut_pos_m))
            sin_el = -np.einsum("usk,uk->us", rel, ut_pos_m) / (rho * r_ut[:, None])
        else:
            sin_el = -np.einsum("usk,uk->us", rel, ut_enu[:, 2, :]) / rho
        elevation = np.arcsin(np.clip(sin_el, -1.0, 1.0))
        visible = elevation >= p.min_elevation_rad

        axes = body_frame(sat_pos_m, sat_vel_m_s)  # (n_sat, 3, 3) rows u_x, u_y, u_z
        inv_rho = 1.0 / rho.T  # (n_sat, n_ut)
        ux = np.einsum("usk,sk->su", rel, axes[:, 0, :]) * inv_rho
        uy = np.einsum("usk,sk->su", rel, axes[:, 1, :]) * inv_rho
        n_sat, n_ut = ux.shape
        kx = dirichlet_kernels(ux.ravel(), self.beam_ux, self.codebook.n_sub_x)
        ky = dirichlet_kernels(uy.ravel(), self.beam_uy, self.codebook.n_sub_y)
        kx = kx.reshape(len(self.beam_ux), n_sat, n_ut)
        ky = ky.reshape(len(self.beam_uy), n_sat, n_ut)

        rx_db = self._rx_const
        if rx_db is None:
            rx_db = self.terminal.gain_db(elevation)
        atm_db = self._atm_const
        if atm_db is None:
            atm_db = self.atmosphere(np.maximum(elevation, 0.0))
        path = self._k_lin / rho2 * 10.0 ** ((rx_db - atm_db) / 10.0)
        snap = Snapshot(
            self, rel, rho, elevation, visible, np.where(visible, path, np.nan), kx, ky, rx_db
        )
        snap.ut_pos_m, snap.ut_enu = ut_pos_m, ut_enu
        if self.other_satellites:
            # Any satellite above the horizon interferes, usable or not: its path without
            # the UT gain, and its direction in the UT panel frame.
            snap.path_no_rx_lin = np.where(elevation > 0.0, path / 10.0 ** (rx_db / 10.0), 0.0)
            basis = panel_basis(ut_pos_m) if ut_enu is None else ut_enu
            snap.u_panel = panel_direction_cosines(basis, -rel / rho[..., None])
        return snap

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
        """Per-UT link on its serving (satellite, beam); NaN where ``sat_idx < 0``.

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
            Trace columns (SI, dB; angular speed in deg/s).
        """
        _, n_sat, n_ut = snap.kx.shape
        if n_sat == 0:  # no satellite to serve anyone this epoch
            return {name: np.full(n_ut, np.nan) for name in SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS}
        served = sat_idx >= 0
        u = np.arange(n_ut)
        s = np.where(served, sat_idx, 0)
        b = np.where(served, beam_idx, 0)
        us = u * n_sat + s  # flat index into (n_ut, n_sat) arrays
        su = s * n_ut + u  # flat index into (n_sat, n_ut) arrays
        # Flat gathers: several times faster than fancy indexing with 3 index arrays.
        plane = n_sat * n_ut
        g_sig = (
            snap.kx.reshape(-1)[self.beam_ix[b] * plane + su]
            * snap.ky.reshape(-1)[self.beam_iy[b] * plane + su]
        )
        g_int = self._same_colour_total(snap, s, b, u, su) - g_sig
        path = snap.path_snr_lin.reshape(-1)[us]
        if rx_fading_lin is not None:
            path = path * rx_fading_lin
        snr = g_sig * path
        i_other = 0.0
        if self.other_satellites and n_sat > 1:
            i_other = self._other_satellites_interference(snap, s, b, u)
        sinr = snr / (g_int * path + i_other + 1.0)  # S / (I + N), Eqs. (18)-(19), over N
        se = np.log1p(sinr) / np.log(2.0)  # log2(1 + SINR), accurate at low SINR

        rho = snap.slant_range_m.reshape(-1)[us]
        elevation = snap.elevation_rad.reshape(-1)[us]
        kin = link_kinematics(
            -snap.rel_m.reshape(-1, 3)[us],
            sat_vel_m_s[s],
            ut_vel_m_s,
            sat_acc_m_s2[s] - ut_acc_m_s2,
            self.params.freq_hz,
        )
        nan = 1.0 if served.all() else np.where(served, 1.0, np.nan)
        if self._rx_const is not None:
            rx_db = np.full(n_ut, self._rx_const)
        else:
            rx_db = snap.gain_rx_db.reshape(-1)[us]
        if self._atm_const is not None:
            atm_db = np.full(n_ut, self._atm_const)
        else:
            atm_db = self.atmosphere(np.maximum(elevation, 0.0))
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
                "throughput_bps": se * (self.bandwidth_hz * nan),
                "doppler_hz": kin["doppler_hz"] * nan,
                "doppler_sat_hz": kin["doppler_sat_hz"] * nan,
                "doppler_ut_hz": kin["doppler_ut_hz"] * nan,
                "doppler_rate_hz_s": kin["doppler_rate_hz_s"] * nan,
                "angular_speed_deg_s": np.degrees(kin["angular_speed_rad_s"]) * nan,
                "azimuth_deg": self._azimuth_deg(snap, us) * nan,
            }

    @staticmethod
    def _azimuth_deg(snap, us):
        """Azimuth of each UT's link (flat index ``us`` into (n_ut, n_sat)) [deg], [0, 360)."""
        los = -snap.rel_m.reshape(-1, 3)[us]  # UT -> satellite
        enu = snap.ut_enu
        if enu is None:
            lat, lon, _ = ecef_to_geodetic(snap.ut_pos_m)
            enu = enu_basis(lat, lon)
        east = np.einsum("uk,uk->u", los, enu[:, 0, :])
        north = np.einsum("uk,uk->u", los, enu[:, 1, :])
        return np.mod(np.degrees(np.arctan2(east, north)), 360.0)

    def _other_satellites_interference(self, snap, s, b, u):
        """Interference over noise from the beams of the other satellites, per UT.

        Their beams of the serving beam's colour, at full power, seen through the UT
        antenna pointed at the serving satellite (``terminal.pattern_lin``).
        """
        bm = snap.gain_tx_bm  # (n_beam, n_sat, n_ut)
        same = (self.colors[None, :] == self.colors[b][:, None]).astype(float)  # (n_ut, n_beam)
        tx = np.einsum("bsu,ub->us", bm, same)  # same-colour TX gain of each satellite
        du = snap.u_panel - snap.u_panel[u, s][:, None, :]
        rx = self.terminal.pattern_lin(du[..., 0], du[..., 1])  # (n_ut, n_sat)
        contrib = tx * rx * snap.path_no_rx_lin
        contrib[u, s] = 0.0  # the serving satellite is counted by _same_colour_total
        return contrib.sum(axis=1)

    def _same_colour_total(self, snap, s, b, u, su):
        """Sum of the TX gains of the beams that share the serving beam's colour."""
        if self.n_colors == 1 and self.n_beam == len(self.beam_ux) * len(self.beam_uy):
            # Full lattice, full reuse: sum_ij kx_i ky_j = (sum_i kx_i)(sum_j ky_j).
            return snap.kx.sum(axis=0).reshape(-1)[su] * snap.ky.sum(axis=0).reshape(-1)[su]
        g = snap.gain_tx_bm[:, s, u].T  # (n_ut, n_beam)
        same = self.colors[None, :] == self.colors[b][:, None]
        return np.einsum("ub,ub->u", g, same)
