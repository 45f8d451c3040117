"""Maps on plain longitude/latitude axes: coastlines, ground tracks, beam cells, UT tracks.

No cartographic library: the axes are equirectangular (x = longitude, y = latitude, in
degrees) with the aspect ``1 / cos(latitude at the centre)``, so shapes near the centre
of the map keep their proportions. Coastlines are Natural Earth 1:50m land (public
domain), shipped in ``leolink/data/coastlines_50m.npz`` (see the provenance file there);
nothing is downloaded.

Inputs are plain arrays (see :func:`plot_map`), as a streaming sink keeps them.
Beam colours come from :func:`beam_colour`, shared with the animation, so a UT coloured
by its serving beam has the colour of that beam's cell.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from leolink.geometry import ecef_to_geodetic
from leolink.land import coastline_arcs

__all__ = [
    "N_BEAM_COLOURS",
    "OUTAGE_COLOUR",
    "beam_colour",
    "break_at_antimeridian",
    "coastlines",
    "draw_base",
    "draw_beam_labels",
    "draw_footprints",
    "draw_ut_labels",
    "draw_ut_points",
    "draw_ut_tracks",
    "map_extent",
    "new_figure",
    "plot_map",
    "rings_deg",
    "subsatellite_points",
]

OUTAGE_COLOUR = (0.35, 0.35, 0.35, 1.0)  # a UT with no serving beam
N_BEAM_COLOURS = 18
_COAST_STYLE = {"color": "0.45", "linewidth": 0.6, "zorder": 1}
_MARGIN_DEG = 2.0
#: rc settings under which the report's axes are made: each title at its fixed place, just
#: above its axes. Left to matplotlib (``None``), every draw lays out each titled axes' y
#: tick labels once more to lift the title over an offset text or ticks on top, which
#: these axes never put under a title (no top ticks; the time panels, titled on the left,
#: show their y values without an offset; the dwell histograms, whose multiplier can meet
#: a title, keep matplotlib's placement): ~8 % of the figures' drawing.
FIXED_TITLE_RC = {"axes.titley": 1.0}


def beam_colour(beam_id):
    """RGBA colour of beam ``beam_id`` (18 tab20 colours, cycling; -1 -> :data:`OUTAGE_COLOUR`).

    The two greys of tab20 are left out so that no beam looks like an outage.

    Parameters
    ----------
    beam_id : int or array_like of int, shape (...)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    palette = _palette()
    beam = np.asarray(beam_id, int)
    rgba = np.empty(beam.shape + (4,))
    rgba[..., :3] = palette[np.mod(beam, palette.shape[0])]
    rgba[..., 3] = 1.0
    rgba[beam < 0] = OUTAGE_COLOUR
    return rgba


@lru_cache(maxsize=1)
def _palette():
    """The beam colours (18, 3): tab20 without its greys, dark colours first, then their
    light partners, so that the first 9 beams get distinct hues."""
    from matplotlib import colormaps

    tab20 = np.delete(np.asarray(colormaps["tab20"].colors, float), [14, 15], axis=0)
    palette = np.concatenate([tab20[0::2], tab20[1::2]])
    palette.flags.writeable = False  # shared by every call
    return palette


def coastlines():
    """World coastlines, Natural Earth 4.1.0 1:50m land (public domain): copies of
    :func:`leolink.land.coastline_arcs`.

    Returns
    -------
    lon_deg, lat_deg : ndarray of float32, shape (n_point,)
        Polylines separated by NaN [deg], also where an arc crosses +-180 deg (a world
        map draws no line across it).
    """
    lon, lat = break_at_antimeridian(*coastline_arcs())
    return lon.astype(np.float32), lat.astype(np.float32)


def subsatellite_points(sat_pos_m):
    """Sub-satellite latitude and longitude [deg] of positions ``(..., 3)`` [m] (sphere)."""
    lat, lon, _ = ecef_to_geodetic(sat_pos_m)
    return np.degrees(lat), np.degrees(lon)


def break_at_antimeridian(lon_deg, lat_deg, *, group=None):
    """Insert NaN where a polyline jumps across +-180 deg (or to another ``group``).

    Parameters
    ----------
    lon_deg, lat_deg : array_like, shape (n,)
        Polyline in drawing order [deg].
    group : array_like, shape (n,), optional
        Track id of each point; a new id starts a new line.

    Returns
    -------
    lon_deg, lat_deg : ndarray, shape (n + n_breaks,)
    """
    lon, lat = np.asarray(lon_deg, float), np.asarray(lat_deg, float)
    jump = np.abs(np.diff(lon)) > 180.0
    if group is not None:
        g = np.asarray(group)
        jump |= g[1:] != g[:-1]
    at = np.flatnonzero(jump) + 1
    return np.insert(lon, at, np.nan), np.insert(lat, at, np.nan)


def map_extent(lon_deg, lat_deg, margin_deg=_MARGIN_DEG):
    """``(lon_min, lon_max, lat_min, lat_max)`` [deg] around finite points, padded.

    The box is widened to at least 4 deg in each direction and clipped to the globe.
    """
    lon, lat = np.asarray(lon_deg, float), np.asarray(lat_deg, float)
    ok = np.isfinite(lon) & np.isfinite(lat)
    if not ok.any():
        return (-180.0, 180.0, -90.0, 90.0)
    lo = np.array([lon[ok].min(), lat[ok].min()]) - margin_deg
    hi = np.array([lon[ok].max(), lat[ok].max()]) + margin_deg
    mid, half = 0.5 * (lo + hi), np.maximum(0.5 * (hi - lo), 2.0)
    lo, hi = mid - half, mid + half
    return (max(lo[0], -180.0), min(hi[0], 180.0), max(lo[1], -90.0), min(hi[1], 90.0))


def new_figure(extent_deg, width_in=8.0, dpi=100):
    """An Agg figure with one map axes sized for ``extent_deg`` (no pyplot state)."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    lon0, lon1, lat0, lat1 = extent_deg
    aspect = 1.0 / max(np.cos(np.radians(0.5 * (lat0 + lat1))), 0.2)
    ratio = aspect * (lat1 - lat0) / max(lon1 - lon0, 1e-9)
    fig = Figure(figsize=(width_in, float(np.clip(width_in * ratio, 2.5, 9.0)) + 0.6), dpi=dpi)
    FigureCanvasAgg(fig)
    with rc_context(FIXED_TITLE_RC):
        ax = fig.add_axes((0.09, 0.08, 0.88, 0.84))
    draw_base(ax, extent_deg)
    return fig, ax


def draw_base(ax, extent_deg):
    """Coastlines, limits, equirectangular aspect and labels on ``ax``."""
    lon0, lon1, lat0, lat1 = extent_deg
    lon, lat = coastlines()
    # Only the points near the view (NaN elsewhere breaks the lines): a regional map
    # draws a few thousand of the 62,000 points.
    near = (lon > lon0 - 1.0) & (lon < lon1 + 1.0) & (lat > lat0 - 1.0) & (lat < lat1 + 1.0)
    ax.plot(np.where(near, lon, np.nan), np.where(near, lat, np.nan), **_COAST_STYLE)
    ax.set_xlim(lon0, lon1)
    ax.set_ylim(lat0, lat1)
    ax.set_aspect(1.0 / max(np.cos(np.radians(0.5 * (lat0 + lat1))), 0.2), adjustable="box")
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    ax.grid(True, alpha=0.25, linewidth=0.5)


def draw_footprints(ax, footprints, *, fill_alpha=0.18, label_beams=True):
    """Beam cells as outlined, lightly filled polygons in the beam's colour.

    ``footprints``: ``beam_id (k,)`` and ``lat_deg, lon_deg (k, n_points)``; rings with a
    NaN point are drawn through the finite points only, rings with fewer than 3 not at all.
    """
    from matplotlib.collections import PolyCollection

    beam = np.asarray(footprints["beam_id"], int)
    lat, lon = np.asarray(footprints["lat_deg"], float), np.asarray(footprints["lon_deg"], float)
    if beam.size == 0:
        return None
    rows, rings = rings_deg(lon.reshape(beam.size, -1), lat.reshape(beam.size, -1))
    if not rings:
        return None
    colours = beam_colour(beam[rows])
    face = colours.copy()
    face[:, 3] = fill_alpha
    coll = PolyCollection(rings, facecolors=face, edgecolors=colours, linewidths=1.0, zorder=2)
    ax.add_collection(coll)
    if label_beams:
        centres = np.array([ring.mean(axis=0) for ring in rings])  # (lon, lat) of each cell
        draw_beam_labels(ax, beam[rows], centres)
    return coll


def draw_beam_labels(ax, beam_id, xy, *, fontsize=6.0):
    """Each beam id written at its point ``xy`` (n, 2), centred, in dark grey.

    One marker line per beam id (the digits' outline as a marker: built once, stamped at
    each point) rather than a text artist per cell: a constellation's map has ~240 cells,
    whose text artists cost half of its drawing. The outline is plain text (a ``"$4$"``
    marker would start matplotlib's mathtext parser, ~0.1 s, for the same glyphs).
    Returns ``{beam_id: Line2D}``, each with the gid ``"beam <id>"``."""
    from matplotlib.path import Path
    from matplotlib.textpath import TextPath

    beam_id, xy = np.asarray(beam_id, int), np.asarray(xy, float).reshape(-1, 2)
    lines = {}
    for b in np.unique(beam_id).tolist():
        text = TextPath((0.0, 0.0), str(b), size=fontsize)  # [pt]
        box = text.get_extents()
        glyphs = Path(text.vertices - [box.x0 + 0.5 * box.width, box.y0 + 0.5 * box.height],
                      text.codes)  # fmt: skip
        # A path marker is scaled by markersize / (2 max |vertex|): this size keeps 1 pt per
        # unit, the digits at ``fontsize``.
        size = 2.0 * float(np.abs(glyphs.vertices).max())
        at = xy[beam_id == b]
        (lines[b],) = ax.plot(at[:, 0], at[:, 1], linestyle="none", marker=glyphs,
                              markersize=size, markerfacecolor="0.15", markeredgewidth=0.0,
                              zorder=3, gid=f"beam {b}")  # fmt: skip
    return lines


def rings_deg(lon, lat):
    """The rows with at least 3 finite points and their rings ``(n_i, 2)`` (lon, lat) of
    the finite points, longitudes unwrapped; whole rings in one vectorized pass (a
    constellation's animation draws ~250 cells a frame)."""
    ok = np.isfinite(lat) & np.isfinite(lon)
    rows = np.flatnonzero(ok.sum(axis=1) >= 3)
    whole = ok[rows].all(axis=1)
    rings = list(np.stack([_unwrap_deg(lon[rows[whole]]), lat[rows[whole]]], axis=-1))
    if whole.all():
        return rows, rings
    out, it = [], iter(rings)
    for r, is_whole in zip(rows.tolist(), whole.tolist(), strict=True):
        m = ok[r]
        out.append(next(it) if is_whole else np.column_stack([_unwrap_deg(lon[r, m]), lat[r, m]]))
    return rows, out


def draw_ut_points(ax, lon_deg, lat_deg, beam_id, *, size=30.0, zorder=5, linewidths=0.6):
    """UTs as dots filled with their serving beam's colour (outage: grey), black edge."""
    return ax.scatter(
        np.asarray(lon_deg, float),
        np.asarray(lat_deg, float),
        s=size,
        c=beam_colour(beam_id),
        edgecolors="black",
        linewidths=linewidths,
        zorder=zorder,
    )


def draw_ut_labels(ax, ut_labels, *, fontsize=7, zorder=6):
    """``UT n`` beside each UT of ``ut_labels`` (``ut_id, lon_deg, lat_deg (j,)``) with a
    finite position; returns the text artists."""
    ut = np.asarray(ut_labels["ut_id"], int)
    lon, lat = (np.asarray(ut_labels[k], float) for k in ("lon_deg", "lat_deg"))
    ok = np.isfinite(lon) & np.isfinite(lat)
    return [
        ax.annotate(f"UT {u}", (x, y), xytext=(4, 4), textcoords="offset points",
                    fontsize=fontsize, zorder=zorder, clip_on=True,
                    bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.7})
        for u, x, y in zip(ut[ok].tolist(), lon[ok].tolist(), lat[ok].tolist(), strict=True)
    ]  # fmt: skip


def _unwrap_deg(lon_deg):
    """Longitudes made continuous (no +-360 jump) along the last axis, so that a ring
    across 180 deg stays whole."""
    return np.degrees(np.unwrap(np.radians(lon_deg), axis=-1))


def plot_map(
    sat_tracks=None,
    footprints=None,
    ut_tracks=None,
    ut_points=None,
    *,
    extent_deg=None,
    title=None,
    width_in=8.0,
    dpi=100,
):
    """Map of a run: coastlines, satellite ground tracks, beam cells and UT tracks.

    Parameters
    ----------
    sat_tracks : dict, optional
        ``sat_id (n,)``, ``time_s (n,)``, ``lat_deg (n,)``, ``lon_deg (n,)``: sub-satellite
        points, rows of one satellite in time order.
    footprints : dict, optional
        ``sat_id (k,)``, ``beam_id (k,)``, ``lat_deg (k, n_points)``, ``lon_deg (k,
        n_points)``: beam cells (e.g. of the serving satellites at one instant), from
        :func:`leolink.antenna.footprint.beam_footprints_ground`.
    ut_tracks : dict, optional
        ``ut_id (m,)``, ``time_s (m,)``, ``lat_deg (m,)``, ``lon_deg (m,)``, ``beam_id
        (m,)``: UT positions; each track segment is coloured by the serving beam.
    ut_points : dict, optional
        ``lat_deg, lon_deg, beam_id (j,)``: UTs drawn as dots coloured by serving beam
        (e.g. at the instant of the ``footprints``).
    extent_deg : (lon_min, lon_max, lat_min, lat_max), optional
        Default: around the UTs and beam cells (or the ground tracks if neither is given).
    title : str, optional
    width_in, dpi : float
        Figure width [in] and resolution [dot/in].

    Returns
    -------
    matplotlib.figure.Figure
    """
    if extent_deg is None:
        extent_deg = _default_extent(sat_tracks, footprints, ut_tracks)
    fig, ax = new_figure(extent_deg, width_in, dpi)
    if sat_tracks is not None and len(sat_tracks["sat_id"]):
        lon, lat = break_at_antimeridian(
            sat_tracks["lon_deg"], sat_tracks["lat_deg"], group=sat_tracks["sat_id"]
        )
        ax.plot(
            lon,
            lat,
            color="tab:red",
            linewidth=1.0,
            alpha=0.7,
            zorder=2,
            label="satellite ground tracks",
        )
    if footprints is not None and len(footprints["beam_id"]):
        draw_footprints(ax, footprints)
    if ut_tracks is not None and len(ut_tracks["ut_id"]):
        draw_ut_tracks(ax, ut_tracks)
    if ut_points is not None and len(ut_points["beam_id"]):
        draw_ut_points(ax, ut_points["lon_deg"], ut_points["lat_deg"], ut_points["beam_id"])
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=7)
    ax.set_title(title or "Ground tracks, beam cells and UTs (coloured by serving beam)")
    return fig


def draw_ut_tracks(ax, ut_tracks, linewidth=2.0):
    """UT tracks as lines, each segment coloured by the serving beam at its start; the
    collection, or None where no UT has two consecutive finite points.

    Consecutive segments of one UT with the same beam are one polyline of the collection
    (a map of 200 UTs x 60 epochs: ~1,700 paths instead of ~12,000 segments, each a
    matplotlib Path to build and draw)."""
    from matplotlib.collections import LineCollection

    ut = np.asarray(ut_tracks["ut_id"])
    order = np.lexsort((np.asarray(ut_tracks["time_s"], float), ut))
    lon, lat = (np.asarray(ut_tracks[k], float)[order] for k in ("lon_deg", "lat_deg"))
    beam, ut = np.asarray(ut_tracks["beam_id"], int)[order], ut[order]
    ok = (ut[1:] == ut[:-1]) & (np.abs(np.diff(lon)) < 180.0)  # same UT, no antimeridian jump
    ok &= np.isfinite(lon[1:] + lon[:-1] + lat[1:] + lat[:-1])
    start = np.flatnonzero(ok)
    if not start.size:  # one point per UT (a one-epoch run): no segment, no legend entry
        return None
    # A new polyline where the previous segment is not the one just before, or its beam differs.
    first = np.r_[True, (np.diff(start) != 1) | (beam[start[1:]] != beam[start[:-1]])]
    begin = start[first]  # first point of each polyline
    end = np.r_[start[np.flatnonzero(first)[1:] - 1], start[-1]] + 2  # past its last point
    xy = np.column_stack([lon, lat])
    coll = LineCollection(
        [xy[a:b] for a, b in zip(begin.tolist(), end.tolist(), strict=True)],
        colors=beam_colour(beam[begin]),
        linewidths=linewidth,
        zorder=4,
        label="UT tracks (colour: serving beam)",
    )
    ax.add_collection(coll)
    return coll


def _default_extent(sat_tracks, footprints, ut_tracks):
    lons, lats = [], []
    for part in (footprints, ut_tracks):
        if part is not None and len(part["lat_deg"]):
            lons.append(np.ravel(part["lon_deg"]))
            lats.append(np.ravel(part["lat_deg"]))
    if not lons and sat_tracks is not None:
        lons.append(np.ravel(sat_tracks["lon_deg"]))
        lats.append(np.ravel(sat_tracks["lat_deg"]))
    if not lons:
        return (-180.0, 180.0, -90.0, 90.0)
    return map_extent(np.concatenate(lons), np.concatenate(lats))
