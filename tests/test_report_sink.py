"""The report sink inside real runs (``leolink run``, nothing reconstructed): what it keeps
equals what the files say, its satellites are the simulator's (pass, Walker and TLE), the
run's own footprint.gif draws each UT in its serving beam's colour and cell, and the run's
own report.html opens in headless Chromium."""

import gc
import json
import math
import subprocess
import sys
import tomllib
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from matplotlib.path import Path as MplPath
from PIL import Image

from browser_helpers import open_page, require_browser
from leolink.io.report.animation import frames_from_stats, write_footprint_gif
from leolink.io.report.maps import N_BEAM_COLOURS, beam_colour
from leolink.io.report.rebuild import stats_from_dir
from leolink.io.report.sink import ReportSink
from leolink.io.report.stats import ReportStats
from leolink.io.sinks import ReportParams
from report_helpers import PAPER, REPO, WALKER, cli, ephemeris

TLE = REPO / "configs" / "examples" / "tle.toml"
HALF_POWER_DB = 10.0 * np.log10(0.5)  # -3.0103 dB
RADIUS_M = 6371e3
OVERLAP_PX = 9.0  # a UT dot is ~7 px across at 80 dpi: closer dots may hide each other
ON_CONTOUR_DB = 0.02  # the drawn polygon cannot decide closer to the contour than this


def _run(out, config, *extra):
    cli("run", config, "--out", out, "--quiet", *extra)
    return out, ReportStats.load(out / "report_stats.npz"), pd.read_csv(out / "trace.csv")


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("paper"), PAPER)


@pytest.fixture(scope="module")
def walker(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("walker"), WALKER)


@pytest.fixture(scope="module")
def tle(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("tle"), TLE)


def test_a_run_writes_the_report_and_its_files(paper):
    out, stats, _ = paper
    names = {p.name for p in out.iterdir()}
    assert {"report.html", "footprint.gif", "report_stats.npz", "events.parquet"} <= names
    assert not {"run.geojson", "run.czml"} & names  # exports are asked for (opt-in)
    listed = {f["path"] for f in json.loads((out / "run.json").read_text())["files"]}
    assert listed == names - {"run.json"}
    # Default time-plot UTs: the first of each population (centre, static, car, aircraft).
    assert stats.series_ut.tolist() == [0, 1, 5, 6]
    events = pd.read_csv(out / "events.csv")
    parquet = pd.read_parquet(out / "events.parquet")
    assert len(events) > 0  # CSV reads whole seconds as integers: compare the values
    pd.testing.assert_frame_equal(parquet, events, check_dtype=False)


def test_what_the_sink_kept_equals_what_the_files_say(paper):
    out, kept, trace = paper
    files = stats_from_dir(out, series_ut=kept.series_ut, max_frames=60)
    np.testing.assert_array_equal(kept.keep_times_s, files.keep_times_s)
    for key in kept.hist:
        np.testing.assert_array_equal(kept.hist[key], files.hist[key], err_msg=key)
    assert kept.service_counts == files.service_counts
    assert sum(kept.service_counts.values()) == len(trace)
    assert kept.outage_reason_counts == files.outage_reason_counts
    for name in ("ut_lat_deg", "ut_lon_deg", "ut_sat", "ut_beam"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(files, name), err_msg=name)
    cols = ["time_s", "ut_id", "sat_id", "beam_id", "snr_db", "sinr_db", "service"]
    pd.testing.assert_frame_equal(kept.series()[cols], files.series()[cols], check_dtype=False)
    pd.testing.assert_frame_equal(kept.events(), files.events(), check_dtype=False)


def test_outage_reasons_are_counted_by_name(tmp_path):
    # The stream carries outage_reason as a code (int8): the report counts the trace's
    # names. A 5 dB threshold puts the paper's pass edges in outage (below_threshold).
    out, kept, trace = _run(tmp_path / "run", PAPER, "--set", "controller.min_snr_db=5.0")
    outage = trace[trace["service"] == "outage"]
    assert len(outage) > 0
    assert kept.outage_reason_counts == outage["outage_reason"].value_counts().to_dict()


def test_a_run_with_the_report_leaves_pandas_unimported(tmp_path):
    # pandas costs ~0.5 s CPU to import and the run itself does not need it (issue 44):
    # the report's statistics, figures and page work on numpy arrays (the plots sink,
    # off here, still reads its rows with pandas).
    code = (
        "import runpy, sys\n"
        f"sys.argv = ['leolink', 'run', {str(PAPER)!r}, '--out', {str(tmp_path / 'run')!r},"
        " '--quiet', '--set', 'output.plots.enabled=false']\n"
        "try:\n    runpy.run_module('leolink.cli', run_name='__main__')\n"
        "except SystemExit as exc:\n    assert not exc.code, exc.code\n"
        "print('pandas' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=REPO, check=True)  # fmt: skip
    assert (tmp_path / "run" / "report.html").is_file()
    assert done.stdout.split()[-1] == "False"


def test_dwell_histograms_count_the_summary_dwells(paper):
    out, kept, _ = paper
    dwell = json.loads((out / "summary.json").read_text())["overall"]["dwell"]
    assert kept.dwell_complete.sum() == dwell["n_complete"] > 0
    assert kept.dwell_censored.sum() == dwell["n_censored"] > 0
    # ~31 s beam dwells of the paper's pass (README): the complete ones sit near 30 s.
    centres = 0.5 * (kept.dwell_edges_s[1:] + kept.dwell_edges_s[:-1])
    mean = (centres * kept.dwell_complete).sum() / kept.dwell_complete.sum()
    assert mean == pytest.approx(dwell["mean_s"], abs=0.5 * np.diff(kept.dwell_edges_s)[0])


@pytest.mark.parametrize("which", ["paper", "walker"])
def test_satellites_are_the_configured_orbits_at_the_kept_epochs(which, paper, walker):
    # Recomputed from the resolved config with leolink.orbit (tests/report_helpers.py).
    out, kept, trace = paper if which == "paper" else walker
    cfg = tomllib.loads((out / "config.resolved.toml").read_text())
    pos, vel, _ = ephemeris(cfg)(kept.keep_times_s)
    np.testing.assert_allclose(kept.sat_pos_m, pos[:, kept.sat_ids], atol=1e-3)
    np.testing.assert_allclose(kept.sat_vel_m_s, vel[:, kept.sat_ids], atol=1e-6)
    served = trace[trace["time_s"].isin(kept.keep_times_s) & trace["ut_id"].isin(kept.sample_ut)]
    assert set(kept.sat_ids) == set(served["sat_id"][served["sat_id"] >= 0])


def test_tle_satellite_states_match_skyfield(tle):
    # skyfield's ITRS adds polar motion (~10 m) and rotates by UT1 (UT1 - UTC = -0.17 s on
    # 2019-12-09: ~85 m); leolink uses sgp4's GMST of the UTC date (tests/test_orbit.py).
    # 150 m still catches a wrong epoch (1 s of orbit = 7.7 km) or frame (1 s of rotation).
    skyfield_api = pytest.importorskip("skyfield.api")
    from skyfield.framelib import itrs

    from leolink.io.tle import read_tle_file

    out, kept, _ = tle
    name, line1, line2 = read_tle_file(REPO / "configs" / "examples" / "tles" / "iss.tle")[0]
    ts = skyfield_api.load.timescale(builtin=True)
    sat = skyfield_api.EarthSatellite(line1, line2, name, ts)
    tt = ts.utc(2019, 12, 9, 16, 37, 29.363 + kept.keep_times_s)  # tle_epoch_utc = t 0
    ref = sat.at(tt).frame_xyz(itrs).m.T
    assert kept.sat_ids.tolist() == [0]
    assert np.all(np.linalg.norm(kept.sat_pos_m[:, 0] - ref, axis=-1) < 150.0)


def _ut_altitude_m(rows, sat_radius_m):
    """UT height from the trace's elevation and slant range and the satellite's radius."""
    d, el = rows["slant_range_m"].to_numpy(), np.radians(rows["elevation_deg"].to_numpy())
    # |sat|^2 = r^2 + d^2 + 2 r d sin(el), solved for the UT radius r.
    r = -d * np.sin(el) + np.sqrt((d * np.sin(el)) ** 2 - d**2 + sat_radius_m**2)
    return r - RADIUS_M


@pytest.mark.parametrize("which", ["paper", "walker", "tle"])
def test_ut_is_inside_its_serving_cell_exactly_when_the_trace_gain_is_above_half_power(
    which, paper, walker, tle
):
    out, kept, trace = {"paper": paper, "walker": walker, "tle": tle}[which]
    n_in = n_out = 0
    for k, f in enumerate(frames_from_stats(kept)):  # every kept epoch: every served UT
        rows = trace[(trace["time_s"] == f.time_s) & (trace["beam_id"] >= 0)]
        radius = dict(zip(kept.sat_ids, np.linalg.norm(kept.sat_pos_m[k], axis=-1), strict=True))
        alt = _ut_altitude_m(rows, rows["sat_id"].map(radius).to_numpy())
        rows = rows[np.abs(alt) < 100.0]  # the cells are drawn on the ground
        peak_db = 10.0 * np.log10(np.prod(kept.n_sub_xy))  # normalized gain: one per element
        margin_db = rows["gain_tx_db"].to_numpy() - peak_db - HALF_POWER_DB
        fp = f.footprints
        for (sat, beam, lon, lat), m in zip(
            rows[["sat_id", "beam_id", "lon_deg", "lat_deg"]].to_numpy(), margin_db, strict=True
        ):
            if abs(m) < ON_CONTOUR_DB:
                continue
            j = np.flatnonzero((fp["sat_id"] == sat) & (fp["beam_id"] == beam))
            assert j.size == 1, f"t = {f.time_s}: no cell drawn for sat {sat} beam {beam}"
            ring = np.column_stack([fp["lon_deg"][j[0]], fp["lat_deg"][j[0]]])
            inside = MplPath(ring).contains_point((lon, lat))
            assert inside == (m > 0), f"t = {f.time_s} sat {sat} beam {beam}: {m:.3f} dB"
            n_in, n_out = n_in + inside, n_out + (not inside)
    assert n_in > 20
    # The paper's O = 1.2 leaves UTs outside half power, so both sides get tested there; the
    # walker and TLE examples' codebooks (no holes) keep every served UT inside its cell.
    assert n_out > 5 if which == "paper" else n_out == 0


def _gif_frames(path):
    with Image.open(path) as im:
        frames = []
        for k in range(im.n_frames):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB")))
        return frames


def test_the_runs_animation_has_a_frame_every_other_kept_epoch_coloured_by_the_trace(
    paper, tmp_path
):
    out, kept, trace = paper
    frames = _gif_frames(out / "footprint.gif")
    # 120 epochs, 60 kept (output.report.max_frames, every 2 s), half of them animated
    np.testing.assert_allclose(kept.keep_times_s, np.arange(0.0, 120.0, 2.0))
    assert len(frames) == 30
    # The same frames drawn again from the saved statistics give the run's file, byte for
    # byte; that drawing also says where each UT is in the image.
    info = write_footprint_gif(tmp_path / "again.gif", frames_from_stats(kept, 30))
    assert (tmp_path / "again.gif").read_bytes() == (out / "footprint.gif").read_bytes()
    steps = np.diff(info["times_s"])  # spread evenly from the first kept epoch to the last
    assert info["times_s"][0] == 0.0 and info["times_s"][-1] == 118.0 and set(steps) <= {4.0, 6.0}
    ids = np.arange(-1, N_BEAM_COLOURS)
    palette = np.round(beam_colour(ids)[:, :3] * 255)
    checked = 0
    for k, t_s in enumerate(info["times_s"]):
        rows = trace[trace["time_s"] == t_s].sort_values("ut_id")
        col, row = info["to_pixel"](rows["lon_deg"].to_numpy(), rows["lat_deg"].to_numpy())
        beam = rows["beam_id"].to_numpy()
        d = np.hypot(col[:, None] - col[None], row[:, None] - row[None]) + np.eye(len(col)) * 99
        hidden = (d < OVERLAP_PX).any(axis=1)  # a neighbour's dark dot edge may cross it
        rgb = frames[k][np.round(row).astype(int), np.round(col).astype(int)].astype(float)
        dist = np.abs(rgb[:, None, :] - palette[None]).sum(axis=-1)
        drawn = ids[np.argmin(dist, axis=1)]
        assert np.all(dist.min(axis=1)[~hidden] < 6), f"t = {t_s}: a dot is not a beam colour"
        np.testing.assert_array_equal(
            drawn[~hidden] % N_BEAM_COLOURS, beam[~hidden] % N_BEAM_COLOURS, err_msg=f"{t_s}"
        )
        checked += int((~hidden).sum())
    assert checked >= 4 * len(frames)


def test_the_runs_own_report_opens_in_headless_chromium(paper, tmp_path):
    require_browser()
    out, _, _ = paper
    state = open_page(out / "report.html")
    assert len(state["images"]) == 9  # 8 figures and the embedded animation
    assert all(i["complete"] and i["width"] > 0 and i["height"] > 0 for i in state["images"])
    assert all(state["decoded"])
    assert state["scripts"] == 0 and state["links"] == []
    assert all(r.startswith(("file:", "data:")) for r in state["resources"]), state["resources"]
    assert [e for e in state["console"] if e["level"] in ("SEVERE", "WARNING")] == []


def test_a_tle_run_in_memory_draws_its_map_and_notebook_views():
    from matplotlib.collections import PolyCollection

    from leolink.app.run import run
    from leolink.config import load_config

    res = run(load_config(TLE, ["output.plots.enabled=false"]))
    assert res.report_stats is not None and res.report_stats.sat_ids.tolist() == [0]
    ax = res.plot_map().axes[0]
    cells = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(cells[0].get_paths()) == res.summary["run"]["n_beam"]
    mean = res.summary["overall"]["sinr_db"]["mean"]
    assert f"<td>mean SINR</td><td>{mean:.4g} dB</td>" in res._repr_html_()
    ds = res.to_xarray()
    row = res.trace[(res.trace["time_s"] == 60.0) & (res.trace["ut_id"] == 1)]
    assert ds["snr_db"].dims == ("time", "ut_id")
    assert float(ds["snr_db"].sel(time=60.0, ut_id=1)) == row["snr_db"].item()
    assert math.isfinite(row["snr_db"].item())


def test_tle_exports_count_from_the_configured_utc_epoch(tle, tmp_path):
    import shutil

    out = tmp_path / "tle"
    shutil.copytree(tle[0], out)
    assert cli("report", out, "--exports", "--no-animation", "--quiet") == ""
    czml = json.loads((out / "run.czml").read_text())
    sat = next(p for p in czml if str(p.get("id", "")).startswith("satellite"))
    assert sat["position"]["epoch"] == "2019-12-09T16:37:29.363Z"  # tle.toml: run.start_utc


def test_report_uts_outside_the_run_are_refused(tmp_path, capsys):
    from leolink.cli import main

    args = ["run", str(PAPER), "--out", str(tmp_path), "--quiet"]
    assert main([*args, "--set", "output.report.uts=[2, 7]"]) == 2
    err = capsys.readouterr().err
    assert "output.report.uts = [2, 7] is not allowed; UT ids of this run are 0 to 6" in err


def _finished_sink(tmp_path, monkeypatch, draw):
    """A 3-UT, 2-epoch report sink finished with ``draw(sink)`` as its drawing."""
    sink = ReportSink(tmp_path, ReportParams())
    sink.start(SimpleNamespace(population=["a"] * 3, n_ut=3, start_s=0.0, n_epochs=2,
                               epoch_s=1.0))  # fmt: skip

    def draw_files(self):  # what _draw_files returns: (animation path, files written)
        draw(self)
        return None, []

    monkeypatch.setattr(ReportSink, "_draw_files", draw_files)
    monkeypatch.setattr(ReportSink, "_draw_figures", lambda self: [])
    sink.finish(SimpleNamespace(dwells={"ut_id": []}))
    return sink


def test_the_report_is_drawn_with_the_heap_frozen_and_released_after(tmp_path, monkeypatch):
    # The run's objects stay out of the collector's passes while the report draws (a
    # full collection walked all of them twice, ~0.25 s at 1,000 UTs) and are collectable
    # again after it: nothing frozen for good.
    assert gc.get_freeze_count() == 0
    made_before = [[]]  # a container the collector tracks, alive through the drawing
    seen = {}

    def draw(sink):
        seen["frozen"] = gc.get_freeze_count()
        seen["walked"] = any(o is made_before for o in gc.get_objects())

    _finished_sink(tmp_path, monkeypatch, draw)
    assert seen["frozen"] > 0
    assert not seen["walked"]
    assert gc.get_freeze_count() == 0
    assert any(o is made_before for o in gc.get_objects(generation=2))


def test_the_heap_is_released_when_the_drawing_fails(tmp_path, monkeypatch):
    def draw(sink):
        assert gc.get_freeze_count() > 0
        raise RuntimeError("drawing failed")

    with pytest.raises(RuntimeError, match="drawing failed"):
        _finished_sink(tmp_path, monkeypatch, draw)
    assert gc.get_freeze_count() == 0


def test_a_heap_the_caller_froze_stays_frozen(tmp_path, monkeypatch):
    # Unfreezing at the end would release the caller's objects too: left alone then.
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        seen = []
        _finished_sink(tmp_path, monkeypatch, lambda sink: seen.append(gc.get_freeze_count()))
        assert seen == [frozen]
        assert gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()
