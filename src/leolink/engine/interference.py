"""Interference sums of the serving links: the serving satellite's same-colour (lit) beams,
and the other satellites' beams seen through the UT antenna pattern.

Functions of a :class:`~leolink.engine.LinkEngine` (its beam lattice, colours, terminal);
``lit`` masks restrict both to the beams a satellite lights (active beams, issue 14),
None keeps every beam (the default path, unchanged).
"""

from __future__ import annotations

import numpy as np

__all__ = ["other_satellites", "same_colour_total"]


def other_satellites(engine, snap, s, b, u, lit=None):
    """Interference over noise from the beams of the other satellites, per UT.

    Their beams of the serving beam's colour, at full power, seen through the UT antenna
    pointed at the serving satellite (``terminal.pattern_lin``); ``s``, ``b``: each UT's
    serving satellite (index into the snapshot's) and beam; ``lit`` (n_sat, n_beam): the
    beams each satellite lights (None: all).
    """
    bm = snap.gain_tx_bm  # (n_beam, n_sat, n_ut)
    same = (engine.colors[None, :] == engine.colors[b][:, None]).astype(float)  # (n_ut, n_beam)
    if lit is None:
        tx = np.einsum("bsu,ub->us", bm, same)  # same-colour TX gain of each satellite
    else:
        tx = np.einsum("bsu,ub,sb->us", bm, same, lit.astype(float))
    du = snap.u_panel - snap.u_panel[u, s][:, None, :]
    rx = engine.terminal.pattern_lin(du[..., 0], du[..., 1])  # (n_ut, n_sat)
    contrib = tx * rx * snap.path_no_rx_lin
    contrib[u, s] = 0.0  # the serving satellite is counted by same_colour_total
    return contrib.sum(axis=1)


def same_colour_total(engine, kx, ky, b, lit=None):
    """Sum of the TX gains of the lit beams that share the serving beam's colour, per row
    (``kx``, ``ky``: the rows' kernels, (n_k, n); ``lit`` (n, n_beam) or None)."""
    if lit is None and engine._full_reuse_lattice:
        # Full lattice, full reuse: sum_ij kx_i ky_j = (sum_i kx_i)(sum_j ky_j).
        return kx.sum(axis=0) * ky.sum(axis=0)
    # (n, n_beam), C-ordered: the sum over beams then adds in one order for any caller.
    g = np.ascontiguousarray((kx[engine.beam_ix] * ky[engine.beam_iy]).T)
    same = engine.colors[None, :] == engine.colors[b][:, None]
    if lit is not None:
        same = same & lit
    return np.einsum("ub,ub->u", g, same)
