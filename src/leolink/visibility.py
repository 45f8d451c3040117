"""Elevations of many TLE satellites from many ground sites, vectorized and in blocks.

For visibility studies (which satellites a site sees, when): sgp4's ``SatrecArray``
propagates every satellite at every time in C; TEME is rotated to the Earth-fixed frame
by GMST82(UT1) (Vallado et al. 2006, AIAA 2006-6753, "TEME"; polar motion neglected,
as :meth:`leolink.orbit.Ephemeris.from_tles`); the elevation over a WGS 84 site is the
angle between the site-to-satellite vector ``d = r - s`` and the ellipsoid normal ``n``,
``asin((n . d) / |d|)``, over all (site, satellite x time) pairs, block by block.
Rounding: < 1e-12 rad, but within ~0.1 deg of the zenith, where the arcsine of a value
near 1 leaves ~1e-8 rad (6e-7 deg).
"""

from __future__ import annotations

import numpy as np

from leolink.geodesy import wgs84_to_ecef

__all__ = ["gmst82_rad", "site_elevations_rad", "teme_to_ecef_m", "tle_elevations_rad"]

SECONDS_PER_DAY = 86_400.0
#: Default memory of one block of work [bytes] (a few float64 arrays of the block's size).
BLOCK_BYTES = 64 * 2**20


def gmst82_rad(jd_ut1, fr_ut1=0.0):
    """Greenwich mean sidereal time, IAU 1982 (sgp4's ``gstime``, vectorized) [rad].

    ``jd_ut1 + fr_ut1`` is the UT1 Julian date [day] (the split keeps the fraction's
    precision; sgp4's ``gstime`` takes their sum).
    """
    t = (np.asarray(jd_ut1, float) - 2451545.0 + np.asarray(fr_ut1, float)) / 36525.0
    seconds = -6.2e-6 * t**3 + 0.093104 * t**2 + (876600.0 * 3600 + 8640184.812866) * t
    return np.mod(np.radians((seconds + 67310.54841) / 240.0), 2.0 * np.pi)


def teme_to_ecef_m(r_teme_m, theta_rad):
    """Rotate TEME positions into the Earth-fixed frame: ``Rz(-theta) r``.

    Parameters
    ----------
    r_teme_m : array_like, shape (..., n_time, 3) [m]
    theta_rad : array_like, shape (n_time,), GMST82 of each time [rad].

    Returns
    -------
    ndarray, shape (..., n_time, 3) [m]
    """
    r = np.asarray(r_teme_m, float)
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    x, y = r[..., 0], r[..., 1]
    return np.stack([c * x + s * y, -s * x + c * y, r[..., 2]], axis=-1)


def _satrec_array(satellites):
    from sgp4.api import SatrecArray

    return satellites if isinstance(satellites, SatrecArray) else SatrecArray(list(satellites))


def tle_elevations_rad(
    satellites,
    site_lat_rad,
    site_lon_rad,
    site_h_m,
    jd,
    fr,
    ut1_minus_utc_s=0.0,
    dtype=np.float64,
    block_bytes=BLOCK_BYTES,
):
    """Elevation of every satellite from every site at every time.

    Parameters
    ----------
    satellites : sgp4.api.SatrecArray or sequence of sgp4.api.Satrec, ``n_sat``.
    site_lat_rad, site_lon_rad, site_h_m : array_like, shape (n_site,)
        Geodetic latitude, longitude [rad] and height above the WGS 84 ellipsoid [m].
    jd, fr : array_like, shape (n_time,)
        UTC Julian date split in whole and fractional parts [day] (as ``sgp4.api.jday``).
    ut1_minus_utc_s : float or array_like, shape (n_time,)
        UT1 - UTC [s] for the Earth's rotation angle (|.| < 0.9 s; 0.9 s is 0.004 deg of
        rotation; it drifts by ~1 ms a day).
    dtype : numpy dtype of the result (float32 halves its memory: 1e-7 rad rounding).
    block_bytes : int, memory of one block's temporaries [bytes].

    Returns
    -------
    elevation_rad : ndarray, shape (n_site, n_sat, n_time)
        NaN where sgp4 failed (decayed orbit, bad elements).
    """
    sats = _satrec_array(satellites)
    jd, fr = np.broadcast_arrays(np.atleast_1d(np.asarray(jd, float)), np.asarray(fr, float))
    lat, lon, h = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, float)) for a in
                                        (site_lat_rad, site_lon_rad, site_h_m)))  # fmt: skip
    site = wgs84_to_ecef(lat, lon, h)  # (n_site, 3)
    normal = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)
    ut1 = np.broadcast_to(np.asarray(ut1_minus_utc_s, float), jd.shape)
    n_sat, n_time = len(sats), jd.size
    out = np.empty((lat.size, n_sat, n_time), dtype)
    # Blocks of times (the satellites' states: ~64 B per satellite-time), then of sites
    # (~6 float64 temporaries per site, satellite and time). Elementwise arithmetic, not
    # matrix products: the result does not depend on the blocks (BLAS rounding does).
    t_step = max(1, min(n_time, int(block_bytes // (64 * max(n_sat, 1)))))
    for t0 in range(0, n_time, t_step):
        t = slice(t0, t0 + t_step)
        r = _earth_fixed_states(sats, jd[t], fr[t], ut1[t])  # (3, n_sat * n_t)
        s_step = max(1, int(block_bytes // (48 * r.shape[1])))
        for lo in range(0, lat.size, s_step):
            elev = _elevations(r, site[lo : lo + s_step], normal[lo : lo + s_step])
            out[lo : lo + s_step, :, t] = elev.reshape(len(elev), n_sat, -1)
    return out


def site_elevations_rad(sat_pos_m, site_m, normal):
    """Elevation of satellites over one site, ``asin(n . d / |d|)``, ``d = r - s``.

    Parameters
    ----------
    sat_pos_m : array_like, shape (..., 3)
        Satellite positions, the site's frame [m].
    site_m, normal : array_like, shape (3,)
        The site's position [m] and its local vertical (unit; the ellipsoid normal on
        WGS 84, the radial direction on the sphere).

    Returns
    -------
    ndarray, shape (...)
        [rad]
    """
    r = np.asarray(sat_pos_m, float)
    flat = np.ascontiguousarray(r.reshape(-1, 3).T)
    site, normal = (np.asarray(a, float).reshape(1, 3) for a in (site_m, normal))
    return _elevations(flat, site, normal)[0].reshape(r.shape[:-1])


def _elevations(r, site, normal):
    """asin(n . d / |d|), d = r - s: (n_site, n_pair) [rad] from r (3, n_pair) [m]."""
    up = np.zeros((len(site), r.shape[1]))
    d2 = np.zeros_like(up)
    for i in range(3):  # x, y, z: d_i = r_i - s_i, accumulated in place
        d = r[i][None, :] - site[:, i : i + 1]
        d2 += d * d
        d *= normal[:, i : i + 1]
        up += d
    np.sqrt(d2, out=d2)
    up /= d2
    return np.arcsin(np.clip(up, -1.0, 1.0, out=up), out=up)


def _earth_fixed_states(sats, jd, fr, ut1_minus_utc_s):
    """Earth-fixed positions of every satellite at every time, as (3, n_sat * n_time)
    [m] (NaN where sgp4 failed)."""
    err, r_km, _ = sats.sgp4(np.ascontiguousarray(jd), np.ascontiguousarray(fr))
    r_m = teme_to_ecef_m(r_km * 1e3, gmst82_rad(jd, fr + ut1_minus_utc_s / SECONDS_PER_DAY))
    r_m[err != 0] = np.nan
    return r_m.reshape(-1, 3).T.copy()  # contiguous rows for the matrix products
