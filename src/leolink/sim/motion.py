"""Satellite and UT states of the run's epochs, computed in blocks of epochs.

Satellites follow the ephemeris and UTs their mobility models, both pure functions of
time (:class:`~leolink.sim.mobility.populations.MotionModel`), so the states of a whole block of
epochs are known before the block starts: the SimPy processes move the shared state one
epoch at a time from the block, and the controller and the monitor evaluate the engine
over the whole block in one vectorized call (:mod:`leolink.sim.candidates.search`,
:mod:`leolink.sim.monitor`). A block aims at :data:`BLOCK_UT_EPOCHS` UT-epochs (64 epochs
of 1,000 UTs, up to 1,024 epochs of a few UTs: a call's fixed cost is paid once a block),
and its states stay within a few tens of MiB.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.sim.mobility.models import UTState

__all__ = ["BLOCK_UT_EPOCHS", "MAX_BLOCK_EPOCHS", "MIN_BLOCK_EPOCHS", "MotionBlock"]
__all__ += ["MotionBlocks", "states"]

#: Longest block [epochs].
MAX_BLOCK_EPOCHS = 1024
#: Shortest block [epochs] but where the states' budget needs fewer (many UTs).
MIN_BLOCK_EPOCHS = 64
#: UT-epochs a block aims at: 64 epochs of 1,000 UTs, longer blocks for fewer UTs, since
#: each block's vectorized calls cost the same few microseconds whatever their size.
BLOCK_UT_EPOCHS = 64_000
#: Float values of one block's states (32 MiB): the block is shorter for many UTs.
_BLOCK_VALUES = 1 << 22


@dataclasses.dataclass
class MotionBlock:
    """States of epochs ``k0 .. k1 - 1`` (leading axis ``k - k0``).

    Attributes
    ----------
    k0, k1 : int
    sat_pos_m, sat_vel_m_s, sat_acc_m_s2 : ndarray, shape (n_k, n_sat, 3)
    ut_pos_m, ut_vel_m_s, ut_acc_m_s2 : ndarray, shape (n_k, n_ut, 3)
    ut_lat_rad, ut_lon_rad, ut_alt_m : ndarray, shape (n_k, n_ut)
    """

    k0: int
    k1: int
    sat_pos_m: np.ndarray
    sat_vel_m_s: np.ndarray
    sat_acc_m_s2: np.ndarray
    ut_pos_m: np.ndarray
    ut_vel_m_s: np.ndarray
    ut_acc_m_s2: np.ndarray
    ut_lat_rad: np.ndarray
    ut_lon_rad: np.ndarray
    ut_alt_m: np.ndarray

    @property
    def n_k(self) -> int:
        return self.k1 - self.k0


class MotionBlocks:
    """The run's states, one block at a time (the current block is kept).

    Parameters
    ----------
    ephemeris : callable
        ``ephemeris(t_s (n_t,)) -> (pos, vel, acc)``, each (n_t, n_sat, 3).
    populations : list of (name, motion model)
        In UT order.
    times_s : ndarray, shape (n_epoch,)
    n_sat, n_ut : int
    """

    def __init__(self, ephemeris, populations, times_s, n_sat, n_ut):
        self.ephemeris, self.populations = ephemeris, populations
        self.times_s = np.asarray(times_s, float)
        per_epoch = 9 * n_sat + 12 * n_ut
        aim = max(MIN_BLOCK_EPOCHS, BLOCK_UT_EPOCHS // max(n_ut, 1))
        most = min(_BLOCK_VALUES // max(per_epoch, 1), aim)
        self.n_block = int(np.clip(most, 1, MAX_BLOCK_EPOCHS))
        self._block = None

    def block_of(self, k):
        """The block holding epoch ``k``."""
        b = self._block
        if b is None or not b.k0 <= k < b.k1:
            k0 = (k // self.n_block) * self.n_block
            self._block = b = self._compute(k0, min(k0 + self.n_block, len(self.times_s)))
        return b

    def _compute(self, k0, k1):
        times = self.times_s[k0:k1]
        pos, vel, acc = self.ephemeris(times)
        blocks = [states(model, times) for _, model in self.populations]
        return MotionBlock(
            k0,
            k1,
            pos,
            vel,
            acc,
            *(_joined([getattr(b, f) for b in blocks]) for f in _UT_FIELDS),
        )


def _joined(parts):
    """The populations' arrays side by side (UT axis 1), C-contiguous: numpy keeps the
    inputs' layout, and a broadcast one (static UTs) would give the engine's reductions
    other strides, hence other last bits."""
    return np.ascontiguousarray(np.concatenate(parts, axis=1))


def states(model, times_s):
    """The model's states at ``times_s``, a :class:`UTState` whose arrays have a leading
    time axis: in one call where the model's class has ``states`` (static UTs, great
    circles), else time after time. (The class, not the instance: a wrapper such as
    ``OnWgs84`` hands unknown attributes to the model it wraps, whose ``states`` would be
    the sphere's.)"""
    if getattr(type(model), "states", None) is not None:
        return model.states(times_s)
    per_t = [model.state(float(t)) for t in times_s]
    return UTState(*(np.stack([getattr(u, f) for u in per_t]) for f in _UT_FIELDS))


_UT_FIELDS = ("pos_m", "vel_m_s", "acc_m_s2", "lat_rad", "lon_rad", "alt_m")
