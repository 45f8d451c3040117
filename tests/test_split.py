"""One run split over parts of its UTs (``leolink run --workers N | --scheduler ADDRESS``):
the same trace, events, summary and report as the single-process run, coupled features
refused, a lost worker stops the run with nothing written (leolink.app.split)."""

from __future__ import annotations

import json
import math
import os
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w

import leolink.app.split as split
from leolink.app.split import regions
from leolink.cli import EXIT_USAGE, main
from leolink.geometry import geodetic_to_ecef
from leolink.rng import ut_keys
from leolink.sim.mobility.models import (
    ConstantVelocity,
    OnWgs84,
    SelectedUTs,
    Static,
    Track,
    Waypoints,
    take_uts,
)

#: Tolerances of two paths that remain (issue 43): the parts sum the other satellites'
#: interference over their own satellite cones, in another order than the whole run.
RTOL = 1e-12
DB_ATOL = 1e-9

#: The split runs' global config, shared with benchmarks/bench_split.py; each test layers
#: its channel, policy, outputs and two populations (fixed and moving, all over the globe).
GLOBAL = Path(__file__).parent / "data" / "global_split.toml"

SPHERE = dict(earth="sphere", interference="all_satellites", policy="max_snr", rlf=False,
              environment="open", report=True, duration=6.0)  # fmt: skip
WGS84 = dict(earth="wgs84", interference="serving_satellite", policy="hysteresis",
             rlf=True, environment="urban", report=False, duration=5.0)  # fmt: skip


def _config(tmp_path, **values):
    v = values
    data = tomllib.loads(GLOBAL.read_text(encoding="utf-8"))
    band = {"placement": "random_region", "lat_band_deg": [-53.0, 53.0]}
    data |= {
        "earth": {"model": v["earth"]},
        "link": {"fading": "rician", "interference": v["interference"]},
        "controller": {"policy": v["policy"], "min_snr_db": -10.0, "rlf": {"enabled": v["rlf"]}},
        "population": [
            {"name": "fixed", "kind": "static", "count": 24, "environment": v["environment"],
             **band},
            {"name": "car", "kind": "constant_velocity", "count": 16, "speed": "car",
             "heading_deg": "random", **band},
        ],
    }  # fmt: skip
    data["run"] |= {"seed": 11, "duration_s": v["duration"]}
    data["output"] |= {"trace": {"formats": ["csv", "parquet"]}, "events": {"formats": ["csv"]}}
    data["output"]["report"]["enabled"] = v["report"]
    path = tmp_path / "global.toml"
    path.write_text(tomli_w.dumps(data), encoding="utf-8")
    return path


def _run(config, out, *extra):
    assert main(["run", str(config), "--out", str(out), "--quiet", *extra]) == 0
    return out


def _same_table(a, b, what):
    """Equal column by column: text and integers exactly, floats within RTOL / DB_ATOL."""
    assert list(a.columns) == list(b.columns), what
    assert len(a) == len(b), what
    for name in a.columns:
        x, y = a[name].to_numpy(), b[name].to_numpy()
        if x.dtype.kind == "f":
            np.testing.assert_allclose(y, x, rtol=RTOL, atol=DB_ATOL, err_msg=f"{what}.{name}")
        else:
            assert (x == y).all(), f"{what}.{name}"


def _same_json(a, b, where="summary"):
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            _same_json(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same_json(x, y, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert math.isclose(a, b, rel_tol=RTOL, abs_tol=DB_ATOL), where
    else:
        assert a == b, where


def _same_outputs(single, parts):
    """trace (sorted by time, UT), events and summary (but its run section) agree."""
    order = ["time_s", "ut_id"]
    trace_a = pd.read_csv(single / "trace.csv").sort_values(order, kind="stable")
    trace_b = pd.read_csv(parts / "trace.csv").sort_values(order, kind="stable")
    _same_table(trace_a.reset_index(drop=True), trace_b.reset_index(drop=True), "trace")
    _same_table(pd.read_parquet(single / "trace.parquet"), pd.read_parquet(parts / "trace.parquet"),
                "trace.parquet")  # fmt: skip
    _same_table(pd.read_csv(single / "events.csv"), pd.read_csv(parts / "events.csv"), "events")
    a, b = (json.loads((d / "summary.json").read_text("utf-8")) for d in (single, parts))
    assert b["run"]["n_ut"] == a["run"]["n_ut"]
    _same_json(
        {k: v for k, v in a.items() if k != "run"}, {k: v for k, v in b.items() if k != "run"}
    )
    return a, b


@pytest.mark.parametrize("values", [SPHERE, WGS84], ids=["sphere", "wgs84-urban-rlf"])
def test_two_workers_give_the_single_process_outputs(tmp_path, values):
    """UTs all over the globe (random headings, Rician draws per UT, other satellites'
    interference; or WGS 84, urban channel states per UT, radio link failures): the split
    run's outputs equal the single run's, and so do those of another partition."""
    config = _config(tmp_path, **values)
    single = _run(config, tmp_path / "single")
    parts = _run(config, tmp_path / "parts", "--workers", "2", "--parts", "3")
    a, b = _same_outputs(single, parts)
    assert a["overall"]["handovers"]["sat_handover"] > 0  # the runs compare something
    assert b["run"]["split"]["parts"] == 3
    assert len(b["run"]["split"]["peak_rss_mib_by_worker"]) <= 2
    assert sorted(p.name for p in parts.iterdir()) == sorted(p.name for p in single.iterdir())
    if values["report"]:  # the report's statistics, from the same stream
        with np.load(single / "report_stats.npz") as x, np.load(parts / "report_stats.npz") as y:
            assert x.files == y.files
            for name in x.files:
                if x[name].dtype.kind == "f":
                    np.testing.assert_allclose(y[name], x[name], rtol=RTOL, atol=DB_ATOL)
                else:
                    assert (x[name] == y[name]).all(), name


def test_parts_in_one_process_do_not_depend_on_the_partition(tmp_path):
    """One worker, 1 vs 7 parts run one after the other in this process."""
    config = _config(tmp_path, **{**SPHERE, "report": False, "duration": 4.0})
    one = _run(config, tmp_path / "one", "--parts", "1")
    seven = _run(config, tmp_path / "seven", "--parts", "7")
    _same_outputs(one, seven)


def test_measurement_errors_do_not_depend_on_the_partition(tmp_path):
    """A3 behind measurement errors drawn per UT, cell and instant (issue 46): the same
    events in one part and in five."""
    config = _config(tmp_path, **{**SPHERE, "report": False, "duration": 4.0})
    sets = ["--set", "controller.policy='a3'", "--set", "controller.measurement.error_db=4.0",
            "--set", "controller.filter.k=0"]  # fmt: skip
    one = _run(config, tmp_path / "one", "--parts", "1", *sets)
    five = _run(config, tmp_path / "five", "--parts", "5", *sets)
    a, _ = _same_outputs(one, five)
    plain = _run(config, tmp_path / "plain", *sets[:2], *sets[4:])
    events = (pd.read_csv(d / "events.csv") for d in (one, plain))
    assert not next(events).equals(next(events))  # the errors change the handovers


def _marker(folder):
    """``tmp_path/lost-once`` of the part ``tmp_path/dask/.parts-*/part-*``."""
    return Path(folder).parents[2] / "lost-once"


def _lost_once(config, source, ut_ids, folder):
    """A part whose first attempt loses its worker process (part 1 only)."""
    if Path(folder).name.endswith("00001"):
        try:  # exclusive: only the first attempt creates it
            os.close(os.open(_marker(folder), os.O_CREAT | os.O_EXCL))
            os._exit(9)
        except FileExistsError:
            pass
    return _run_part(config, source, ut_ids, folder)


@pytest.mark.optional_extra("dist")
def test_external_dask_scheduler_gives_the_single_process_outputs(tmp_path, monkeypatch):
    """``--scheduler ADDRESS`` of a cluster started here (its workers waited for); the
    worker running part 1 is lost once: dask runs the part again on another worker."""
    distributed = pytest.importorskip("dask.distributed")
    config = _config(tmp_path, **{**SPHERE, "report": False, "duration": 4.0})
    single = _run(config, tmp_path / "single")
    monkeypatch.setattr(split, "run_part", _lost_once)  # the workers import this module
    with (
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster,
        distributed.Client(cluster) as client,
    ):
        client.wait_for_workers(2)
        parts = _run(config, tmp_path / "dask", "--scheduler", cluster.scheduler_address)
    _, b = _same_outputs(single, parts)
    assert b["run"]["split"]["parts"] == split.SCHEDULER_PARTS
    assert (tmp_path / "lost-once").exists()  # the worker was lost, the part ran again
    assert not list(parts.glob(".parts-*"))  # the parts' folder, the lost one's files too


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        (["satellite_array.active_beams='demand'"], "satellite_array.active_beams = 'demand'"),
        (["scheduler.kind='round_robin'"], "scheduler.kind = 'round_robin'"),
        (["scheduler.kind='round_robin'", "link.precoder='zf'"], "link.precoder = 'zf'"),
    ],
)
def test_coupled_features_are_refused_by_run_and_validate(tmp_path, capsys, overrides, key):
    config = _config(tmp_path, **{**SPHERE, "report": False})
    args = [str(config), *(a for o in overrides for a in ("--set", o))]
    out = tmp_path / "out"
    assert main(["run", *args, "--out", str(out), "--quiet", "--workers", "2"]) == EXIT_USAGE
    said = capsys.readouterr().err.strip()
    assert main(["validate", *args, "--workers", "2"]) == EXIT_USAGE
    assert capsys.readouterr().err.strip() == said
    assert said.count("\n") == 0 and key in said and "--workers 2" in said
    assert not out.exists() or not any(out.iterdir())
    assert main(["validate", *args]) == 0  # the same config runs unsplit


def test_bad_split_options_are_one_line(tmp_path, capsys):
    config = _config(tmp_path, **{**SPHERE, "report": False})
    for extra, text in (
        (["--workers", "0"], "workers = 0 is not allowed"),
        (["--parts", "0"], "--parts 0 is not allowed"),
        (["--workers", "2", "--scheduler", "127.0.0.1:1"], "not both"),
    ):
        assert main(["validate", str(config), *extra]) == EXIT_USAGE
        assert text in capsys.readouterr().err


def _dies_in_part_one(config, source, ut_ids, folder):
    if Path(folder).name.endswith("00001"):
        os._exit(9)  # the worker process is lost, as a killed or crashed machine's
    return _run_part(config, source, ut_ids, folder)


_run_part = split.run_part


def test_a_lost_worker_stops_the_run_and_writes_nothing(tmp_path, capsys, monkeypatch):
    """A local worker that dies: one line, exit 2, no output and no part left."""
    monkeypatch.setattr(split, "run_part", _dies_in_part_one)  # forked workers inherit it
    config = _config(tmp_path, **{**SPHERE, "report": False, "duration": 3.0})
    out = tmp_path / "out"
    assert main(["run", str(config), "--out", str(out), "--quiet", "--workers", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert "a worker process died" in err and "no output written" in err and "\n" not in err
    assert list(out.iterdir()) == []


# --------------------------------------------------------------------------- the pieces
def test_regions_are_compact_and_even():
    rng = np.random.default_rng(5)
    lat = np.arcsin(rng.uniform(-0.8, 0.8, 5000))
    lon = rng.uniform(-np.pi, np.pi, 5000)
    for n_parts in (1, 2, 3, 7, 16):
        parts = regions(lat, lon, n_parts)
        assert len(parts) == n_parts
        assert np.array_equal(np.sort(np.concatenate(parts)), np.arange(5000))
        sizes = [len(p) for p in parts]
        assert max(sizes) - min(sizes) <= 1
        assert all(np.all(np.diff(p) > 0) for p in parts)
    # 16 regions of a sixteenth of the band's area A = 0.8 * 4 pi / 16 sr each, cut on
    # their longer side so at most 2:1: the half-diagonal sqrt(5 A / 8) = 36 deg bounds
    # how far a UT lies from its region's centre (a random split: ~180 deg)
    up = geodetic_to_ecef(lat, lon, 0.0)
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    for p in regions(lat, lon, 16):
        centre = up[p].mean(axis=0)
        centre /= np.linalg.norm(centre)
        assert np.degrees(np.arccos(np.clip(up[p] @ centre, -1, 1)).max()) < 37.0
    assert len(regions(lat[:3], lon[:3], 8)) == 3  # never an empty part


def test_keys_of_some_uts_are_their_keys_in_the_whole_run():
    """Built from each UT's own spawn key, as SeedSequence.spawn builds the whole run's."""
    ids = np.array([0, 3, 4, 17, 99])
    assert np.array_equal(ut_keys(42, None, ids), ut_keys(42, 100)[ids])
    assert not np.array_equal(ut_keys(43, None, ids), ut_keys(42, 100)[ids])


def _models():
    rng = np.random.default_rng(1)
    lat, lon = rng.uniform(-1, 1, 9), rng.uniform(-3, 3, 9)
    heading, speed = rng.uniform(0, 6, 9), rng.uniform(0, 250, 9)
    tracks = [
        Track(np.array([0.0, 50.0]), np.array([a, a + 0.01]), np.array([b, b]), np.zeros(2))
        for a, b in zip(lat, lon, strict=True)
    ]
    return {
        "static": Static(lat, lon, rng.uniform(0, 100, 9)),
        "moving": ConstantVelocity(lat, lon, 0.0, heading, speed, t0_s=3.0),
        "wgs84": OnWgs84(ConstantVelocity(lat, lon, 10.0, heading, speed)),
        "tracks": Waypoints(tracks),
    }


@pytest.mark.parametrize("kind", ["static", "moving", "wgs84", "tracks"])
def test_some_uts_of_a_model_move_as_in_the_whole_model(kind):
    model = _models()[kind]
    index = np.array([1, 4, 8])
    part = take_uts(model, index)
    assert part.n_ut == 3 and getattr(part, "moves", True) == getattr(model, "moves", True)
    assert isinstance(part, SelectedUTs) == (kind == "tracks")
    for t_s in (0.0, 20.0, 61.5):
        whole, mine = model.state(t_s), part.state(t_s)
        for field in ("pos_m", "vel_m_s", "acc_m_s2", "lat_rad", "lon_rad", "alt_m"):
            np.testing.assert_allclose(getattr(mine, field), getattr(whole, field)[index],
                                       rtol=1e-15, atol=1e-9)  # fmt: skip
    assert take_uts(model, np.array([], int)).state(1.0).pos_m.shape == (0, 3)


# ------------------------------------------------------------- stops and killed parents
def _parts_running(tmp_path, out):
    """A ``--workers 2`` run in a process of its own, once its parts are being written."""
    from test_signals import _children, _start, _wait_for

    config = _config(tmp_path, **{**SPHERE, "report": False, "duration": 60.0})
    proc = _start("run", config, "--out", out, "--quiet", "--workers", "2", "--parts", "4")
    _wait_for(lambda: list(out.glob(".parts-*.partial/part-*")), "the parts being written")
    return proc, _children(proc.pid)


def _gone(workers):
    from test_signals import _alive, _kill_left, _wait_for

    try:
        _wait_for(lambda: not any(_alive(w) for w in workers), "the workers to exit")
    finally:
        _kill_left(workers)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="POSIX signals, /proc")
def test_a_stopped_split_run_leaves_no_parts(tmp_path):
    """SIGTERM to the parent while its parts run: the workers are stopped, the parts'
    folder removed, one line and 143 (issue 47)."""
    import signal

    out = tmp_path / "out"
    proc, workers = _parts_running(tmp_path, out)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    _gone(workers)
    assert proc.returncode == 143, err
    assert len(err.strip().splitlines()) == 1 and "stopped by SIGTERM" in err, err
    assert [p.name for p in out.iterdir()] == []


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="POSIX signals, /proc")
def test_the_parts_of_a_killed_split_run_are_removed_by_the_next_run(tmp_path):
    """SIGKILL of the parent (nothing runs in it): its workers die with it, its parts'
    folder stays; the next command that claims the folder removes it (and leaves a folder
    of the user's with a like name that is not a parts folder)."""
    out = tmp_path / "out"
    proc, workers = _parts_running(tmp_path, out)
    proc.kill()
    proc.communicate(timeout=120)
    _gone(workers)
    left = list(out.glob(".parts-*.partial"))
    assert left  # what the next run is to clean
    mine = out / ".parts-mine.partial"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine", encoding="utf-8")
    config = _config(tmp_path, **{**SPHERE, "report": False, "duration": 2.0})
    _run(config, out)
    assert sorted(p.name for p in out.glob(".parts-*")) == [mine.name]
    assert (mine / "notes.txt").read_text(encoding="utf-8") == "mine"
    assert (out / "run.json").is_file()


def _exit_at_once():
    pass


def test_stopping_a_worker_that_has_just_exited_is_not_an_error():
    """Under load the pool's own shutdown can stop a worker between ``is_alive()`` and the
    signal (seen at load 30: the run said "No such process" instead of its line)."""
    import multiprocessing

    from leolink.app.sweep_exec import _stop_workers

    proc = multiprocessing.get_context("fork").Process(target=_exit_at_once)
    proc.start()
    proc.join()  # gone and reaped: its pid names no process
    proc.is_alive = lambda: True  # as it was when asked, an instant before it exited
    _stop_workers([proc])  # no ProcessLookupError
    assert proc.exitcode == 0
