"""``leolink passes``: when each satellite of a config rises over a site, culminates and
sets, in the run's window, from the run's ephemeris and Earth model
(:func:`leolink.passes.find_passes`)."""

from __future__ import annotations

import math
from datetime import UTC, timedelta

import numpy as np

from leolink.app.orbits import ephemeris_from_config
from leolink.app.run import time_zero_utc
from leolink.errors import ConfigError
from leolink.geodesy import wgs84_to_ecef
from leolink.geometry import enu_basis, geodetic_to_ecef
from leolink.passes import find_passes
from leolink.sim.runner import epoch_times
from leolink.visibility import site_elevations_rad

__all__ = ["parse_site", "site_passes"]

#: The site's bounds, as a population's (``lat_deg``, ``lon_deg``, ``alt_m``).
SITE_LIMITS = ((-90.0, 90.0, "latitude [deg]"), (-180.0, 180.0, "longitude [deg]"),
               (-500.0, 20_000.0, "height [m]"))  # fmt: skip


def parse_site(text):
    """``"LAT,LON[,ALT]"`` -> ``(lat_deg, lon_deg, alt_m)``; ConfigError names ``--site``."""
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (2, 3):
        raise ConfigError(f"--site {text!r} is not allowed; use LAT,LON or LAT,LON,ALT (numbers)")
    values += [0.0] * (3 - len(values))
    for value, (low, high, meaning) in zip(values, SITE_LIMITS, strict=True):
        if not low <= value <= high:
            raise ConfigError(
                f"--site {text!r} is not allowed: {meaning} {value:g} is outside "
                f"[{low:g}, {high:g}]"
            )
    return tuple(values)


def _site_frame(cfg, lat_deg, lon_deg, alt_m):
    """The site's position and vertical in the run's Earth model."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    if cfg.earth.model == "wgs84":
        pos = wgs84_to_ecef(lat, lon, alt_m)
    else:
        pos = geodetic_to_ecef(lat, lon, alt_m, radius_m=cfg.earth.radius_m)
    return np.asarray(pos, float), enu_basis(lat, lon)[..., 2, :]


def site_passes(cfg, site, min_elevation_deg=None):
    """The passes over ``site`` (lat_deg, lon_deg, alt_m) in the recorded window of
    ``cfg``, as dicts: ``sat_id``, ``name``, ``rise_s``/``culmination_s``/``set_s``
    (simulation time, None outside the window), the same as ``*_utc`` (ISO 8601, None
    when the run has no calendar time) and ``max_elevation_deg``."""
    mask_deg = (
        cfg.constellation.min_elevation_deg if min_elevation_deg is None else min_elevation_deg
    )
    if not 0.0 <= mask_deg < 90.0:
        raise ConfigError(f"--min-elevation-deg {mask_deg:g} is not allowed; use [0, 90)")
    ephemeris = ephemeris_from_config(cfg)
    site_m, normal = _site_frame(cfg, *site)
    r = cfg.run
    times, n_warm = epoch_times(r.start_s, r.epoch_s, r.warmup_s, r.duration_s)

    def elevation_rad(t_s, sat=None):
        pos = ephemeris(np.asarray(t_s, float))[0]  # (n_t, n_sat, 3)
        if sat is not None:
            pos = pos[np.arange(len(sat)), sat]
        return site_elevations_rad(pos, site_m, normal)

    window = (float(times[n_warm]), float(times[-1]))
    passes = find_passes(elevation_rad, window, math.radians(mask_deg))
    return [_record(p, ephemeris.names, time_zero_utc(cfg)) for p in passes]


def _record(p, names, zero_utc):
    def utc(t_s):
        if t_s is None or zero_utc is None:
            return None
        when = zero_utc.astimezone(UTC) + timedelta(seconds=t_s)
        return when.isoformat(timespec="milliseconds").replace("+00:00", "Z")

    times = {"rise": p.rise_s, "culmination": p.culmination_s, "set": p.set_s}
    return {
        "sat_id": p.sat,
        "name": names[p.sat] if names else str(p.sat),
        **{f"{k}_utc": utc(t) for k, t in times.items()},
        **{f"{k}_s": t for k, t in times.items()},
        "max_elevation_deg": math.degrees(p.max_elevation_rad),
    }
