"""The link engine: one vectorized call per epoch for all UTs, satellites and beams.

``LinkEngine.evaluate`` turns positions and velocities into the per (UT, satellite, beam)
SNR that the beam controller needs; ``LinkEngine.serve`` then gives, per UT, everything
about its serving link: gains, losses, SNR, SINR with the serving satellite's other
beams as interference, spectral efficiency, throughput, Doppler and angular speed.

Axis order is ``(n_ut, n_sat, n_beam)``; no Python loop over UTs, satellites or beams.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from leolink import kinematics
from leolink.geometry import body_frame
from leolink.link.budget import fspl_db, noise_power_dbw

__all__ = ["LinkEngine", "LinkParams", "Snapshot", "reuse_colors"]


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

    @property
    def noise_dbw(self) -> float:
        return float(noise_power_dbw(self.noise_temp_dbk, self.bandwidth_hz))


@dataclass
class Snapshot:
    """What ``evaluate`` computed for one epoch (arrays over (n_ut, n_sat[, n_beam]))."""

    rel_m: np.ndarray  # (n_ut, n_sat, 3) satellite -> UT vector
    slant_range_m: np.ndarray  # (n_ut, n_sat)
    elevation_rad: np.ndarray  # (n_ut, n_sat)
    visible: np.ndarray  # (n_ut, n_sat) bool, above the minimum elevation
    gain_tx_lin: np.ndarray  # (n_ut, n_sat, n_beam)
    gain_rx_db: np.ndarray  # (n_ut, n_sat)
    fspl_db: np.ndarray  # (n_ut, n_sat)
    atm_db: np.ndarray  # (n_ut, n_sat)
    path_snr_lin: np.ndarray  # (n_ut, n_sat) SNR per unit TX gain
    snr_db: np.ndarray  # (n_ut, n_sat, n_beam), NaN where not visible


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
    terminal : object with ``gain_db(elevation_rad)``
        UT antenna, steered at the serving satellite (paper Sec. 4.1).
    params : LinkParams
    atmosphere : callable
        ``atmosphere(elevation_rad) -> loss_db``, broadcasting.
    colors : ndarray of int, shape (n_beam,), optional
        Reuse colour per beam; only beams of the serving beam's colour interfere.
    """

    def __init__(self, codebook, terminal, params, atmosphere, colors=None):
        self.codebook = codebook
        self.terminal = terminal
        self.params = params
        self.atmosphere = atmosphere
        n_beam = len(codebook.u_xy)
        self.colors = np.zeros(n_beam, dtype=np.int64) if colors is None else np.asarray(colors)
        n_colors = int(self.colors.max()) + 1
        # Each colour has 1/n_colors of the band: less noise, less throughput.
        self.bandwidth_hz = params.bandwidth_hz / n_colors
        self.noise_dbw = float(noise_power_dbw(params.noise_temp_dbk, self.bandwidth_hz))
        # same[b, b'] = 1 where b' interferes with b (same colour, other beam)
        self.same_color = (self.colors[:, None] == self.colors[None, :]).astype(float)
        np.fill_diagonal(self.same_color, 0.0)

    @property
    def n_beam(self) -> int:
        return len(self.codebook.u_xy)

    def evaluate(self, ut_pos_m, sat_pos_m, sat_vel_m_s):
        """Geometry, gains and SNR for every (UT, satellite, beam).

        Parameters
        ----------
        ut_pos_m : ndarray, shape (n_ut, 3)
        sat_pos_m, sat_vel_m_s : ndarray, shape (n_sat, 3)
            Same Earth-centred frame as ``ut_pos_m``.

        Returns
        -------
        Snapshot
        """
        p = self.params
        rel = ut_pos_m[:, None, :] - sat_pos_m[None, :, :]  # satellite -> UT
        rho = np.sqrt(np.einsum("usk,usk->us", rel, rel))
        up = ut_pos_m / np.linalg.norm(ut_pos_m, axis=-1, keepdims=True)
        sin_el = -np.einsum("usk,uk->us", rel, up) / rho
        elevation = np.arcsin(np.clip(sin_el, -1.0, 1.0))
        visible = elevation >= p.min_elevation_rad

        axes = body_frame(sat_pos_m, sat_vel_m_s)  # (n_sat, 3, 3) rows u_x, u_y, u_z
        u_xy = np.einsum("usk,sak->usa", rel, axes[:, :2, :]) / rho[..., None]
        gain_tx = self.codebook.gain_lin(u_xy)  # (n_ut, n_sat, n_beam)

        loss_fs = fspl_db(rho, p.freq_hz)
        loss_atm = np.broadcast_to(self.atmosphere(np.maximum(elevation, 0.0)), rho.shape)
        gain_rx = np.broadcast_to(self.terminal.gain_db(elevation), rho.shape)
        path_db = p.ptx_dbw - p.cable_loss_db - loss_fs - loss_atm + gain_rx - self.noise_dbw
        path_lin = np.where(visible, 10.0 ** (path_db / 10.0), np.nan)
        with np.errstate(divide="ignore"):
            snr_db = 10.0 * np.log10(gain_tx * path_lin[..., None])
        return Snapshot(
            rel, rho, elevation, visible, gain_tx, gain_rx, loss_fs, loss_atm, path_lin, snr_db
        )

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
        n_ut = len(sat_idx)
        served = sat_idx >= 0
        u = np.arange(n_ut)
        s = np.where(served, sat_idx, 0)
        b = np.where(served, beam_idx, 0)

        g_all = snap.gain_tx_lin[u, s]  # (n_ut, n_beam)
        g_sig = g_all[u, b]
        g_int = np.einsum("ub,ub->u", g_all, self.same_color[b])
        path = snap.path_snr_lin[u, s]
        if rx_fading_lin is not None:
            path = path * rx_fading_lin
        snr = g_sig * path
        sinr = snr / (g_int * path + 1.0)  # SINR = S / (I + N), both scaled by the noise
        se = np.log2(1.0 + sinr)

        rel = snap.rel_m[u, s]  # satellite -> UT
        sat_p = -rel  # UT -> satellite, translation invariant for the kinematics below
        zero = np.zeros_like(rel)
        f = self.params.freq_hz
        d_sat = kinematics.doppler_sat_hz(zero, sat_vel_m_s[s], -sat_p, f)
        d_ut = kinematics.doppler_ut_hz(zero, ut_vel_m_s, sat_p, f)
        rate = kinematics.doppler_rate_hz_s(
            sat_p, sat_vel_m_s[s], sat_acc_m_s2[s], zero, ut_vel_m_s, ut_acc_m_s2, freq_hz=f
        )
        w = kinematics.angular_speed_rad_s(sat_p, sat_vel_m_s[s], zero, ut_vel_m_s)

        nan = np.where(served, 1.0, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            cols = {
                "elevation_deg": np.degrees(snap.elevation_rad[u, s]) * nan,
                "slant_range_m": snap.slant_range_m[u, s] * nan,
                "gain_tx_db": 10.0 * np.log10(g_sig) * nan,
                "gain_rx_db": snap.gain_rx_db[u, s] * nan,
                "fspl_db": snap.fspl_db[u, s] * nan,
                "atm_db": snap.atm_db[u, s] * nan,
                "snr_db": 10.0 * np.log10(snr) * nan,
                "sinr_db": 10.0 * np.log10(sinr) * nan,
                "se_bps_hz": se * nan,
                "throughput_bps": se * self.bandwidth_hz * nan,
                "doppler_hz": (d_sat + d_ut) * nan,
                "doppler_sat_hz": d_sat * nan,
                "doppler_ut_hz": d_ut * nan,
                "doppler_rate_hz_s": rate * nan,
                "angular_speed_deg_s": np.degrees(w) * nan,
            }
        return cols
