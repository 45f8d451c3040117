"""Closed-form complex response of the hybrid array's subarray beams (Sec. 2.1 and 3.2 of [1]).

The digital precoder ``F_BB`` needs the *complex* channel between each RF chain and each UT,
not only the gains. With the conventions of :mod:`leolink.antenna.array` (element
``n = i_x n_y + i_y`` at ``(i_x, i_y)`` half wavelengths from the array origin, steering
vector ``[a(u)]_n = exp(-i pi (i_x u_x + i_y u_y))``, column ``m`` of ``F_RF`` =
``exp(-i pi (i_x b_x + i_y b_y))`` on the elements of the subarray that radiates beam ``m``
and 0 elsewhere), the response of beam ``m`` towards direction ``u`` is

    h_m(u) = a(u)^H f_m / ||f_m||
           = exp(i pi [(x0 + (N_x - 1) / 2) d_x + (y0 + (N_y - 1) / 2) d_y])
             K(d_x, N_x) K(d_y, N_y) / sqrt(N_x N_y),

with ``d = u - b_m``, ``(x0, y0)`` the element indices of the subarray's first element
(:func:`subarray_origins`), ``N_x x N_y`` the subarray size and
``K(d, N) = sin(N pi d / 2) / sin(pi d / 2)`` the real (signed) Dirichlet kernel: the sum
``sum_{k<N} exp(i pi k d)`` is ``exp(i pi (N - 1) d / 2) K(d, N)``. The first factor is the
phase of the subarray's centre, ``x0 + (N_x - 1) / 2`` elements from the array origin.

Normalization: ``||f_m|| = sqrt(N_x N_y)``, so ``|h_m(u)|^2`` is exactly leolink's normalized
gain ``|a^H f|^2 / ||f||^2`` (:func:`leolink.antenna.array.beam_gain_lin`), peak
``N_x N_y``; a unit-power symbol on RF chain ``m`` (``||[F_BB]_{m,:}||^2 = 1``) then radiates
the per-beam power of the link budget, as in leolink's ``ptx_dbw`` convention.

Which subarray radiates which beam matters only for the phase: the gain ``|h_m|^2`` does
not depend on it, the relative phases between beams (hence ZF/MMSE) do. The common
range phase ``exp(-i 2 pi rho / lambda)`` of a UT multiplies a whole row of the channel
matrix and is left out (no SINR of :mod:`leolink.link.precoder` depends on row phases).

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
"""

import numpy as np

__all__ = ["beam_response", "chain_response", "subarray_origins"]

# |sin(pi d / 2)| below which K(d, N) is replaced by its limit N: the relative error of the
# limit is (N^2 - 1) x^2 / 6 < 1e-10 for N <= 1e3 at x = 1e-8.
_SIN_TINY = 1e-8


def subarray_origins(array):
    """Element indices ``(x0, y0)`` of the first element of each subarray (RF chain).

    Chain ``m = (i_x // n_sub_x) n_rf_y + i_y // n_sub_y`` (the paper's ``I_RF``, as
    :meth:`leolink.antenna.array.HybridArray.rf_index`), so chain ``m`` starts at
    ``x0 = (m // n_rf_y) n_sub_x``, ``y0 = (m % n_rf_y) n_sub_y``.

    Parameters
    ----------
    array : leolink.antenna.array.HybridArray

    Returns
    -------
    ndarray of int, shape (n_rf, 2)
        ``(x0, y0)`` in elements (half wavelengths) from the array origin.
    """
    m = np.arange(array.n_rf)
    return np.stack([(m // array.n_rf_y) * array.n_sub_x, (m % array.n_rf_y) * array.n_sub_y], -1)


def _signed_kernel(d, n):
    """Real Dirichlet kernel sin(n pi d / 2) / sin(pi d / 2) of d reduced to [-1, 1]."""
    x = 0.5 * np.pi * d
    s = np.sin(x)
    small = np.abs(s) < _SIN_TINY
    return np.where(small, float(n), np.sin(n * x) / np.where(small, 1.0, s))


def beam_response(u_xy, beam_u_xy, origin_xy, n_sub_x, n_sub_y):
    """Complex response ``a(u)^H f_m / ||f_m||`` of DFT beams on offset subarrays, closed form.

    Parameters
    ----------
    u_xy : array_like, shape (..., 2)
        Directions ``(u_x, u_y)`` in the satellite body frame [-].
    beam_u_xy : array_like, shape (..., n_beam, 2)
        Beam boresights [-], broadcastable against ``u_xy[..., None, :]`` (per-satellite
        beams: pass ``(n_sat, 1, n_beam, 2)`` with ``u_xy`` of shape ``(n_sat, n_ut, 2)``).
    origin_xy : array_like, shape (..., n_beam, 2)
        First element ``(x0, y0)`` of the subarray that radiates each beam [elements],
        e.g. ``subarray_origins(array)[chain]``; broadcastable like ``beam_u_xy``.
    n_sub_x, n_sub_y : int
        Subarray elements along x and y.

    Returns
    -------
    ndarray of complex, shape (..., n_beam)
        ``h``, with ``|h|^2`` the normalized gain (peak ``n_sub_x n_sub_y``).

    Notes
    -----
    Every term ``exp(i pi k d)`` has period 2 in ``d``, so ``d`` is reduced to ``[-1, 1]``
    first: the kernel's only 0/0 is then at ``d = 0`` (limit ``N``), and grating lobes
    (``d = +-2``) come out exact.
    """
    d = np.asarray(u_xy, dtype=float)[..., None, :] - np.asarray(beam_u_xy, dtype=float)
    d = d - 2.0 * np.round(0.5 * d)
    c = np.asarray(origin_xy, dtype=float) + 0.5 * (np.array([n_sub_x, n_sub_y]) - 1.0)
    phase = np.pi * (c[..., 0] * d[..., 0] + c[..., 1] * d[..., 1])
    amp = _signed_kernel(d[..., 0], n_sub_x) * _signed_kernel(d[..., 1], n_sub_y)
    return (amp / np.sqrt(n_sub_x * n_sub_y)) * np.exp(1j * phase)


def chain_response(u_xy, beam_u_xy, chain, array):
    """Response of beams radiated by given RF chains of a hybrid array; 0 for dark beams.

    Parameters
    ----------
    u_xy : array_like, shape (..., 2)
        Directions in the body frame [-].
    beam_u_xy : array_like, shape (..., n_beam, 2)
        Beam boresights [-], broadcastable as in :func:`beam_response`.
    chain : array_like of int, shape (..., n_beam)
        RF chain (subarray) radiating each beam, ``-1`` for a dark beam (response 0),
        e.g. from :func:`leolink.sim.beams.active.assign_chains`; broadcastable like the beams.
    array : leolink.antenna.array.HybridArray

    Returns
    -------
    ndarray of complex, shape (..., n_beam)
    """
    chain = np.asarray(chain)
    lit = chain >= 0
    origin = subarray_origins(array)[np.where(lit, chain, 0)]
    h = beam_response(u_xy, beam_u_xy, origin, array.n_sub_x, array.n_sub_y)
    return np.where(lit, h, 0.0)
