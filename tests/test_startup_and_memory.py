"""Start-up cost: the run command imports no heavy library it does not need (a 10-UT run's
wall time is mostly start-up: pandas alone is ~0.5 s, matplotlib ~0.7 s); the plot sink's
memory stays bounded in run length without losing rows."""

import json
import os
import subprocess
import sys

HEAVY = ("pandas", "matplotlib", "scipy", "itur", "pyarrow.compute", "pyarrow.parquet")


def test_importing_the_cli_and_run_loads_no_heavy_library():
    """Importing the CLI and the run loads none; a whole run with its default files (plots
    and report off) none but pyarrow.parquet, for events.parquet: the config (every
    registered kind's module: sinks, policies, terminals), the scenario, the epochs and
    every sink's end (the ephemeris-error sink imported pandas to find it had no rows)."""
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
    assert json.loads(done.stdout) == [[], ["pyarrow.parquet"]]


def test_a_run_too_small_to_repay_numbas_start_never_imports_numba():
    """20 UTs x 120 epochs, one satellite: each block's engine calls cover more than
    JIT_MIN_PAIRS pairs, the run far fewer than MIN_RUN_PAIRS, so numba's start (0.8-0.9
    s, more than the whole run) is not paid (a fresh process, as the leolink command)."""
    import numpy as np

    from leolink.engine import jit
    from leolink.sim.motion import MotionBlocks

    sets = ["run.duration_s=120", "run.epoch_s=1.0", "population.1.count=17",
            'population.1.placement="random"', "population.1.x_m=[]", "population.1.y_m=[]",
            "output.plots.enabled=false", "output.report.enabled=false"]  # fmt: skip
    code = (
        "import sys, json, tempfile, leolink.app.run; "
        "from leolink.config import load_config; "
        f"res = leolink.app.run.run(load_config('configs/paper.toml', {sets!r}), "
        "tempfile.mkdtemp()); "
        "print(json.dumps([len(res.trace), 'numba' in sys.modules]))"
    )
    env = {k: v for k, v in os.environ.items() if k != "LEOLINK_JIT"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, env=env)  # fmt: skip
    assert json.loads(done.stdout) == [20 * 120, False]
    n_block = MotionBlocks(None, [], np.arange(120.0), 1, 20).n_block
    assert 20 * min(n_block, 120) >= jit.JIT_MIN_PAIRS > 0  # (the premise: large calls)
    assert 20 * 120 < jit.MIN_RUN_PAIRS


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
