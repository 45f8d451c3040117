"""The compiled kernel of :func:`leolink.visibility.tle_elevations_rad` (``leolink._kernels``,
C; imported by :mod:`leolink.visibility` only when the extension is built).

It repeats the numpy code's operations one for one, in the same order (the sums start
from 0.0 as the numpy accumulators do), so that ``sin(elevation) = n . d / |d|`` gets the
numpy code's bits; the arcsine is not the C library's (numpy's float64 loop on x86-64
without AVX-512) but :func:`asin`, fdlibm's, which has no branch, so the loop is
vectorized (the C library's scalar ``asin`` took ~70 % of the kernel's time): the two
differ by at most 1 ulp (2.2e-16 rad, ``tests/test_visibility.py``). Each site is one
thread's and every lane does the same operations (no contraction into FMA), so neither
the thread count nor the vector width (8 doubles with AVX-512, 4 with AVX2, 2 elsewhere:
the loop's clone is chosen when the module loads) changes a bit. The sines and the
arcsines of a row are two loops over chunks of 256 times (3.5 ns an elevation on one
thread here, 6.5 as one loop, 4.2 with the numba kernel it replaced). No temporaries
beyond a chunk: the work is the arithmetic, not the memory.
"""

from __future__ import annotations

import numpy as np

from leolink import _kernels

__all__ = ["asin", "elevations"]

#: ``elevations(r, site, normal, out, t0, lo, hi)``: fill ``out[i, s, t0 + k]`` with
#: ``asin(n_i . d / |d|)``, ``d = r[:, s n_t + k] - site_i``, for ``k < n_t = r.shape[1] /
#: n_sat`` and the sites ``lo .. hi - 1``, without the GIL. ``r`` (3, n_sat n_t): Earth-fixed
#: satellite positions [m], satellite-major, C-contiguous rows; ``site``, ``normal``
#: (n_site, 3): site positions [m] and ellipsoid normals; ``out`` (n_site, n_sat, n_time),
#: float64 or float32, C-contiguous: the whole result, not a block's view (unit-stride
#: stores are what the compiler vectorizes).
elevations = _kernels.elevations


def asin(x):
    """Arcsine of every value of ``x`` in [-1, 1] [rad], the kernel's: fdlibm's method
    (FreeBSD msun ``e_asin.c``), every branch computed and one selected; NaN stays NaN.

    |x| < 0.5: ``x + x R(x**2)``; else, with ``z = (1 - |x|) / 2`` (exact) and
    ``s = sqrt(z)``, ``asin|x| = pi/2 - 2 (s + s R(z))``: as is for |x| >= 0.975, else with
    ``s = f + c`` split (``f`` the high part of ``s``, Veltkamp's split) so that
    ``pi/4 - 2 f`` loses nothing. Within 1 ulp of the C library's ``asin``
    (``tests/test_visibility.py``).
    """
    x = np.ascontiguousarray(x, float)
    out = np.empty_like(x)
    _kernels.asin_of(x.reshape(-1), out.reshape(-1))
    return out
