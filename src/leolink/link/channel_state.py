"""Spatially consistent, seeded LoS state and shadowing per (UT, satellite) pair.

Each pair carries three standard Gaussian driving variables, evolved by an AR(1) /
exponential correlation along the distance the pair's ray moved since the last epoch,
``z_k = rho z_{k-1} + sqrt(1 - rho^2) w_k`` with ``rho = exp(-d / d_corr)``
(the exponential autocorrelation of TR 38.901 Eq. (7.4-5) [2], used by its clause 7.6.3):

- ``z_los`` decides the state: the correlated uniform ``Phi(z_los)`` below the LoS
  probability of TR 38.811 Table 6.6.1-1 at the current elevation means LoS
  (TR 38.901 clause 7.6.3.3 [2]); since the probability is interpolated in elevation and
  ``z_los`` moves continuously, the state flips only where the threshold crosses it;
- ``z_sf_los`` and ``z_sf_nlos``: two independent shadowing fields, one per link state as
  TR 38.901 generates its large-scale parameters per state; ``shadow_db`` is
  ``sigma_SF(elevation, state) * z`` of the current state (TR 38.811 Tables 6.6.2-1..3).

Correlation distances [m] (defaults of :func:`environment_model`, overridable): LoS state
50 (dense urban, urban, suburban) and 60 (rural), TR 38.901 Table 7.6.3.1-2 for UMa/UMi
and RMa, mapped onto the NTN environments by leolink (TR 38.811 gives none); shadowing
37 in LoS and 50 in NLoS (120 for rural), TR 38.811 Tables 6.7.2-1a..8b (the values of
TR 38.901 Table 7.5-6 for UMa and RMa).

Motion of the ray (leolink choice, for docs/errata.md): LoS and shadowing are taken to be
set by obstacles at one characteristic height ``h`` above the UT antenna
(``clutter_height_m``; defaults 20 / 15 / 8 / 3.5 m for dense urban / urban / suburban /
rural). The ray to the satellite pierces that height at ``P = x_UT + h cot(el) u(az)``
(``u`` the horizontal unit vector of the azimuth), and the distance that drives the
decorrelation is ``|P_k - P_{k-1}|``. A UT that moves by ``dx`` under a fixed satellite
direction moves ``P`` by exactly ``dx`` (the terrestrial case of TR 38.901); a static UT
decorrelates as the satellite crosses the sky, slowly near zenith (``P`` stays above the
UT) and fast at low elevation. The elevation in ``cot`` is clamped at 10 degrees, the
lowest tabulated angle. If only the distance the UT moved is known (not its direction),
the two shifts are added in quadrature (exact in mean square for a random relative
direction).

Randomness: the innovations ``w_k`` of a pair at epoch ``k`` are a pure function of (UT
key of :func:`leolink.rng.ut_keys`, satellite id, ``k``): no dependence on chunking,
order of the candidates or workers. State lives in ``(n_ut, n_slot)`` arrays aligned with
the current candidates' ids (56 bytes a pair, 1.1 MB for 1000 UTs x 20 candidates,
whatever the constellation size: the three variables, the elevation and the ray's offset
``P - x_UT``, carried so that an epoch computes only its own); a pair absent from the
previous state starts from the stationary N(0, 1). Time chunks must hand the state on;
UT chunks need nothing.

References
----------
.. [1] 3GPP TR 38.811 V15.4.0 (2020-09), clauses 6.6.1, 6.6.2, 6.6.6, 6.7.2.
.. [2] 3GPP TR 38.901 V17.0.0 (2022-03), "Study on channel model for frequencies from
   0.5 to 100 GHz", Eq. (7.4-5), clauses 7.5, 7.6.3; Tables 7.5-6, 7.6.3.1-2.
"""

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from leolink import compiled
from leolink import rng as lrng
from leolink.errors import ConfigError
from leolink.link import environment as env

__all__ = [
    "ChannelOptions",
    "ChannelState",
    "EnvironmentModel",
    "LinkTerms",
    "advance",
    "ar1_mix",
    "ar1_step",
    "ar1_weights",
    "effective_displacement_m",
    "dense_terms",
    "direction_enu",
    "empty_state",
    "environment_model",
    "innovations",
    "link_terms",
    "pair_keys",
    "pair_terms",
]

# (LoS-state, SF LoS, SF NLoS correlation distance [m], clutter height above the UT [m]).
_DEFAULTS = {
    "open": (50.0, 37.0, 50.0, 0.0),
    "rural": (60.0, 37.0, 120.0, 3.5),
    "suburban": (50.0, 37.0, 50.0, 8.0),
    "urban": (50.0, 37.0, 50.0, 15.0),
    "dense_urban": (50.0, 37.0, 50.0, 20.0),
}
_MIN_ELEVATION_RAD = np.radians(10.0)  # lowest tabulated angle of TR 38.811
_TAN_MIN_ELEVATION = np.tan(_MIN_ELEVATION_RAD)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
# Separates the environment's streams from any other use of the same UT keys.
_DOMAIN = np.uint64(0x6C62272E07BB0142)


@dataclass(frozen=True)
class EnvironmentModel:
    """Resolved environment parameters of one UT population (see :func:`environment_model`)."""

    environment: str
    freq_hz: float
    band: str
    los_corr_distance_m: float
    sf_corr_distance_los_m: float
    sf_corr_distance_nlos_m: float
    clutter_height_m: float
    scintillation: bool = False
    geomagnetic_latitude_deg: float | None = None


@dataclass(frozen=True)
class ChannelOptions:
    """The optional settings of an environment's channel (the config's
    ``[population.channel]``); None: the module docstring's defaults.

    Attributes
    ----------
    band : {None, "s", "ka"}
        Table band; ``None``: :func:`leolink.link.environment.band_for_frequency`.
    scintillation : bool
        Add the clause 6.6.6 scintillation margin (off: the paper neglects it).
    geomagnetic_latitude_deg : float, optional
        Needed with ``scintillation`` below 6 GHz.
    los_corr_distance_m, sf_corr_distance_los_m, sf_corr_distance_nlos_m : float, optional
        Correlation distances [m].
    clutter_height_m : float, optional
        Obstacle height above the UT antenna [m] for the ray shift.
    """

    band: str | None = None
    scintillation: bool = False
    geomagnetic_latitude_deg: float | None = None
    los_corr_distance_m: float | None = None
    sf_corr_distance_los_m: float | None = None
    sf_corr_distance_nlos_m: float | None = None
    clutter_height_m: float | None = None


def environment_model(environment, freq_hz, options=None):
    """Validate and resolve an environment once, at the edge (ConfigError on bad values).

    Parameters
    ----------
    environment : str
        One of :data:`leolink.link.environment.ENVIRONMENTS`.
    freq_hz : float
        Carrier frequency [Hz].
    options : ChannelOptions, optional
        Band, scintillation, correlation distances, clutter height (None: defaults).

    Returns
    -------
    EnvironmentModel
    """
    o = ChannelOptions() if options is None else options
    env.validate_environment(environment)
    defaults = _DEFAULTS[environment]
    given = (o.los_corr_distance_m, o.sf_corr_distance_los_m, o.sf_corr_distance_nlos_m)
    names = ("los_corr_distance_m", "sf_corr_distance_los_m", "sf_corr_distance_nlos_m")
    dists = [d if v is None else float(v) for v, d in zip(given, defaults[:3], strict=True)]
    for name, value in zip(names, dists, strict=True):
        if not value > 0.0:
            raise ConfigError(f"{name} = {value!r} is not allowed; use a value > 0 (metres)")
    height = defaults[3] if o.clutter_height_m is None else float(o.clutter_height_m)
    if not height >= 0.0:
        raise ConfigError(f"clutter_height_m = {height!r} is not allowed; use a value >= 0")
    model = EnvironmentModel(
        environment,
        float(freq_hz),
        env.band_for_frequency(freq_hz, o.band),
        *dists,
        height,
        bool(o.scintillation),
        o.geomagnetic_latitude_deg,
    )
    if o.scintillation:  # fail now, not at the first epoch, if the latitude is missing
        env.scintillation_db(45.0, model.freq_hz, o.geomagnetic_latitude_deg)
    return model


@dataclass(frozen=True)
class ChannelState:
    """Driving variables of the (UT, candidate satellite) pairs after one epoch.

    Attributes (all shape (n_ut, n_slot); slot ``j`` of UT ``i`` is satellite
    ``sat_id[i, j]``, ``-1`` an empty slot):
    ``sat_id`` (int64), ``z_los``, ``z_sf_los``, ``z_sf_nlos`` (float64, N(0, 1)),
    ``elevation_rad`` (float64, of that epoch: the tables' argument);
    ``ray_east_m``, ``ray_north_m`` (float64, the ray's piercing offset of that epoch,
    :func:`ray_offset_en_m` [m], 0 in empty slots: the next epoch's displacement needs
    only its own offset; kept exact so that an unchanged geometry gives a zero
    displacement, not a rounding residue that ``sqrt(1 - rho^2)`` would amplify);
    ``epoch`` (int, -1 before the first :func:`advance`).
    """

    sat_id: np.ndarray
    z_los: np.ndarray
    z_sf_los: np.ndarray
    z_sf_nlos: np.ndarray
    elevation_rad: np.ndarray
    ray_east_m: np.ndarray
    ray_north_m: np.ndarray
    epoch: int = -1


def empty_state(n_ut):
    """A state with no pair yet (every pair of the first epoch starts stationary)."""
    f = np.zeros((n_ut, 0))
    return ChannelState(np.zeros((n_ut, 0), dtype=np.int64), f, f, f, f, f, f, -1)


def pair_keys(ut_keys, sat_id):
    """64-bit key of each (UT, satellite) pair (SplitMix64 of the UT key and the id).

    Parameters
    ----------
    ut_keys : ndarray of uint64, shape (n_ut,)
        From :func:`leolink.rng.ut_keys` (the UT's key, whatever chunk it is in).
    sat_id : array_like of int, shape (n_ut, n_slot)

    Returns
    -------
    ndarray of uint64, shape (n_ut, n_slot)
    """
    sat = np.asarray(sat_id).astype(np.int64).view(np.uint64)
    with np.errstate(over="ignore"):
        return pair_key(np.asarray(ut_keys, dtype=np.uint64)[:, None], sat)


@compiled.jitable
def pair_key(ut_key, sat):
    """:func:`pair_keys` of uint64 UT keys and satellite ids (arrays that broadcast, or a
    compiled loop's scalars)."""
    return lrng.mix64(ut_key ^ lrng.mix64(sat * _GOLDEN + _DOMAIN))


def innovations(keys, epoch):
    """Three independent N(0, 1) draws per pair for ``epoch``: (w_los, w_sf_los, w_sf_nlos).

    Box-Muller through :func:`leolink.rng.complex_normal` (real and imaginary parts of a
    CN(0, 1) draw are independent N(0, 1/2)) at counters ``2 epoch`` and ``2 epoch + 1``.

    Returns
    -------
    ndarray, shape (3, n_ut, n_slot)
    """
    with np.errstate(over="ignore"):
        w = pair_innovations(keys, np.asarray(2 * epoch, dtype=np.uint64))
    return np.stack(w)


@compiled.jitable
def pair_innovations(key, counter):
    """:func:`innovations` of uint64 ``key`` at the counter ``2 epoch`` (uint64): the tuple
    (w_los, w_sf_los, w_sf_nlos) (arrays, or a compiled loop's scalars)."""
    g0 = lrng.complex_normal_of(key, counter)
    g1 = lrng.complex_normal_of(key, counter + np.uint64(1))
    s = np.sqrt(2.0)
    return s * g0[0], s * g0[1], s * g1[0]


@compiled.jitable
def ar1_step(z_prev, distance_m, corr_distance_m, w):
    """Exponentially correlated Gaussian step, TR 38.901 Eq. (7.4-5) [2].

    ``rho = exp(-d / d_corr)``, ``z = rho z_prev + sqrt(1 - rho^2) w``: keeps N(0, 1)
    stationary and gives ``corr(z(x), z(x + d)) = exp(-d / d_corr)`` along a track.
    ``distance_m = inf`` (rho = 0) starts a new pair from the stationary distribution.

    Parameters
    ----------
    z_prev, distance_m, w : ndarray or float, broadcastable
        Previous value, distance moved [m], fresh N(0, 1) innovation.
    corr_distance_m : float
        Correlation distance [m], > 0.
    """
    return ar1_mix(z_prev, ar1_weights(distance_m, corr_distance_m), w)


@compiled.jitable
def ar1_weights(distance_m, corr_distance_m):
    """The weights ``(rho, sqrt(1 - rho^2))`` of :func:`ar1_step` (a compiled loop
    computes them once for two fields of the same correlation distance)."""
    rho = np.exp(-distance_m / corr_distance_m)
    return rho, np.sqrt(1.0 - rho * rho)


@compiled.jitable
def ar1_mix(z_prev, weights, w):
    """:func:`ar1_step` of its :func:`ar1_weights`."""
    return weights[0] * z_prev + weights[1] * w


def direction_enu(elevation_rad, azimuth_rad):
    """Unit vector (east, north, up) of the direction of elevation and azimuth [rad]
    (azimuth from north towards east): a tuple of arrays."""
    el, az = np.asarray(elevation_rad, dtype=float), np.asarray(azimuth_rad, dtype=float)
    return np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)


@compiled.jitable
def ray_offset_en_m(east, north, up, clutter_height_m):
    """Horizontal offset (east, north) [m] from the UT of the ray's piercing point at the
    clutter height ``h`` (module docstring), of the direction to the satellite given by its
    components (east, north, up) in the UT's frame, of any length (:func:`direction_enu`,
    or a link vector: no angle needed). ``h cot(max(el, 10 deg))
    (sin az, cos az)`` is ``h (east, north) / max(up, tan(10 deg) |(east, north)|)``
    (arrays, or a compiled loop's scalars; a square root, not ``hypot``, which costs a
    compiled loop ~4x: nothing here is near overflow)."""
    horizontal = np.sqrt(east * east + north * north)
    scale = clutter_height_m / np.maximum(up, _TAN_MIN_ELEVATION * horizontal)
    return scale * east, scale * north


@compiled.jitable
def ray_moved_m(ut_step_en_m, previous_en_m, current_en_m):
    """Distance the ray's piercing point moved (:func:`effective_displacement_m` of a UT
    step (east, north) [m]): ``previous_en_m`` and ``current_en_m`` the ray's offsets
    (east, north) [m] of the two epochs (:func:`ray_offset_en_m`; tuples of arrays that
    broadcast, or a compiled loop's scalars)."""
    e0, n0 = previous_en_m
    e1, n1 = current_en_m
    east, north = ut_step_en_m[0] + (e1 - e0), ut_step_en_m[1] + (n1 - n0)
    return np.sqrt(east * east + north * north)  # (not hypot: see ray_offset_en_m)


def effective_displacement_m(ut_step_m, el_prev_rad, az_prev_rad, el_rad, az_rad, clutter_height_m):
    """Distance the ray's piercing point moved between two epochs (module docstring).

    Parameters
    ----------
    ut_step_m : ndarray, shape (n_ut, 2) or (n_ut,)
        UT displacement since the last epoch: (east, north) [m], or its length [m] only
        (then added in quadrature to the ray shift).
    el_prev_rad, az_prev_rad, el_rad, az_rad : ndarray, shape (n_ut, n_slot)
        Elevation and azimuth at the previous and the current epoch [rad].
    clutter_height_m : float

    Returns
    -------
    ndarray, shape (n_ut, n_slot)
        Distance [m], >= 0.
    """
    previous = ray_offset_en_m(*direction_enu(el_prev_rad, az_prev_rad), clutter_height_m)
    current = ray_offset_en_m(*direction_enu(el_rad, az_rad), clutter_height_m)
    return _offset_displacement_m(ut_step_m, previous, current)


def _offset_displacement_m(ut_step_m, previous_en_m, current_en_m):
    """:func:`effective_displacement_m` of the ray's offsets (east, north) [m] of the two
    epochs (tuples of arrays (n_ut, n_slot))."""
    step = np.asarray(ut_step_m, dtype=float)
    if step.ndim == 2:
        return ray_moved_m((step[:, None, 0], step[:, None, 1]), previous_en_m, current_en_m)
    shift = [c - p for c, p in zip(current_en_m, previous_en_m, strict=True)]
    return np.sqrt(step[:, None] ** 2 + (shift[0] * shift[0] + shift[1] * shift[1]))


def _carry(state, sat_id, rows, slots):
    """Previous values of the entries ``(rows, slots)`` of ``sat_id`` (its valid ones, in
    row-major order), and which of them had a previous value: the previous state's entry
    of the same (row, satellite), found by sorted keys (no (n_slot x n_old_slot) match)."""
    old_rows, old_slots = np.nonzero(state.sat_id >= 0)
    old_sat = state.sat_id[old_rows, old_slots]
    sat = sat_id[rows, slots]
    n_key = int(max(old_sat.max(initial=0), sat.max(initial=0))) + 1
    old_key = old_rows * n_key + old_sat
    order = np.argsort(old_key, kind="stable")  # equal keys: the first slot, as before
    old_key = old_key[order]
    key = rows * n_key + sat
    fields = ("z_los", "z_sf_los", "z_sf_nlos", "ray_east_m", "ray_north_m")
    if old_key.size == 0:  # the first epoch: every pair new
        return np.zeros(key.size, bool), {name: np.zeros(key.size) for name in fields}
    idx = np.minimum(np.searchsorted(old_key, key), old_key.size - 1)
    had = old_key[idx] == key
    src_rows, src_slots = old_rows[order][idx], old_slots[order][idx]
    prev = {}
    for name in fields:
        prev[name] = np.where(had, getattr(state, name)[src_rows, src_slots], 0.0)
    return had, prev


def advance(state, model, ut_keys, sat_id, elevation_rad, azimuth_rad, ut_step_m, epoch):
    """Advance every (UT, candidate satellite) pair to ``epoch``; pure (returns a new state).

    Parameters
    ----------
    state : ChannelState
        State after the previous epoch (:func:`empty_state` at the start).
    model : EnvironmentModel
    ut_keys : ndarray of uint64, shape (n_ut,)
        Per-UT keys (:func:`leolink.rng.ut_keys`), the same whatever the chunking.
    sat_id : array_like of int, shape (n_ut, n_slot)
        Current candidates of each UT (serving and interfering paths), ``-1`` padding.
    elevation_rad, azimuth_rad : array_like, shape (n_ut, n_slot)
        Current geometry of each pair [rad].
    ut_step_m : array_like, shape (n_ut, 2) or (n_ut,)
        UT displacement since the state's epoch [m] (:func:`effective_displacement_m`).
    epoch : int
        Epoch index (> ``state.epoch``); keys the innovations.

    Returns
    -------
    ChannelState
        Slots aligned with ``sat_id``.
    """
    if not epoch > state.epoch:
        raise ValueError(f"epoch = {epoch!r} must exceed the state's epoch {state.epoch}")
    sat_id = np.asarray(sat_id, dtype=np.int64)
    el = np.asarray(elevation_rad, dtype=float)
    az = np.asarray(azimuth_rad, dtype=float)
    # Only the pairs with a satellite evolve (row-major); empty slots keep zeros.
    rows, slots = np.nonzero(sat_id >= 0)
    had, prev = _carry(state, sat_id, rows, slots)
    step = np.asarray(ut_step_m, dtype=float)[rows]  # each pair's UT step, (n, 2) or (n,)
    ray_en = ray_offset_en_m(*direction_enu(el[rows, slots], az[rows, slots]),
                             model.clutter_height_m)  # fmt: skip
    moved_m = _offset_displacement_m(
        step, (prev["ray_east_m"][:, None], prev["ray_north_m"][:, None]),
        (ray_en[0][:, None], ray_en[1][:, None]),
    )[:, 0]  # fmt: skip
    distance_m = np.where(had, moved_m, np.inf)  # new pair: rho = 0, stationary start
    keys = np.asarray(ut_keys, dtype=np.uint64)[rows]
    w = innovations(pair_keys(keys, sat_id[rows, slots][:, None])[:, 0], epoch)
    dists = (model.los_corr_distance_m, model.sf_corr_distance_los_m, model.sf_corr_distance_nlos_m)
    z = []
    for i, (name, d) in enumerate(zip(("z_los", "z_sf_los", "z_sf_nlos"), dists, strict=True)):
        dense = np.zeros(sat_id.shape)
        dense[rows, slots] = ar1_step(prev[name], distance_m, d, w[i])
        z.append(dense)
    ray = []
    for values in ray_en:
        dense = np.zeros(sat_id.shape)
        dense[rows, slots] = values
        ray.append(dense)
    return ChannelState(sat_id, *z, el, *ray, int(epoch))


class LinkTerms(NamedTuple):
    """Environment terms of each pair, shape (n_ut, n_slot); NaN / False in empty slots.

    ``los`` (bool), ``shadow_db`` (zero-mean, positive = more loss), ``clutter_db``
    (NLoS only), ``scintillation_db`` (margin), ``extra_loss_db`` (their sum, to subtract
    from the pair's SNR, or from an interferer's received power).
    """

    los: np.ndarray
    shadow_db: np.ndarray
    clutter_db: np.ndarray
    scintillation_db: np.ndarray
    extra_loss_db: np.ndarray


def link_terms(state, model):
    """LoS state, shadowing, clutter and scintillation of every pair of ``state``.

    Parameters
    ----------
    state : ChannelState
    model : EnvironmentModel

    Returns
    -------
    LinkTerms
        ``los = Phi(z_los) < P_LoS(el)`` (TR 38.901 clause 7.6.3.3 with TR 38.811
        Table 6.6.1-1); ``shadow_db = sigma_SF(el, los) z_sf`` of the current state and
        ``clutter_db = CL(el)`` if NLoS (Tables 6.6.2-1..3); ``open``: always LoS, 0 dB.
        Shape (n_ut, n_slot), NaN / False in empty slots.
    """
    pairs = np.flatnonzero(state.sat_id >= 0)
    return dense_terms(pair_terms(state, model, pairs), pairs, state.sat_id.shape)


def dense_terms(terms, pairs, shape):
    """:class:`LinkTerms` of the pairs ``pairs`` (shape (n,): flat, row-major indices)
    spread on a grid of ``shape``: NaN / False elsewhere."""
    out = []
    for name, values in zip(LinkTerms._fields, terms, strict=True):
        dense = np.zeros(shape, bool) if name == "los" else np.full(shape, np.nan)
        dense.reshape(-1)[pairs] = values
        out.append(dense)
    return LinkTerms(*out)


def pair_terms(state, model, pairs):
    """:func:`link_terms` of the pairs ``pairs`` of ``state`` only (flat, row-major
    indices of slots with a satellite, e.g. :func:`numpy.flatnonzero` of ``sat_id >= 0``):
    :class:`LinkTerms` of shape (n,), the same values."""

    def take(field):  # (a flat index: ~3x faster than a (rows, slots) pair)
        return np.take(field.reshape(-1), pairs)

    z_los, el_deg = take(state.z_los), np.degrees(take(state.elevation_rad))
    name, band = model.environment, model.band
    if name == "open":
        los = np.ones(el_deg.shape, dtype=bool)
        shadow_db, clutter_db = np.zeros(el_deg.shape), np.zeros(el_deg.shape)
    else:
        from scipy.special import ndtri  # here, not at import: scipy costs ~0.3 s of start-up

        # Compare in the Gaussian domain (exact, no erf): Phi(z) < p  <=>  z < Phi^-1(p).
        # the four table values of each pair, its elevation looked up once
        p_los, sigma_los, sigma_nlos, cl_db = env.link_table_values(el_deg, name, band)
        los = z_los < ndtri(p_los)
        z_sf = np.where(los, take(state.z_sf_los), take(state.z_sf_nlos))
        shadow_db = np.where(los, sigma_los, sigma_nlos) * z_sf  # shadow_sigma_db's choice
        clutter_db = np.where(los, 0.0, cl_db)
    if model.scintillation:
        scint_db = env.scintillation_db(el_deg, model.freq_hz, model.geomagnetic_latitude_deg)
    else:
        scint_db = np.zeros(el_deg.shape)
    return LinkTerms(los, shadow_db, clutter_db, scint_db, shadow_db + clutter_db + scint_db)
