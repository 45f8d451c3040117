"""Recorded tracks with UTC timestamps: CSV ``time_utc``, GPX files (gpxpy), the run's
clock (run.start_utc), and the report of UTs held outside their track's time span."""

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from leolink.config import load_config
from leolink.io.tracks import TrackFileError, read_track, read_track_csv, read_track_gpx

ROOT = Path(__file__).resolve().parents[1]
SHIP = ROOT / "configs" / "examples" / "ship.toml"
T0 = datetime(2024, 5, 1, 12, 0, 0, tzinfo=UTC)

GPX = """<?xml version="1.0" encoding="UTF-8"?>
<gpx version="1.1" creator="leolink test" xmlns="http://www.topografix.com/GPX/1/1">
  <trk><name>ferry</name>
    <trkseg>
      <trkpt lat="35.95" lon="-5.60"><ele>12.0</ele><time>2024-05-01T12:00:30Z</time></trkpt>
      <trkpt lat="35.949" lon="-5.607"><ele>12.5</ele><time>2024-05-01T12:01:30Z</time></trkpt>
    </trkseg>
    <trkseg>
      <trkpt lat="35.948" lon="-5.613"><time>2024-05-01T14:02:30+02:00</time></trkpt>
    </trkseg>
  </trk>
  <trk>
    <trkseg>
      <trkpt lat="36.0" lon="-5.5"><time>2024-05-01T11:59:00Z</time></trkpt>
      <trkpt lat="36.0" lon="-5.49"><time>2024-05-01T12:03:00Z</time></trkpt>
    </trkseg>
  </trk>
</gpx>
"""


def test_gpx_tracks_are_read_with_their_utc_times(tmp_path):
    """One UT per <trk>, segments joined; UTC offsets honoured; <ele> optional."""
    path = tmp_path / "ferry.gpx"
    path.write_text(GPX, encoding="utf-8")
    ferry, other = read_track_gpx(path, T0)
    assert ferry.ut_id == "ferry" and other.ut_id == "ferry-1"
    np.testing.assert_allclose(ferry.time_s, [30.0, 90.0, 150.0])  # 14:02:30+02:00 = 12:02:30Z
    np.testing.assert_allclose(np.degrees(ferry.lat_rad), [35.95, 35.949, 35.948])
    np.testing.assert_allclose(ferry.alt_m, [12.0, 12.5, 0.0])
    np.testing.assert_allclose(other.time_s, [-60.0, 180.0])
    assert read_track(path, T0)[0].ut_id == "ferry"  # by extension


def test_gpx_needs_times_and_a_clock(tmp_path):
    path = tmp_path / "x.gpx"
    path.write_text(GPX.replace("<time>2024-05-01T12:01:30Z</time>", ""), encoding="utf-8")
    with pytest.raises(TrackFileError, match=r"x.gpx: track 'ferry', point 1: no <time>"):
        read_track_gpx(path, T0)
    path.write_text(GPX, encoding="utf-8")
    with pytest.raises(TrackFileError, match="set run.start_utc"):
        read_track_gpx(path, None)
    path.write_text("<gpx>not closed", encoding="utf-8")
    with pytest.raises(TrackFileError, match="x.gpx: line 1: not a valid GPX file"):
        read_track_gpx(path, T0)


def test_csv_with_utc_timestamps(tmp_path):
    path = tmp_path / "car.csv"
    path.write_text(
        "time_utc,lat_deg,lon_deg,alt_m\n"
        "2024-05-01T12:00:10Z,40.0,-3.7,650\n"
        "2024-05-01T12:00:20.5Z,40.001,-3.7,651\n",
        encoding="utf-8",
    )
    (track,) = read_track_csv(path, T0)
    np.testing.assert_allclose(track.time_s, [10.0, 20.5])
    with pytest.raises(TrackFileError, match="set run.start_utc"):
        read_track_csv(path, None)
    path.write_text("time_utc,lat_deg,lon_deg,alt_m\nnoon,40,-3.7,0\n", encoding="utf-8")
    with pytest.raises(TrackFileError, match=r"line 2, column 'time_utc': not an ISO 8601"):
        read_track_csv(path, T0)


def _gpx_config(tmp_path, start_utc, duration_s=120.0):
    path = tmp_path / "ferry.gpx"
    path.write_text(GPX, encoding="utf-8")
    over = [
        f'run.start_utc="{start_utc}"',
        f"run.duration_s={duration_s}",
        f'population.1.track_file="{path}"',
        "output.plots.enabled=false",
    ]
    return load_config(SHIP, over)


def test_a_gpx_population_runs_on_the_run_clock_and_held_uts_are_reported(tmp_path, capsys):
    """run.start_utc = 12:00:00: the ferry's first fix is at t = 30 s; before it and after
    its last fix (t = 150 s) the UT holds a fix, and the run says for how long."""
    from leolink.app.run import run
    from leolink.cli import main

    cfg = _gpx_config(tmp_path, "2024-05-01T12:00:00Z", duration_s=180.0)
    res = run(cfg)
    tr = res.trace
    ferry = tr[tr.population == "ship"]
    first = ferry[ferry.ut_id == 1].set_index("time_s")
    assert first.lat_deg.loc[30.0] == pytest.approx(35.95, abs=1e-9)
    assert first.lat_deg.loc[150.0] == pytest.approx(35.948, abs=1e-9)
    assert (first.lat_deg.loc[:30.0] == first.lat_deg.loc[30.0]).all()  # held before
    cover = {c["label"]: c for c in res.summary["run"]["track_coverage"]}
    # recorded epochs 0..179 s: before 30 s (30 epochs) and after 150 s (29 epochs)
    assert cover["ferry"]["held_s"] == 59.0 and (
        cover["ferry"]["first_s"],
        cover["ferry"]["last_s"],
    ) == (30.0, 150.0)
    assert "ferry-1" not in cover  # fixes from -60 s to 180 s: the whole run
    notes = [n for n in res.summary["run"]["notes"] if "track 'ferry'" in n]
    assert len(notes) == 1 and "held at its first or last fix for 59 s" in notes[0]
    out = tmp_path / "out"
    sets = [
        f'population.1.track_file="{tmp_path / "ferry.gpx"}"',
        'run.start_utc="2024-05-01T12:00:00Z"',
        "output.plots.enabled=false",
    ]
    argv = ["run", str(SHIP), "--out", str(out), "--quiet"]
    assert main(argv + [x for s in sets for x in ("--set", s)]) == 0
    assert "note: UT 1 ('ship', track 'ferry')" in capsys.readouterr().err  # shown even --quiet


def test_run_start_utc_shifts_a_utc_track(tmp_path):
    """The same GPX file on two run clocks 60 s apart: the UT is 60 s further along."""
    from leolink.app.scenario import build_scenario

    a = build_scenario(_gpx_config(tmp_path, "2024-05-01T12:00:00Z")).populations[1][1]
    b = build_scenario(_gpx_config(tmp_path, "2024-05-01T12:01:00Z")).populations[1][1]
    sa, sb = a.state(90.0), b.state(30.0)
    np.testing.assert_allclose(sa.pos_m, sb.pos_m, atol=1e-6)


def test_a_utc_track_without_run_start_utc_is_refused(tmp_path):
    from leolink.app.scenario import build_scenario

    path = tmp_path / "ferry.gpx"
    path.write_text(GPX, encoding="utf-8")
    cfg = load_config(SHIP, [f'population.1.track_file="{path}"'])
    with pytest.raises(
        TrackFileError, match="ferry.gpx: the track has UTC timestamps; set run.start_utc"
    ):
        build_scenario(cfg)
