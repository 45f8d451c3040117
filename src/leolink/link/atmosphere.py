"""Atmospheric loss on the UT-satellite slant path, Sec. 2.2 of [1].

Four models, built by :func:`atmosphere_model` as ``callable(elevation_rad) -> loss_db``:

- ``fixed``: one number (the paper's Table uses 0.017 dB, see docs/errata.md);
- ``itu_p676``: gaseous attenuation of ITU-R P.676 via ``itur`` [2];
- ``itu_p618``: gas + rain + cloud + scintillation of ITU-R P.618 via ``itur`` [3] (opt-in);
- ``paper``: the paper's own model, the specific attenuation ``A(f, T(h), P(h), rho(h))``
  of ITU-R P.676 integrated along the slant path from 0 to 81 km through the 1976 US
  Standard Atmosphere [4], with 7.5 g/m^3 of water vapour at sea level, proportional to
  the air density up to 2.3 km and zero above.

``itur`` is slow, so every model except ``fixed`` is tabulated once on an elevation
grid by :class:`AtmosphereTable` at its first use (a scenario built and not run, as by
``leolink validate``, never computes it) and interpolated (vectorized) afterwards.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] ITU-R P.676-12, "Attenuation by atmospheric gases and related effects."
.. [3] ITU-R P.618-13, "Propagation data and prediction methods required for the design
   of Earth-space telecommunication systems."
.. [4] NOAA/NASA/USAF, "U.S. Standard Atmosphere, 1976", NOAA-S/T 76-1562.
"""

import functools
import warnings
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.constants import EARTH_RADIUS_M
from leolink.link.standard_atmosphere import (
    paper_model_db,
    paper_water_vapour_g_m3,
    shell_path_length_m,
    specific_attenuation_db_m,
    us_standard_atmosphere,
)
from leolink.registry import Params, Registry

__all__ = [
    "ATMOSPHERES",
    "AtmosphereModel",
    "AtmosphereTable",
    "P618Terms",
    "atmosphere_model",
    "fixed_loss_db",
    "itu_p618_db",
    "itu_p676_db",
    "paper_model_db",
    "paper_water_vapour_g_m3",
    "shell_path_length_m",
    "site_surface_conditions",
    "specific_attenuation_db_m",
    "us_standard_atmosphere",
]


def fixed_loss_db(elevation_rad, loss_db):
    """A constant loss [dB] with the shape of ``elevation_rad``."""
    return np.full(np.shape(elevation_rad), float(loss_db))


@runtime_checkable
class AtmosphereModel(Protocol):
    """``model(elevation_rad) -> loss_db`` (broadcasting); ``constant_db`` is the loss
    when it does not depend on the elevation (callers then skip the evaluation), else None.
    """

    constant_db: float | None

    def __call__(self, elevation_rad: np.ndarray) -> np.ndarray: ...


class FixedLoss:
    """The same loss at every elevation (the paper's Table value), as a model callable.

    ``constant_db`` lets callers skip the per-element evaluation.
    """

    def __init__(self, loss_db):
        self.constant_db = float(loss_db)

    def __call__(self, elevation_rad):
        return fixed_loss_db(elevation_rad, self.constant_db)


def itu_p676_db(
    elevation_rad, freq_hz, pressure_hpa=1013.25, temp_k=288.15, rho_g_m3=7.5, mode="exact"
):
    """Gaseous attenuation on the slant path, ITU-R P.676 via ``itur`` [dB].

    ``mode='exact'`` (default) is the layer-by-layer ray trace of P.676 Annex 1 (curved
    Earth, refraction; it uses the P.835 reference profiles scaled to the surface
    ``rho_g_m3`` and ignores ``pressure_hpa``/``temp_k``); ``mode='approx'`` is Annex 2,
    ``(gamma_o h_o + gamma_w h_w) / sin(el)``, only for 5 to 90 deg. Slow: tabulate.

    Parameters
    ----------
    elevation_rad : array_like, shape (n,)
        Elevation [rad].
    freq_hz : float
        Carrier frequency [Hz].
    pressure_hpa, temp_k, rho_g_m3 : float
        Surface pressure [hPa], temperature [K], water-vapour density [g/m^3].

    Returns
    -------
    ndarray, shape of ``elevation_rad``
        Loss [dB].
    """
    from itur.models import itu676

    el_deg = np.degrees(np.asarray(elevation_rad, dtype=float))
    if mode == "approx" and np.any(el_deg < 5.0):
        warnings.warn(
            "ITU-R P.676 approx mode below 5 deg elevation: use mode='exact'", stacklevel=2
        )
    if mode == "exact":
        return p676_ray_trace_db(el_deg, freq_hz, rho_g_m3)
    with warnings.catch_warnings():
        # itur's range check fires at exactly 90 deg too (np.mod(90, 90) = 0 < 5).
        warnings.filterwarnings("ignore", message=".*only recommended for elevation.*")
        out = itu676.gaseous_attenuation_slant_path(
            freq_hz / 1e9, np.atleast_1d(el_deg), rho_g_m3, pressure_hpa, temp_k, mode=mode
        )
    return np.asarray(getattr(out, "value", out), dtype=float).reshape(el_deg.shape)


#: Layers of the ray trace of ITU-R P.676-12 Annex 1 (Eqs. 14-15: 922 layers to 100 km).
_P676_LAYERS = 922


def p676_ray_trace_db(el_deg, freq_hz, rho_g_m3):
    """ITU-R P.676-12 Annex 1 slant-path gaseous attenuation (Eqs. 13-19) [dB], every
    elevation at once.

    ``itur``'s ``gaseous_attenuation_slant_path(mode='exact')`` traces one elevation at a
    time and evaluates the line-by-line specific attenuation of each of the 922 layers
    for each elevation (46 x 922 calls for a 2-degree table: 5 s idle, 14 s loaded). The
    specific attenuation of a layer does not depend on the elevation: here it is taken
    once per layer from ``itur`` (``gamma_exact``, the same P.835 reference profiles and
    P.453 refractive index) and the ray is traced for every elevation together, with
    ``itur``'s arithmetic, so that the two agree to rounding (tests/test_atmosphere.py).

    Parameters
    ----------
    el_deg : array_like
        Elevation [deg], any shape.
    freq_hz : float
        Carrier frequency [Hz].
    rho_g_m3 : float
        Surface water-vapour density [g/m^3] (the profile of P.835 is scaled to it).

    Returns
    -------
    ndarray, shape of ``el_deg``
        Loss [dB].
    """
    from itur.models.itu453 import radio_refractive_index
    from itur.models.itu676 import gamma_exact
    from itur.models.itu835 import (
        standard_pressure,
        standard_temperature,
        standard_water_vapour_density,
    )

    k = np.arange(_P676_LAYERS)
    delta_km = 0.0001 * np.exp(k / 100)  # Eq. 14
    h_km = 0.0001 * (np.exp(k / 100.0) - 1.0) / (np.exp(1.0 / 100.0) - 1.0)  # Eq. 15
    t_k = standard_temperature(h_km).to("K").value
    p_hpa = standard_pressure(h_km).value
    rho = standard_water_vapour_density(h_km, rho_0=rho_g_m3).value
    n = radio_refractive_index(p_hpa, rho * t_k / 216.7, t_k).value
    n_ratio = n / np.pad(n[1:], (0, 1), mode="edge")
    gamma_db_km = np.asarray(gamma_exact(freq_hz / 1e9, p_hpa, rho, t_k).value, dtype=float)
    b = np.pi / 2 - np.deg2rad(np.asarray(el_deg, dtype=float))
    total = np.zeros_like(b)
    for r, delta, g, n_r in zip(6371 + h_km, delta_km, gamma_db_km, n_ratio, strict=True):
        a = -r * np.cos(b) + 0.5 * np.sqrt(
            4 * r**2 * np.cos(b) ** 2 + 8 * r * delta + 4 * delta**2
        )  # Eq. 17
        cos_arg = np.clip((-(a**2) - 2 * r * delta - delta**2) / (2 * a * r + 2 * a * delta), -1, 1)
        total += a * g  # Eq. 13
        b = np.arcsin(np.sin(np.pi - np.arccos(cos_arg)) * n_r)  # Eqs. 18a, 19a
    return total


def site_surface_conditions(lat_deg, lon_deg, p_percent=50.0):
    """Surface pressure [hPa], temperature [K], water vapour [g/m^3] and altitude [m] of a site.

    From the maps shipped with ``itur`` (offline): P.1511 altitude, P.835 pressure at
    that altitude, P.1510 mean surface temperature, P.836 vapour density exceeded
    ``p_percent`` of the time.
    """
    from itur.models import itu835, itu836, itu1510, itu1511

    def val(q):
        return float(np.squeeze(getattr(q, "value", q)))

    alt_km = val(itu1511.topographic_altitude(lat_deg, lon_deg))
    return {
        "pressure_hpa": val(itu835.standard_pressure(alt_km)),
        "temp_k": val(itu1510.surface_mean_temperature(lat_deg, lon_deg)),
        "rho_g_m3": val(itu836.surface_water_vapour_density(lat_deg, lon_deg, p_percent, alt_km)),
        "altitude_m": alt_km * 1e3,
    }


@dataclass(frozen=True)
class P618Terms:
    """The terms of ITU-R P.618's total attenuation that :func:`itu_p618_db` sums."""

    rain: bool = True
    clouds: bool = True
    scintillation: bool = True
    gas: bool = True


def itu_p618_db(
    elevation_rad,
    freq_hz,
    lat_deg,
    lon_deg,
    p_percent=1.0,
    diameter_m=1.0,
    terms=None,
):
    """Total attenuation exceeded ``p_percent`` of the time, ITU-R P.618 via ``itur`` [dB].

    Gas (P.676), rain (P.618/P.837/P.838), clouds (P.840) and scintillation (P.618, for
    an antenna of ``diameter_m``), at the site ``lat_deg, lon_deg``; ``terms``
    (:class:`P618Terms`, None: all four) says which are summed. ``itur`` warns below
    5 deg elevation. Slow: tabulate (:class:`AtmosphereTable`).
    """
    t = P618Terms() if terms is None else terms
    import itur

    el_deg = np.degrees(np.atleast_1d(np.asarray(elevation_rad, dtype=float)))
    with warnings.catch_warnings():
        if np.all(el_deg >= 5.0):  # only the spurious 90 deg warning (np.mod(90, 90) < 5)
            warnings.filterwarnings("ignore", message=".*only recommended for elevation.*")
        out = itur.atmospheric_attenuation_slant_path(
            lat_deg,
            lon_deg,
            freq_hz / 1e9,
            el_deg,
            p_percent,
            diameter_m,
            include_rain=t.rain,
            include_clouds=t.clouds,
            include_scintillation=t.scintillation,
            include_gas=t.gas,
        )
    return np.asarray(getattr(out, "value", out), dtype=float).reshape(np.shape(elevation_rad))


_HALF_DEGREE_RAD = np.pi / 360.0


class AtmosphereTable:
    """A loss model tabulated on an elevation grid and interpolated (vectorized).

    The table stores ``loss(el) / m(el)``, with ``m`` the path length through a 10 km
    shell relative to zenith: this ratio is smooth down to 0 deg, where the loss itself
    bends like ``1 / sin(el)``. Elevations below the grid give NaN (no link).

    Parameters
    ----------
    loss_fn : callable
        ``loss_fn(elevation_rad array) -> loss_db array``, called once, on the grid, when
        the table is first used (:attr:`loss_db`): a scenario built and not run (``leolink
        validate``, the parent of a split run) never loads ``itur``'s maps.
    min_elevation_rad : float
        First grid point [rad].
    step_rad : float
        Grid step [rad] (default 0.5 deg); the last point is pi/2.
    """

    _SHELL_M = 10e3
    constant_db = None  # depends on the elevation

    def __init__(self, loss_fn, min_elevation_rad=0.0, step_rad=_HALF_DEGREE_RAD):
        n = int(np.ceil((np.pi / 2 - min_elevation_rad) / step_rad)) + 1
        self.elevation_rad = np.linspace(min_elevation_rad, np.pi / 2, max(n, 2))
        self._loss_fn = loss_fn

    @functools.cached_property
    def loss_db(self):
        """The loss on the grid [dB], shape of :attr:`elevation_rad` (computed once)."""
        return np.asarray(self._loss_fn(self.elevation_rad), dtype=float)

    @functools.cached_property
    def _ratio(self):
        return self.loss_db / self._airmass(self.elevation_rad)

    @classmethod
    def _airmass(cls, elevation_rad):
        r = EARTH_RADIUS_M
        return shell_path_length_m(elevation_rad, r, r + cls._SHELL_M, r) / cls._SHELL_M

    def __call__(self, elevation_rad):
        """Loss [dB] at ``elevation_rad`` (any shape); NaN below the grid."""
        el = np.minimum(np.asarray(elevation_rad, dtype=float), np.pi / 2)
        ratio = np.interp(el, self.elevation_rad, self._ratio, left=np.nan)
        return ratio * self._airmass(el)


#: Atmosphere models by config name (``atmosphere.model``). Builders read the carrier
#: frequency, the ROI centre (``site_lat_deg``, ``site_lon_deg``) and the lowest elevation
#: to tabulate (``table_min_elevation_deg``) from the build context.
ATMOSPHERES: Registry[AtmosphereModel] = Registry("atmosphere.model", protocol=AtmosphereModel)


class FixedConfig(Params):
    loss_db: float = Field(0.017, ge=0.0, le=100.0, description="loss at every elevation [dB]")


class ItuP618Config(Params):
    exceedance_percent: float = Field(
        1.0, ge=0.001, le=5.0, description="percentage of time exceeded p [%] (P.618: 0.001-5)"
    )
    antenna_diameter_m: float = Field(0.6, gt=0.0, le=20.0, description="terminal diameter [m]")


# Slow models are tabulated every 2 deg from 2 deg below the lowest used elevation: the
# table interpolates loss / air mass, which is smooth, so this stays within 2e-4 (relative)
# of direct ITU-R P.676 calls (0.5 deg steps: 1.5e-5, at 3.4x the set-up time).
_TABLE_STEP_DEG = 2.0


def _table(fn, ctx):
    min_el = np.radians(max(0.0, getattr(ctx, "table_min_elevation_deg", 0.0)))
    return AtmosphereTable(lambda el: fn(el, ctx.freq_hz), min_el, np.radians(_TABLE_STEP_DEG))


ATMOSPHERES.add(
    "fixed",
    lambda p, ctx: FixedLoss(p.loss_db),
    config=FixedConfig,
    doc="one number at every elevation (the paper's Table: 0.017 dB)",
)


def _p676(p, ctx):
    def loss_db(el, f):  # at the table's first use: the site's maps are itur's largest
        site = site_surface_conditions(ctx.site_lat_deg, ctx.site_lon_deg)
        site.pop("altitude_m")
        return itu_p676_db(el, f, **site)

    return _table(loss_db, ctx)


ATMOSPHERES.add(
    "itu_p676", _p676, doc="gaseous attenuation of ITU-R P.676 at the ROI centre (itur)"
)


def _p618(p, ctx):
    here = {"lat_deg": ctx.site_lat_deg, "lon_deg": ctx.site_lon_deg}
    return _table(
        lambda el, f: itu_p618_db(
            el, f, p_percent=p.exceedance_percent, diameter_m=p.antenna_diameter_m, **here
        ),
        ctx,
    )


ATMOSPHERES.add(
    "itu_p618",
    _p618,
    config=ItuP618Config,
    doc="gas, rain, cloud and scintillation of ITU-R P.618 at the ROI centre (itur)",
)
ATMOSPHERES.add(
    "paper",
    lambda p, ctx: _table(paper_model_db, ctx),
    doc="the paper's P.676 integral through the 1976 US Standard Atmosphere",
)


def atmosphere_model(kind, freq_hz, min_elevation_deg=0.0, step_deg=0.5, **params):
    """Build ``callable(elevation_rad array) -> loss_db array`` from Python.

    Parameters
    ----------
    kind : {'fixed', 'itu_p676', 'itu_p618', 'paper'}
        Model (module docstring). ``fixed`` takes ``loss_db``; ``itu_p618`` needs
        ``lat_deg, lon_deg``; ``itu_p676`` takes the surface conditions, or a site
        ``lat_deg, lon_deg`` (:func:`site_surface_conditions`), or the standard values.
    freq_hz : float
        Carrier frequency [Hz].
    min_elevation_deg, step_deg : float
        Grid of the :class:`AtmosphereTable` of the tabulated kinds [deg].
    **params
        Keyword arguments of the model function (:func:`fixed_loss_db`,
        :func:`itu_p676_db`, :func:`itu_p618_db`, :func:`paper_model_db`).
    """
    if kind == "fixed":
        return FixedLoss(**params)
    if kind == "itu_p676" and ("lat_deg" in params or "lon_deg" in params):
        site = site_surface_conditions(params.pop("lat_deg"), params.pop("lon_deg"))
        site.pop("altitude_m")
        params = {**site, **params}
    fn = {"itu_p676": itu_p676_db, "itu_p618": itu_p618_db, "paper": paper_model_db}[kind]
    return AtmosphereTable(
        lambda el: fn(el, freq_hz, **params), np.radians(min_elevation_deg), np.radians(step_deg)
    )
