"""The steering mode of ``[satellite_array]``: its entry built with what it needs of the run.

``earth_fixed`` needs the cells: the ground points of the codebook's beam boresights at
the reference instant (each satellite's own, from the ephemeris), or the configured
latitudes and longitudes; both are placed on the run's Earth model (the sphere, or the
WGS 84 ellipsoid at the same latitude and longitude).
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from leolink.geodesy import wgs84_to_ecef
from leolink.geometry import ecef_to_geodetic, geodetic_to_ecef, ray_to_ground

__all__ = ["steering_from_config", "surface_point"]


def surface_point(cfg, lat_rad, lon_rad):
    """Points on the run's Earth (``[earth]``: the sphere, or WGS 84) [m], ``(..., 3)``."""
    if cfg.earth.model == "wgs84":
        return wgs84_to_ecef(lat_rad, lon_rad, 0.0)
    return geodetic_to_ecef(lat_rad, lon_rad, 0.0, cfg.earth.radius_m)


def steering_from_config(cfg, codebook, ephemeris=None):
    """The :class:`~leolink.antenna.steering.SteeringMode` of ``[satellite_array]``.

    ``ephemeris``: the run's (built from the config when needed and not given).
    """
    from leolink.app.orbits import ephemeris_from_config

    radius = cfg.earth.radius_m
    u = np.asarray(codebook.u_xy, float)

    def surface(lat_rad, lon_rad):
        return surface_point(cfg, lat_rad, lon_rad)

    def footprint_cells(t_s):
        eph = ephemeris_from_config(cfg) if ephemeris is None else ephemeris
        pos, vel, _ = eph(np.array([t_s]))
        hit = ray_to_ground(pos[0][:, None, :], vel[0][:, None, :], u[None], radius)
        lat, lon, _ = ecef_to_geodetic(hit, radius)
        return surface(lat, lon)  # (n_sat, n_beam, 3)

    r = cfg.run
    ctx = SimpleNamespace(
        beam_u_xy=u,
        phase_bits=cfg.satellite_array.phase_bits,
        min_elevation_rad=math.radians(cfg.constellation.min_elevation_deg),
        default_reference_s=r.start_s + 0.5 * r.duration_s,
        footprint_cells=footprint_cells,
        ground_points=surface,
    )
    return cfg.satellite_array.build_kind("steering", ctx)
