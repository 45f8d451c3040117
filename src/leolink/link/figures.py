"""The link figures engineers quote: EIRP, G/T, C/N0, CNR, Es/N0, Eb/N0 and link margin.

All functions are pure numpy, in dB units, and broadcast over ``(n_time, n_ut, n_sat,
n_beam)``. They chain as

    EIRP  = P_TX - L_cable + G_TX                                   [dBW]
    G/T   = G_RX - 10 log10(T_sys)                                  [dB/K]
    C/N0  = EIRP - L_path + G/T - 10 log10(k)                       [dBHz]
    CNR   = C/N0 - 10 log10(B)                                      [dB]   (TR 38.821 6.1.3.1)
    R_s   = B / (1 + alpha)                                         [baud]
    Es/N0 = C/N0 - 10 log10(R_s)                                    [dB]
    M     = Es/N0 - (Es/N0)_required                                [dB]

with ``L_path`` the sum of every propagation loss (FSPL, atmosphere, scintillation,
shadowing margin, polarization and additional losses), and ``k`` Boltzmann's constant
(exact: -228.599 dBW/K/Hz; TR 38.821 rounds it to -228.6).

Conventions: ``ptx_dbw`` is the power per beam (as in :mod:`leolink.link.budget`), so the
EIRP is per beam. The symbol rate fills the channel with a root-raised-cosine spectrum of
roll-off ``alpha`` (occupied bandwidth ``R_s (1 + alpha)``, EN 302 307-1 clause 5.6); the
noise bandwidth of the matched filter is ``R_s``, hence ``Es/N0 = C / (N0 R_s)`` and
``Es/N0 = CNR + 10 log10(1 + alpha)`` when the CNR is taken over the channel ``B``.

References
----------
.. [1] 3GPP TR 38.821 V16.0.0, Sec. 6.1.3.1 (CNR) and Table 6.1.1.1-3 (UE G/T from gain,
   antenna temperature and noise figure).
.. [2] ETSI EN 302 307-1 V1.4.1, clause 5.6 (baseband shaping and quadrature modulation).
.. [3] G. Maral, M. Bousquet, "Satellite Communications Systems", 5th ed., Wiley 2009
   (C/N0, G/T and Es/N0 in the link budget).
"""

import numpy as np

from leolink.constants import BOLTZMANN_DBW_K_HZ

__all__ = [
    "cn0_dbhz",
    "cnr_db",
    "ebn0_db",
    "eirp_density_dbw_mhz",
    "eirp_dbw",
    "eirp_from_density_dbw",
    "esn0_db",
    "g_over_t_db_k",
    "margin_db",
    "symbol_rate_baud",
    "system_noise_temp_k",
]

# Reference temperature of the noise figure (IEEE definition, TR 38.821 Table 6.1.1.1-3).
REFERENCE_TEMP_K = 290.0
_HZ_PER_MHZ = 1e6


def _db10(x):
    """``10 log10(x)`` of a positive quantity (``-inf`` at 0)."""
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(np.asarray(x, dtype=float))


def eirp_dbw(ptx_dbw, cable_loss_db, gain_tx_db):
    """Equivalent isotropically radiated power ``P_TX - L_cable + G_TX``.

    Parameters
    ----------
    ptx_dbw : array_like
        Transmit power per beam at the amplifier output [dBW].
    cable_loss_db : array_like
        Loss between amplifier and antenna [dB], positive.
    gain_tx_db : array_like
        Transmit antenna (beam) gain towards the receiver [dBi].

    Returns
    -------
    ndarray, broadcast shape
        EIRP per beam [dBW].
    """
    return np.asarray(ptx_dbw, dtype=float) - cable_loss_db + gain_tx_db


def eirp_density_dbw_mhz(eirp_dbw, bandwidth_hz):
    """EIRP spectral density ``EIRP - 10 log10(B / 1 MHz)`` [dBW/MHz] (TR 38.821 Table 6.1.1.1-1).

    Parameters
    ----------
    eirp_dbw : array_like
        EIRP spread evenly over the bandwidth [dBW].
    bandwidth_hz : array_like
        Occupied bandwidth [Hz].

    Returns
    -------
    ndarray
        EIRP density [dBW/MHz].
    """
    return np.asarray(eirp_dbw, dtype=float) - _db10(np.asarray(bandwidth_hz) / _HZ_PER_MHZ)


def eirp_from_density_dbw(eirp_density_dbw_mhz, bandwidth_hz):
    """Inverse of :func:`eirp_density_dbw_mhz`: total EIRP [dBW] over ``bandwidth_hz``.

    TR 38.821 specifies satellites by EIRP density (4 dBW/MHz over 400 MHz in Ka band gives
    30.02 dBW).
    """
    return np.asarray(eirp_density_dbw_mhz, dtype=float) + _db10(
        np.asarray(bandwidth_hz) / _HZ_PER_MHZ
    )


def system_noise_temp_k(antenna_temp_k, noise_figure_db, reference_temp_k=REFERENCE_TEMP_K):
    """Receiver system noise temperature ``T_a + T_0 (10^(NF/10) - 1)`` [K].

    The antenna temperature plus the receiver's equivalent input noise temperature (Friis);
    TR 38.821 Table 6.1.1.1-3 writes the same G/T as
    ``G - NF - 10 log10(T_0 + (T_a - T_0) 10^(-NF/10))``.

    Parameters
    ----------
    antenna_temp_k : array_like
        Antenna noise temperature [K] (TR 38.821: 150 K VSAT, 290 K handheld).
    noise_figure_db : array_like
        Receiver noise figure [dB] (TR 38.821: 1.2 dB VSAT, 7 dB handheld).
    reference_temp_k : float
        Reference temperature of the noise figure [K], 290 K.

    Returns
    -------
    ndarray
        System noise temperature [K].
    """
    f_lin = 10.0 ** (np.asarray(noise_figure_db, dtype=float) / 10.0)
    return np.asarray(antenna_temp_k, dtype=float) + reference_temp_k * (f_lin - 1.0)


def g_over_t_db_k(gain_rx_db, *, noise_temp_k=None, noise_temp_dbk=None):
    """Receiver figure of merit ``G/T = G_RX - 10 log10(T_sys)`` [dB/K].

    Give the noise temperature either in kelvin or in dBK (exactly one of the two).

    Parameters
    ----------
    gain_rx_db : array_like
        Receive antenna gain [dBi].
    noise_temp_k : array_like, optional
        System noise temperature [K].
    noise_temp_dbk : array_like, optional
        System noise temperature [dBK] (the paper's Table: 24.1 dBK).

    Returns
    -------
    ndarray, broadcast shape
        G/T [dB/K].

    Raises
    ------
    TypeError
        Neither or both noise temperatures given.
    """
    if (noise_temp_k is None) == (noise_temp_dbk is None):
        raise TypeError("g_over_t_db_k needs exactly one of noise_temp_k, noise_temp_dbk")
    t_dbk = _db10(noise_temp_k) if noise_temp_dbk is None else np.asarray(noise_temp_dbk, float)
    return np.asarray(gain_rx_db, dtype=float) - t_dbk


def cn0_dbhz(eirp_dbw, path_loss_db, g_over_t_db_k):
    """Carrier-to-noise-density ratio ``C/N0 = EIRP - L_path + G/T - k`` [dBHz].

    Parameters
    ----------
    eirp_dbw : array_like
        EIRP towards the receiver [dBW].
    path_loss_db : array_like
        Total propagation loss [dB], positive: FSPL + atmosphere + scintillation +
        shadowing margin + polarization + additional losses (the caller sums them).
    g_over_t_db_k : array_like
        Receiver G/T [dB/K].

    Returns
    -------
    ndarray, broadcast shape
        C/N0 [dBHz].
    """
    return np.asarray(eirp_dbw, dtype=float) - path_loss_db + g_over_t_db_k - BOLTZMANN_DBW_K_HZ


def cnr_db(cn0_dbhz, bandwidth_hz):
    """Carrier-to-noise ratio over a noise bandwidth ``B``: ``C/N0 - 10 log10(B)`` [dB].

    This is the CNR of TR 38.821 Sec. 6.1.3.1 (B = channel bandwidth) and equals
    :func:`leolink.link.budget.snr_db` for the same link.
    """
    return np.asarray(cn0_dbhz, dtype=float) - _db10(bandwidth_hz)


def symbol_rate_baud(bandwidth_hz, rolloff):
    """Symbol rate that fills ``bandwidth_hz`` with roll-off ``rolloff``: ``B / (1 + alpha)``.

    Parameters
    ----------
    bandwidth_hz : array_like
        Channel (occupied) bandwidth [Hz].
    rolloff : array_like
        Root-raised-cosine roll-off ``alpha`` in [0, 1] (DVB-S2X: 0.05 ... 0.35).

    Returns
    -------
    ndarray
        Symbol rate [baud].
    """
    return np.asarray(bandwidth_hz, dtype=float) / (1.0 + np.asarray(rolloff, dtype=float))


def esn0_db(cn0_dbhz, symbol_rate_baud):
    """Energy per symbol over noise density ``Es/N0 = C/N0 - 10 log10(R_s)`` [dB]."""
    return np.asarray(cn0_dbhz, dtype=float) - _db10(symbol_rate_baud)


def ebn0_db(esn0_db, spectral_efficiency_bit_sym):
    """Energy per information bit ``Eb/N0 = Es/N0 - 10 log10(eta)`` [dB] (eta in bit/symbol)."""
    return np.asarray(esn0_db, dtype=float) - _db10(spectral_efficiency_bit_sym)


def margin_db(esn0_db, required_esn0_db):
    """Link margin ``Es/N0 - (Es/N0)_required`` [dB]; positive: the link closes.

    ``required_esn0_db`` is the demodulator threshold *including* any implementation margin
    (e.g. a MODCOD's ideal Es/N0 plus the modem's implementation loss).
    """
    return np.asarray(esn0_db, dtype=float) - required_esn0_db
