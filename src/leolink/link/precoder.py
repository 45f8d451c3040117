"""Digital precoder ``F_BB`` of the hybrid architecture ``F = F_RF F_BB`` (Sec. 2.1 of [1]).

The paper envisions "a digital precoder at the satellite to manage inter-beam interference
in the context of a full frequency reuse system", under the per-RF-chain power constraint
``||[F_BB]_{m,:}||^2 <= P_RF``. In one slot each active beam serves at most one UT, so the
baseband problem is a small MISO broadcast channel: ``n_ut <= n_beam`` single-antenna UTs,
``n_beam`` RF chains.

Channel model: row ``k`` of ``H`` (shape ``(..., n_ut, n_beam)``) is UT ``k``'s received
amplitude from each RF chain, ``H[k, m] = sqrt(path_snr_lin_k) h_m(u_k)``, with ``h_m`` the
beam response of :mod:`leolink.antenna.response` and ``path_snr_lin`` the link budget's SNR
per unit transmit gain (power per chain, FSPL, atmosphere, UT antenna gain, over the
noise). ``H`` is thus normalized so that the noise power is ``noise_lin`` (1 by default),
and ``p_rf`` is the chain power in the same unit as the power inside ``path_snr_lin``:
built from the engine's ``path_snr_lin`` (which contains ``ptx_dbw``), pass ``p_rf = 1``.
UT ``k`` receives ``y_k = H[k, :] F_BB s + n_k`` with unit-power symbols ``s``, so

    SINR_k = |[H F]_{k,k}|^2 / (sum_{j != k} |[H F]_{k,j}|^2 + noise_lin).

Precoders (``kind``):

- ``"none"``: ``F = sqrt(p_rf) E``, ``E[m, k] = 1`` if beam ``m`` serves UT ``k`` (today's
  leolink: each beam radiates its own UT's symbol at full power; the SINR is the paper's).
- ``"zf"``: ``F = H^H (H H^H)^{-1}`` (the pseudo-inverse; zero interference when the
  precoder's channel is the true one). Every UT then receives the same amplitude
  (``H F = c I``): under the common power scaling below every UT of a slot gets the SINR
  of the weakest, ill-conditioned slots cost everyone.
- ``"zf_normalized"``: the pseudo-inverse with unit-norm columns, ``F = H^+ D``, ``D``
  diagonal (still ``H F`` diagonal: zero interference), so each UT's direction carries
  the same power before the per-chain scaling instead of the same received amplitude
  (the "ZF beamforming" of Yoo and Goldsmith [5] with equal power per UT).
- ``"mmse"``: regularized ZF ``F = H^H (H H^H + alpha I)^{-1}`` with the noise-optimal
  ``alpha = n_ut noise_lin / P_total`` of Peel, Hochwald and Swindlehurst [2] (their
  ``alpha = K / rho``, ``rho`` the total transmit SNR), ``P_total = n_beam p_rf`` the power
  of all active chains (the sum-power relaxation of the per-chain constraints).

Power scaling (the same for every kind): ``F = c F_0`` with one factor per problem,
``c^2 = p_rf / max_m ||[F_0]_{m,:}||^2``, so the most loaded chain meets its constraint with
equality and the others stay below. A common factor keeps the zero-forcing structure
(``H F`` stays diagonal); scaling each row to ``p_rf`` would meet all constraints with
equality but re-introduce interference (``H D F_0`` is not diagonal). This is the usual
closed-form normalization of multibeam satellite precoding under per-feed constraints
[3]; it is not the optimum: the best ZF precoder under per-antenna constraints is a
different generalized inverse with per-UT powers found by convex optimization [4]
(not implemented).

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] C. B. Peel, B. M. Hochwald, A. L. Swindlehurst, "A vector-perturbation technique
   for near-capacity multiantenna multiuser communication - Part I: channel inversion
   and regularization," IEEE Trans. Commun., 53(1), pp. 195-202, 2005.
.. [3] A. Segneri et al., "Closed-form power normalization methods for a satellite MIMO
   system," Sensors, 22(7), 2586, 2022.
.. [4] A. Wiesel, Y. C. Eldar, S. Shamai, "Zero-forcing precoding and generalized
   inverses," IEEE Trans. Signal Process., 56(9), pp. 4409-4418, 2008.
.. [5] T. Yoo, A. Goldsmith, "On the optimality of multiantenna broadcast scheduling
   using zero-forcing beamforming," IEEE J. Sel. Areas Commun., 24(3), pp. 528-541, 2006.
"""

from typing import Literal, Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.errors import ConfigError
from leolink.link.budget import sinr_lin
from leolink.registry import Params, Registry

__all__ = [
    "IDLE_BEAMS",
    "PRECODERS",
    "Precoder",
    "chain_power",
    "mmse_regularization",
    "precode",
    "precoder_matrix",
    "sinr_after_precoding",
]


@runtime_checkable
class Precoder(Protocol):  # pragma: no mutate block (a contract, no code)
    """A digital precoder ``F_BB`` (``link.precoder``), :func:`precoder_matrix` of a kind."""

    #: ``"none"``: the engine's path is kept (no baseband precoding: today's leolink).
    kind: str
    #: What a lit beam without a scheduled UT in a slot does (:data:`IDLE_BEAMS`).
    idle_beams: str

    def __call__(self, h_est, p_rf=1.0, serving_beam=None, ut_mask=None, beam_mask=None):
        """``F_BB (..., n_beam, n_ut)`` of :func:`precoder_matrix`."""
        ...


#: Precoders by config name (``link.precoder``); their names are the kinds of
#: :func:`precoder_matrix`.
PRECODERS: Registry[Precoder] = Registry("link.precoder", Precoder)
_KINDS = ("none", "zf", "zf_normalized", "mmse")  # the closed forms of precoder_matrix
#: What a lit beam does in a slot where no UT of its cell is scheduled (``idle_beams``):
#: ``"silent"``: its chain radiates nothing, the precoder spans the scheduled UTs' chains
#: only; ``"transmit"``: full buffer, it carries a stream to its cell centre (the beam's
#: boresight, a UT with the mean path of the slot's scheduled UTs), precoded with the others
#: over all lit chains, as every lit beam radiates under ``precoder = "none"``.
IDLE_BEAMS = ("silent", "transmit")


class _Fixed:
    def __init__(self, kind, alpha_scale=1.0, idle_beams="silent"):
        self.kind, self.alpha_scale, self.idle_beams = kind, float(alpha_scale), idle_beams

    def __call__(self, h_est, p_rf=1.0, serving_beam=None, ut_mask=None, beam_mask=None):
        alpha = None
        if self.kind == "mmse" and self.alpha_scale != 1.0:
            ut, beam = _masks(np.asarray(h_est), ut_mask, beam_mask)
            alpha = self.alpha_scale * mmse_regularization(
                ut.sum(-1), np.maximum(beam.sum(-1), 1), p_rf
            )
        return precoder_matrix(h_est, self.kind, p_rf, serving_beam, ut_mask, beam_mask,
                               alpha=alpha)  # fmt: skip


class PrecoderConfig(Params):
    idle_beams: Literal["silent", "transmit"] = Field(
        "silent",
        description="a lit beam with no UT scheduled in a slot: 'silent' (its chain radiates "
        "nothing) or 'transmit' (full buffer: a stream to its cell centre, precoded with the "
        "others over all lit chains, like every lit beam under precoder = 'none')",
    )


class MmseConfig(PrecoderConfig):
    alpha_scale: float = Field(
        1.0,
        gt=0.0,
        le=1e6,
        description="regularization over the noise-optimal n_ut / (n_beam P_RF)",
    )


# "none": every lit beam radiates its cell's stream in every slot (the engine's path).
PRECODERS.add(
    "none",
    lambda p, c: _Fixed("none", idle_beams="transmit"),
    doc="no digital precoder (F_BB = selection)",
)
PRECODERS.add(
    "zf",
    lambda p, c: _Fixed("zf", idle_beams=p.idle_beams),
    config=PrecoderConfig,
    doc="zero forcing, F = H^H (H H^H)^-1",
)
PRECODERS.add(
    "zf_normalized",
    lambda p, c: _Fixed("zf_normalized", idle_beams=p.idle_beams),
    config=PrecoderConfig,
    doc="zero forcing with unit-norm columns (equal power per UT)",
)
PRECODERS.add(
    "mmse",
    lambda p, c: _Fixed("mmse", p.alpha_scale, p.idle_beams),
    config=MmseConfig,
    doc="regularized ZF, F = H^H (H H^H + alpha I)^-1",
)


def _masks(h, ut_mask, beam_mask):
    """Boolean UT (..., n_ut) and beam (..., n_beam) masks broadcast to h's batch shape."""
    batch, (n_ut, n_beam) = h.shape[:-2], h.shape[-2:]
    ut = np.ones(batch + (n_ut,), bool) if ut_mask is None else ut_mask
    beam = np.ones(batch + (n_beam,), bool) if beam_mask is None else beam_mask
    return np.broadcast_to(ut, batch + (n_ut,)), np.broadcast_to(beam, batch + (n_beam,))


def mmse_regularization(n_ut, n_beam, p_rf=1.0, noise_lin=1.0):
    """Noise-optimal regularization ``alpha = n_ut noise / (n_beam p_rf)`` of [2] in the module.

    Parameters
    ----------
    n_ut, n_beam : array_like of int
        Scheduled UTs and active beams (RF chains) of each problem.
    p_rf : float
        Power per RF chain, unit of ``H`` [-].
    noise_lin : float
        Noise power, unit of ``H`` [-].

    Returns
    -------
    ndarray
        ``alpha`` [-], broadcast shape of the inputs.
    """
    return np.asarray(n_ut, float) * noise_lin / (np.asarray(n_beam, float) * p_rf)


def chain_power(f_bb):
    """Power of each RF chain, ``||[F_BB]_{m,:}||^2``, shape (..., n_beam)."""
    return np.sum(np.abs(f_bb) ** 2, axis=-1)


def _selection(serving_beam, ut, n_beam):
    """E (..., n_beam, n_ut): 1 where beam m serves UT k (UTs with -1 or masked: none)."""
    serving_beam = np.asarray(serving_beam)
    e = (serving_beam[..., None, :] == np.arange(n_beam)[:, None]) & ut[..., None, :]
    return e.astype(complex)


def precoder_matrix(
    h_est,
    kind,
    p_rf=1.0,
    serving_beam=None,
    ut_mask=None,
    beam_mask=None,
    noise_lin=1.0,
    alpha=None,
):
    """Digital precoder ``F_BB`` from the channel the satellite believes, power-scaled.

    Parameters
    ----------
    h_est : array_like of complex, shape (..., n_ut, n_beam)
        Channel used to compute the precoder (noise-normalized, see the module docstring);
        any batch shape (satellites, slots, drops).
    kind : {"none", "zf", "zf_normalized", "mmse"}
    p_rf : float
        Power per RF chain, ``P_RF`` [unit of ``H``], > 0.
    serving_beam : array_like of int, shape (..., n_ut), optional
        Beam of each UT; required for ``"none"`` (one UT per beam), ignored otherwise.
    ut_mask, beam_mask : array_like of bool, shape (..., n_ut) / (..., n_beam), optional
        Padding of ragged batches: False = no UT in that row / dark beam. Their rows and
        columns of ``h_est`` are ignored; ``F_BB`` is 0 there.
    noise_lin : float
        Noise power in the unit of ``H`` (``alpha`` of MMSE).
    alpha : array_like, shape (...), optional
        MMSE regularization; default :func:`mmse_regularization` (studies may sweep it).

    Returns
    -------
    ndarray of complex, shape (..., n_beam, n_ut)
        ``F_BB`` with ``max_m ||[F_BB]_{m,:}||^2 = p_rf`` in every problem that serves a UT.

    Raises
    ------
    ConfigError
        For an unknown ``kind``, or ``"none"`` without ``serving_beam``.
    """
    if kind not in _KINDS:
        raise ConfigError(f"link.precoder = {kind!r} is not allowed; use one of {_KINDS}")
    h = np.asarray(h_est, dtype=complex)
    ut, beam = _masks(h, ut_mask, beam_mask)
    h = np.where(ut[..., :, None] & beam[..., None, :], h, 0.0)
    if kind == "none":
        if serving_beam is None:
            raise ConfigError("precoder 'none' needs serving_beam (the beam of each UT)")
        f0 = _selection(serving_beam, ut, h.shape[-1])
    elif kind in ("zf", "zf_normalized"):
        # pinv = H^H (H H^H)^-1 for full row rank; zero rows (padding) give columns of
        # rounding noise (~1e-17), zeroed here: normalized, they would radiate full power.
        f0 = np.where(ut[..., None, :], np.linalg.pinv(h), 0.0)
        if kind == "zf_normalized":
            norm = np.linalg.norm(f0, axis=-2, keepdims=True)
            f0 = f0 / np.where(norm > 0.0, norm, 1.0)
    else:
        if alpha is None:
            alpha = mmse_regularization(ut.sum(-1), np.maximum(beam.sum(-1), 1), p_rf, noise_lin)
        alpha = np.broadcast_to(np.asarray(alpha, dtype=float), h.shape[:-2])
        gram = h @ np.conj(np.swapaxes(h, -1, -2))
        # alpha on the scheduled UTs' diagonal; 1 on padding rows keeps the solve regular
        # (their rows of H are 0, so their columns of F come out 0 whatever the value).
        diag = np.where(ut, alpha[..., None], 1.0)
        gram = gram + diag[..., :, None] * np.eye(h.shape[-2])
        # F = H^H (H H^H + alpha I)^-1 = (solve((H H^H + alpha I)^H, H))^H; Gram is Hermitian.
        f0 = np.conj(np.swapaxes(np.linalg.solve(gram, h), -1, -2))
    return _scale_to_chain_power(f0, p_rf)


def _scale_to_chain_power(f0, p_rf):
    """c F0 with c^2 = p_rf / max row power (F0 = 0 stays 0)."""
    peak = np.max(chain_power(f0), axis=-1, initial=0.0)
    with np.errstate(divide="ignore"):
        c = np.where(peak > 0.0, np.sqrt(p_rf / np.where(peak > 0.0, peak, 1.0)), 0.0)
    return f0 * c[..., None, None]


def sinr_after_precoding(h_true, f_bb, ut_mask=None, noise_lin=1.0):
    """Per-UT SINR through the true channel of a precoder computed from another channel.

    Parameters
    ----------
    h_true : array_like of complex, shape (..., n_ut, n_beam)
        The channel the signal really goes through (noise-normalized).
    f_bb : array_like of complex, shape (..., n_beam, n_ut)
        Precoder from :func:`precoder_matrix` (computed from the estimated channel).
    ut_mask : array_like of bool, shape (..., n_ut), optional
        False for padding rows (SINR NaN there).
    noise_lin : float or ndarray, shape (..., n_ut)
        Noise (and any interference outside ``H``) power in the unit of ``H``.

    Returns
    -------
    ndarray, shape (..., n_ut)
        ``|[H F]_kk|^2 / (sum_{j != k} |[H F]_kj|^2 + noise_lin)`` [-] (linear).
    """
    g = np.abs(np.asarray(h_true, dtype=complex) @ np.asarray(f_bb, dtype=complex)) ** 2
    signal = np.diagonal(g, axis1=-2, axis2=-1)
    sinr = sinr_lin(signal, g.sum(axis=-1) - signal, noise_lin)
    if ut_mask is not None:
        sinr = np.where(ut_mask, sinr, np.nan)
    return sinr


def precode(h_est, kind, h_true=None, p_rf=1.0, serving_beam=None, ut_mask=None, beam_mask=None):
    """``F_BB`` from ``h_est`` and the SINR it gives through ``h_true`` (default: ``h_est``).

    Shapes and units as :func:`precoder_matrix` and :func:`sinr_after_precoding`
    (noise power 1). With an ephemeris-error model the caller builds ``h_est`` from the
    directions the satellite computes from its believed position and ``h_true`` from the
    real ones; the mismatch leaves residual interference even under ZF.

    Returns
    -------
    f_bb : ndarray of complex, shape (..., n_beam, n_ut)
    sinr_lin : ndarray, shape (..., n_ut)
    """
    f_bb = precoder_matrix(h_est, kind, p_rf, serving_beam, ut_mask, beam_mask)
    h_true = h_est if h_true is None else h_true
    if beam_mask is not None:  # a dark beam radiates nothing, whatever its true channel
        h_true = np.where(np.asarray(beam_mask)[..., None, :], h_true, 0.0)
    return f_bb, sinr_after_precoding(h_true, f_bb, ut_mask)
