"""Link budget: FSPL, noise, RSS, SNR, SINR, spectral efficiency, throughput.

Sec. 2.2 ("Link budget model") and Sec. 4 ("Coverage and spectral efficiency") of [1].
Every function is pure numpy and broadcasts over ``(n_time, n_ut, n_sat, n_beam)``.

Power convention: ``ptx_dbw`` is the power **per beam** (per RF chain), as in the
paper's Table (P_TX = 15 dBW); a total power split over beams is the caller's choice.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] ITU-R P.525-4, "Calculation of free-space attenuation."
.. [3] 3GPP TR 38.821 V16.1.0, "Solutions for NR to support non-terrestrial networks."
"""

from dataclasses import asdict, dataclass

import numpy as np

import leolink.compiled
from leolink.constants import BOLTZMANN_DBW_K_HZ, SPEED_OF_LIGHT_M_S

__all__ = [
    "LinkBudget",
    "db",
    "fspl_db",
    "interference_dbw",
    "lin",
    "noise_power_dbw",
    "rsrp_dbm",
    "rss_dbw",
    "sinr_lin",
    "snr_db",
    "spectral_efficiency_bps_hz",
    "throughput_bps",
]


def db(x):
    """Linear power ratio -> dB: ``10 log10(x)`` (``-inf`` for 0)."""
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(x)


def lin(x_db):
    """dB -> linear power ratio: ``10**(x/10)``."""
    return 10.0 ** (np.asarray(x_db, dtype=float) / 10.0)


@leolink.compiled.jitable
def fspl_db(distance_m, freq_hz):
    """Free-space path loss, Eq. (5) of [1], ``20 log10(4 pi d f / c)`` (also in the
    compiled loops, on one link's floats).

    Parameters
    ----------
    distance_m : array_like, shape (n_ut, n_sat) or broadcastable
        Slant range UT-satellite [m].
    freq_hz : float or array_like
        Carrier frequency [Hz].

    Returns
    -------
    float or ndarray, broadcast shape of the inputs
        Loss [dB], positive.
    """
    d = np.float64(distance_m)  # (float64 whatever the input's type, as sinr_lin)
    return 20.0 * np.log10(4.0 * np.pi * d * freq_hz / SPEED_OF_LIGHT_M_S)


def noise_power_dbw(noise_temp_dbk, bandwidth_hz):
    """Thermal noise power ``sigma^2 = T[dBK] + k[dBW/K/Hz] + B[dBHz]``, Eq. (4) of [1].

    Uses the exact ``10 log10(1.380649e-23) = -228.599`` dBW/K/Hz; the paper rounds
    it to -228.6 (0.001 dB, see docs/errata.md).

    Parameters
    ----------
    noise_temp_dbk : float or array_like
        System noise temperature [dBK] (the paper's Table: 24.1 dBK).
    bandwidth_hz : float or array_like
        Noise bandwidth [Hz].

    Returns
    -------
    ndarray
        Noise power [dBW].
    """
    return np.asarray(noise_temp_dbk, dtype=float) + BOLTZMANN_DBW_K_HZ + db(bandwidth_hz)


def rsrp_dbm(snr_db, noise_temp_dbk, subcarrier_spacing_hz):
    """SS-RSRP per resource element [dBm] of a link with SNR ``snr_db`` (TS 38.215 5.1.1).

    RSRP is the power of one resource element (one subcarrier ``df``) of the SSS:
    ``RSRP = EIRP_RE - L + G_RX`` with ``EIRP_RE = EIRP - 10 log10(B / df)`` the EIRP
    density per subcarrier of a beam spreading its power evenly over its band ``B``.
    Its SNR is ``EIRP - L + G_RX - (T + k + 10 log10 B)`` (:func:`noise_power_dbw`), so

        RSRP [dBm] = SNR + (T + k + 10 log10 df) + 30,

    the SNR plus the thermal noise of one subcarrier, whatever ``B`` (and the reuse
    colour's share of it) is.

    Parameters
    ----------
    snr_db : array_like [dB]
    noise_temp_dbk : float [dBK], system noise temperature.
    subcarrier_spacing_hz : float [Hz], the SSB's subcarrier spacing (15 or 30 kHz in
        FR1, 120 or 240 kHz in FR2).

    Returns
    -------
    ndarray [dBm]
    """
    return np.asarray(snr_db, float) + noise_power_dbw(noise_temp_dbk, subcarrier_spacing_hz) + 30.0


def rss_dbw(ptx_dbw, cable_db, gain_tx_db, atm_db, fspl_db, gain_rx_db):
    """Received signal strength, Eq. (3) of [1] (Sec. 2.2.1).

    ``RSS = P_TX - LP_cable + G_TX - LP_at - LP_fs + G_RX`` (all terms broadcast).

    Parameters
    ----------
    ptx_dbw : float or array_like
        Transmit power per beam (per RF chain) [dBW].
    cable_db, atm_db, fspl_db : array_like
        Losses [dB], positive numbers.
    gain_tx_db, gain_rx_db : array_like
        Transmit (satellite beam) and receive (UT) gains [dB].

    Returns
    -------
    ndarray
        RSS [dBW].
    """
    return (
        np.asarray(ptx_dbw, dtype=float)
        - cable_db
        + gain_tx_db
        - atm_db
        - fspl_db
        + np.asarray(gain_rx_db, dtype=float)
    )


def interference_dbw(ptx_dbw, cable_db, gain_tx_other_lin, atm_db, fspl_db, gain_rx_db):
    """Inter-beam interference power, the paper's ``I``, Eq. (18) of [1], corrected.

    The paper writes ``I = P - L_cable + G_TX - L_at - L_fs + G_RX^interf`` with
    ``G_RX^interf = sum_{n != sel} G_TX_n``: the labels are swapped. The sum of the
    *other* beams' transmit gains replaces ``G_TX`` and the UT gain ``G_RX`` stays
    (docs/errata.md). Each beam radiates ``ptx_dbw`` (per-beam convention).

    Parameters
    ----------
    gain_tx_other_lin : array_like
        ``sum_{n != sel} G_TX_n``, linear, of the beams not serving this UT.
    ptx_dbw, cable_db, atm_db, fspl_db, gain_rx_db : array_like
        As in :func:`rss_dbw`.

    Returns
    -------
    ndarray
        Interference power [dBW] (``-inf`` when there is no other beam).
    """
    return rss_dbw(ptx_dbw, cable_db, db(gain_tx_other_lin), atm_db, fspl_db, gain_rx_db)


def snr_db(rss_dbw, noise_dbw):
    """SNR = RSS - sigma^2 [dB], Eq. (2) of [1]."""
    return np.asarray(rss_dbw, dtype=float) - noise_dbw


@leolink.compiled.jitable
def sinr_lin(signal_lin, interference_lin, noise_lin):
    """SINR ``S / (I + sigma^2)``, linear, Eq. (19) of [1].

    The one place the SINR is formed: the engine's serving links
    (:meth:`leolink.engine.LinkEngine.serve_pairs`), the precoded path
    (:func:`leolink.link.precoder.sinr_after_precoding`) and the active-beam choice
    (:mod:`leolink.sim.beams.active`) call it, on arrays. Arithmetic only: a compiled loop
    may call it on scalars as it is (:mod:`leolink.compiled`).

    Parameters
    ----------
    signal_lin, interference_lin, noise_lin : float or ndarray, broadcastable
        Received signal, interference and noise powers, in one linear unit ([W], or
        normalized to the noise).

    Returns
    -------
    float or ndarray, broadcast shape of the inputs
        SINR [-] (linear).
    """
    return np.float64(signal_lin) / (interference_lin + noise_lin)


@leolink.compiled.jitable
def spectral_efficiency_bps_hz(sinr_lin):
    """Shannon spectral efficiency ``log2(1 + SINR)`` [bit/s/Hz], Sec. 4.2 of [1] (unnumbered).

    As ``log1p(SINR) / ln 2``: accurate at low SINR, where ``1 + SINR`` would round.
    """
    return np.log1p(np.float64(sinr_lin)) / np.log(2.0)


@leolink.compiled.jitable
def throughput_bps(se_bps_hz, bandwidth_hz):
    """Throughput ``B log2(1 + SINR)`` [bit/s], Sec. 4.2 of [1] (unnumbered), from the
    spectral efficiency [bit/s/Hz] and the bandwidth [Hz] (also in the compiled loops)."""
    return np.float64(se_bps_hz) * bandwidth_hz


@dataclass(frozen=True)
class LinkBudget:
    """One downlink budget, term by term (used by ``leolink budget``).

    All scalars: angles in degrees (CLI edge), powers in dBW, losses and gains in dB.
    ``eirp_dbw = ptx_dbw - cable_db + gain_tx_db`` (per beam); ``other_loss_db``: the
    constant losses besides FSPL and atmosphere (scintillation, shadowing margin,
    polarization, additional: TR 38.821 Table 6.1.3.3-1), subtracted from the RSS.
    """

    elevation_deg: float
    slant_range_m: float
    fspl_db: float
    atm_db: float
    other_loss_db: float
    cable_db: float
    gain_tx_db: float
    gain_rx_db: float
    ptx_dbw: float
    eirp_dbw: float
    rss_dbw: float
    noise_dbw: float
    snr_db: float

    @classmethod
    def compute(
        cls,
        *,
        elevation_deg,
        slant_range_m,
        freq_hz,
        ptx_dbw,
        gain_tx_db,
        gain_rx_db,
        noise_temp_dbk,
        bandwidth_hz,
        atm_db=0.0,
        cable_db=0.0,
        other_loss_db=0.0,
    ):
        """Build the budget from the link parameters (scalars) with this module's formulas."""
        loss_fs_db = float(fspl_db(slant_range_m, freq_hz))
        rss = float(
            rss_dbw(ptx_dbw, cable_db, gain_tx_db, atm_db + other_loss_db, loss_fs_db, gain_rx_db)
        )
        noise = float(noise_power_dbw(noise_temp_dbk, bandwidth_hz))
        return cls(
            elevation_deg=float(elevation_deg),
            slant_range_m=float(slant_range_m),
            fspl_db=loss_fs_db,
            atm_db=float(atm_db),
            other_loss_db=float(other_loss_db),
            cable_db=float(cable_db),
            gain_tx_db=float(gain_tx_db),
            gain_rx_db=float(gain_rx_db),
            ptx_dbw=float(ptx_dbw),
            eirp_dbw=float(ptx_dbw - cable_db + gain_tx_db),
            rss_dbw=rss,
            noise_dbw=noise,
            snr_db=rss - noise,
        )

    def as_dict(self):
        """The terms as a plain ``dict`` (field order kept), for JSON and tables."""
        return asdict(self)
