"""Rician receive gain of the UT, Eqs. (15)-(17) of [1] (Sec. 4.1).

With the channel of Eq. (11) (Eq. (10) before the gain is factored out),
``H = gamma (a_u(v) + a_R / sqrt(K)) a_sat^H``, and the UT combiner ``w_u`` matched to
the known LoS direction, the receive gain is

    G_RX = |<a_u(v) + a_R / sqrt(K), w_u>|^2 / ||w_u||^2
         = |sqrt(N) e^{i phi} + g / sqrt(K)|^2,   g ~ CN(0, 1),

where ``N = |<a_u(v), w_u>|^2 / ||w_u||^2`` is the **LoS beamforming gain** of the UT
(linear, e.g. ``n_x n_y`` for a UPA steered exactly at the satellite) and, for
``Sigma = I``, ``<a_R, w_u> / ||w_u|| ~ CN(0, 1)``. The LoS phase does not change the
distribution, so it is dropped. Its mean is ``N + 1/K`` (Eq. (17), the paper's final
expression; Eq. (16) splits the mean into the LoS and diffuse terms).

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
"""

import numpy as np

__all__ = ["mean_rician_gain_lin", "rician_gain_from_draws_lin", "rician_gain_lin"]


def mean_rician_gain_lin(n_lin, k):
    """Mean receive gain ``N + 1/K``, Eq. (17) of [1].

    Parameters
    ----------
    n_lin : array_like
        LoS beamforming gain of the UT combiner, ``|<a_u(v), w_u>|^2 / ||w_u||^2``,
        linear (not dB).
    k : array_like
        Rician factor ``K_r`` (linear, > 0; the paper's Table: 10).

    Returns
    -------
    ndarray, broadcast shape
        Mean gain, linear.
    """
    return np.asarray(n_lin, dtype=float) + 1.0 / np.asarray(k, dtype=float)


def rician_gain_lin(n_lin, k, rng, size=None):
    """Random instantaneous receive gain ``|sqrt(N) + g / sqrt(K)|^2``, ``g ~ CN(0, 1)``.

    Parameters
    ----------
    n_lin : array_like
        LoS beamforming gain ``N`` of the UT (linear), see module docstring.
    k : array_like
        Rician factor ``K_r`` (linear, > 0).
    rng : numpy.random.Generator
        Source of randomness (one per run/UT, see DESIGN.md).
    size : int or tuple, optional
        Output shape; default the broadcast shape of ``n_lin`` and ``k``.

    Returns
    -------
    ndarray
        Gain samples, linear; mean ``N + 1/K`` (:func:`mean_rician_gain_lin`).
    """
    n = np.asarray(n_lin, dtype=float)
    k = np.asarray(k, dtype=float)
    if size is None:
        size = np.broadcast_shapes(n.shape, k.shape)
    # CN(0, 1): real and imaginary parts N(0, 1/2).
    g = (rng.standard_normal(size) + 1j * rng.standard_normal(size)) * np.sqrt(0.5)
    return rician_gain_from_draws_lin(n, k, g)


def rician_gain_from_draws_lin(n_lin, k, g):
    """``|sqrt(N) + g / sqrt(K)|^2`` for given ``g ~ CN(0, 1)`` draws (e.g. counter-based
    ones of :mod:`leolink.rng`, one per UT and epoch)."""
    return np.abs(np.sqrt(n_lin) + g / np.sqrt(k)) ** 2
