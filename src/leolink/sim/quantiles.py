"""Exact median and percentiles of small tables, numpy's values bit for bit, without
loading ``numpy.ma``: numpy.median, numpy.percentile and numpy.unique import it on first
use, 7-11 ms of a small run's start (docs/speed_history.md).

Streams of samples get :mod:`leolink.sim.histograms` instead (bounded memory).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["median", "percentile_of_sorted"]


def median(values):
    """numpy.median of finite values.

    Parameters
    ----------
    values : float array (n,), n >= 1, finite.

    Returns
    -------
    float : the middle value, or the mean ``(a + b) / 2`` of the two middle ones.
    """
    v = np.asarray(values, np.float64)
    half = v.size // 2
    # numpy takes the mean of the middle slice: a sum from +0.0 (so -0.0 comes out +0.0).
    if v.size % 2:
        return float(0.0 + np.partition(v, half)[half])
    middle = np.partition(v, [half - 1, half])
    return float((0.0 + middle[half - 1] + middle[half]) / 2)


def percentile_of_sorted(sorted_values, q_percent):
    """numpy.percentile (linear, Hyndman and Fan's 7th method) of sorted finite values.

    Parameters
    ----------
    sorted_values : float array (n,), n >= 1, finite, ascending.
    q_percent : float in [0, 100].

    Returns
    -------
    float : between the two values around the rank ``(n - 1) q / 100``, computed from the
    nearer one as numpy's ``_lerp`` does (the same rounding).
    """
    s = np.asarray(sorted_values, np.float64)
    rank = (s.size - 1) * (q_percent / 100)
    if rank >= s.size - 1:
        # numpy's index of the last value is -1, and its weight the rank's distance from
        # it: rank + 1 (which decides the zero's sign of a last value -0.0).
        a = b = float(s[-1])
        t = rank + 1
    else:
        below = math.floor(rank)
        a, b = float(s[below]), float(s[below + 1])
        t = rank - below
    return b - (b - a) * (1 - t) if t >= 0.5 else a + (b - a) * t
