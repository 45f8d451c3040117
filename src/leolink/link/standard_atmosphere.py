"""The paper's atmospheric model: ITU-R P.676 integrated through the 1976 US Standard
Atmosphere along the slant path (Sec. 2.2 of [1]).

The specific attenuation ``A(f, T(h), P(h), rho(h))`` of ITU-R P.676 Annex 1 [2] is
integrated from 0 to 81 km over spherical shells, with 7.5 g/m^3 of water vapour at sea
level, proportional to the air density up to 2.3 km and zero above.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] ITU-R P.676-12, "Attenuation by atmospheric gases and related effects."
.. [3] NOAA/NASA/USAF, "U.S. Standard Atmosphere, 1976", NOAA-S/T 76-1562.
"""

import numpy as np

from leolink.constants import EARTH_RADIUS_M

__all__ = [
    "paper_model_db",
    "paper_water_vapour_g_m3",
    "shell_path_length_m",
    "specific_attenuation_db_m",
    "us_standard_atmosphere",
]

# --- 1976 US Standard Atmosphere, layers to 86 km (84.852 km geopotential) -----------
_EARTH_RADIUS_1976_M = 6_356_766.0  # r0 of the geopotential conversion [3]
_GMR_K_M = 9.80665 * 0.0289644 / 8.31432  # g0 M0 / R* = 0.0341632 K/m [3]
_H_BASE_M = np.array([0.0, 11e3, 20e3, 32e3, 47e3, 51e3, 71e3])
_LAPSE_K_M = np.array([-6.5e-3, 0.0, 1e-3, 2.8e-3, 0.0, -2.8e-3, -2.0e-3])


def _layer_bases():
    """Base temperature [K] and pressure [Pa] of each layer, chained from sea level."""
    t_b, p_b = [288.15], [101_325.0]
    for i in range(len(_H_BASE_M) - 1):
        dh, lapse = _H_BASE_M[i + 1] - _H_BASE_M[i], _LAPSE_K_M[i]
        t_top = t_b[i] + lapse * dh
        if lapse == 0.0:
            p_top = p_b[i] * np.exp(-_GMR_K_M * dh / t_b[i])
        else:
            p_top = p_b[i] * (t_b[i] / t_top) ** (_GMR_K_M / lapse)
        t_b.append(t_top)
        p_b.append(p_top)
    return np.array(t_b), np.array(p_b)


_T_BASE_K, _P_BASE_PA = _layer_bases()


def us_standard_atmosphere(altitude_m, geopotential=False):
    """Temperature and pressure of the 1976 US Standard Atmosphere below 86 km [3].

    Piecewise-linear molecular-scale temperature in geopotential altitude
    ``H = r0 h / (r0 + h)``; the kinetic-temperature correction above 80 km (< 0.05 %)
    is neglected.

    Parameters
    ----------
    altitude_m : array_like
        Geometric altitude [m] (geopotential if ``geopotential=True``), 0 to 86 km.

    Returns
    -------
    temp_k, pressure_pa : ndarray, shape of ``altitude_m``
        Temperature [K] and total pressure [Pa].
    """
    h = np.asarray(altitude_m, dtype=float)
    h_geo = h if geopotential else _EARTH_RADIUS_1976_M * h / (_EARTH_RADIUS_1976_M + h)
    i = np.clip(np.searchsorted(_H_BASE_M, h_geo, side="right") - 1, 0, len(_H_BASE_M) - 1)
    lapse, t_b, p_b = _LAPSE_K_M[i], _T_BASE_K[i], _P_BASE_PA[i]
    dh = h_geo - _H_BASE_M[i]
    temp_k = t_b + lapse * dh
    iso = lapse == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        p_grad = p_b * (t_b / temp_k) ** (_GMR_K_M / np.where(iso, 1.0, lapse))
    pressure_pa = np.where(iso, p_b * np.exp(-_GMR_K_M * dh / t_b), p_grad)
    return temp_k, pressure_pa


def paper_water_vapour_g_m3(altitude_m, rho0_g_m3=7.5, top_m=2300.0):
    """The paper's water-vapour profile [g/m^3], Sec. 2.2 of [1].

    ``rho0`` at sea level, proportional to the air density ``P / T`` up to ``top_m``
    (2.3 km, where the standard atmosphere reaches 0 C), zero above.
    """
    h = np.asarray(altitude_m, dtype=float)
    temp_k, pressure_pa = us_standard_atmosphere(h)
    density_ratio = (pressure_pa / 101_325.0) * (288.15 / temp_k)
    return np.where(h <= top_m, rho0_g_m3 * density_ratio, 0.0)


def specific_attenuation_db_m(freq_hz, pressure_hpa, rho_g_m3, temp_k):
    """Gaseous specific attenuation ``gamma_o + gamma_w`` of ITU-R P.676 Annex 1 [dB/m].

    ``pressure_hpa`` is the dry-air pressure [hPa]; arrays broadcast (via ``itur``).
    """
    from itur.models import itu676

    gamma = itu676.gamma_exact(freq_hz / 1e9, pressure_hpa, rho_g_m3, temp_k)
    return np.asarray(getattr(gamma, "value", gamma), dtype=float) / 1e3


def shell_path_length_m(elevation_rad, r_low_m, r_high_m, r_ut_m):
    """Straight-ray path length between the spheres ``r_low`` and ``r_high`` [m].

    For a ray leaving radius ``r_ut`` at elevation ``el``, the distance to radius ``r``
    is ``s(r) = sqrt(r^2 - r_ut^2 cos^2 el) - r_ut sin el``; the length inside the shell
    is ``s(r_high) - s(r_low)``. Finite at 0 deg (unlike ``dh / sin el``).
    """
    el = np.asarray(elevation_rad, dtype=float)
    c2 = (r_ut_m * np.cos(el)) ** 2
    return np.sqrt(r_high_m**2 - c2) - np.sqrt(r_low_m**2 - c2)


def paper_model_db(
    elevation_rad,
    freq_hz,
    ut_altitude_m=0.0,
    top_m=81e3,
    rho0_g_m3=7.5,
    vapour_top_m=2300.0,
    step_m=25.0,
    radius_m=EARTH_RADIUS_M,
):
    """The paper's atmospheric loss ``LP_at = int A(f, T(h), P(h), rho(h)) ds`` [dB].

    Eq. (6) of [1] (Sec. 2.2.1): midpoint rule on shells of ``step_m`` from the UT altitude to
    ``top_m`` (81 km), spherical-shell straight-ray geometry (refraction neglected),
    1976 US Standard Atmosphere, the paper's water vapour (:func:`paper_water_vapour_g_m3`).
    The paper writes ``dh``; the path element along the slant ray is used here.

    Parameters
    ----------
    elevation_rad : array_like, shape (...)
        Elevation of the satellite seen from the UT [rad], 0 to pi/2.
    freq_hz : float
        Carrier frequency [Hz].

    Returns
    -------
    ndarray, shape (...)
        Loss [dB]. Memory grows as ``size * n_layers``: use :class:`AtmosphereTable`.
    """
    edges_m = np.arange(ut_altitude_m, top_m + 0.5 * step_m, step_m)
    h_mid = 0.5 * (edges_m[1:] + edges_m[:-1])
    temp_k, pressure_pa = us_standard_atmosphere(h_mid)
    rho = paper_water_vapour_g_m3(h_mid, rho0_g_m3, vapour_top_m)
    e_hpa = rho * temp_k / 216.7  # water-vapour partial pressure, P.676 Eq. (4)
    gamma_db_m = specific_attenuation_db_m(freq_hz, pressure_pa / 100.0 - e_hpa, rho, temp_k)
    el = np.asarray(elevation_rad, dtype=float)[..., None]
    r_ut = radius_m + ut_altitude_m
    length_m = shell_path_length_m(el, radius_m + edges_m[:-1], radius_m + edges_m[1:], r_ut)
    return np.sum(gamma_db_m * length_m, axis=-1)
