"""The trigger policies evaluate only the cells at or above the service threshold.

Their decisions do not depend on cells below it (sim/handover/trigger_run.py: such a cell is not
detected, its filter restarts), so the candidate search leaves those cells out
(``usable_cells_only``, sim/candidates/search.py). Checked here on real runs: the same policy on the
exhaustive tables (every cell of every visible satellite, every pair evaluated) gives the
same trace and events, bit for bit.
"""

import pandas as pd
import pytest

from leolink.app.scenario import build_scenario
from leolink.config import load_config, updated
from pruning_helpers import trace_and_events

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
WALKER = ROOT / "configs" / "examples" / "walker.toml"


def _run(sets, exhaustive):
    scen = build_scenario(load_config(WALKER, ["run.duration_s=300", *sets]))
    return trace_and_events(scen, exhaustive)


@pytest.mark.parametrize(
    "sets",
    [
        ["controller.policy=a3", "controller.a3.hysteresis_db=1", "controller.a3.offset_db=1"],
        ["controller.policy=a5", "controller.filter.k=8"],
        ["controller.policy=d1"],
        ["controller.policy=t1"],
        ["controller.policy=cho"],
        ["controller.policy=time_to_exit", "controller.rlf.enabled=true"],
    ],
    ids=lambda s: s[0].split("=")[1],
)
def test_trigger_policies_on_the_thresholded_tables_choose_as_on_every_cell(sets):
    trace, events = _run(sets, exhaustive=False)
    trace_ref, events_ref = _run(sets, exhaustive=True)
    assert events.kind.isin(["beam_handover", "sat_handover"]).sum() > 10
    pd.testing.assert_frame_equal(trace, trace_ref)
    pd.testing.assert_frame_equal(events, events_ref)


def test_a3_at_zero_on_the_thresholded_tables_serves_the_brute_force_best():
    """The thresholded tables against an independent reference, not only against the
    exhaustive ones: A3 with no offset, hysteresis, time to trigger or L3 filter (TS 38.331
    5.5.4.4, every parameter 0) enters whenever a cell beats the serving one, so on the
    pruned tables the serving (satellite, beam) is the best one found by brute force from an
    orbit, gains and budget computed another way (tests/independent.py), and a UT is in
    outage exactly where no cell reaches the threshold. The threshold, 0 dB, lies among the
    best SNRs of this run (-0.9 .. 0.6 dB from its 1st percentile to its median), so a
    floor placed above it takes cells the brute force serves."""
    import test_trace_independent as ti

    base = ti.SCENARIOS["walker_rotating"]()
    a3_at_zero = ["controller.policy=a3", "controller.filter.k=0", "controller.min_snr_db=0"]
    cfg = updated(base, a3_at_zero)
    trace, events = trace_and_events(build_scenario(cfg), exhaustive=False)
    served = trace.service == "served"
    assert 0.05 < (trace.service == "outage").mean() < 0.5 and served.sum() > 500
    assert events.kind.isin(["beam_handover", "sat_handover"]).sum() > 10
    ti.check_serving_is_the_best(cfg, trace, ti.Recomputed(cfg, trace))


def test_predictive_on_the_thresholded_tables_chooses_as_on_every_cell():
    # Predictive declares usable_cells_only too: a cell below the threshold now scores NaN
    # (the controller masks it), whatever its SNR at t + lookahead. A -3 dB threshold lies
    # among the cells a UT of this run sees (a floor 3 dB higher changes its trace).
    sets = ["controller.policy=predictive", "controller.predictive.lookahead_s=30",
            "controller.min_snr_db=-3"]  # fmt: skip
    trace, events = _run(sets, exhaustive=False)
    trace_ref, events_ref = _run(sets, exhaustive=True)
    assert events.kind.isin(["beam_handover", "sat_handover"]).sum() > 10
    pd.testing.assert_frame_equal(trace, trace_ref)
    pd.testing.assert_frame_equal(events, events_ref)


@pytest.mark.parametrize("level", ["satellite", "cell"])
def test_t1_looking_ahead_the_serving_satellite_alone_chooses_as_looking_ahead_every_one(
    level, monkeypatch
):
    # T1 reads the end of service at the serving candidate only (Thresh1), so the run looks
    # ahead the serving satellite alone (trigger_run._serving_only); the reference looks
    # ahead every usable satellite, as for time_to_exit. A 2 s lead and a 3 s duration put
    # the T1 window inside the passes of this run.
    from leolink.sim.handover import trigger_run

    sets = ["controller.policy=t1", "controller.t1.lead_s=2.0", "controller.t1.duration_s=3.0",
            f"controller.t1.level={level!r}", "run.duration_s=600",
            "population.1.count=8"]  # fmt: skip
    assert trigger_run._serving_only(
        build_scenario(load_config(WALKER, sets)).policy.inner, "service_end_s"
    )
    trace, events = _run(sets, exhaustive=False)
    monkeypatch.setattr(trigger_run, "_serving_only", lambda policy, field: False)
    trace_ref, events_ref = _run(sets, exhaustive=False)
    assert events.kind.isin(["sat_handover"]).sum() > 10
    pd.testing.assert_frame_equal(trace, trace_ref)
    pd.testing.assert_frame_equal(events, events_ref)
