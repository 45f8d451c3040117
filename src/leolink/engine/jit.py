"""Compiled kernels (numba), optional: the same numbers as the numpy code they replace.

numba is imported on first use only, and only for work large enough to repay its start-up
(``JIT_MIN_PAIRS``); ``LEOLINK_JIT=0`` in the environment turns every kernel off (the
numpy code then runs everywhere). Kernels compile once per machine (``cache=True``).

:func:`screen_kernel` is the fused form of :func:`leolink.engine.screening.screen`: it
decides which pairs the engine evaluates, never a value that reaches an output, so it
may (and does) round differently from the numpy screening; both bounds are rigorous.
"""

from __future__ import annotations

import functools
import os

__all__ = ["JIT_MIN_PAIRS", "enabled", "screen_kernel"]

#: Smallest number of (UT, satellite) pairs per call worth a compiled kernel.
JIT_MIN_PAIRS = 20_000


@functools.cache
def enabled():
    """Whether numba is installed and not turned off (``LEOLINK_JIT=0``)."""
    if os.environ.get("LEOLINK_JIT", "1").strip() in ("0", "false", "no", "off"):
        return False
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


@functools.cache
def screen_kernel():
    """The compiled screening loop (see :func:`_screen_loop`)."""
    import numba

    return numba.njit(cache=True, nogil=True)(_screen_loop)


def _screen_loop(ut_pos, ut_up, sphere, sat_pos, ax_x, ax_y, bx, by, nx, ny, k_lin, s_min, band,
                 slack, ut_factor, code, bound, sin_out):  # fmt: skip
    """Fill ``code``, ``bound`` and ``sin_out`` (n_u, n_s) as ``screening.screen`` does.

    ``ut_factor (n_u,)``: each UT's ``G_rx / L_atm`` bound where it does not depend on
    the elevation (1 elsewhere: the caller multiplies it in afterwards). The envelope's
    sine is bounded below by its Taylor polynomial to x^7 (an alternating series: the
    partial sum after a negative term is below ``sin x`` on ``[0, pi]``), so the bound
    only grows.
    """
    n_u, n_s = code.shape
    half_pi = 1.5707963267948966
    for i in range(n_u):
        px, py, pz = ut_pos[i, 0], ut_pos[i, 1], ut_pos[i, 2]
        if sphere:
            r = (px * px + py * py + pz * pz) ** 0.5
            ex, ey, ez = px / r, py / r, pz / r
        else:
            ex, ey, ez = ut_up[i, 0], ut_up[i, 1], ut_up[i, 2]
        for j in range(n_s):
            dx, dy, dz = px - sat_pos[j, 0], py - sat_pos[j, 1], pz - sat_pos[j, 2]
            rho2 = dx * dx + dy * dy + dz * dz
            rho = rho2**0.5
            s_el = -(dx * ex + dy * ey + dz * ez) / rho
            sin_out[i, j] = s_el
            if s_el < s_min - band:
                code[i, j] = 0
                bound[i, j] = -1.0
                continue
            code[i, j] = 2 if s_el >= s_min + band else 1
            ux = (dx * ax_x[j, 0] + dy * ax_x[j, 1] + dz * ax_x[j, 2]) / rho
            uy = (dx * ax_y[j, 0] + dy * ax_y[j, 1] + dz * ax_y[j, 2]) / rho
            g = k_lin * (1.0 + slack) / rho2 * ut_factor[i]
            for u, beams, n in ((ux, bx, nx), (uy, by, ny)):
                d = 2.0 - max(u - beams[0], beams[-1] - u)
                for b in beams:
                    d = min(d, abs(u - b))
                x = half_pi * min(max(d, 0.0), 1.0)
                x2 = x * x
                s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0)))
                g *= min(float(n), 1.0 / (n * s * s)) if s > 0.0 else float(n)
            bound[i, j] = g
