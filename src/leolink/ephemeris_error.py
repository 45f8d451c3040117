"""Ephemeris errors: the satellite states the controller believes, beside the true ones.

The paper's design rests on the UTs (and the satellite) knowing the ephemeris; its
conclusion asks for "an accurate model for the error in the satellite's position and
trajectory". An :class:`EstimatedEphemeris` wraps the true ephemeris and adds, per
satellite, a position error in its along-track / cross-track / radial frame (the body
frame of :func:`leolink.geometry.body_frame`: x along-track, y cross-track, z radial)
and a velocity error in the same frame. The controller (beam and satellite choice, the
UT's antenna pointing, the satellite's re-steering of Earth-fixed beams) uses the
estimated states; the link is evaluated on the true ones.

Models (config ``[ephemeris_error] model``, registry :data:`EPHEMERIS_ERRORS`):

- ``none``: no error (the default; the run is the error-free run, bit for bit).
- ``rtn``: ``e(t) = offset + n_k * (sigma + g * age_h(t))`` per satellite and axis, with
  ``n_k ~ N(0, 1)`` drawn once per update period ``k`` (seeded: the run's seed and the
  satellite, so a satellite's error does not depend on chunking), ``age_h`` the hours since
  the last update (``update_period_s``; none: since time 0) and ``g`` the along-track
  growth ``growth_m_per_h`` (propagated-TLE errors grow mostly along-track; cross-track and
  radial stay at their sigma). Velocity error: ``de/dt`` plus ``N(0, velocity_m_s)`` per
  axis and period. Zero sigmas and offsets give the true states exactly.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.geometry import body_frame
from leolink.registry import Params, Registry

__all__ = ["EPHEMERIS_ERRORS", "EphemerisErrorModel", "EstimatedEphemeris", "RtnError"]
__all__ += ["rtn_to_frame"]

_SECONDS_PER_HOUR = 3600.0
#: Spawn key of the ephemeris-error draws under the run's seed.
_STREAM = 0x45504845  # "EPHE"


@runtime_checkable
class EphemerisErrorModel(Protocol):  # pragma: no mutate block (a contract, no code)
    """``offsets(t_s (n_t,), n_sat) -> (dpos (n_t, n_sat, 3), dvel (n_t, n_sat, 3))`` in the
    along-track / cross-track / radial frame [m, m/s]; ``is_zero``: no error at all."""

    is_zero: bool

    def offsets(self, t_s, n_sat): ...


EPHEMERIS_ERRORS: Registry[EphemerisErrorModel] = Registry(
    "ephemeris_error.model", protocol=EphemerisErrorModel
)


class NoError:
    """No ephemeris error (the paper)."""

    is_zero = True

    def offsets(self, t_s, n_sat):
        z = np.zeros((len(t_s), n_sat, 3))
        return z, z.copy()


class RtnError:
    """Gaussian along/cross/radial errors with a constant offset and along-track growth.

    Parameters
    ----------
    sigma_m : (3,) float
        1-sigma along-track, cross-track, radial [m].
    offset_m : (3,) float
        Deterministic offsets, same axes [m].
    velocity_m_s : float
        1-sigma velocity error per axis [m/s].
    growth_m_per_h : float
        Along-track sigma growth per hour since the last update [m/h].
    update_period_s : float or None
        Time between updates (new draws, age 0); None: one draw per run.
    seed : int
    """

    def __init__(self, sigma_m, offset_m, velocity_m_s, growth_m_per_h, update_period_s, seed):
        self.sigma = np.asarray(sigma_m, float)
        self.offset = np.asarray(offset_m, float)
        self.sigma_v = float(velocity_m_s)
        self.growth = np.array([growth_m_per_h, 0.0, 0.0]) / _SECONDS_PER_HOUR  # m/s
        self.period = update_period_s
        self.seed = int(seed)
        self.is_zero = not (self.sigma.any() or self.offset.any() or self.sigma_v
                            or self.growth.any())  # fmt: skip

    def _draws(self, k, n_sat):
        """``n (n_sat, 6)``: position and velocity draws of update period ``k``."""
        seq = np.random.SeedSequence([self.seed, _STREAM, int(k)])
        return np.random.default_rng(seq).standard_normal((n_sat, 6))

    def offsets(self, t_s, n_sat):
        t = np.asarray(t_s, float)
        if self.period is None:
            k, age = np.zeros(t.shape, np.int64), t
        else:
            k = np.floor(t / self.period).astype(np.int64)
            age = t - k * self.period
        dpos, dvel = np.empty((t.size, n_sat, 3)), np.empty((t.size, n_sat, 3))
        for kk in np.unique(k):  # few update periods per block of epochs
            rows = np.flatnonzero(k == kk)
            n = self._draws(kk, n_sat)
            a = age[rows][:, None, None]
            dpos[rows] = self.offset + n[None, :, :3] * (self.sigma + self.growth * a)
            dvel[rows] = n[None, :, :3] * self.growth + self.sigma_v * n[None, :, 3:]
        return dpos, dvel


def rtn_to_frame(pos_m, vel_m_s, d_rtn):
    """Vectors ``d_rtn (..., 3)`` (along, cross, radial) of the states ``pos_m, vel_m_s
    (..., 3)`` in the Earth-centred frame of the states: ``d @ body_frame``."""
    return np.einsum("...j,...jk->...k", d_rtn, body_frame(pos_m, vel_m_s))


class EstimatedEphemeris:
    """The ephemeris the controller believes: ``true`` plus ``model``'s errors.

    ``__call__(t_s, sats=None) -> (pos, vel, acc)`` as :class:`leolink.orbit.Ephemeris`
    (the true acceleration: the error model has no second derivative worth modelling).
    """

    def __init__(self, true, model):
        self.true, self.model = true, model
        self.n_sat = true.n_sat

    def __call__(self, t_s, sats=None):
        t = np.atleast_1d(np.asarray(t_s, float))
        pos, vel, acc = self.true(t) if sats is None else self.true(t, sats)
        dpos, dvel = self.model.offsets(t, self.n_sat)  # (every satellite's draws)
        if sats is not None:
            dpos, dvel = dpos[:, sats], dvel[:, sats]
        return pos + rtn_to_frame(pos, vel, dpos), vel + rtn_to_frame(pos, vel, dvel), acc


class NoneConfig(Params):
    pass


class RtnConfig(Params):
    along_track_m: float = Field(0.0, ge=0.0, le=1e7, description="1-sigma along-track [m]")
    cross_track_m: float = Field(0.0, ge=0.0, le=1e7, description="1-sigma cross-track [m]")
    radial_m: float = Field(0.0, ge=0.0, le=1e7, description="1-sigma radial [m]")
    along_track_offset_m: float = Field(
        0.0, ge=-1e7, le=1e7, description="constant along-track offset [m] (+: ahead)"
    )
    cross_track_offset_m: float = Field(0.0, ge=-1e7, le=1e7, description="constant [m]")
    radial_offset_m: float = Field(0.0, ge=-1e7, le=1e7, description="constant [m] (+: up)")
    velocity_m_s: float = Field(0.0, ge=0.0, le=1e4, description="1-sigma per axis [m/s]")
    growth_m_per_h: float = Field(
        0.0, ge=0.0, le=1e7, description="along-track sigma growth since an update [m/h]"
    )
    update_period_s: float | None = Field(
        None, gt=0.0, le=1e9, description="time between ephemeris updates [s] (none: one)"
    )


def _build_rtn(p, ctx):
    return RtnError(
        (p.along_track_m, p.cross_track_m, p.radial_m),
        (p.along_track_offset_m, p.cross_track_offset_m, p.radial_offset_m),
        p.velocity_m_s,
        p.growth_m_per_h,
        p.update_period_s,
        ctx.seed,
    )


EPHEMERIS_ERRORS.add(
    "none", lambda p, ctx: NoError(), doc="no ephemeris error (the paper)", config=NoneConfig
)
EPHEMERIS_ERRORS.add(
    "rtn",
    _build_rtn,
    doc="along/cross/radial Gaussian errors, constant offsets, along-track growth",
    config=RtnConfig,
)
