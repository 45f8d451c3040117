"""One satellite's multibeam snapshot: coupling loss, geometry SIR and SINR of UTs dropped
over its cells (3GPP TR 38.821 clause 6.1.1, the system-level calibration).

The scenario of TR 38.821 Table 6.1.1.1-5: one satellite, its central beam at nadir
(elevation 90 deg), beams on the hexagonal UV grid of :mod:`leolink.antenna.beam_layout`,
the circular-aperture pattern of TR 38.811 Sec. 6.4.1 (:mod:`leolink.antenna.aperture`),
the same EIRP density in every beam, static UTs "with uniform distribution in all the
Voronoi cell area associated to each beam", attached by RSRP with 0 dB margin (for one
satellite and equal EIRP: the beam of highest gain), line of sight, no fading. Per UT,
with ``g_b`` the normalized pattern gain of beam ``b`` towards it and ``s`` its beam:

- coupling loss ``CL = FSPL + L_atm - G_max - 10 log10(g_s) - G_rx`` [dB] ("the signal loss
  from the antenna port to the antenna port");
- geometry SIR ``g_s / sum_{b != s, colour(b) = colour(s)} g_b`` (every beam radiates the
  same EIRP density over the same band and path, so powers reduce to pattern gains);
- SNR (the CNR of TR 38.821 Sec. 6.1.3.1 off boresight) ``EIRP + 10 log10(g_s) - FSPL
  - L_atm + G/T - k - 10 log10(B)`` with ``EIRP`` the beam's peak EIRP over its band ``B``;
- geometry SINR ``1 / (1 / SIR + 1 / SNR)``.

UTs are drawn uniformly in area on the spherical Earth over a cap around the nadir point
that holds the inner cells (the statistics' cells); those attached to another beam are
dropped, so each inner cell holds a uniform drop of its own area (about
``uts_per_beam`` UTs each: the drop count is ``uts_per_beam`` times the cap's UV area over
one cell's). The TR asks for "at least 10" per beam; more only shrinks the sampling error
of the percentiles.

References
----------
.. [1] 3GPP TR 38.821 V16.2.0, clause 6.1.1.1, Tables 6.1.1.1-1, -3, -4, -5, -6.
.. [2] 3GPP TR 38.811 V15.4.0, Sec. 6.4.1 (antenna) and 6.6.2 (free-space path loss).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.antenna.aperture import aperture_ka, circular_aperture_pattern_lin
from leolink.antenna.beam_layout import HexBeamLayout, n_beams_within
from leolink.engine.links import reuse_colors
from leolink.geometry import direction_cosines, look_angles, ray_to_ground
from leolink.link.budget import db, fspl_db, sinr_lin
from leolink.link.figures import cn0_dbhz, cnr_db, eirp_from_density_dbw, g_over_t_db_k

__all__ = [
    "CAP_UV_RADIUS_SPACINGS",
    "MultibeamSatellite",
    "Snapshot",
    "drop_uts",
    "inner_beam_count",
    "off_axis_angle_rad",
    "snapshot",
]

#: UV radius of the drop cap in beam spacings beyond the inner tiers: ``t`` tiers' cells
#: reach ``(t + 1/sqrt(3)) ABS`` from nadir, so ``(t + 1) ABS`` holds them all.
CAP_UV_RADIUS_SPACINGS = 1.0


@dataclasses.dataclass(frozen=True)
class MultibeamSatellite:
    """The satellite of the snapshot and its beams.

    Attributes
    ----------
    layout : leolink.antenna.beam_layout.HexBeamLayout
    n_colors : int
        Frequency-reuse colours (1, 3 or 4); each beam has ``1 / n_colors`` of the band.
    altitude_m, radius_m : float
        Altitude over the spherical Earth and its radius [m].
    freq_hz, diameter_m, gain_max_dbi : float
        Carrier [Hz], aperture diameter [m] and boresight gain [dBi] (TR 38.811 6.4.1).
    eirp_density_dbw_mhz : float
        EIRP density of every beam at its peak [dBW/MHz] (TR 38.821 Table 6.1.1.1-1).
    bandwidth_hz : float
        The band the colours share [Hz]; each beam has ``bandwidth_hz / n_colors``.
    other_loss_db : float
        Losses besides FSPL and atmosphere [dB] (scintillation, polarization, ...).
    """

    layout: HexBeamLayout
    n_colors: int
    altitude_m: float
    radius_m: float
    freq_hz: float
    diameter_m: float
    gain_max_dbi: float
    eirp_density_dbw_mhz: float
    bandwidth_hz: float
    other_loss_db: float = 0.0

    @property
    def beam_bandwidth_hz(self):
        """Each beam's band ``B / n_colors`` [Hz] (the EIRP density is per MHz of it)."""
        return self.bandwidth_hz / self.n_colors

    @property
    def colors(self):
        """Reuse colour of each beam (the lattice rule of the hybrid codebook's beams)."""
        return reuse_colors(self.layout.lattice_ij, self.n_colors)

    def position_m(self):
        """The satellite over the point ``(0, 0, R)`` [m], moving along +x: (1, 3), (1, 3)."""
        return np.array([[0.0, 0.0, self.radius_m + self.altitude_m]]), np.array([[1.0, 0, 0]])


@dataclasses.dataclass(frozen=True)
class Snapshot:
    """Per-UT figures of the UTs in the inner cells, each shape (n_ut,).

    ``serving`` beam ids, ``elevation_rad``, ``slant_range_m``, and in dB ``cl_db``
    (coupling loss), ``sir_db``, ``snr_db``, ``sinr_db``.
    """

    serving: np.ndarray
    elevation_rad: np.ndarray
    slant_range_m: np.ndarray
    cl_db: np.ndarray
    sir_db: np.ndarray
    snr_db: np.ndarray
    sinr_db: np.ndarray


def off_axis_angle_rad(beam_uv, ut_uv):
    """Angle between Earth-pointing directions given by direction cosines [rad].

    ``2 arcsin(|b - d| / 2)`` of the unit vectors ``(u_x, u_y, -sqrt(1 - u_x^2 - u_y^2))``
    (accurate for the small angles inside a beam, where ``arccos`` of the dot product
    loses half the digits).

    Parameters
    ----------
    beam_uv : array_like, shape (n_beam, 2)
    ut_uv : array_like, shape (n_ut, 2)

    Returns
    -------
    ndarray, shape (n_ut, n_beam)
    """

    def unit(uv):
        uv = np.asarray(uv, dtype=float)
        return np.concatenate([uv, -np.sqrt(1.0 - np.sum(uv * uv, -1, keepdims=True))], -1)

    chord = np.linalg.norm(unit(ut_uv)[:, None, :] - unit(beam_uv)[None, :, :], axis=-1)
    return 2.0 * np.arcsin(np.minimum(0.5 * chord, 1.0))


def drop_uts(rng, n_ut, cap_uv_radius, sat):
    """``n_ut`` UT positions uniform in area over the ground cap seen within
    ``cap_uv_radius`` of nadir [m], shape (n_ut, 3) (sphere of ``sat.radius_m``)."""
    pos, vel = sat.position_m()
    edge = ray_to_ground(pos[0], vel[0], np.array([cap_uv_radius, 0.0]), sat.radius_m)
    cos_max = edge[2] / sat.radius_m  # the cap's edge: Earth-central angle from nadir
    cos_g = rng.uniform(cos_max, 1.0, n_ut)  # uniform area on a sphere: cos uniform
    az = rng.uniform(0.0, 2.0 * np.pi, n_ut)
    sin_g = np.sqrt(1.0 - cos_g * cos_g)
    return sat.radius_m * np.stack([sin_g * np.cos(az), sin_g * np.sin(az), cos_g], axis=1)


def _geometry_sir(gain_lin, serving, colors):
    """``g_s / sum of the other same-colour beams' g`` per UT [-]."""
    rows = np.arange(gain_lin.shape[0])
    same = colors[None, :] == colors[serving][:, None]
    signal = gain_lin[rows, serving]
    return signal / (np.sum(np.where(same, gain_lin, 0.0), axis=1) - signal)


def snapshot(sat, ut_pos_m, n_inner, noise_temp_dbk, gain_rx_db, atm_db):
    """Coupling loss, geometry SIR, SNR and SINR of the UTs attached to the inner beams.

    Parameters
    ----------
    sat : MultibeamSatellite
    ut_pos_m : ndarray, shape (n, 3)
        UT positions (e.g. :func:`drop_uts`) [m].
    n_inner : int
        The first ``n_inner`` beams are the statistics' cells (19: 2 tiers).
    noise_temp_dbk : float
        UT system noise temperature [dBK] (with the receive gain: the UT's G/T).
    gain_rx_db, atm_db : callable
        UT receive gain [dBi] and atmospheric loss [dB] of the elevation [rad].

    Returns
    -------
    Snapshot
    """
    pos, vel = sat.position_m()
    ut_uv = direction_cosines(pos, vel, ut_pos_m)
    gain = circular_aperture_pattern_lin(
        off_axis_angle_rad(sat.layout.beam_uv, ut_uv), aperture_ka(sat.freq_hz, sat.diameter_m)
    )
    serving = np.argmax(gain, axis=1)  # RSRP attachment, 0 dB margin
    keep = serving < n_inner
    gain, serving, ut = gain[keep], serving[keep], ut_pos_m[keep]
    el, _, rng_m = look_angles(ut, pos)
    g_s = gain[np.arange(serving.size), serving]
    path_db = fspl_db(rng_m, sat.freq_hz) + atm_db(el) + sat.other_loss_db
    g_rx = gain_rx_db(el)
    bw_hz = sat.beam_bandwidth_hz
    eirp = eirp_from_density_dbw(sat.eirp_density_dbw_mhz, bw_hz) + db(g_s)
    snr = cnr_db(cn0_dbhz(eirp, path_db, g_over_t_db_k(g_rx, noise_temp_dbk=noise_temp_dbk)),
                 bw_hz)  # fmt: skip
    sir = _geometry_sir(gain, serving, sat.colors)
    snr_lin = 10.0 ** (snr / 10.0)
    sinr = sinr_lin(snr_lin, snr_lin / sir, 1.0)
    cl = path_db - sat.gain_max_dbi - db(g_s) - g_rx
    return Snapshot(serving, el, rng_m, cl, db(sir), snr, db(sinr))


def inner_beam_count(inner_tiers):
    """Beams whose cells hold the statistics' UTs (TR 38.821: 2 tiers, 19 beams)."""
    return n_beams_within(inner_tiers)
