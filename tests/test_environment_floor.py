"""The candidate search's floor is lowered by the environment margin (sim/decide.py).

A trigger policy sees only the cells at or above the service threshold
(``usable_cells_only``), so the search leaves out cells whose open-country SNR is below it.
With an environment, shadowing can lift a path by several dB: a cell below the threshold
in open country may be above it after the environment, so the floor drops by the
environment's margin (``Decider.with_channel``). Checked on a real multi-satellite run
with shadowed UTs: the thresholded, pruned tables give the same trace and events, bit for
bit, as every cell of every visible satellite with every pair evaluated.
"""

import pandas as pd

from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.io.sinks import MemorySink
from leolink.sim.runner import run_simulation

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
WALKER = ROOT / "configs" / "examples" / "walker.toml"


def _run(tmp_path, exhaustive):
    text = WALKER.read_text()
    # The threshold (min_snr_db = 1 dB) in the middle of the SNRs after the environment.
    # Every UT in a shadowed environment (TR 38.811 suburban: LoS sigma up to several dB).
    text = text.replace('placement = "center"', 'placement = "center"\nenvironment = "suburban"')
    text = text.replace("count = 3", 'count = 3\nenvironment = "suburban"')
    path = tmp_path / "walker_suburban.toml"
    path.write_text(text)
    sets = ["run.duration_s=200", "controller.policy=a3", "controller.a3.offset_db=0",
            "controller.a3.hysteresis_db=0.5", "controller.min_snr_db=1",
            "output.plots.enabled=false"]  # fmt: skip
    scen = build_scenario(load_config(path, sets))
    if exhaustive:
        scen.policy.usable_cells_only = False  # no floor: every visible cell in the tables
        scen.prune = False  # every pair of the cone evaluated
    sink = MemorySink()
    run_simulation(scen, [sink])
    return sink.trace(), sink.events()


def test_shadowed_trigger_run_on_the_floored_tables_equals_every_cell(tmp_path):
    trace, events = _run(tmp_path, exhaustive=False)
    trace_ref, events_ref = _run(tmp_path, exhaustive=True)
    pd.testing.assert_frame_equal(trace, trace_ref)
    pd.testing.assert_frame_equal(events, events_ref)
    # The threshold (1 dB) sits in the middle of the shadowed SNRs: handovers and outages.
    assert events.kind.isin(["beam_handover", "sat_handover"]).sum() >= 5
    assert (events.kind == "outage_end").sum() >= 5
