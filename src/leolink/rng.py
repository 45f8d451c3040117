"""Counter-based random numbers: one stream per UT, drawn for all UTs at once.

A ``numpy.random.Generator`` per UT would force a Python loop per UT per epoch. Instead
each UT gets a 64-bit key from ``SeedSequence(seed).spawn`` (as DESIGN.md asks), and the
draw of UT ``u`` at epoch ``k`` is a pure function of ``(key_u, k, stream)`` (SplitMix64
finalizer). Results therefore do not depend on chunking, ordering or process count.
"""

import numpy as np

from leolink import compiled

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def ut_keys(seed, n_ut, ut_ids=None):
    """One 64-bit key per UT, from ``SeedSequence(seed).spawn(n_ut)``.

    Parameters
    ----------
    seed : int
    n_ut : int, UTs of the run.
    ut_ids : array_like of int or None
        Only these UTs' keys (a part of a split run): ``ut_keys(seed, n_ut)[ut_ids]``,
        built from each UT's own child ``SeedSequence(seed, spawn_key=(id,))``, as
        ``spawn`` builds them, without the others.

    Returns
    -------
    ndarray of uint64, shape (n_ut,) or (len(ut_ids),)
    """
    root = np.random.SeedSequence(seed)
    if ut_ids is None:
        children = root.spawn(n_ut)
    else:
        children = [
            np.random.SeedSequence(
                root.entropy, spawn_key=(*root.spawn_key, int(i)), pool_size=root.pool_size
            )  # fmt: skip
            for i in ut_ids
        ]
    return np.array([c.generate_state(1, dtype=np.uint64)[0] for c in children], dtype=np.uint64)


@compiled.jitable
def mix64(z):
    """SplitMix64's finalizer of the uint64 ``z`` (arrays, or a compiled loop's scalars;
    wrapping products: callers on numpy scalars silence the overflow warning)."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def uniform(keys, counter, stream=0):
    """Uniform draws in (0, 1), one per key, for integer ``counter`` (e.g. the epoch).

    Parameters
    ----------
    keys : ndarray of uint64, shape (n,)
    counter : int or ndarray of int, broadcastable to (n,)
    stream : int
        Separates independent uses (fading real part, imaginary part, ...).
    """
    with np.errstate(over="ignore"):
        return uniform_of(keys, np.asarray(counter, dtype=np.uint64), np.uint64(stream))


@compiled.jitable
def uniform_of(keys, counter, stream):
    """:func:`uniform` of uint64 ``keys``, ``counter`` and ``stream`` (arrays, or a
    compiled loop's scalars)."""
    z = keys + (counter * np.uint64(2) + stream) * _GOLDEN
    bits = mix64(mix64(z)) >> np.uint64(11)  # 53 random bits
    return (bits + 0.5) / 9007199254740992.0  # 2^53


def complex_normal(keys, counter):
    """Circular complex Gaussian CN(0, 1) draws (Box-Muller), one per key."""
    with np.errstate(over="ignore"):
        re, im = complex_normal_of(keys, np.asarray(counter, dtype=np.uint64))
    return re + 1j * im


@compiled.jitable
def complex_normal_of(keys, counter):
    """:func:`complex_normal` of uint64 ``keys`` and ``counter``: its (real, imaginary)
    parts (arrays, or a compiled loop's scalars; a cosine and a sine, not the complex
    ``exp``, which costs numba ~2x)."""
    u1 = uniform_of(keys, counter, np.uint64(0))
    u2 = uniform_of(keys, counter, np.uint64(1))
    radius = np.sqrt(-np.log(u1))  # |g|^2 ~ Exp(1)
    angle = 2.0 * np.pi * u2
    return radius * np.cos(angle), radius * np.sin(angle)


def standard_normal(keys, counter):
    """Real Gaussian N(0, 1) draws (Box-Muller), one per key: ``sqrt(2)`` times the real
    part of :func:`complex_normal`'s draw of the same key and counter, without its
    imaginary part."""
    u1 = uniform(keys, counter, stream=0)
    u2 = uniform(keys, counter, stream=1)
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)
