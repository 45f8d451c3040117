"""Link figures of the serving links: EIRP, C/N0, Es/N0, margin, MODCOD and ACM throughput.

A vectorized post-processing of the engine's per-UT serving-link columns (its ``snr_db``,
``sinr_db`` and ``gain_tx_db``), so that the engine itself does not change:

    EIRP  = P_TX - L_cable + G_TX                       [dBW]   (per beam)
    C/N0  = SNR + 10 log10(B)                           [dBHz]
    Es/N0 = X + 10 log10(1 + alpha)                     [dB]    X = SNR or SINR (``metric``)
    M     = Es/N0 - (Es/N0)_required                    [dB]
    MODCOD = best DVB-S2X row with esn0_ideal + margin_impl <= Es/N0
    R_ACM = eta(MODCOD) B / (1 + alpha)                 [bit/s]

with ``B`` the bandwidth of one beam's colour (the engine's noise bandwidth). The engine's
SNR is ``C / (N0 B)`` (C including the mean or drawn fading), hence ``C/N0 = SNR B``; the
symbol rate ``R_s = B / (1 + alpha)`` fills the channel, and the matched filter's noise
bandwidth is ``R_s``, hence ``Es/N0 = C / (N0 R_s) = SNR (1 + alpha)``
(:mod:`leolink.link.figures`).

``metric = "sinr"`` (the default) treats the interference as noise: Es/N0 is then
``Es / (N0 + I0)`` and the MODCOD and margin are those the receiver can actually use; with
``"snr"`` they are the thermal link-budget figures. ``C/N0`` is always thermal (no I).

References
----------
.. [1] ETSI EN 302 307-2 V1.1.1 (DVB-S2X), Table 20a; EN 302 307-1 V1.4.1, clause 5.6.
.. [2] G. Maral, M. Bousquet, "Satellite Communications Systems", 5th ed., Wiley 2009.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from leolink.link.modcod import modcod_spectral_efficiency, modcod_table, select_modcod

__all__ = [
    "FIGURE_COLUMNS",
    "ROLLOFFS",
    "THROUGHPUT_COLUMNS",
    "LinkFigureParams",
    "esn0_and_modcod",
    "link_figure_columns",
    "link_modcod",
]

#: Trace columns that :func:`link_figure_columns` adds (``modcod`` as row codes, -1 none).
FIGURE_COLUMNS = ("eirp_dbw", "cn0_dbhz", "esn0_db", "margin_db", "modcod")
#: Frame columns (not in the trace) with both throughputs, for the summary.
THROUGHPUT_COLUMNS = ("throughput_shannon_bps", "throughput_dvbs2x_bps")
#: DVB-S2X roll-offs (EN 302 307-2 clause 5.6: 0.05, 0.10, 0.15; EN 302 307-1: 0.20-0.35).
ROLLOFFS = (0.05, 0.10, 0.15, 0.20, 0.25, 0.35)


@dataclass(frozen=True)
class LinkFigureParams:
    """What the link figures need besides the engine's columns.

    Attributes
    ----------
    ptx_dbw : float, power per beam at the amplifier [dBW].
    cable_loss_db : float, amplifier to antenna [dB].
    bandwidth_hz : float, one colour's bandwidth (the engine's noise bandwidth) [Hz].
    rolloff : float, root-raised-cosine roll-off ``alpha``.
    implementation_margin_db : float, added to every MODCOD threshold [dB].
    required_esn0_db : float or None, threshold of ``margin_db`` [dB]; None: the most
        robust MODCOD's ideal Es/N0 plus the implementation margin (the link closes at all).
    metric : ``"snr"`` or ``"sinr"``, the ratio Es/N0 is taken from.
    throughput_model : ``"shannon"`` (the paper, ``B log2(1 + SINR)``) or ``"dvbs2x"``
        (ACM), what the trace's ``throughput_bps`` and ``se_bps_hz`` hold.
    """

    ptx_dbw: float
    cable_loss_db: float
    bandwidth_hz: float
    rolloff: float = 0.20
    implementation_margin_db: float = 0.0
    required_esn0_db: float | None = None
    metric: str = "sinr"
    throughput_model: str = "shannon"

    @property
    def symbol_rate_baud(self) -> float:
        """``B / (1 + alpha)`` [baud]."""
        return self.bandwidth_hz / (1.0 + self.rolloff)

    @property
    def threshold_db(self) -> float:
        """The Es/N0 the margin is counted from [dB]."""
        if self.required_esn0_db is not None:
            return float(self.required_esn0_db)
        return float(modcod_table().esn0_ideal_db.min()) + self.implementation_margin_db


def esn0_and_modcod(snr_db, sinr_db, p):
    """``(ratio_db, esn0_db, modcod)`` of the metric ``p.metric``: Es/N0 = ratio + 10 log10(1 +
    alpha) (the symbol rate B / (1 + alpha) in the noise bandwidth B), the most efficient
    MODCOD whose threshold plus the implementation margin it meets (-1: none)."""
    ratio_db = np.asarray(sinr_db if p.metric == "sinr" else snr_db, float)
    esn0 = ratio_db + 10.0 * np.log10(1.0 + p.rolloff)
    return ratio_db, esn0, select_modcod(esn0, p.implementation_margin_db)


def link_modcod(snr_db, sinr_db, params):
    """The MODCOD row of each serving link (int, -1 where none closes it or no link), as
    the ``modcod`` column of :func:`link_figure_columns`; shapes (n_ut,)."""
    return esn0_and_modcod(snr_db, sinr_db, params)[2]


def link_figure_columns(snr_db, sinr_db, gain_tx_db, params, served_fraction=1.0):
    """The link-figure columns of the serving links, vectorized over UTs.

    Parameters
    ----------
    snr_db, sinr_db, gain_tx_db : ndarray, shape (n_ut,)
        The engine's serving-link SNR, SINR [dB] (NaN: no link) and beam gain [dBi].
    params : LinkFigureParams
    served_fraction : float or ndarray, shape (n_ut,)
        Part of the epoch with service (handover execution), scales the ACM throughput as
        the engine's Shannon throughput is scaled.

    Returns
    -------
    dict of ndarray, shape (n_ut,)
        ``eirp_dbw, cn0_dbhz, esn0_db, margin_db`` [dBW, dBHz, dB, dB], ``modcod`` (int
        row of the MODCOD table, -1: none closes the link or no link) and
        ``throughput_dvbs2x_bps`` (NaN where there is no link, as the Shannon figure).
    """
    p = params
    snr_db = np.asarray(snr_db, float)
    ratio_db, esn0, modcod = esn0_and_modcod(snr_db, sinr_db, p)
    eta = modcod_spectral_efficiency(modcod)
    no_link = np.isnan(ratio_db)
    acm = np.where(no_link, np.nan, eta * p.symbol_rate_baud * served_fraction)
    return {
        "eirp_dbw": p.ptx_dbw - p.cable_loss_db + np.asarray(gain_tx_db, float),
        "cn0_dbhz": snr_db + 10.0 * np.log10(p.bandwidth_hz),
        "esn0_db": esn0,
        "margin_db": esn0 - p.threshold_db,
        "modcod": modcod.astype(np.int64),
        "throughput_dvbs2x_bps": acm,
    }
