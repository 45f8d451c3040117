"""benchmarks/run_all.py runs every benchmark it names, and names every benchmark.

``run_all.py`` skips a listed name that is not a file, with a note: that is how the peer
comparison dropped out of it unseen (listed as ``bench_opensatcom``, the file being
``bench_peer.py``, until 2026-12-02).
"""

import importlib.util
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _run_all():
    spec = importlib.util.spec_from_file_location("run_all", BENCHMARKS / "run_all.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_listed_benchmark_is_a_file_and_every_file_is_listed():
    run_all = _run_all()
    files = {p.stem for p in BENCHMARKS.glob("bench_*.py")}
    assert set(run_all.MODULES) <= files, set(run_all.MODULES) - files
    assert files == set(run_all.MODULES) | set(run_all.RUN_ALONE)
    assert not set(run_all.MODULES) & set(run_all.RUN_ALONE)


def test_every_aim_belongs_to_a_listed_benchmark():
    run_all = _run_all()
    listed = {m.removeprefix("bench_") for m in run_all.MODULES}
    assert {name.split(".")[0] for name in run_all.AIMS} <= listed


def test_every_benchmark_is_in_the_readme_table():
    text = (BENCHMARKS / "README.md").read_text()
    for path in BENCHMARKS.glob("bench_*.py"):
        assert f"`{path.name}`" in text, path.name


def test_the_table_prints_every_figure_numbers_and_text(capsys):
    """A module may return a text figure (bench_peer's ``peer_version``): the table shows
    it instead of failing on it (as it did, after every benchmark had run)."""
    run_all = _run_all()
    flat = {"peer.peer_version": "0.7.0", "engine.ut_epochs_per_s": 4.5e6, "sim.wall_s": 9.0}
    run_all.print_table(flat, before={"sim.wall_s": 10.0})
    out = capsys.readouterr().out
    assert "0.7.0" in out and "1.50x" in out and "0.90x" in out
