"""Config ``[[population]]`` tables -> mobility objects (one object per population)."""

from __future__ import annotations

import math

import numpy as np

from leolink.sim.mobility import (
    ConstantVelocity,
    RecordedTrack,
    Static,
    Track,
    Waypoints,
    place_grid,
    place_random,
    resolve_speed_m_s,
    roi_points_to_geodetic,
)

__all__ = ["populations_from_config"]


def _grid_points(count, rx_m, ry_m):
    """About ``count`` grid points inside the ellipse (the densest grid that has enough,
    thinned evenly to exactly ``count``)."""
    n = max(1, math.ceil(math.sqrt(count * 4.0 / math.pi)))
    while True:
        nx = max(1, round(n * math.sqrt(rx_m / ry_m)))
        ny = max(1, round(n * math.sqrt(ry_m / rx_m)))
        x, y = place_grid(nx, ny, rx_m, ry_m)
        if len(x) >= count:
            keep = np.round(np.linspace(0, len(x) - 1, count)).astype(int)
            return x[keep], y[keep]
        n += 1


def _start_points(pop, rx_m, ry_m, rng):
    if pop.placement == "center":
        return np.zeros(pop.count), np.zeros(pop.count)
    if pop.placement == "points":
        return np.asarray(pop.x_m, float), np.asarray(pop.y_m, float)
    if pop.placement == "random":
        return place_random(pop.count, rx_m, ry_m, rng)
    return _grid_points(pop.count, rx_m, ry_m)


def _headings(pop, n, track_heading_rad, rng):
    h = pop.heading_deg
    if h == "random":
        return rng.uniform(0.0, 2.0 * np.pi, n)
    rule = {"along_track": 0.0, "against_track": np.pi, "cross_track": np.pi / 2}
    if isinstance(h, str):
        return np.full(n, track_heading_rad + rule[h])
    return np.full(n, math.radians(h))


def populations_from_config(cfg, track_heading_rad, rng):
    """Mobility objects of every ``[[population]]``, in config order.

    Parameters
    ----------
    cfg : Config
    track_heading_rad : float
        Azimuth of the ROI x axis at the ROI centre (placement and relative headings).
    rng : numpy.random.Generator
        For random placement and headings (the run's generator).

    Returns
    -------
    list of (PopulationSection, mobility object)
    """
    rx, ry = cfg.roi_semi_axes_m()
    lat_c, lon_c = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    radius = cfg.earth.radius_m
    out = []
    for pop in cfg.population:
        if pop.kind == "track":
            out.append((pop, RecordedTrack(pop.track_file, radius_m=radius)))
            continue
        if pop.kind == "waypoints":
            w = np.asarray(pop.waypoints, float)
            track = Track(w[:, 0], np.radians(w[:, 1]), np.radians(w[:, 2]), w[:, 3], pop.name)
            out.append((pop, Waypoints([track], radius_m=radius)))
            continue
        x, y = _start_points(pop, rx, ry, rng)
        lat, lon = roi_points_to_geodetic(x, y, lat_c, lon_c, track_heading_rad, radius)
        speed = pop.speed_m_s if pop.speed_m_s is not None else resolve_speed_m_s(pop.speed or 0.0)
        if pop.kind == "static" or speed == 0.0:
            out.append((pop, Static(lat, lon, pop.alt_m)))
        else:
            heading = _headings(pop, len(x), track_heading_rad, rng)
            out.append(
                (
                    pop,
                    ConstantVelocity(
                        lat, lon, pop.alt_m, heading, speed, t0_s=cfg.run.start_s, radius_m=radius
                    ),
                )
            )
    return out
