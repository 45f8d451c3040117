"""The numba kernel of :func:`leolink.visibility.tle_elevations_rad` (numba required;
imported by :mod:`leolink.visibility` only when compiled kernels are on).

It repeats the numpy code's operations one for one, in the same order (the sums start
from 0.0 as the numpy accumulators do, the arcsine is the C library's, as numpy's float64
loop on x86-64 without AVX-512), so that an elevation gets the same bits from either
(``tests/test_visibility.py``); each site is one thread's, so the thread count does not
change them. No temporaries: the work is the arithmetic, not the memory.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, parallel=True, nogil=True)
def elevations(r, site, normal, out):
    """Fill ``out[i, s, k]`` with ``asin(n_i . d / |d|)``, ``d = r[:, s n_t + k] - site_i``.

    Parameters
    ----------
    r : ndarray, shape (3, n_sat * n_t)
        Earth-fixed satellite positions [m], satellite-major.
    site, normal : ndarray, shape (n_site, 3)
        Site positions [m] and ellipsoid normals.
    out : ndarray, shape (n_site, n_sat, n_t), float64 or float32 (any strides)
    """
    n_site, n_sat, n_t = out.shape
    for i in numba.prange(n_site):
        s0, s1, s2 = site[i, 0], site[i, 1], site[i, 2]
        u0, u1, u2 = normal[i, 0], normal[i, 1], normal[i, 2]
        for s in range(n_sat):
            for k in range(n_t):
                p = s * n_t + k
                d0, d1, d2 = r[0, p] - s0, r[1, p] - s1, r[2, p] - s2
                rho = np.sqrt(((0.0 + d0 * d0) + d1 * d1) + d2 * d2)
                up = (((0.0 + d0 * u0) + d1 * u1) + d2 * u2) / rho
                if up > 1.0:  # np.clip, which keeps NaN
                    up = 1.0
                elif up < -1.0:
                    up = -1.0
                out[i, s, k] = np.arcsin(up)
