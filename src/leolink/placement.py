"""Placing UTs in the paper's ROI plane (Sec. 3.1 of [1]) and mapping them to the ground.

The ROI plane is tangent to the sphere at the ROI centre, ``x`` along the satellites'
ground track, ``y`` completing the right-handed frame with ``z`` up; points map to the
ground by the paper's central (gnomonic) projection
``p = R (R u_c + x e_x + y e_y) / sqrt(R^2 + x^2 + y^2)``.

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO satellite
   communications", Sec. 3.1.
"""

import math

import numpy as np

from leolink.constants import EARTH_RADIUS_M
from leolink.geometry import (
    ecef_to_geodetic,
    enu_basis,
    geodetic_to_ecef,
    ground_to_roi,
    roi_to_ground,
)
from leolink.greatcircle import great_circle_velocity
from leolink.land import coastline_arcs, is_land

__all__ = [
    "geodetic_to_roi_points",
    "grid_points",
    "has_land",
    "lat_lon_grid",
    "place_grid",
    "place_random",
    "random_region",
    "roi_points_to_geodetic",
]


def _roi_frame(lat_c_rad, lon_c_rad, track_heading_rad, radius_m):
    """A stand-in 'satellite' (position, velocity) whose body frame is the ROI frame."""
    up = enu_basis(lat_c_rad, lon_c_rad)[..., 2, :]
    e_x = great_circle_velocity(lat_c_rad, lon_c_rad, track_heading_rad, 1.0)
    return radius_m * up, e_x


def roi_points_to_geodetic(
    x_m, y_m, lat_c_rad, lon_c_rad, track_heading_rad, radius_m=EARTH_RADIUS_M
):
    """ROI-plane points to the ground, central projection of Sec. 3.1 of [1].

    ``p = R (R u_c + x e_x + y e_y) / sqrt(R^2 + x^2 + y^2)`` with ``u_c`` the centre's unit
    vector, ``e_x`` the unit tangent at the centre along ``track_heading_rad`` and
    ``e_y = u_c x e_x`` (x along-track, z up, right-handed: y points left of the track).
    The paper writes ``u_y = u_x x u_sat``, the opposite sign (see docs/errata.md).

    Parameters
    ----------
    x_m, y_m : array_like, shape (...)
        Along-track and cross-track coordinates [m].
    lat_c_rad, lon_c_rad : float
        ROI centre [rad].
    track_heading_rad : float
        Azimuth of the along-track axis at the centre, from north clockwise [rad].
    radius_m : float
        Earth radius [m].

    Returns
    -------
    lat_rad, lon_rad : ndarray, shape (...)
        Ground points [rad].
    """
    centre, e_x = _roi_frame(lat_c_rad, lon_c_rad, track_heading_rad, radius_m)
    pos = roi_to_ground(x_m, y_m, centre, e_x, radius_m=radius_m)
    lat, lon, _ = ecef_to_geodetic(pos, radius_m=radius_m)
    return lat, lon


def geodetic_to_roi_points(
    lat_rad, lon_rad, lat_c_rad, lon_c_rad, track_heading_rad, radius_m=EARTH_RADIUS_M
):
    """Inverse of :func:`roi_points_to_geodetic`: ``x = R p.e_x / p.u_c``, ``y = R p.e_y / p.u_c``.

    Returns ``(x_m, y_m)`` with shape of the inputs; NaN for points on the far hemisphere.
    """
    centre, e_x = _roi_frame(lat_c_rad, lon_c_rad, track_heading_rad, radius_m)
    pos = geodetic_to_ecef(lat_rad, lon_rad, 0.0, radius_m=radius_m)
    return ground_to_roi(pos, centre, e_x, radius_m=radius_m)


def place_random(n, rx_m, ry_m, rng):
    """``n`` points uniform over the area of the ellipse ``(x/rx)^2 + (y/ry)^2 <= 1``.

    Uniform in the ROI plane; on the ground the density falls by the projection's area
    factor ``(1 + rho^2/R^2)^(3/2)`` (about 1 % at 534 km from the centre).

    Parameters
    ----------
    n : int
        Number of points.
    rx_m, ry_m : float
        Along-track and cross-track semi-axes [m].
    rng : numpy.random.Generator
        Random source.

    Returns
    -------
    x_m, y_m : ndarray, shape (n,)
        ROI-plane coordinates [m].
    """
    rho = np.sqrt(rng.random(n))  # sqrt: uniform in area, not in radius
    ang = 2.0 * np.pi * rng.random(n)
    return rx_m * rho * np.cos(ang), ry_m * rho * np.sin(ang)


def place_grid(n_x, n_y, rx_m, ry_m):
    """Centres of an ``n_x`` by ``n_y`` grid of cells on the ellipse's bounding box, kept
    where inside the ellipse (so fewer than ``n_x n_y`` points, ordered x fastest).

    Returns
    -------
    x_m, y_m : ndarray, shape (n_inside,)
        ROI-plane coordinates [m].
    """
    x = rx_m * ((np.arange(n_x) + 0.5) * 2.0 / n_x - 1.0)
    y = ry_m * ((np.arange(n_y) + 0.5) * 2.0 / n_y - 1.0)
    xx, yy = np.meshgrid(x, y)
    inside = (xx / rx_m) ** 2 + (yy / ry_m) ** 2 <= 1.0
    return xx[inside], yy[inside]


def grid_points(count, rx_m, ry_m):
    """About ``count`` grid points inside the ellipse: the densest :func:`place_grid` that
    has enough, thinned evenly to exactly ``count``.

    Returns
    -------
    x_m, y_m : ndarray, shape (count,)
        ROI-plane coordinates [m].
    """
    n = max(1, math.ceil(math.sqrt(count * 4.0 / math.pi)))
    while True:
        nx = max(1, round(n * math.sqrt(rx_m / ry_m)))
        ny = max(1, round(n * math.sqrt(ry_m / rx_m)))
        x, y = place_grid(nx, ny, rx_m, ry_m)
        if len(x) >= count:
            keep = np.round(np.linspace(0, len(x) - 1, count)).astype(int)
            return x[keep], y[keep]
        n += 1


# --- Placement by geography (latitude and longitude) -------------------------------------


def lat_lon_grid(spacing_deg, lat_band_deg=(-90.0, 90.0), lon_range_deg=(-180.0, 180.0)):
    """Points of a near-equal-area grid in a latitude band and longitude range.

    Rows every ``spacing_deg`` of latitude, at the centres of the band's rows; along a
    row at latitude ``phi`` the points are ``spacing_deg / cos(phi)`` of longitude apart
    (rounded to fill the range evenly), so each point stands for about the same area,
    ``(spacing_deg * pi / 180)^2 R^2``, and per-UT statistics average over area.

    Parameters
    ----------
    spacing_deg : float
        Spacing of the rows, and along the equator [deg], > 0.
    lat_band_deg, lon_range_deg : (float, float)
        ``(low, high)`` latitude in [-90, 90] and longitude in [-180, 180] [deg].

    Returns
    -------
    lat_deg, lon_deg : ndarray, shape (n,)
        Ordered by row (south to north), then by longitude (west to east).
    """
    (lat_lo, lat_hi), (lon_lo, lon_hi) = lat_band_deg, lon_range_deg
    n_rows = math.floor((lat_hi - lat_lo) / spacing_deg + 0.5)
    if n_rows < 1:
        return np.empty(0), np.empty(0)
    lat = lat_lo + (np.arange(n_rows) + 0.5) * (lat_hi - lat_lo) / n_rows
    width = lon_hi - lon_lo
    per_row = np.maximum(1, np.round(width * np.cos(np.radians(lat)) / spacing_deg)).astype(int)
    row = np.repeat(np.arange(n_rows), per_row)
    k = np.arange(len(row)) - np.repeat(np.cumsum(per_row) - per_row, per_row)
    return lat[row], lon_lo + (k + 0.5) * width / per_row[row]


def random_region(n, lat_band_deg, lon_range_deg, rng, land_only=False):
    """``n`` points uniform on the sphere's area inside a latitude band and longitude range.

    ``sin(lat)`` is uniform between the band's sines (the area between two parallels is
    proportional to the difference of their sines), the longitude uniform in its range.
    With ``land_only``, points at sea are drawn again (rejection: still uniform over the
    land of the region, :func:`leolink.land.is_land`), in batches of ``n`` / (the land
    fraction so far); the caller checks first that the region has land
    (:func:`has_land`).

    Returns
    -------
    lat_deg, lon_deg : ndarray, shape (n,)
    """
    s_lo, s_hi = (math.sin(math.radians(v)) for v in lat_band_deg)

    def draw(k):
        lat = np.degrees(np.arcsin(np.clip(rng.uniform(s_lo, s_hi, k), -1.0, 1.0)))
        return lat, rng.uniform(*lon_range_deg, k)

    if not land_only:
        return draw(n)
    lats, lons, n_drawn, n_kept = [], [], 0, 0
    while n_kept < n:
        k = max(64, math.ceil(1.2 * (n - n_kept) * max(n_drawn, 1) / max(n_kept, 1)))
        lat, lon = draw(min(k, 4_000_000))
        keep = is_land(lat, lon)
        lats.append(lat[keep])
        lons.append(lon[keep])
        n_drawn, n_kept = n_drawn + len(lat), n_kept + int(keep.sum())
    return np.concatenate(lats)[:n], np.concatenate(lons)[:n]


def has_land(lat_band_deg, lon_range_deg):
    """Whether a region has land: a coastline vertex inside it, or one of a 5 x 5 grid of
    its points on land (a region without coastline is all land or all sea)."""
    (lat_lo, lat_hi), (lon_lo, lon_hi) = lat_band_deg, lon_range_deg
    lon, lat = coastline_arcs()
    if np.any((lat > lat_lo) & (lat < lat_hi) & (lon > lon_lo) & (lon < lon_hi)):
        return True
    step = min(lat_hi - lat_lo, (lon_hi - lon_lo) * 0.5) / 5.0
    probe_lat, probe_lon = lat_lon_grid(max(step, 1e-6), lat_band_deg, lon_range_deg)
    return bool(is_land(probe_lat, probe_lon).any())
