"""The numba kernel of :func:`leolink.visibility.tle_elevations_rad` (numba required;
imported by :mod:`leolink.visibility` only when compiled kernels are on).

It repeats the numpy code's operations one for one, in the same order (the sums start
from 0.0 as the numpy accumulators do), so that ``sin(elevation) = n . d / |d|`` gets the
numpy code's bits; the arcsine is not the C library's (numpy's float64 loop on x86-64
without AVX-512) but :func:`asin`, fdlibm's, which has no branch, so the loop is
vectorized (AVX2: 4 elevations at a time; the C library's scalar ``asin`` took ~70 % of
the kernel's time): the two differ by at most 1 ulp (2.2e-16 rad,
``tests/test_visibility.py``). Each site is one thread's and every lane does the same
operations (no contraction into FMA: numba does not allow it without ``fastmath``), so
neither the thread count nor the vector width changes a bit. No temporaries: the work is
the arithmetic, not the memory.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# FreeBSD msun e_asin.c (fdlibm 5.3; Copyright (C) 1993 by Sun Microsystems, Inc.:
# "Permission to use, copy, modify, and distribute this software is freely granted,
# provided that this notice is preserved"): pi/2 and pi/4 split in a high and a low part,
# and the rational R(z) = P(z) / Q(z) of (asin(x) - x) / x**3 at z = x**2 on [0, 0.25]
# (its Remez error < 2**-58.75).
_PIO2_HI, _PIO2_LO = 1.57079632679489655800e00, 6.12323399573676603587e-17
_PIO4_HI = 7.85398163397448278999e-01
_P0, _P1, _P2 = 1.66666666666666657415e-01, -3.25565818622400915405e-01, 2.01212532134862925881e-01
_P3, _P4, _P5 = -4.00555345006794114027e-02, 7.91534994289814532176e-04, 3.47933107596021167570e-05
_Q1, _Q2 = -2.40339491173441421878e00, 2.02094576023350569471e00
_Q3, _Q4 = -6.88283971605453293030e-01, 7.70381505559019352791e-02
#: 2**27 + 1: Veltkamp's splitter, whose high part of ``s`` has 26 bits (``f * f`` is exact).
_SPLIT = 134217729.0


@numba.njit(inline="always", nogil=True, error_model="numpy")
def asin(x):
    """Arcsine of ``x`` in [-1, 1] [rad], fdlibm's method (FreeBSD msun ``e_asin.c``),
    every branch computed and one selected (vectorizable); NaN stays NaN.

    |x| < 0.5: ``x + x R(x**2)``; else, with ``z = (1 - |x|) / 2`` (exact) and
    ``s = sqrt(z)``, ``asin|x| = pi/2 - 2 (s + s R(z))``: as is for |x| >= 0.975, else
    with ``s = f + c`` split (``f`` the high part of ``s``) so that ``pi/4 - 2 f`` loses
    nothing. fdlibm clears the low 32 bits of ``s`` for ``f``; Veltkamp's split here (no
    bit access in numba), any ``f`` whose square is exact will do. Within 1 ulp of the C
    library's ``asin`` (``tests/test_visibility.py``).
    """
    a = abs(x)
    small = a < 0.5
    z = a * a if small else (1.0 - a) * 0.5
    p = z * (_P0 + z * (_P1 + z * (_P2 + z * (_P3 + z * (_P4 + z * _P5)))))
    q = 1.0 + z * (_Q1 + z * (_Q2 + z * (_Q3 + z * _Q4)))
    r = p / q
    s = np.sqrt(z)
    near_one = _PIO2_HI - (2.0 * (s + s * r) - _PIO2_LO)
    hi = _SPLIT * s
    f = hi - (hi - s)
    c = (z - f * f) / (s + f)
    middle = _PIO4_HI - ((2.0 * s * r - (_PIO2_LO - 2.0 * c)) - (_PIO4_HI - 2.0 * f))
    y = a + a * r if small else (near_one if a >= 0.975 else middle)
    return math.copysign(y, x)  # asin(-0.0) = -0.0, as the C library's


@numba.njit(cache=True, parallel=True, nogil=True, error_model="numpy")
def elevations(r, site, normal, out, t0):
    """Fill ``out[i, s, t0 + k]`` with ``asin(n_i . d / |d|)``, ``d = r[:, s n_t + k] -
    site_i``, for ``k < n_t = r.shape[1] / n_sat``.

    Parameters
    ----------
    r : ndarray, shape (3, n_sat * n_t)
        Earth-fixed satellite positions [m], satellite-major.
    site, normal : ndarray, shape (n_site, 3)
        Site positions [m] and ellipsoid normals.
    out : ndarray, shape (n_site, n_sat, n_time), float64 or float32, C-contiguous
        The whole result, not a block's view: a strided view's unknown stride keeps
        LLVM from vectorizing the stores (3x the time).
    t0 : int, the block's first time.
    """
    n_site, n_sat = out.shape[0], out.shape[1]
    n_t = r.shape[1] // n_sat
    for i in numba.prange(n_site):
        s0, s1, s2 = site[i, 0], site[i, 1], site[i, 2]
        u0, u1, u2 = normal[i, 0], normal[i, 1], normal[i, 2]
        for s in range(n_sat):
            row = out[i, s]
            for k in range(n_t):
                p = s * n_t + k
                d0, d1, d2 = r[0, p] - s0, r[1, p] - s1, r[2, p] - s2
                rho = np.sqrt(((0.0 + d0 * d0) + d1 * d1) + d2 * d2)
                up = (((0.0 + d0 * u0) + d1 * u1) + d2 * u2) / rho
                if up > 1.0:  # np.clip, which keeps NaN
                    up = 1.0
                elif up < -1.0:
                    up = -1.0
                row[t0 + k] = asin(up)
