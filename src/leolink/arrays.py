"""Array helpers where numpy's general routine is slow for the tables leolink builds."""

from __future__ import annotations

import numpy as np

__all__ = [
    "KeyTable",
    "any_per_group",
    "nonzero_2d",
    "reduce_groups",
    "take_rows",
    "unique_inverse",
]

#: From this many entries on, the flat path of :func:`nonzero_2d` is faster (measured on
#: numpy 2.4: the two break even near 1,000 entries).
FLAT_MIN_SIZE = 1024


def nonzero_2d(mask):
    """``np.nonzero`` of a 2-D array: ``(rows, cols)``, the same indices in the same
    row-major order.

    numpy's N-d ``nonzero`` tracks both coordinates while it scans; dividing the flat
    indices by the row length is faster from about a thousand entries on (numpy 2.4 here:
    68 -> 25 us for a (1000, 16) table of 20 % hits, 1.29 -> 0.08 ms for (13, 37177) with
    203 hits). Smaller tables take numpy's own path.

    Parameters
    ----------
    mask : array_like, 2-D
        Entries that are not zero (or True) are returned.

    Returns
    -------
    rows, cols : ndarray of intp
    """
    mask = np.asarray(mask)
    if mask.ndim != 2:
        raise ValueError(f"nonzero_2d takes a 2-D array, not one of shape {mask.shape}")
    if mask.size < FLAT_MIN_SIZE:
        return np.nonzero(mask)
    rows, cols = np.divmod(np.flatnonzero(mask), mask.shape[1])
    return rows, cols


def reduce_groups(ufunc, x, size):
    """``ufunc`` reduced over each group of ``size`` consecutive entries on the last axis:
    ``x (..., n * size)`` -> ``(..., n)`` (a satellite's beams on a cell axis).

    One ``ufunc(out, slice, out=out)`` per position in the group, over strided slices:
    numpy's ``ufunc.reduce`` along a short last axis runs an inner loop per group (numpy
    2.4 here: ~3x slower for ``any`` of (1000, 31 * 15), the trigger run's satellite axis;
    ~5x for ``fmax``). Exact for an associative, commutative ``ufunc`` (``logical_or``,
    ``fmax``).

    Parameters
    ----------
    ufunc : numpy.ufunc, binary
    x : ndarray, last axis a multiple of ``size``
    size : int >= 1

    Returns
    -------
    ndarray of ``x``'s dtype, the last axis ``size`` times shorter
    """
    groups = x.reshape(*x.shape[:-1], x.shape[-1] // size, size)
    out = groups[..., 0].copy()
    for k in range(1, size):
        ufunc(out, groups[..., k], out=out)
    return out


def any_per_group(mask, size):
    """Whether any entry of each group of ``size`` consecutive entries on the last axis is
    set: ``mask (..., n * size)`` -> ``(..., n)``, bool (:func:`reduce_groups` of
    ``logical_or``)."""
    return reduce_groups(np.logical_or, np.asarray(mask, bool), size)


def take_rows(a, *index):
    """``a[index[0], index[1], ...]`` for non-negative integer arrays over ``a``'s leading
    axes: one ``np.take`` along the flattened leading axes.

    numpy's advanced indexing copies each selected row through its general iterator;
    ``np.take`` along axis 0 copies whole rows at once (numpy 2.4 here: 64,000 rows of 3
    floats out of a (64, 1, 3) array, 0.63 -> 0.12 ms).

    Parameters
    ----------
    a : ndarray, at least ``len(index)`` axes (not C-contiguous: numpy's indexing, as
        flattening its leading axes would copy it whole)
    *index : arrays of int, one per leading axis, broadcast together, each within its axis
        (no negative indices: they would select other rows)

    Returns
    -------
    ndarray, shape ``broadcast(index).shape + a.shape[len(index):]``
    """
    if not a.flags.c_contiguous:  # (flattening would copy the whole array first)
        return a[tuple(index)]
    lead = a.shape[: len(index)]
    flat = np.asarray(index[0], np.intp)
    for size, idx in zip(lead[1:], index[1:], strict=True):
        flat = flat * size + np.asarray(idx, np.intp)
    return np.take(a.reshape(-1, *a.shape[len(index) :]), flat, axis=0)


def unique_inverse(keys):
    """``np.unique(keys, return_inverse=True)`` of 1-D integer ``keys``: the sorted
    distinct keys and each key's index among them, in one linear pass where ``keys`` are
    sorted already (the search's pairs, epoch after epoch: numpy's sorts them again,
    numpy 2.4 here: 2.1 -> 0.4 ms for 64,000 keys).

    Returns
    -------
    unique : ndarray, shape (n_unique,)
    inverse : ndarray of intp, shape keys.shape
    """
    keys = np.asarray(keys)
    if keys.ndim != 1 or keys.size < 2 or (keys[1:] < keys[:-1]).any():
        return np.unique(keys, return_inverse=True)
    new = np.empty(keys.size, bool)
    new[0], new[1:] = True, keys[1:] != keys[:-1]
    return keys[new], np.cumsum(new, dtype=np.intp) - 1


class KeyTable:
    """A lookup of configured values by integer key (a cell, a satellite), the later of
    two entries for one key winning, vectorized over the queries.

    Parameters
    ----------
    keys : array_like of int, shape (n,)
    values : array_like, shape (n, ...)
    """

    def __init__(self, keys, values):
        keys = np.asarray(keys, np.int64).reshape(-1)
        values = np.asarray(values, float)
        last = len(keys) - 1 - np.unique(keys[::-1], return_index=True)[1]  # sorted keys
        self.keys, self.values = keys[last], values[last]

    def get(self, query, fill):
        """``values`` at each key of ``query`` (any shape), ``fill`` where it has none;
        shape ``query.shape + values.shape[1:]``."""
        query = np.asarray(query, np.int64)
        tail = self.values.shape[1:]
        if self.keys.size == 0:
            return np.full(query.shape + tail, fill, float)
        at = np.minimum(np.searchsorted(self.keys, query), self.keys.size - 1)
        hit = (self.keys[at] == query).reshape(query.shape + (1,) * len(tail))
        return np.where(hit, self.values[at], fill)
