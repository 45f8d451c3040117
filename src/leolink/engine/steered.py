"""Beam kernels of re-steered or quantized beams (:mod:`leolink.antenna.steering`).

With a steering mode that moves the beams (``earth_fixed``) or quantized phase shifters,
the beams of a pair are not the codebook's lattice: each satellite row has its own beam
centres ``v (n_s, n_beam, 2)``. The engine then keeps one kernel row per beam
(``beam_ix = beam_iy = arange(n_beam)``, so ``kx[beam_ix] ky[beam_iy]`` is still the
gain):

- ideal phases: ``kx[b] = k_x(u_x - v_bx)``, ``ky[b] = k_y(u_y - v_by)``, the closed form
  (a re-steered DFT beam is the DFT kernel centred at the cell's direction);
- quantized phases: ``kx[b]`` = the explicit array factor
  (:func:`~leolink.antenna.steering.quantized_gain_lin`), ``ky[b] = 1``.

A beam that is off (its cell outside the field of regard) has zero gain.

The screening bound (:func:`steered_bound_lin`): for ideal phases the best beam of a pair
is bounded by ``E_x(u_x) E_y(u_y)``, the Dirichlet envelopes at the distance to the
nearest of its satellite's beam centres along each axis (``max_b k_x k_y <= max_b k_x
max_b k_y``), as for the lattice. Quantized phases have sidelobes the envelope does not
bound, so the bound is ``n_x n_y`` (the peak of any unit-modulus weights): no pair above
the mask is pruned, which is rigorous and only slower.
"""

from __future__ import annotations

import numpy as np

from leolink.antenna.array import ula_gain
from leolink.antenna.steering import quantized_gain_lin

__all__ = [
    "beam_centres",
    "kernel_rows",
    "per_beam_steering",
    "steered_bound_lin",
    "steered_kernels",
]


def per_beam_steering(steering):
    """``steering`` if its beams need kernels of their own (they move, or have quantized
    phases), else None (the codebook's lattice: ideal body-fixed beams)."""
    if steering is None or not (steering.moves_beams or steering.phase_bits is not None):
        return None
    return steering


def kernel_rows(steering, beam_ix, beam_iy):
    """The engine's kernel row of each beam: the lattice's, or row b for beam b."""
    if steering is None:
        return beam_ix, beam_iy
    rows = np.arange(len(beam_ix))
    return rows, rows


def beam_centres(engine, sat_pos_m, axes, sat_id):
    """``(v (n_s, n_beam, 2), on (n_s, n_beam))`` of the satellite rows."""
    sat_id = np.arange(len(sat_pos_m)) if sat_id is None else np.asarray(sat_id)
    return engine.steering.beam_cosines(sat_pos_m, axes, sat_id)


def steered_kernels(engine, ux, uy, sat, v, on):
    """Kernel rows ``kx, ky (n_beam, m)`` of pairs seen at ``(ux, uy) (m,)`` from
    satellite rows ``sat (m,)`` whose beam centres are ``v``, ``on`` (module docstring)."""
    cb = engine.codebook
    vp, onp = v[sat], on[sat].T  # (m, n_beam, 2), (n_beam, m)
    if engine.steering.phase_bits is None:
        kx = ula_gain(ux[None, :] - vp[..., 0].T, cb.n_sub_x)
        ky = ula_gain(uy[None, :] - vp[..., 1].T, cb.n_sub_y)
    else:
        u = np.stack([ux, uy], axis=-1)
        kx = quantized_gain_lin(u, vp, cb.n_sub_x, cb.n_sub_y, engine.steering.phase_bits)
        ky = np.ones_like(kx)
    return np.where(onp, kx, 0.0), ky


def _envelope(u, centres, n):
    """``min(n, 1 / (n sin^2(pi d / 2)))``, ``d`` the distance (modulo 2) from ``u (n_u,
    n_s)`` to the nearest of each satellite's ``centres (n_s, n_beam)``."""
    d = np.full(u.shape, np.inf)
    for b in range(centres.shape[1]):
        dd = np.abs(u - centres[None, :, b])
        np.minimum(d, np.minimum(dd, 2.0 - dd), out=d)
    s = np.sin(0.5 * np.pi * np.clip(d, 0.0, 1.0))
    with np.errstate(divide="ignore", over="ignore"):
        return np.minimum(float(n), 1.0 / (n * s * s))


def steered_bound_lin(engine, ux, uy, sat_pos_m, axes, sat_id):
    """Upper bound of every beam's gain for directions ``ux, uy (n_u, n_s)`` of the
    satellites ``sat_pos_m (n_s, 3)`` (module docstring)."""
    cb = engine.codebook
    if engine.steering.phase_bits is not None:
        return np.full(ux.shape, float(cb.n_sub_x * cb.n_sub_y))
    v, _ = beam_centres(engine, sat_pos_m, axes, sat_id)
    # sin is computed exactly here (not from below): the slack of the screening covers its
    # rounding, ~1e-16 relative, as it covers the geometry's.
    return _envelope(ux, v[..., 0], cb.n_sub_x) * _envelope(uy, v[..., 1], cb.n_sub_y)
