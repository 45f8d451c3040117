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
    map_extent,
    new_figure,
    rings_deg,
)

__all__ = [
    "Frame",
    "animation_frames",
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


def animation_frames(n_kept):
    """Frames of a run's ``footprint.gif`` from its ``n_kept`` kept epochs: every other one,
    first and last included (:func:`select_frames`). Each frame costs ~15 ms of drawing
    and encoding; half of them still show the cells gliding (a few km a frame where a
    cell is tens of km across), and the map keeps every kept epoch."""
    return max((int(n_kept) + 1) // 2, 1)


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


TITLE = "beam cells and UTs by serving beam, "
_DOT_PT, _DOT_EDGE_PT = 6.0, 0.6  # UT dot diameter and edge [pt], as draw_ut_points(size=36)
_LABEL_PT, _LABEL_OFFSET_PT = 7.0, 4.0  # draw_ut_labels' font size and offset [pt]


class _Painter:
    """Each frame's cells, UT dots, UT labels and title drawn with Pillow over the static
    map that matplotlib drew once: the same colours, sizes and places as :func:`draw_frame`
    (map points through the axes' own ``transData``), clipped to the axes, at a fixed cost
    per frame of a few milliseconds (matplotlib's artists cost ~40 ms a frame)."""

    def __init__(self, fig, ax, dpi):
        from matplotlib.font_manager import FontProperties, findfont
        from PIL import ImageFont

        self.height = int(round(fig.bbox.height))
        box = ax.get_window_extent()
        self.clip = (int(np.ceil(box.x0)), int(np.ceil(self.height - box.y1)),
                     int(np.floor(box.x1)), int(np.floor(self.height - box.y0)))  # fmt: skip
        title = ax.title.get_window_extent()
        self.title_xy = (0.5 * (title.x0 + title.x1), self.height - 0.5 * (title.y0 + title.y1))
        # the map's axes are linear: one affine matrix takes (lon, lat) to display pixels
        self.affine = np.asarray(ax.transData.get_affine().get_matrix())
        px = dpi / 72.0
        font = findfont(FontProperties(family=["DejaVu Sans", "sans-serif"]))
        self.title_font = ImageFont.truetype(font, round(10 * px))
        self.label_font = ImageFont.truetype(font, round(_LABEL_PT * px))
        self.dot_r, self.edge = 0.5 * _DOT_PT * px, max(int(round(_DOT_EDGE_PT * px)), 1)
        self.offset = _LABEL_OFFSET_PT * px

    def _pixels(self, lon_deg, lat_deg):
        """Image (column, row) of map points, row 0 at the top."""
        (a, b, c), (d, e, f) = self.affine[:2]
        lon, lat = np.asarray(lon_deg, float), np.asarray(lat_deg, float)
        return a * lon + b * lat + c, self.height - (d * lon + e * lat + f)

    def _layer(self):
        from PIL import Image

        x0, y0, x1, y1 = self.clip
        return Image.new("RGBA", (x1 - x0, y1 - y0), (0, 0, 0, 0))

    def _cells(self, draw, footprints):
        beam = np.asarray(footprints["beam_id"], int)
        if beam.size == 0:
            return
        lon = np.asarray(footprints["lon_deg"], float).reshape(beam.size, -1)
        lat = np.asarray(footprints["lat_deg"], float).reshape(beam.size, -1)
        rows, rings = rings_deg(lon, lat)
        if not rings:
            return
        colours = np.round(beam_colour(beam[rows]) * 255).astype(int).tolist()
        points = np.concatenate(rings)  # every ring's pixels at once
        x, y = self._pixels(points[:, 0], points[:, 1])
        xy = np.column_stack([x - self.clip[0], y - self.clip[1]]).ravel().tolist()  # x0, y0, ..
        ends = (2 * np.cumsum([len(r) for r in rings])).tolist()
        alpha = round(255 * FILL_ALPHA)
        for lo, hi, c in zip([0, *ends[:-1]], ends, colours, strict=True):
            draw.polygon(xy[lo:hi], fill=(*c[:3], alpha), outline=tuple(c), width=1)

    def _dots(self, draw, frame):
        ok = np.isfinite(frame.ut_lat_deg) & np.isfinite(frame.ut_lon_deg)
        x, y = self._pixels(frame.ut_lon_deg[ok], frame.ut_lat_deg[ok])
        colours = np.round(beam_colour(frame.ut_beam[ok]) * 255).astype(int).tolist()
        r, (cx, cy) = self.dot_r, self.clip[:2]
        for xi, yi, c in zip((x - cx).tolist(), (y - cy).tolist(), colours, strict=True):
            draw.ellipse((xi - r, yi - r, xi + r, yi + r), fill=tuple(c), outline=(0, 0, 0, 255),
                         width=self.edge)  # fmt: skip

    def _labels(self, draw, labels):
        ut = np.asarray(labels["ut_id"], int)
        lon, lat = (np.asarray(labels[k], float) for k in ("lon_deg", "lat_deg"))
        ok = np.isfinite(lon) & np.isfinite(lat)
        x, y = self._pixels(lon[ok], lat[ok])
        pad = 0.1 * self.label_font.size
        for u, xi, yi in zip(ut[ok].tolist(), x.tolist(), y.tolist(), strict=True):
            at = (xi - self.clip[0] + self.offset, yi - self.clip[1] - self.offset)
            l, t, r, b = draw.textbbox(at, f"UT {u}", font=self.label_font, anchor="ld")
            draw.rectangle((l - pad, t - pad, r + pad, b + pad), fill=(255, 255, 255, 178))
            draw.text(at, f"UT {u}", font=self.label_font, fill=(0, 0, 0, 255), anchor="ld")

    def frame(self, background, frame):
        """``background`` (RGBA Image) with ``frame`` drawn on it, as an RGB Image."""
        from PIL import ImageDraw

        image = background.copy()
        # The opaque dots go on the cells' layer (an opaque pixel covers the same whether
        # drawn there or blended over it); the translucent label boxes need their own.
        layer = self._layer()
        draw = ImageDraw.Draw(layer)
        self._cells(draw, frame.footprints)
        self._dots(draw, frame)
        image.alpha_composite(layer, dest=self.clip[:2])
        if frame.ut_labels is not None:
            layer = self._layer()
            self._labels(ImageDraw.Draw(layer), frame.ut_labels)
            image.alpha_composite(layer, dest=self.clip[:2])
        ImageDraw.Draw(image).text(
            self.title_xy,
            f"{TITLE}t = {frame.time_s:.1f} s",
            font=self.title_font,
            fill=(0, 0, 0, 255),
            anchor="mm",
        )
        return image.convert("RGB")


def _render(out, frames, extent, fps, dpi, width_in):
    """Draw the static map once with matplotlib, then each frame over a copy of it with
    Pillow (:class:`_Painter`), and write the GIF with Pillow to the file ``out``."""
    from PIL import Image

    fig, ax = new_figure(extent, width_in=width_in, dpi=dpi)
    ax.set_title(f"{TITLE}t = 0000.0 s", fontsize=10)
    ax.apply_aspect()  # places the axes (equal aspect) as drawing would, without a draw
    painter = _Painter(fig, ax, dpi)
    ax.title.set_visible(False)
    canvas = fig.canvas
    canvas.draw()  # once: the static map, without the title the frames write
    rgba = np.asarray(canvas.buffer_rgba())
    background = Image.fromarray(rgba.copy(), "RGBA")
    palette = _palette(rgba[..., :3], FILL_ALPHA)
    images = [
        painter.frame(background, f).quantize(palette=palette, dither=Image.Dither.NONE)
        for f in frames
    ]
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
