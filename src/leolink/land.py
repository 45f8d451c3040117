"""Land and sea: which points of the globe are on land, from the coastlines leolink ships.

The data are Natural Earth 4.1.0 1:50m "land" (public domain), stored as closed polylines
in ``leolink/data/coastlines_50m.npz`` (provenance next to it). A point is on land when a
ray from it towards the east crosses the coastline rings an odd number of times (the
even-odd rule, so a lake that is a hole in a continent is water), in the plane of
longitude and latitude: Natural Earth cuts its polygons at the antimeridian, so they close
in that plane. Six arcs end on the antimeridian (Wrangel Island, Chukotka); each is closed
by the meridian segment between its ends, which an eastward ray never crosses.

At the 1:50m scale a coastline is placed to ~1 km: points that near a coast may fall on
either side.
"""

from __future__ import annotations

import math
from functools import lru_cache
from importlib import resources

import numpy as np

__all__ = ["coastline_arcs", "is_land"]


@lru_cache(maxsize=1)
def coastline_arcs():
    """The shipped coastlines, Natural Earth 4.1.0 1:50m land.

    Returns
    -------
    lon_deg, lat_deg : ndarray of float32, shape (n_point,)
        Closed polylines (arcs) separated by NaN [deg], WGS 84 longitude and latitude.
    """
    ref = resources.files("leolink") / "data" / "coastlines_50m.npz"
    with resources.as_file(ref) as path, np.load(path) as data:
        lon, lat = data["lon_deg"].copy(), data["lat_deg"].copy()
    lon.flags.writeable = lat.flags.writeable = False  # shared by every call
    return lon, lat


@lru_cache(maxsize=1)
def _edges():
    """Every edge of every ring as ``(x0, y0, x1, y1)`` (n_edge, 4) float64 [deg], with the
    rings' bounding boxes ``(lon_min, lon_max, lat_min, lat_max, first, stop)`` per ring."""
    lon, lat = (a.astype(float) for a in coastline_arcs())
    cut = np.flatnonzero(np.isnan(lon))
    starts, stops = np.r_[0, cut + 1], np.r_[cut, len(lon)]
    edges, boxes, n = [], [], 0
    for a, b in zip(starts, stops, strict=True):  # ~1,400 rings, once per process
        x, y = _unwrapped(lon[a:b], lat[a:b])
        if not len(x):
            continue
        x1, y1 = np.r_[x[1:], x[0]], np.r_[y[1:], y[0]]  # closed (a no-op for closed arcs)
        edges.append(np.stack([x, y, x1, y1], axis=1))
        boxes.append((x.min(), x.max(), y.min(), y.max(), n, n + len(x)))
        n += len(x)
    return np.concatenate(edges), np.asarray(boxes)


def _unwrapped(x, y):
    """An arc with +180 restored where quantization wrote -180 (next to eastern
    longitudes), and closed through the pole when it runs from -180 to +180 (Antarctica)."""
    x = x.copy()
    if len(x) < 2:
        return x, y
    x[(x == -180.0) & (np.maximum(np.r_[x[1], x[:-1]], np.r_[x[1:], x[-2]]) > 90.0)] = 180.0
    if {float(x[0]), float(x[-1])} == {-180.0, 180.0}:
        pole = math.copysign(90.0, float(np.mean(y)))
        x, y = np.r_[x, x[-1], x[0]], np.r_[y, pole, pole]
    return x, y


def is_land(lat_deg, lon_deg):
    """Whether each point is on land (Natural Earth 1:50m, even-odd rule).

    Parameters
    ----------
    lat_deg, lon_deg : array_like, shape (n,)
        Latitude in [-90, 90], longitude in [-180, 180] (wrapped if beyond) [deg].

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    lat = np.atleast_1d(np.asarray(lat_deg, float))
    lon = (np.atleast_1d(np.asarray(lon_deg, float)) + 180.0) % 360.0 - 180.0
    edges, boxes = _edges()
    inside = np.zeros(lat.shape, bool)
    for x0, x1, y0, y1, a, b in boxes:  # per ring: only the points in its box
        near = np.flatnonzero((lat >= y0) & (lat <= y1) & (lon >= x0) & (lon <= x1))
        if near.size:
            inside[near] ^= _odd_crossings(lat[near], lon[near], edges[int(a) : int(b)])
    return inside


def _odd_crossings(lat, lon, edges):
    """Whether an eastward ray from each point crosses the ring's edges an odd number of
    times (edges taken half-open in latitude, so a vertex is counted once)."""
    out = np.zeros(lat.shape, bool)
    step = max(1, 2**20 // max(len(edges), 1))  # bounded (points x edges) temporaries
    x0, y0, x1, y1 = (edges[:, k] for k in range(4))
    for i in range(0, len(lat), step):
        py, px = lat[i : i + step, None], lon[i : i + step, None]
        spans = (y0 > py) != (y1 > py)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cross = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
        out[i : i + step] = np.count_nonzero(spans & (x_cross > px), axis=1) % 2 == 1
    return out
