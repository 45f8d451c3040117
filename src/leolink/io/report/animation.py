"""Animation of the beam footprints moving over the ground, UTs coloured by serving beam.

Frame ``k`` shows, at the kept epoch ``t_k``: the coastlines, the half-power cells of
every beam of each satellite that serves one of the sampled UTs at ``t_k`` (computed from
the satellite state at ``t_k`` with :func:`leolink.antenna.footprint.beam_footprints_ground`)
and the sampled UTs as dots filled with the colour of their serving beam at ``t_k``
(:func:`leolink.io.report.maps.beam_colour`; grey in outage). The inputs are the subsampled
arrays of :class:`leolink.io.report.stats.ReportStats`.

Size: frames are first subsampled to ``max_frames``; if the GIF still exceeds
``max_bytes`` the frame count is halved and the file rewritten (at most 4 times), so a
10-minute run stays under the budget (~10 MB by default).
"""

from __future__ import annotations

import io
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from leolink.antenna.footprint import beam_footprints_ground
from leolink.io.atomic import atomic_file
from leolink.io.report.maps import (
    N_BEAM_COLOURS,
    beam_colour,
    draw_footprints,
    draw_ut_labels,
    draw_ut_points,
    map_extent,
    new_figure,
)

__all__ = [
    "Frame",
    "build_frames",
    "footprint_cells",
    "frames_from_stats",
    "select_frames",
    "write_footprint_gif",
]

MAX_BYTES = 10_000_000
FILL_ALPHA = 0.18  # cell fill opacity
_MAX_SHRINKS = 4


@dataclass(frozen=True)
class Frame:
    """One animation frame: time, beam cells and UT dots.

    Attributes
    ----------
    time_s : float
        Epoch [s].
    footprints : dict
        ``sat_id, beam_id (k,)``, ``lat_deg, lon_deg (k, n_points)`` [deg].
    ut_lat_deg, ut_lon_deg : ndarray, shape (n_ut,)
        Sampled UT positions [deg] (NaN: no trace row at that epoch).
    ut_beam : ndarray of int, shape (n_ut,)
        Serving beam (-1 in outage).
    ut_labels : dict, optional
        ``ut_id, lon_deg, lat_deg (j,)``: UTs labelled ``UT n`` in the frame.
    """

    time_s: float
    footprints: dict
    ut_lat_deg: np.ndarray
    ut_lon_deg: np.ndarray
    ut_beam: np.ndarray
    ut_labels: dict | None = None


def select_frames(n_available, max_frames):
    """Indices of at most ``max_frames`` frames spread evenly over ``n_available``
    (first and last included)."""
    if n_available <= max_frames:
        return np.arange(n_available)
    return np.unique(np.round(np.linspace(0, n_available - 1, max(int(max_frames), 1))).astype(int))


def footprint_cells(sat_ids, sat_pos_m, sat_vel_m_s, serving, beam_u_xy, n_sub_xy):
    """Half-power cells of every beam of the satellites whose id is in ``serving``.

    Parameters
    ----------
    sat_ids : ndarray, shape (n_sat,)
    sat_pos_m, sat_vel_m_s : ndarray, shape (n_sat, 3)
        States at one instant [m, m/s]; rows with NaN positions are skipped.
    serving : array_like
        Satellite ids to draw.
    beam_u_xy : ndarray, shape (n_beam, 2)
        Codebook [-] (row = beam id).
    n_sub_xy : (int, int)
        Subarray elements per beam.

    Returns
    -------
    dict
        ``sat_id, beam_id (k,)``, ``lat_deg, lon_deg (k, n_points)`` [deg],
        ``k = n_serving n_beam``.
    """
    rows = np.flatnonzero(np.isin(sat_ids, serving) & np.isfinite(sat_pos_m[:, 0]))
    n_beam = beam_u_xy.shape[0]
    if rows.size == 0:
        empty = np.zeros((0, 1))
        return {
            "sat_id": np.zeros(0, int),
            "beam_id": np.zeros(0, int),
            "lat_deg": empty,
            "lon_deg": empty,
        }
    lat, lon = beam_footprints_ground(sat_pos_m[rows], sat_vel_m_s[rows], beam_u_xy, *n_sub_xy)
    return {
        "sat_id": np.repeat(np.asarray(sat_ids)[rows], n_beam),
        "beam_id": np.tile(np.arange(n_beam), rows.size),
        "lat_deg": lat.reshape(rows.size * n_beam, -1),
        "lon_deg": lon.reshape(rows.size * n_beam, -1),
    }


def build_frames(
    times_s,
    ut_lat_deg,
    ut_lon_deg,
    ut_sat,
    ut_beam,
    sat_ids,
    sat_pos_m,
    sat_vel_m_s,
    beam_u_xy,
    n_sub_xy,
    max_frames=120,
):
    """Frames from the subsampled run data.

    Parameters
    ----------
    times_s : array_like, shape (n_k,)
        Kept epochs [s].
    ut_lat_deg, ut_lon_deg : array_like, shape (n_k, n_ut)
        Sampled UT positions [deg].
    ut_sat, ut_beam : array_like of int, shape (n_k, n_ut)
        Serving satellite and beam (-1 in outage).
    sat_ids : array_like, shape (n_sat,)
    sat_pos_m, sat_vel_m_s : array_like, shape (n_k, n_sat, 3)
        Satellite states at the kept epochs [m, m/s], the frame of the UT positions.
    beam_u_xy : array_like, shape (n_beam, 2)
        Codebook (row = beam id) [-].
    n_sub_xy : (int, int)
        Subarray elements per beam.
    max_frames : int
        Frames kept (:func:`select_frames`).

    Returns
    -------
    list of Frame
    """
    beam_u_xy = np.asarray(beam_u_xy, float)
    frames = []
    for k in select_frames(len(times_s), max_frames):  # one frame at a time: bounded memory
        serving = np.unique(ut_sat[k][ut_sat[k] >= 0])
        cells = footprint_cells(
            np.asarray(sat_ids),
            np.asarray(sat_pos_m[k], float),
            np.asarray(sat_vel_m_s[k], float),
            serving,
            beam_u_xy,
            n_sub_xy,
        )
        frames.append(
            Frame(
                float(times_s[k]),
                cells,
                np.asarray(ut_lat_deg[k], float),
                np.asarray(ut_lon_deg[k], float),
                np.asarray(ut_beam[k], int),
            )
        )
    return frames


def frames_from_stats(stats, max_frames=120):
    """:func:`build_frames` on the arrays of a :class:`~leolink.io.report.stats.ReportStats`,
    the time-plot UTs (``series_ut``) labelled ``UT n``."""
    frames = build_frames(
        stats.keep_times_s,
        stats.ut_lat_deg,
        stats.ut_lon_deg,
        stats.ut_sat,
        stats.ut_beam,
        stats.sat_ids,
        stats.sat_pos_m,
        stats.sat_vel_m_s,
        stats.beam_u_xy,
        stats.n_sub_xy,
        max_frames,
    )
    j = np.searchsorted(stats.sample_ut, stats.series_ut)
    k = np.searchsorted(stats.keep_times_s, [f.time_s for f in frames])
    return [
        replace(f, ut_labels={"ut_id": stats.series_ut, "lat_deg": stats.ut_lat_deg[i, j],
                              "lon_deg": stats.ut_lon_deg[i, j]})
        for f, i in zip(frames, k.tolist(), strict=True)
    ]  # fmt: skip


def frames_extent(frames):
    """A map extent holding every UT dot and beam cell of all frames."""
    lon = [np.ravel(f.ut_lon_deg) for f in frames] + [
        np.ravel(f.footprints["lon_deg"]) for f in frames
    ]
    lat = [np.ravel(f.ut_lat_deg) for f in frames] + [
        np.ravel(f.footprints["lat_deg"]) for f in frames
    ]
    return map_extent(np.concatenate(lon), np.concatenate(lat), margin_deg=1.0)


def draw_frame(ax, frame, title_prefix=""):
    """Draw ``frame``'s cells and UTs on a map axes; returns the artists (to remove later)."""
    artists = []
    coll = draw_footprints(ax, frame.footprints, fill_alpha=FILL_ALPHA, label_beams=False)
    if coll is not None:
        artists.append(coll)
    ok = np.isfinite(frame.ut_lat_deg) & np.isfinite(frame.ut_lon_deg)
    artists.append(
        draw_ut_points(ax, frame.ut_lon_deg[ok], frame.ut_lat_deg[ok], frame.ut_beam[ok], size=36.0)
    )
    if frame.ut_labels is not None:
        artists += draw_ut_labels(ax, frame.ut_labels)
    artists.append(ax.set_title(f"{title_prefix}t = {frame.time_s:.1f} s", fontsize=10))
    return artists


def _palette(background_rgb, fill_alpha):
    """One GIF palette for all frames: the exact beam and outage colours, the beam colours
    blended at ``fill_alpha`` over white (cell fills), black, white and 190 colours of the
    static background, so a UT dot keeps its beam's exact RGB."""
    from PIL import Image

    solid = beam_colour(np.arange(-1, N_BEAM_COLOURS))[:, :3]
    fills = fill_alpha * solid[1:] + (1.0 - fill_alpha)
    exact = np.round(np.vstack([solid, fills, [[0, 0, 0], [1, 1, 1]]]) * 255).astype(np.uint8)
    base = Image.fromarray(np.ascontiguousarray(background_rgb)).quantize(190)
    base_rgb = np.asarray(base.getpalette()[: 3 * 190], np.uint8).reshape(-1, 3)
    colours = np.vstack([exact, base_rgb])[:256]
    flat = np.zeros(768, np.uint8)
    flat[: colours.size] = colours.ravel()
    pal = Image.new("P", (1, 1))
    pal.putpalette(flat.tolist())
    return pal


def _render(out, frames, extent, fps, dpi, width_in):
    """Draw the static map once, then only each frame's cells and UTs over a copy of it
    (blitting: ~10x faster than redrawing the coastlines per frame), and write the GIF
    with Pillow (the writer behind matplotlib's ``PillowWriter``) to the file ``out``."""
    from PIL import Image

    fig, ax = new_figure(extent, width_in=width_in, dpi=dpi)
    ax.set_title("beam cells and UTs by serving beam, t = 0000.0 s", fontsize=10)
    title = ax.title
    title.set_animated(True)
    canvas = fig.canvas
    title.set_visible(False)
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    palette = _palette(np.asarray(canvas.buffer_rgba())[..., :3], FILL_ALPHA)
    title.set_visible(True)
    images = []
    for frame in frames:  # one frame at a time
        canvas.restore_region(background)
        artists = draw_frame(ax, frame, "beam cells and UTs by serving beam, ")
        for artist in artists:
            artist.set_animated(True)
            ax.draw_artist(artist) if artist is not title else fig.draw_artist(artist)
        rgba = np.asarray(canvas.buffer_rgba())
        frame_rgb = Image.fromarray(rgba[..., :3].copy())
        images.append(frame_rgb.quantize(palette=palette, dither=Image.Dither.NONE))
        for artist in artists[:-1]:  # the title text is reused by set_title
            artist.remove()
    images[0].save(
        out,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        loop=0,
        duration=int(round(1000.0 / fps)),
        optimize=False,
        disposal=1,
    )
    return fig, ax


def write_footprint_gif(
    path, frames, *, fps=5, dpi=80, width_in=7.0, max_bytes=MAX_BYTES, extent_deg=None
):
    """Write the animation as a GIF (matplotlib's PillowWriter), within a size budget.

    Parameters
    ----------
    path : path-like
        Output ``.gif``, written atomically (:func:`leolink.io.atomic.atomic_file`).
    frames : list of Frame
    fps : float
        Frames per second of playback.
    dpi, width_in : float
        Resolution [dot/in] and width [in] (the image is ``width_in * dpi`` px wide).
    max_bytes : int
        Size budget; over it, every other frame is dropped and the GIF rewritten.
    extent_deg : tuple, optional
        Map extent; default :func:`frames_extent`.

    Returns
    -------
    dict
        ``path``, ``n_frames``, ``times_s`` (of the frames written), ``extent_deg``,
        ``size_px`` (width, height), ``n_bytes``, ``to_pixel(lon_deg, lat_deg) -> (col,
        row)`` (image pixel of a map point, row 0 at the top).
    """
    path = Path(path)
    extent = tuple(extent_deg) if extent_deg is not None else frames_extent(frames)
    for _ in range(_MAX_SHRINKS + 1):  # drawn in memory (at most ~max_bytes), then written
        gif = io.BytesIO()
        fig, _ax = _render(gif, frames, extent, fps, dpi, width_in)
        if gif.tell() <= max_bytes or len(frames) <= 2:
            break
        frames = frames[::2]
    with atomic_file(path) as fh:  # the one atomic writer (leolink.io.atomic)
        fh.write(gif.getbuffer())
    size_px = tuple(int(round(v)) for v in fig.get_size_inches() * dpi)

    def to_pixel(lon_deg, lat_deg):
        """Image (column, row) of map points, row 0 at the top, as in the GIF."""
        xy = _ax.transData.transform(np.column_stack([lon_deg, lat_deg]))
        return xy[:, 0], size_px[1] - xy[:, 1]

    return {
        "path": path,
        "n_frames": len(frames),
        "times_s": [f.time_s for f in frames],
        "extent_deg": extent,
        "size_px": size_px,
        "n_bytes": path.stat().st_size,
        "to_pixel": to_pixel,
    }
