"""UT environments in a run: each (UT, satellite) path's LoS state, shadowing, clutter.

Every ``[[population]]`` names an ``environment`` (:data:`ENVIRONMENTS`, default
``"open"``: the paper's line-of-sight link, nothing added) and may carry a ``channel``
table (:class:`ChannelParams`). :class:`ChannelTracker` owns the per-pair states of
:mod:`leolink.link.channel_state` for the whole run: once per epoch, in epoch order
(warm-up included), it advances every pair of a UT and a satellite above the mask and
gives the environment's extra loss of each path (:class:`EpochChannel`). The loss enters

- the candidate table the controller decides on: the channel of a block's epochs is drawn
  before the block's candidate search, which prunes on each path's SNR after its own loss
  (:class:`~leolink.sim.decide.Decider`; exact, no margin); blockage moves handovers and
  causes outages, with reason ``blocked``;
- the trace: the serving path's ``los``, ``shadow_db``, ``clutter_db`` and
  ``scintillation_db`` columns and its SNR and SINR, the serving satellite's other beams
  sharing the path's state and each interfering satellite's path having its own.

Speed: with the compiled loops on (:mod:`leolink.compiled`) one numba loop per
population (:func:`_advance_rows`) does an epoch's elevations, state carry, ray shift,
innovations and AR(1) step, calling the same physics functions as the numpy path
(:func:`leolink.link.channel_state.advance`); the two agree to 1e-9 dB (tested: the loop
takes the ray's offset from the link's (east, north, up), with no azimuth and no
trigonometry, the numpy path from the angles; they round differently).

Which pairs have a state: at epoch ``k``, those of UT ``u`` and every satellite above
the mask for ``u`` (0 degrees with other-satellite interference). That set is a function
of the UT's own geometry, not of the other UTs (the epoch's satellite cone holds every
such satellite), so with the per-UT keys of :func:`leolink.rng.ut_keys` a UT has the same
states in any run that holds it, and any motion-block length gives the same states.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from pydantic import Field

from leolink import compiled
from leolink.errors import ConfigError
from leolink.link import channel_state as cs
from leolink.link.environment import ENVIRONMENTS
from leolink.registry import Params

__all__ = ["ENVIRONMENTS", "ChannelParams", "ChannelTracker", "EpochChannel"]
__all__ += ["environment_models"]


class ChannelParams(Params):
    """``[population.channel]``: the TR 38.811 channel of a non-open environment."""

    band: Literal["s", "ka"] | None = Field(
        None,
        description="table band 's' or 'ka' (none: from the carrier, Ka from 6.32 GHz up, "
        "so 11.45 GHz uses Ka; leolink.link.environment.band_for_frequency)",
    )
    scintillation: bool = Field(
        False, description="add the TR 38.811 clause 6.6.6 scintillation margin"
    )
    geomagnetic_latitude_deg: float | None = Field(
        None, ge=-90.0, le=90.0, description="needed with scintillation below 6 GHz [deg]"
    )
    los_corr_distance_m: float | None = Field(
        None, gt=0.0, le=1e5, description="LoS-state correlation distance (none: 50 m, rural 60)"
    )
    sf_corr_distance_los_m: float | None = Field(
        None, gt=0.0, le=1e5, description="LoS shadowing correlation distance (none: 37 m)"
    )
    sf_corr_distance_nlos_m: float | None = Field(
        None, gt=0.0, le=1e5, description="NLoS shadowing correlation distance (none: 50 m, "
        "rural 120)",
    )  # fmt: skip
    clutter_height_m: float | None = Field(
        None, ge=0.0, le=500.0, description="obstacle height above the UT antenna (none: "
        "dense urban 20 m, urban 15, suburban 8, rural 3.5)",
    )  # fmt: skip


def environment_models(populations, freq_hz):
    """The :class:`~leolink.link.channel_state.EnvironmentModel` of every population.

    Parameters
    ----------
    populations : sequence of population parameter models (``environment``, ``channel``)
    freq_hz : float
        Carrier frequency [Hz] (chooses the table band unless ``channel.band`` does).

    Returns
    -------
    list of EnvironmentModel, or None when every population is ``open`` without
    scintillation (the run is then the paper's: no state, no extra column).
    """
    models = []
    for i, p in enumerate(populations):
        ch = p.channel if p.channel is not None else ChannelParams()
        try:
            models.append(
                cs.environment_model(p.environment, freq_hz, cs.ChannelOptions(**ch.model_dump()))
            )
        except ConfigError as exc:
            raise ConfigError(f"population.{i}.channel: {exc}") from None
    if all(m.environment == "open" and not m.scintillation for m in models):
        return None
    return models


@dataclasses.dataclass(frozen=True)
class EpochChannel:
    """The environment of every path of one epoch, kept for the pairs with a state only.

    Attributes: ``cone`` (n_cone,), the epoch's candidate satellites (ascending);
    ``has`` (n_ut, n_cone), whether UT ``u``'s path to ``cone[j]`` has a state (the
    satellite is above the mask for ``u``); ``los``, ``shadow_db``, ``clutter_db``
    (n_pair,) and ``scintillation_db`` (n_pair,), or None where no population has it (0
    dB): the :class:`~leolink.link.channel_state.LinkTerms` of the pairs of ``has``, in
    row-major order. A block of 64 epochs of 1,000 UTs with ~63 satellites each above the
    mask holds ~70 MB so (the dense (n_ut, n_cone) terms of every cone satellite: 350 MB).
    """

    cone: np.ndarray
    has: np.ndarray
    los: np.ndarray
    shadow_db: np.ndarray
    clutter_db: np.ndarray
    scintillation_db: np.ndarray | None = None

    @property
    def extra_loss_db(self):
        """Each pair's extra loss [dB], (n_pair,): shadowing + clutter + scintillation."""
        scint = 0.0 if self.scintillation_db is None else self.scintillation_db
        return self.shadow_db + self.clutter_db + scint

    def loss_grid(self):
        """Extra loss [dB] of every (UT, cone satellite) path, (n_ut, n_cone); 0 without
        a state."""
        out = np.zeros(self.has.shape)
        out[self.has] = self.extra_loss_db
        return out

    def _pairs(self, sat):
        """Index of the pair of UT ``u`` and satellite ``sat[u, ...]`` in the kept pairs,
        and whether it has a state."""
        sat = np.asarray(sat, np.int64)
        if self.cone.size == 0:
            return np.zeros(sat.shape, np.int64), np.zeros(sat.shape, bool)
        slot = np.clip(np.searchsorted(self.cone, sat), 0, self.cone.size - 1)
        rows = np.arange(sat.shape[0]).reshape((-1,) + (1,) * (sat.ndim - 1))
        ok = self.has[rows, slot] & (self.cone[slot] == sat) & (sat >= 0)
        index = np.cumsum(self.has.reshape(-1)) - 1  # row-major position of each state
        return np.where(ok, index[rows * self.cone.size + slot], 0), ok

    def loss_db(self, sat):
        """Extra loss [dB] of the paths to satellites ``sat (n_ut, m)``; 0 without a state."""
        pair, ok = self._pairs(sat)
        return _take(self.extra_loss_db, pair, ok, 0.0)

    def apply(self, table, n_beam):
        """The candidate table with each cell's SNR lowered by its path's extra loss."""
        sat = np.where(table.cell >= 0, table.cell // n_beam, -1)
        return table.like(table.snr_db - self.loss_db(sat))

    def columns(self, sat):
        """Trace columns of the path of each UT to satellite ``sat (n_ut,)``.

        ``los`` 1.0 / 0.0 (NaN without a path), ``shadow_db``, ``clutter_db``,
        ``scintillation_db``; and ``extra_loss_db`` (0 without a path).
        """
        pair, ok = self._pairs(sat)
        out = {
            "los": _take(self.los.astype(float), pair, ok, np.nan),
            "shadow_db": _take(self.shadow_db, pair, ok, np.nan),
            "clutter_db": _take(self.clutter_db, pair, ok, np.nan),
            "scintillation_db": _take(self._scintillation(), pair, ok, np.nan),
        }
        out["extra_loss_db"] = _take(self.extra_loss_db, pair, ok, 0.0)
        return out

    def _scintillation(self):
        """``scintillation_db`` (n_pair,), zeros where no population has it."""
        s = self.scintillation_db
        return np.zeros(self.los.size) if s is None else s

    @property
    def sat_id(self):
        """(n_ut, n_cone): ``cone[j]`` where the pair has a state, -1 elsewhere."""
        return np.where(self.has, self.cone[None, :], -1)

    @property
    def terms(self):
        """The dense :class:`~leolink.link.channel_state.LinkTerms` (n_ut, n_cone), NaN /
        False without a state."""
        part = cs.LinkTerms(self.los, self.shadow_db, self.clutter_db, self._scintillation(),
                            self.extra_loss_db)  # fmt: skip
        return cs.dense_terms(part, np.flatnonzero(self.has), self.has.shape)


def _take(values, pair, ok, fill):
    """``values[pair]`` where ``ok``, ``fill`` elsewhere (``values`` may be empty)."""
    if values.size == 0:
        return np.full(pair.shape, fill)
    return np.where(ok, values[pair], fill)


class ChannelTracker:
    """Channel states of every (UT, satellite above the mask) pair, epoch after epoch.

    Parameters
    ----------
    models : sequence of EnvironmentModel
        One per population, in UT order.
    counts : sequence of int
        UTs of each population.
    ut_keys : ndarray of uint64, shape (n_ut,)
        :func:`leolink.rng.ut_keys` of the run's seed.
    min_elevation_rad : float
        Mask of the pairs that get a state [rad].
    """

    def __init__(self, models, counts, ut_keys, min_elevation_rad):
        self.models = list(models)
        bounds = np.concatenate(([0], np.cumsum(counts))).astype(int)
        self.slices = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        self.keys = np.asarray(ut_keys, np.uint64)
        self.min_el = float(min_elevation_rad)
        self.scintillation = any(m.scintillation for m in self.models)
        self.states = [cs.empty_state(s.stop - s.start) for s in self.slices]
        self.prev_pos_m = None
        self.k = -1
        sizes = [s.stop - s.start for s in self.slices]
        #: The environment of every UT (``RunInfo.environment``).
        self.environment = tuple(
            m.environment for m, n in zip(self.models, sizes, strict=True) for _ in range(n)
        )

    def step(self, k, ut_pos_m, ut_enu, sat_pos_m, cone):
        """Advance every pair to epoch ``k`` (called once per epoch, in order).

        Parameters
        ----------
        k : int
            Epoch index (warm-up included).
        ut_pos_m : ndarray, shape (n_ut, 3)
        ut_enu : ndarray, shape (n_ut, 3, 3)
            Each UT's east, north, up rows.
        sat_pos_m : ndarray, shape (n_sat, 3)
            Every satellite (global ids).
        cone : ndarray of int, sorted
            The epoch's candidate satellites: every satellite above the mask for some UT.

        Returns
        -------
        EpochChannel
        """
        if k <= self.k:
            raise ValueError(f"epoch {k} after epoch {self.k}: the channel moves forward only")
        cone = np.asarray(cone, np.int64)
        step_m = np.zeros((len(ut_pos_m), 2))
        if self.prev_pos_m is not None:
            moved = ut_pos_m - self.prev_pos_m
            step_m = np.stack([np.einsum("uk,uk->u", moved, ut_enu[:, i, :]) for i in (0, 1)], -1)
        self.prev_pos_m, self.k = ut_pos_m.copy(), k
        frame = (ut_pos_m, ut_enu, step_m)
        parts = []
        for i, (model, sl) in enumerate(zip(self.models, self.slices, strict=True)):
            at = tuple(a[sl] for a in frame)
            if compiled.use(at[0].shape[0] * cone.size):
                self.states[i] = _advance_compiled(self.states[i], model, self.keys[sl], at,
                                                   (sat_pos_m, cone, self.min_el), k)  # fmt: skip
            else:
                el, az = look_angles_rad(_links(at[0], sat_pos_m, cone), _frame_rows(at[1]))
                sat_id = np.where(el >= self.min_el, cone[None, :], -1)
                self.states[i] = cs.advance(self.states[i], model, self.keys[sl], sat_id, el, az,
                                            at[2], k)  # fmt: skip
            parts.append(cs.pair_terms(self.states[i], model,
                                       np.flatnonzero(self.states[i].sat_id >= 0)))  # fmt: skip
        has = np.concatenate([st.sat_id >= 0 for st in self.states])
        terms = cs.LinkTerms(*(np.concatenate(f) for f in zip(*parts, strict=True)))
        scint = terms.scintillation_db if self.scintillation else None
        return EpochChannel(cone, has, terms.los, terms.shadow_db, terms.clutter_db, scint)


def _links(ut_pos_m, sat_pos_m, cone):
    """The links UT -> satellite of every UT and cone satellite: the tuple (x, y, z) [m]
    of arrays (n_ut, n_cone)."""
    return tuple(sat_pos_m[cone, c][None, :] - ut_pos_m[:, c, None] for c in range(3))


def _frame_rows(ut_enu):
    """``ut_enu (n_ut, 3, 3)`` as ``enu[i, c]`` of shape (n_ut, 1): row ``i`` (east,
    north, up), component ``c``, broadcasting over a UT's cone (:func:`look_angles_rad`)."""
    return np.moveaxis(ut_enu, 0, -1)[..., None]


@compiled.jitable
def look_angles_rad(los, enu):
    """Elevation and azimuth [rad] of the link ``los`` = (x, y, z) (UT -> satellite) in the
    UT's frame ``enu[i, c]`` (row ``i`` east, north, up; component ``c``): ``asin(up /
    |los|)`` and ``atan2(east, north)``. Arrays that broadcast, or one link's scalars and
    its UT's (3, 3) rows in a compiled loop (:func:`_advance_rows`)."""
    east, north, _ = link_enu(los, enu)
    return elevation_rad(los, enu), np.arctan2(east, north)


@compiled.jitable
def elevation_rad(los, enu):
    """The elevation of :func:`look_angles_rad` alone (no arctangent)."""
    return np.arcsin(sine_of_elevation(los, enu))


@compiled.jitable
def link_enu(los, enu):
    """Components (east, north, up) [m] of the link ``los`` in the UT's frame ``enu``, of
    :func:`look_angles_rad`'s arguments."""
    x, y, z = los
    return (x * enu[0, 0] + y * enu[0, 1] + z * enu[0, 2],
            x * enu[1, 0] + y * enu[1, 1] + z * enu[1, 2],
            x * enu[2, 0] + y * enu[2, 1] + z * enu[2, 2])  # fmt: skip


@compiled.jitable
def sine_of_elevation(los, enu):
    """``up / |los|`` clipped to [-1, 1], of :func:`look_angles_rad`'s arguments."""
    x, y, z = los
    up = link_enu(los, enu)[2]
    return np.minimum(np.maximum(up / np.sqrt(x * x + y * y + z * z), -1.0), 1.0)


#: Margin on the sine of the mask below which a link is out without its arcsine (the
#: arcsine's rounding is ~1e-16): the links near the mask are decided on the angle itself.
_SINE_GUARD = 1e-9


def _advance_compiled(state, model, keys, at, sky, k):
    """:func:`leolink.link.channel_state.advance` of the UTs ``at`` = (positions, ENU
    rows, steps (east, north)) to the cone's satellites above the mask, ``sky`` =
    (satellite positions, cone, mask [rad]), by :func:`_advance_rows`: the same state,
    but for the elevations of the links far below the mask (NaN: an empty slot's elevation
    is never read)."""
    if not k > state.epoch:
        raise ValueError(f"epoch = {k!r} must exceed the state's epoch {state.epoch}")
    n_ut, n_cone = at[0].shape[0], sky[1].size
    sat_id = np.empty((n_ut, n_cone), np.int64)
    out = (sat_id, *(np.empty((n_ut, n_cone)) for _ in range(6)))
    old = (state.sat_id, state.z_los, state.z_sf_los, state.z_sf_nlos, state.ray_east_m,
           state.ray_north_m)  # fmt: skip
    params = np.array([model.clutter_height_m, model.los_corr_distance_m,
                       model.sf_corr_distance_los_m, model.sf_corr_distance_nlos_m, sky[2],
                       np.sin(sky[2]) - _SINE_GUARD])  # fmt: skip
    compiled.run_rows(_advance_rows, n_ut, at, (sky[0], sky[1]), old, (keys, np.uint64(2 * k)),
                      params, out, row_size=n_cone)  # fmt: skip
    return cs.ChannelState(*out, int(k))


@compiled.jit
def _advance_rows(at, sky, old, keys, params, out, lo, hi):
    """The UTs ``lo .. hi - 1`` of :func:`_advance_compiled`: each cone satellite's
    elevation (:func:`elevation_rad`); above the mask, the ray's offset of the link's
    components (:func:`link_enu`), the pair's state carried from ``old`` (a UT's valid
    slots ascend in satellite id, as the cone does), moved by
    :func:`~leolink.link.channel_state.ray_moved_m` and stepped by
    :func:`~leolink.link.channel_state.ar1_step` with the pair's innovations.
    ``keys``: (UT keys, counter ``2 k``); ``params``: clutter height, the three
    correlation distances [m], the mask [rad] and the sine below which a link is out."""
    ut_pos, ut_enu, step = at
    sat_pos, cone = sky
    sat_id, z_los, z_sf_los, z_sf_nlos, el_out, east_out, north_out = out
    for u in range(lo, hi):
        p = 0
        for j in range(cone.size):
            s = cone[j]
            los = (sat_pos[s, 0] - ut_pos[u, 0], sat_pos[s, 1] - ut_pos[u, 1],
                   sat_pos[s, 2] - ut_pos[u, 2])  # fmt: skip
            sat_id[u, j] = -1
            z_los[u, j] = z_sf_los[u, j] = z_sf_nlos[u, j] = 0.0
            east_out[u, j] = north_out[u, j] = 0.0
            el_out[u, j] = np.nan
            if sine_of_elevation(los, ut_enu[u]) < params[5]:  # far below: no arcsine
                continue
            el = elevation_rad(los, ut_enu[u])
            el_out[u, j] = el
            if el < params[4]:
                continue
            sat_id[u, j] = s
            ray = cs.ray_offset_en_m(*link_enu(los, ut_enu[u]), params[0])
            east_out[u, j], north_out[u, j] = ray
            while p < old[0].shape[1] and old[0][u, p] < s:  # (-1: an empty slot)
                p += 1
            had = p < old[0].shape[1] and old[0][u, p] == s
            d_m = np.inf
            z0 = (0.0, 0.0, 0.0)
            if had:
                d_m = cs.ray_moved_m((step[u, 0], step[u, 1]), (old[4][u, p], old[5][u, p]),
                                     ray)  # fmt: skip
                z0 = (old[1][u, p], old[2][u, p], old[3][u, p])
            w = cs.pair_innovations(cs.pair_key(keys[0][u], np.uint64(s)), keys[1])
            a_los = cs.ar1_weights(d_m, params[1])
            # the defaults share 50 m between the LoS state and NLoS shadowing: one exp
            a_nlos = a_los if params[3] == params[1] else cs.ar1_weights(d_m, params[3])
            z_los[u, j] = cs.ar1_mix(z0[0], a_los, w[0])
            z_sf_los[u, j] = cs.ar1_step(z0[1], d_m, params[2], w[1])
            z_sf_nlos[u, j] = cs.ar1_mix(z0[2], a_nlos, w[2])
