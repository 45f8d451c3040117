"""Active beams: which codebook beams each satellite lights in an epoch, and on which chain.

The paper: "some active beams will be selected from the set available in the codebook"
depending on where the users are (Sec. 3.2 of [1]); each RF chain drives one subarray and
radiates one beam (Sec. 2.1), so a codebook may hold more beams than chains but at most
``n_rf`` are lit at once. Only lit beams radiate (and interfere); the controller chooses
among lit beams (:func:`restrict_to_lit`).

Selectors (pure functions, boolean ``lit`` masks of shape ``(n_sat, n_beam)``):

- :func:`select_all`: every beam, allowed only when ``n_beam <= n_rf`` (today's leolink).
- :func:`select_demand`: the ``n_rf`` beams whose cells (UTs whose best beam it is) hold
  the most UTs; ties go to the lower ``beam_id``; empty cells stay dark.
- :func:`select_greedy_sum_rate`: beams added one at a time, each time the one that most
  raises the delivered sum rate without precoder (module function's docstring).
- :func:`select_hopping`: a beam-hopping illumination pattern (rows = dwells, as the
  beam-hopping super-frames of DVB-S2X [2] Annex E carry), cycled with a dwell per row.

Chain assignment (:func:`assign_chains`), a leolink decision: the lit beams of a
satellite, in ascending ``beam_id`` order, take chains ``0, 1, ...``. When every beam of a
codebook with ``n_beam = n_rf`` is lit this is the identity of
:meth:`leolink.antenna.array.HybridArray.precoder` (beam ``m`` on chain ``m``; for the
paper's 5 x 3 codebook and 5 x 3 subarrays, both row-major by (x, y), each beam's
subarray sits where its footprint is). The chain changes no gain, only the phase of the
beam's response (the subarray's phase centre, :mod:`leolink.antenna.response`), which
matters for the digital precoder only.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] ETSI EN 302 307-2 V1.3.1 (2021-07), DVB-S2X, Annex E (super-frame formats for
   beam hopping).
"""

import numpy as np

from leolink.errors import ConfigError
from leolink.link.budget import sinr_lin, spectral_efficiency_bps_hz

__all__ = [
    "DARK_BEAM_FALLBACKS",
    "assign_chains",
    "cell_counts",
    "default_hopping_pattern",
    "hopping_slot",
    "illumination_fraction",
    "restrict_to_lit",
    "select_all",
    "select_demand",
    "select_greedy_sum_rate",
    "select_hopping",
    "validate_pattern",
]

#: What a UT whose best beam is dark does (:func:`restrict_to_lit`).
DARK_BEAM_FALLBACKS = ("neighbour", "wait")


def select_all(n_sat, n_beam, n_rf):
    """Every beam lit; the codebook must not hold more beams than RF chains.

    Returns
    -------
    ndarray of bool, shape (n_sat, n_beam)
    """
    if n_beam > n_rf:
        raise ConfigError(
            f"beams.active = 'all' lights {n_beam} beams but the array has n_rf = {n_rf} RF "
            "chains; use 'demand' or 'hopping', or fewer beams"
        )
    return np.ones((n_sat, n_beam), bool)


def cell_counts(sat_idx, best_beam, n_sat, n_beam):
    """UTs per (satellite, beam) cell: UT ``k`` counts for ``(sat_idx[k], best_beam[k])``.

    Parameters
    ----------
    sat_idx, best_beam : array_like of int, shape (n_ut,)
        Satellite and best codebook beam of each UT; ``-1`` = not counted.

    Returns
    -------
    ndarray of int, shape (n_sat, n_beam)
    """
    sat_idx, best_beam = np.asarray(sat_idx), np.asarray(best_beam)
    ok = (sat_idx >= 0) & (best_beam >= 0)
    flat = sat_idx[ok] * n_beam + best_beam[ok]
    return np.bincount(flat, minlength=n_sat * n_beam).reshape(n_sat, n_beam)


def select_demand(counts, n_rf):
    """Light the (at most) ``n_rf`` beams whose cells hold the most UTs.

    Parameters
    ----------
    counts : array_like of int, shape (n_sat, n_beam)
        UTs per cell (:func:`cell_counts`).
    n_rf : int
        RF chains per satellite.

    Returns
    -------
    ndarray of bool, shape (n_sat, n_beam)
        Lit beams: the top ``n_rf`` counts, ties to the lower ``beam_id``; cells without
        UTs stay dark (a dark beam adds no interference).
    """
    counts = np.asarray(counts)
    order = np.argsort(-counts, axis=-1, kind="stable")  # stable: ties by beam_id
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.arange(counts.shape[-1]), axis=-1)
    return (rank < n_rf) & (counts > 0)


def _delivered_sum_rate(snr, trial):
    """Sum over lit beams of the mean rate of their UTs, no precoder, (n_sat, n_cand).

    snr (n_sat, 1, n_ut, n_beam) linear, 0 for absent UTs; trial (n_sat, n_cand, n_beam).
    """
    s = snr * trial[:, :, None, :]
    best = np.argmax(s, axis=-1)  # each UT on its best lit beam
    sig = np.take_along_axis(s, best[..., None], axis=-1)[..., 0]
    rate = spectral_efficiency_bps_hz(sinr_lin(sig, s.sum(-1) - sig, 1.0))
    present = sig > 0.0
    one_hot = (best[..., None] == np.arange(s.shape[-1])) & present[..., None]
    rate_sum = np.einsum("scub,scu->scb", one_hot, rate)
    n = one_hot.sum(axis=-2)
    return np.sum(rate_sum / np.maximum(n, 1), axis=-1)


def select_greedy_sum_rate(snr_lin, n_rf):
    """Greedy beam activation for the delivered sum rate, without digital precoder.

    The delivered rate of a lit beam is the mean ``log2(1 + SINR)`` of the UTs it serves
    (one UT per beam per slot, round robin), each UT on its best lit beam with the other
    lit beams as interference. Starting from no beam, the beam that most raises the sum
    over beams is lit, until ``n_rf`` are lit or no beam raises it (lighting a beam over
    few UTs can cost its neighbours more than it brings).

    Parameters
    ----------
    snr_lin : array_like, shape (n_sat, n_ut, n_beam)
        Linear SNR of every UT in every codebook beam of each satellite (full power, the
        engine's ``gain_tx_lin * path_snr_lin``); 0 or NaN for UTs the satellite does not
        serve.
    n_rf : int
        RF chains per satellite.

    Returns
    -------
    ndarray of bool, shape (n_sat, n_beam)
    """
    snr = np.nan_to_num(np.asarray(snr_lin, dtype=float), nan=0.0)[:, None]
    n_sat, n_beam = snr.shape[0], snr.shape[-1]
    lit = np.zeros((n_sat, n_beam), bool)
    current = np.zeros(n_sat)
    eye = np.eye(n_beam, dtype=bool)
    for _ in range(min(n_rf, n_beam)):  # <= n_rf steps; vectorized over sats, beams, UTs
        trial = lit[:, None, :] | eye[None]
        value = np.where(lit, -np.inf, _delivered_sum_rate(snr, trial))
        pick = np.argmax(value, axis=-1)  # ties: lower beam_id
        gain = np.take_along_axis(value, pick[:, None], -1)[:, 0] > current
        lit[np.flatnonzero(gain), pick[gain]] = True
        current = np.where(gain, value[np.arange(n_sat), pick], current)
        if not gain.any():
            break
    return lit


def validate_pattern(pattern, n_rf):
    """Check a hopping pattern: boolean ``(n_dwell, n_beam)``, at most ``n_rf`` per dwell.

    Returns
    -------
    ndarray of bool, shape (n_dwell, n_beam)
    """
    p = np.asarray(pattern)
    if p.ndim != 2 or p.shape[0] < 1 or p.dtype != bool:
        raise ConfigError(
            f"beams.hopping pattern has shape {p.shape} and dtype {p.dtype}; use a boolean "
            "(n_dwell, n_beam) table, one row per dwell"
        )
    over = np.flatnonzero(p.sum(axis=1) > n_rf)
    if over.size:
        raise ConfigError(
            f"beams.hopping dwell {int(over[0])} lights {int(p[over[0]].sum())} beams; "
            f"the array has n_rf = {n_rf} RF chains (at most one beam per chain)"
        )
    return p


def default_hopping_pattern(n_beam, n_rf):
    """Illumination pattern covering the codebook in ``ceil(n_beam / n_rf)`` dwells.

    Dwell ``g`` lights beams ``g, g + G, g + 2 G, ...`` (``G`` dwells): each beam once per
    cycle; ``ceil(n_beam / G) <= n_rf`` beams per dwell; beams lit together are ``G``
    apart in ``beam_id`` (row-major lattice order), which keeps neighbours apart.

    Returns
    -------
    ndarray of bool, shape (G, n_beam)
    """
    n_dwell = -(-n_beam // n_rf)
    return np.arange(n_beam)[None, :] % n_dwell == np.arange(n_dwell)[:, None]


def _cycle(dwell_s, n_dwell):
    """Dwell durations (n_dwell,) [s] and their start times within the cycle."""
    dwell_s = np.broadcast_to(np.asarray(dwell_s, dtype=float), (n_dwell,))
    if np.any(~(dwell_s > 0.0)):
        raise ConfigError(f"beams.hopping dwell_s = {dwell_s.tolist()!r}; use durations > 0 s")
    return dwell_s, np.concatenate([[0.0], np.cumsum(dwell_s)])


def hopping_slot(t_s, dwell_s, n_dwell):
    """Index of the dwell (pattern row) active at times ``t_s`` (cycle starts at t = 0).

    Parameters
    ----------
    t_s : array_like
        Times [s].
    dwell_s : float or array_like, shape (n_dwell,)
        Duration of each dwell [s], > 0.
    n_dwell : int
        Rows of the pattern.

    Returns
    -------
    ndarray of int, shape of ``t_s``
    """
    _, edges = _cycle(dwell_s, n_dwell)
    phase = np.mod(np.asarray(t_s, dtype=float), edges[-1])
    return np.clip(np.searchsorted(edges, phase, side="right") - 1, 0, n_dwell - 1)


def select_hopping(t_s, pattern, dwell_s, n_rf):
    """Lit beams at times ``t_s`` under a hopping pattern, shape ``t_s.shape + (n_beam,)``."""
    p = validate_pattern(pattern, n_rf)
    return p[hopping_slot(t_s, dwell_s, p.shape[0])]


def illumination_fraction(t_start_s, t_end_s, pattern, dwell_s):
    """Fraction of ``[t_start_s, t_end_s)`` during which each beam is lit, exact.

    For an epoch longer than a dwell: the time share that a beam's UTs can be served.

    Returns
    -------
    ndarray, shape (n_beam,)
        In ``[0, 1]``.
    """
    p = np.asarray(pattern, bool)
    dwell, edges = _cycle(dwell_s, p.shape[0])
    period = edges[-1]

    def lit_time(t):  # beam-seconds lit in [0, t), (n_beam,)
        n_cycles, rest = np.divmod(t, period)
        within = np.clip(rest - edges[:-1], 0.0, dwell)  # (n_dwell,)
        return n_cycles * (dwell @ p) + within @ p

    span = t_end_s - t_start_s
    if not span > 0.0:
        raise ConfigError(f"illumination window [{t_start_s}, {t_end_s}) is empty")
    return (lit_time(t_end_s) - lit_time(t_start_s)) / span


def assign_chains(lit, n_rf):
    """RF chain of each lit beam: lit beams by ascending ``beam_id`` take chains 0, 1, ...

    Parameters
    ----------
    lit : array_like of bool, shape (..., n_beam)
    n_rf : int

    Returns
    -------
    ndarray of int, shape (..., n_beam)
        Chain index, ``-1`` for dark beams.

    Raises
    ------
    ConfigError
        If a row lights more than ``n_rf`` beams.
    """
    lit = np.asarray(lit, bool)
    n_lit = lit.sum(axis=-1)
    if np.any(n_lit > n_rf):
        raise ConfigError(
            f"{int(n_lit.max())} beams lit at once but the array has n_rf = {n_rf} RF chains"
        )
    return np.where(lit, np.cumsum(lit, axis=-1) - 1, -1)


def restrict_to_lit(snr_db, lit, fallback="neighbour"):
    """SNR table the controller chooses from: dark beams removed.

    Parameters
    ----------
    snr_db : array_like, shape (n_ut, n_sat, n_beam)
        SNR of every codebook beam [dB] (engine), NaN where not visible.
    lit : array_like of bool, shape (n_sat, n_beam)
    fallback : {"neighbour", "wait"}
        ``"neighbour"``: a UT whose best beam is dark is served by its best lit beam (of
        any satellite), typically an adjacent cell a few dB down. ``"wait"``: such a UT
        gets no candidate this epoch (outage until its beam is lit: the beam-hopping
        model, where a UT is served during its own beam's dwell).

    Returns
    -------
    snr_db : ndarray, shape (n_ut, n_sat, n_beam)
        NaN on dark beams (and, under ``"wait"``, on every beam of a waiting UT).
    best_dark : ndarray of bool, shape (n_ut,)
        UTs whose best visible beam is dark (under ``"neighbour"`` they are served by a
        lit neighbour; under ``"wait"`` they are in outage: trace reason ``beam_dark``).
    """
    if fallback not in DARK_BEAM_FALLBACKS:
        raise ConfigError(
            f"beams.dark_fallback = {fallback!r} is not allowed; use one of {DARK_BEAM_FALLBACKS}"
        )
    snr = np.asarray(snr_db, dtype=float)
    lit = np.asarray(lit, bool)
    n_ut = snr.shape[0]
    flat = np.where(np.isnan(snr), -np.inf, snr).reshape(n_ut, -1)
    best = np.argmax(flat, axis=1)
    has_any = np.isfinite(flat[np.arange(n_ut), best])
    best_dark = has_any & ~lit.reshape(-1)[best]
    out = np.where(lit[None], snr, np.nan)
    if fallback == "wait":
        out[best_dark] = np.nan
    return out, best_dark
