"""Start-up cost: the run command imports no heavy library it does not need (a 10-UT run's
wall time is mostly start-up: pandas alone is ~0.5 s, matplotlib ~0.7 s); the plot sink's
memory stays bounded in run length without losing rows."""

import json
import subprocess
import sys

HEAVY = ("pandas", "matplotlib", "scipy", "itur", "pyarrow.compute", "pyarrow.parquet")


def test_importing_the_cli_and_run_loads_no_heavy_library():
    """Importing the CLI and the run loads none; a whole run with its default files (plots
    and report off) none but pyarrow.parquet, for events.parquet, and scipy, which numba
    imports when the compiled loops first load it (its LAPACK bindings, ~20 ms of numba's
    ~0.35 s): the config (every registered kind's module: sinks, policies, terminals), the
    scenario, the epochs and every sink's end (the ephemeris-error sink imported pandas to
    find it had no rows)."""
    code = (
        "import sys, json, tempfile, leolink.cli, leolink.app.run; "
        "from leolink.config import load_config; "
        f"loaded = lambda: [m for m in {list(HEAVY)!r} if m in sys.modules]; "
        "first = loaded(); "
        "leolink.app.run.run(load_config('configs/paper.toml', ['run.duration_s=3', "
        "'output.plots.enabled=false', 'output.report.enabled=false']), tempfile.mkdtemp()); "
        "print(json.dumps([first, loaded()]))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert json.loads(done.stdout) == [[], ["scipy", "pyarrow.parquet"]]


def test_plot_sink_keeps_exactly_the_chosen_uts_rows_across_compactions(monkeypatch):
    """The plot sink merges its per-epoch tables every COMPACT_TABLES epochs (bounded
    memory); fed a real run's trace epoch by epoch, it keeps every row of the chosen UTs."""
    import leolink.io.sinks as S
    from leolink.app.run import run
    from leolink.config import load_config
    from leolink.sim.streams import EpochFrame

    res = run(load_config("configs/paper.toml", ["output.plots.enabled=false"]))
    trace, chosen = res.trace, [0, 3]
    monkeypatch.setattr(S, "COMPACT_TABLES", 7)
    sink = S.PlotSink(".", None, chosen)
    sink.start(None)
    no_events = {k: trace.ut_id.to_numpy()[:0] for k in ("ut_id",)}
    for k, (t, rows) in enumerate(trace.groupby("time_s", sort=True)):
        cols = {c: rows[c].to_numpy() for c in trace.columns}
        sink.epoch(EpochFrame(k, float(t), cols, no_events, {}))
    assert len(sink._rows) < 7
    kept = S.pa.concat_tables(sink._rows).to_pandas()
    want = trace[trace.ut_id.isin(chosen)].reset_index(drop=True)
    assert len(kept) == len(want) > 200
    assert (kept.time_s.to_numpy() == want.time_s.to_numpy()).all()
    assert (kept.snr_db.to_numpy() == want.snr_db.to_numpy()).all()
