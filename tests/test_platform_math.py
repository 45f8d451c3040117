"""tests/platform_math.py: the tolerance the kernel checks fall back to on SVML machines."""

import numpy as np

from platform_math import ATOL_ANGLE_DB, NUMPY_IS_LIBM, ULPS, close, same


def test_close_is_ulps_of_the_larger_value_or_the_absolute_tolerance():
    x = np.array([1.0, 1e-300, 250.0, 0.0])
    up = x + ULPS * np.spacing(x)
    assert close(x, up).all()
    assert not close(x, x + (ULPS + 1) * np.spacing(x)).any()
    assert close(0.0, 0.5 * ATOL_ANGLE_DB, atol=ATOL_ANGLE_DB)
    assert not close(0.0, 2.0 * ATOL_ANGLE_DB, atol=ATOL_ANGLE_DB)
    nan, inf = float("nan"), float("inf")
    assert close([nan, inf, -inf], [nan, inf, -inf]).all()
    assert not close([nan, inf, 1.0, inf], [1.0, 1e308, inf, -inf]).any()


def test_same_keeps_dtype_shape_and_exact_integers():
    a = np.arange(4.0)
    assert same(a, a.copy()) and not same(a, a.astype(np.float32)) and not same(a, a[:3])
    assert not same(np.arange(3), np.array([0, 1, 3]))
    nudged = np.nextafter(a, np.inf)
    assert same(a, nudged) is (not NUMPY_IS_LIBM)  # exact where numpy's loops are libm's
