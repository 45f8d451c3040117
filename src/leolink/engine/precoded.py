"""The precoded path of the engine: SINR after the digital precoder ``F_BB`` (issue 14).

Kept apart from :meth:`leolink.engine.LinkEngine.serve_pairs` (whose default path, and its
fused kernel, stay as they are): precoding couples the UTs scheduled together, so it is
a small matrix problem per (satellite, slot), not an element-wise function of a pair.

Problem ``p`` is one satellite in one slot: the UTs ``k = 0 .. B - 1`` it serves then, one
per lit beam (:mod:`leolink.sim.beams.scheduler`); beam ``j`` is UT ``j``'s serving beam, on RF
chain ``chain[j]``. The channel the precoder sees is the LoS response from the known
ephemeris times the UT antenna gain and the path (:mod:`leolink.link.precoder`):

    H[k, j] = sqrt(path_snr_lin_k) h_{b_j}(u_k) 1[colour(b_j) = colour(b_k)],

``h`` the closed-form complex subarray response of :func:`leolink.antenna.response.chain_response`
(``|h|^2`` is the engine's beam gain), ``u_k`` UT ``k``'s direction cosines in the
satellite body frame, ``path_snr_lin`` the engine's SNR per unit TX gain (power per chain,
FSPL, atmosphere, UT gain, fading, over the noise of one colour's band): a UT does not
hear beams of another colour, so with reuse colours the problem splits into one per
colour by itself. The precoder is power-scaled so that the most loaded chain radiates
``P_RF`` (``p_rf = 1`` in this normalization); the SINR of UT ``k`` is

    |[H F]_kk|^2 / (sum_{j != k} |[H F]_kj|^2 + 1 + I_other,k),

``I_other`` the other satellites' interference over the noise (0 unless enabled).

Seam for the ephemeris-error model (issue 15, steering): ``h_est`` defaults to the true
channel; a caller with the satellite's *believed* directions passes ``u_est_xy`` and the
precoder is computed from them while the SINR goes through the true ``u_xy``
(:func:`leolink.link.precoder.precode`'s ``h_true``), leaving residual interference.
"""

from __future__ import annotations

import numpy as np

from leolink.antenna.response import chain_response
from leolink.link.precoder import sinr_after_precoding

__all__ = ["channel", "precoded_sinr"]


def channel(u_xy, path_snr_lin, beam_u_xy, chain, colors, member, array):
    """Noise-normalized channel ``H (P, B, B)`` of padded problems.

    Parameters
    ----------
    u_xy : ndarray, shape (P, B, 2)
        Direction of each problem's UTs in the satellite body frame [-].
    path_snr_lin : ndarray, shape (P, B)
        SNR per unit TX gain of each UT [-] (0 on padding).
    beam_u_xy : ndarray, shape (P, B, 2)
        Boresight of each UT's serving beam [-].
    chain : ndarray of int, shape (P, B)
        RF chain of each serving beam (-1 on padding).
    colors : ndarray of int, shape (P, B)
        Reuse colour of each serving beam.
    member : ndarray of bool, shape (P, B)
        False on padding.
    array : leolink.antenna.array.HybridArray

    Returns
    -------
    ndarray of complex, shape (P, B, B)
    """
    h = chain_response(u_xy, beam_u_xy[:, None, :, :], chain[:, None, :], array)
    same = colors[:, :, None] == colors[:, None, :]
    ok = member[:, :, None] & member[:, None, :] & same
    return np.where(ok, np.sqrt(path_snr_lin)[..., None] * h, 0.0)


def precoded_sinr(precoder, h_true, member, i_other_lin, h_est=None):
    """SINR [-] of every problem's UTs after ``precoder``, shape (P, B), NaN on padding.

    Parameters
    ----------
    precoder : leolink.link.precoder.Precoder
    h_true : ndarray of complex, shape (P, B, B)
        :func:`channel`; the signal goes through it.
    member : ndarray of bool, shape (P, B)
    i_other_lin : ndarray, shape (P, B)
        Other satellites' interference over the noise.
    h_est : ndarray of complex, shape (P, B, B), optional
        The channel the precoder is computed from (default ``h_true``).
    """
    serving = np.broadcast_to(np.arange(member.shape[1]), member.shape)
    h_est = h_true if h_est is None else h_est
    f = precoder(h_est, 1.0, serving_beam=serving, ut_mask=member, beam_mask=member)
    with np.errstate(invalid="ignore", divide="ignore"):  # padding: 0 / 0, masked
        return sinr_after_precoding(h_true, f, member, 1.0 + i_other_lin)
