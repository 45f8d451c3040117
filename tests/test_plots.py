"""Tests of leolink.plots: files exist, are whole PNGs at 150 dpi, are written atomically."""

import json
import struct
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from leolink.errors import LeolinkError
from leolink.io import coverage_plots, plots

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
MIN_PNG_BYTES = 10_000  # a blank 150-dpi figure with only axes is ~15 kB; a stub is < 1 kB
ROI_AXES_M = (500e3, 250e3)
CELL_X_M, CELL_Y_M = 400e3, 300e3  # beam cell size of the synthetic grid (3 x 2 cells)


def coverage_df(rng):
    """21 x 11 grid over [-600, 600] x [-300, 300] km; beam = ix + 3 * iy of its 400x300 km cell."""
    x_m, y_m = np.meshgrid(np.linspace(-600e3, 600e3, 21), np.linspace(-300e3, 300e3, 11))
    x_m, y_m = x_m.ravel(), y_m.ravel()
    ix = np.clip(((x_m + 600e3) // CELL_X_M).astype(int), 0, 2)
    iy = np.clip(((y_m + 300e3) // CELL_Y_M).astype(int), 0, 1)
    in_roi = (x_m / ROI_AXES_M[0]) ** 2 + (y_m / ROI_AXES_M[1]) ** 2 <= 1
    snr_db = 20 - 10 * ((x_m / 600e3) ** 2 + (y_m / 300e3) ** 2)
    df = pd.DataFrame(
        {
            "x_m": x_m,
            "y_m": y_m,
            "lat_deg": 40 + y_m / 111e3,
            "lon_deg": -3 + x_m / 85e3,
            "best_beam": ix + 3 * iy,
            "snr_db": snr_db,
            "sinr_db": snr_db - 5,
            "se_bps_hz": np.log2(1 + 10 ** (snr_db / 10)),
            "doppler_hz": -4e5 * x_m / 600e3,
            "angular_speed_deg_s": 0.5 + 0.1 * np.hypot(x_m, y_m) / 600e3,
            "in_roi": in_roi,
        }
    )
    return df.iloc[rng.permutation(len(df))].reset_index(drop=True)  # row order must not matter


def run_data(n_time=61):
    """UT 0: beam 3 -> 4 at t = 30 s, satellite 1 -> 2 at t = 45 s; UT 1 always in outage."""
    t_s = np.arange(n_time, dtype=float)
    beam0 = np.where(t_s < 30, 3, 4)
    sat0 = np.where(t_s < 45, 1, 2)
    snr0 = 15 - 0.01 * (t_s % 30) ** 2
    trace = pd.DataFrame(
        {
            "time_s": np.concatenate([t_s, t_s]),
            "ut_id": np.repeat([0, 1], n_time),
            "sat_id": np.concatenate([sat0, np.full(n_time, -1)]),
            "beam_id": np.concatenate([beam0, np.full(n_time, -1)]),
            "snr_db": np.concatenate([snr0, np.full(n_time, np.nan)]),
            "sinr_db": np.concatenate([snr0 - 3, np.full(n_time, np.nan)]),
            "throughput_bps": np.concatenate([np.full(n_time, 1e8), np.zeros(n_time)]),
            "doppler_hz": np.concatenate([2e5 - 7e3 * t_s, np.full(n_time, np.nan)]),
            "elevation_deg": np.concatenate([40 + 0.5 * t_s, np.full(n_time, np.nan)]),
        }
    )
    events = pd.DataFrame(
        {
            "time_s": [30.0, 45.0],
            "ut_id": [0, 0],
            "kind": ["beam_handover", "sat_handover"],
            "from_sat": [1, 1],
            "from_beam": [3, 4],
            "to_sat": [1, 2],
            "to_beam": [4, 4],
            "snr_before_db": [6.0, 8.0],
            "snr_after_db": [15.0, 12.0],
        }
    )
    summary = {
        "per_ut": [
            {
                "ut_id": 0,
                "dwell": {"complete_s": [15.0], "censored": []},
                "handovers": {"beam_handover": 1, "sat_handover": 1},
            },  # fmt: skip
            {"ut_id": 1, "dwell": {"complete_s": [], "censored": []}, "handovers": {}},
        ],
        "overall": {
            "handovers": {"beam_handover": 1, "sat_handover": 1},
            "dwell": {"complete_s": [15.0]},
        },
    }
    return trace, events, summary


def png_size_px(path):
    """(width, height) from the IHDR chunk, read independently of matplotlib."""
    head = path.read_bytes()[:24]
    return struct.unpack(">II", head[16:24])


def assert_pngs(paths, out_dir, names):
    assert sorted(p.name for p in paths) == sorted(names)
    for p in paths:
        data = p.read_bytes()
        assert data.startswith(PNG_MAGIC), p
        assert data.endswith(b"IEND\xaeB`\x82"), p  # complete file, not truncated
        assert len(data) > MIN_PNG_BYTES, (p, len(data))
    assert not list(out_dir.glob("*.partial"))


COVERAGE_FILES = [
    "coverage_beams.png",
    "coverage_snr.png",
    "coverage_sinr.png",
    "coverage_se.png",
    "coverage_doppler.png",
    "coverage_angular_speed.png",
    "coverage_cuts.png",
]
RUN_FILES = ["snr_time.png", "doppler_time.png", "dwell_hist.png", "handovers.png"]


def test_grid_reshape_recovers_the_field_from_shuffled_rows():
    df = coverage_df(np.random.default_rng(1))
    x_m, y_m, snr = coverage_plots._grid(df, "snr_db")
    assert snr.shape == (11, 21)
    xx, yy = np.meshgrid(x_m, y_m)  # the closed form, evaluated on the sorted axes
    np.testing.assert_allclose(snr, 20 - 10 * ((xx / 600e3) ** 2 + (yy / 300e3) ** 2))


def test_beam_ids_are_written_at_cell_centroids():
    df = coverage_df(np.random.default_rng(2))
    fig = coverage_plots._beam_map(df, ROI_AXES_M, "t")
    texts = {t.get_text(): t.get_position() for t in fig.axes[0].texts}
    assert sorted(texts) == [str(b) for b in range(6)]
    # Centroid of the grid nodes inside each known cell, from the cell bounds (not from best_beam).
    x_m = np.linspace(-600e3, 600e3, 21)
    y_m = np.linspace(-300e3, 300e3, 11)
    for beam in range(6):
        ix, iy = beam % 3, beam // 3
        xs = x_m[
            (x_m >= -600e3 + ix * CELL_X_M) & ((x_m < -600e3 + (ix + 1) * CELL_X_M) | (ix == 2))
        ]
        ys = y_m[
            (y_m >= -300e3 + iy * CELL_Y_M) & ((y_m < -300e3 + (iy + 1) * CELL_Y_M) | (iy == 1))
        ]
        np.testing.assert_allclose(texts[str(beam)], (xs.mean() / 1e3, ys.mean() / 1e3))


def test_plot_coverage_writes_all_maps_at_150_dpi_despite_nan_and_no_beam(tmp_path):
    df = coverage_df(np.random.default_rng(3))
    df.loc[df.index[:50], ["snr_db", "sinr_db", "se_bps_hz", "doppler_hz"]] = np.nan
    df.loc[df.index[:50], "best_beam"] = -1  # no serving beam: drawn grey
    paths = coverage_plots.plot_coverage(df, tmp_path, ROI_AXES_M, " (t = 0 s)")
    assert_pngs(paths, tmp_path, COVERAGE_FILES)
    # maps are 8 in wide; at 150 dpi that is 1200 px (constrained layout keeps the size)
    assert png_size_px(tmp_path / "coverage_snr.png")[0] == 8 * 150


def test_plot_codebook(tmp_path):
    beams = [
        {"beam_id": i, "u_x": 0.02 * (i % 3 - 1), "u_y": 0.03 * (i // 3 - 0.5),
         "x_m": 300e3 * (i % 3 - 1), "y_m": 120e3 * (i // 3 - 0.5), "lat_deg": 0, "lon_deg": 0}
        for i in range(6)
    ]  # fmt: skip
    info = {"oversampling": 2.49, "roi_semi_axes_m": [534.1e3, 170.5e3], "beams": beams}
    path = tmp_path / "codebook.png"
    assert coverage_plots.plot_codebook(None, info, path) == [path]
    assert_pngs([path], tmp_path, ["codebook.png"])


def test_plot_run_with_handovers_outage_and_missing_uts(tmp_path):
    trace, events, summary = run_data()
    paths = plots.plot_run(trace, events, summary, tmp_path, ut_ids=(0, 1, 7))
    assert_pngs(paths, tmp_path, RUN_FILES)


def test_plot_run_with_empty_events_and_no_dwell(tmp_path):
    trace, events, summary = run_data()
    summary["overall"]["dwell"]["complete_s"] = []
    paths = plots.plot_run(trace, events.iloc[:0], summary, tmp_path, ut_ids=(1, 99))
    assert_pngs(paths, tmp_path, RUN_FILES)
    texts = [t.get_text() for t in plots._dwell_hist(summary).axes[0].texts]
    assert texts == ["no complete dwell"]
    # events=None is accepted as "no events"
    assert plots._snr_time(trace, None, [0, 1]).axes[0].get_title() == "UT 0"


def test_many_uts_get_a_rate_histogram():
    trace, _, summary = run_data()  # trace spans 60 s = 1 min
    summary["per_ut"] = [
        {
            "ut_id": u,
            "dwell": {"complete_s": [], "censored": []},
            "handovers": {"beam_handover": u % 4},
        }
        for u in range(40)
    ]
    ax = plots._handovers(float(np.ptp(trace["time_s"])), summary).axes[0]
    assert "1/min" in ax.get_xlabel()
    heights = [patch.get_height() for patch in ax.patches]
    assert sum(heights) == 40  # every UT in one bin; rates 0..3 per minute
    assert min(patch.get_x() for patch in ax.patches) == pytest.approx(0.0)


def test_plot_sweep(tmp_path):
    table = pd.DataFrame({"speed_m_s": [0.0, 30.0, 60.0], "mean_snr_db": [10, 9.5, 9.0],
                          "handovers_per_min": [1.0, 1.5, 2.2]})  # fmt: skip
    paths = plots.plot_sweep(table, tmp_path, "speed_m_s", ["mean_snr_db", "handovers_per_min"])
    assert_pngs(paths, tmp_path, ["sweep_speed_m_s.png"])
    with pytest.raises(LeolinkError, match="no column 'nope'"):
        plots.plot_sweep(table, tmp_path, "speed_m_s", "nope")


def test_unwritable_directory_raises_and_leaves_nothing(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    with pytest.raises(OSError):  # root ignores chmod, so block with a file in the path
        coverage_plots.plot_coverage(
            coverage_df(np.random.default_rng(5)), blocker / "out", ROI_AXES_M
        )
    trace, events, summary = run_data()
    with pytest.raises(OSError):
        plots.plot_run(trace, events, summary, blocker)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_failure_mid_call_removes_every_partial(tmp_path, monkeypatch):
    real_savefig = Figure.savefig
    calls = []

    def failing_savefig(self, fname, **kw):
        calls.append(fname)
        if len(calls) == 3:
            real_savefig(self, fname, **kw)  # a partial file exists when the error hits
            raise OSError("disk full")
        return real_savefig(self, fname, **kw)

    monkeypatch.setattr(Figure, "savefig", failing_savefig)
    trace, events, summary = run_data()
    with pytest.raises(OSError, match="disk full"):
        plots.plot_run(trace, events, summary, tmp_path)
    assert len(calls) == 3
    assert list(tmp_path.iterdir()) == []  # no partial and no half set of final PNGs


def test_dwell_histogram_of_a_real_run_shows_its_dwells(tmp_path):
    # The summary of a real paper run, not a hand-made one: the histogram's bars count every
    # complete dwell of summary.json, and the censored ones are drawn apart.
    from leolink.app.run import run
    from leolink.config import load_config

    paper = Path(__file__).resolve().parents[1] / "configs" / "paper.toml"
    run(load_config(paper), out_dir=tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    n_complete = summary["overall"]["dwell"]["n_complete"]
    n_censored = summary["overall"]["dwell"]["n_censored"]
    assert n_complete > 0 and n_censored > 0
    ax = plots._dwell_hist(summary).axes[0]
    filled = [p for p in ax.patches if p.get_fill()]
    assert sum(p.get_height() for p in filled) == n_complete
    assert any(f"censored ({n_censored}" in t.get_text() for t in ax.get_legend().get_texts())
    assert (tmp_path / "dwell_hist.png").stat().st_size > 0


def _rgb_present(fig, rgb, tol=8):
    """Whether any pixel of the drawn figure, legends left out, is within ``tol`` of colour
    ``rgb`` (0-255)."""
    for legend in filter(None, (ax.get_legend() for ax in fig.axes)):
        legend.remove()
    fig.canvas.draw()
    px = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    return bool((np.abs(px - np.array(rgb)).max(axis=-1) <= tol).any())


def _twin_uts(trace):
    """UT 1 follows UT 0's Doppler and angular speed exactly (UTs a few km apart)."""
    u0 = trace[trace.ut_id == 0]
    twin = u0.assign(ut_id=1)
    return pd.concat([u0, twin], ignore_index=True).assign(
        angular_speed_deg_s=lambda d: 0.5 + 0.01 * d.time_s,
        doppler_rate_hz_s=-7e3,
    )


TAB_BLUE, TAB_ORANGE = (31, 119, 180), (255, 127, 14)  # the lines of the first two UTs


def test_a_ut_whose_curve_coincides_with_an_earlier_ones_leaves_it_visible():
    from leolink.io.report.figures import fig_angular_speed, fig_doppler

    trace = _twin_uts(run_data()[0])
    for fig in (plots._doppler_time(trace, [0, 1]), fig_doppler(trace), fig_angular_speed(trace)):
        assert _rgb_present(fig, TAB_BLUE) and _rgb_present(fig, TAB_ORANGE)


def test_outage_is_in_the_legend_only_of_a_panel_with_outage():
    trace, events, _ = run_data()
    fig = plots._snr_time(trace, events, [0, 1])
    served, never = ([t.get_text() for t in ax.get_legend().get_texts()] for ax in fig.axes[:2])
    assert "outage" not in served and "outage" in never


def test_handover_bars_stay_clear_of_the_top_and_of_the_legend():
    _, _, summary = run_data()
    summary["per_ut"] += [
        {"ut_id": u, "handovers": {"beam_handover": 4, "sat_handover": 0}} for u in (2, 3)
    ]
    fig = plots._handovers(60.0, summary)
    fig.canvas.draw()
    ax = fig.axes[0]
    legend = ax.get_legend().get_window_extent()
    bars = [p.get_window_extent() for p in ax.patches if p.get_height() > 0]
    assert max(p.get_y() + p.get_height() for p in ax.patches) < ax.get_ylim()[1]
    assert not any(legend.overlaps(b) for b in bars)


def _titles_and_offset_texts(fig):
    """Window boxes of each axes' titles (left, centre, right) and of its visible y offset
    text, once the figure is drawn."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    out = []
    for ax in fig.axes:
        names = {ax.get_title(loc) for loc in ("left", "center", "right")} - {""}
        titles = [a.get_window_extent(renderer) for a in ax.get_children()
                  if type(a).__name__ == "Text" and a.get_text() in names]  # fmt: skip
        offset = ax.yaxis.get_offset_text()
        shown = offset.get_visible() and offset.get_text()
        out.append((titles, offset.get_window_extent(renderer) if shown else None))
    return out


def test_no_report_title_sits_over_an_offset_text_above_its_axes():
    # The report's titles stay at their fixed place (maps.FIXED_TITLE_RC) but the dwell
    # histograms': matplotlib does not lift them. An SNR and SINR steady to 1e-4 dB (an offset
    # above the y axis, which the time panels turn off: their title is on the left), an angular
    # speed steady to 1e-6 deg/s (an offset) and dwell counts of 3e6 (a multiplier, which
    # the censored panel's title would cover) must leave every title clear.
    from leolink.io.report.figures import fig_angular_speed, fig_dwell, fig_snr_time

    t = np.arange(10.0)
    series = {"time_s": t, "ut_id": np.zeros(10, int), "snr_db": 20.0 + 1e-4 * t,
              "sinr_db": 20.0 + 1e-4 * t, "service": np.full(10, "served"),
              "angular_speed_deg_s": 1.0 + 1e-6 * t}  # fmt: skip
    events = {"time_s": np.empty(0), "ut_id": np.empty(0, int), "kind": np.empty(0, str)}
    counts = np.full(10, 3_000_000)
    figures = (fig_snr_time(series, events), fig_angular_speed(series),
               fig_dwell(np.linspace(0.0, 100.0, 11), counts, counts, 50.0))  # fmt: skip
    n_offsets = 0
    for fig in figures:
        for titles, offset in _titles_and_offset_texts(fig):
            assert titles
            n_offsets += offset is not None
            assert offset is None or not any(offset.overlaps(t) for t in titles)
    assert n_offsets == 3  # angular speed's offset, each dwell panel's multiplier
