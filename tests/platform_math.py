"""Whether this machine's numpy computes transcendental functions as the C library does.

The compiled kernels (engine/kernels.py) repeat the numpy code's operations one for one;
their ``np.arcsin``, ``np.log10``, ... lower to the C library's functions (LLVM's
intrinsics call libm). numpy's own float64 loops are the C library's too, except on CPUs
with AVX-512 (``AVX512_SKX`` and later), where numpy >= 1.22 dispatches ``arcsin``,
``arctan2``, ``log10``, ``log1p``, ``exp``, ``power`` and others to Intel's SVML: results
within a few ulp of the C library's, not its bits (measured on an AMD EPYC with
AVX512_ICL on 2026-12-02: 8 % of ``arcsin`` values 1 ulp off, 20 % of ``log10`` values up
to 2 ulp). ``sin``, ``cos`` and ``sqrt`` are the same bits everywhere.

Where :data:`NUMPY_IS_LIBM` is True the kernels must give numpy's bits; elsewhere
:func:`same` allows :data:`ULPS` units in the last place of each value (a value is a
short chain of such functions, each a few ulp off), and an absolute :data:`ATOL_ANGLE_DB`
for values in dB, radians or degrees (sums whose terms are much larger than they are).
"""

from __future__ import annotations

import math

import numpy as np

#: The functions numpy may take from SVML, each checked against Python's ``math`` (libm).
_PROBES = (
    (np.arcsin, math.asin, np.linspace(-0.999, 0.999, 4001)),
    (np.log10, math.log10, np.geomspace(1e-6, 1e6, 4001)),
    (np.log1p, math.log1p, np.geomspace(1e-6, 1e6, 4001)),
    (np.exp, math.exp, np.linspace(-30.0, 30.0, 4001)),
    (lambda y: np.arctan2(y, 0.3), lambda y: math.atan2(y, 0.3), np.linspace(-5, 5, 4001)),
    (lambda x: np.power(10.0, x), lambda x: 10.0**x, np.linspace(-8.0, 8.0, 4001)),
)


def _numpy_is_libm():
    for fn, ref, x in _PROBES:
        if not np.array_equal(fn(x), np.array([ref(v) for v in x.tolist()])):
            return False
    return True


#: numpy's transcendental loops give the C library's bits on this machine.
NUMPY_IS_LIBM = _numpy_is_libm()
#: Units in the last place allowed where they do not (see the module docstring).
ULPS = 16
#: Absolute tolerance of a value in dB, radians or degrees that ends a chain of such
#: functions: the terms of a dB sum reach ~200 dB (a path loss), so a sum near 0 keeps
#: their rounding, ~ULPS ulp of 256 (9e-13 dB; 9e-13 rad is 6 um at 6,371 km).
ATOL_ANGLE_DB = ULPS * float(np.spacing(256.0))


def close(a, b, ulps=ULPS, atol=0.0):
    """Elementwise: equal (NaN with NaN, infinities with themselves), or finite and within
    ``ulps`` units in the last place of the larger magnitude, or within ``atol``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = np.spacing(np.maximum(np.abs(a), np.abs(b)))
    with np.errstate(invalid="ignore"):
        near = np.abs(a - b) <= np.maximum(ulps * scale, atol)
    return (np.isfinite(a) & np.isfinite(b) & near) | (a == b) | (np.isnan(a) & np.isnan(b))


def same(a, b, atol=0.0):
    """The same dtype and shape, and the same values: bit for bit (NaN equal to NaN) where
    :data:`NUMPY_IS_LIBM`, else floats :func:`close` (integers and booleans still equal);
    ``atol`` (e.g. :data:`ATOL_ANGLE_DB` for dB, radians, degrees) only in the latter case."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if NUMPY_IS_LIBM or a.dtype.kind != "f":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(close(a, b, atol=atol).all())
