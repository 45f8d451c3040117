"""The candidate search prunes on each path's SNR after its environment loss.

A trigger policy sees only the cells at or above the service threshold
(``usable_cells_only``), so the search leaves out cells below it; a policy with a window
(``max_snr``: the best cell only) leaves out the cells further below the best. With an
environment, shadowing can lift a path by several dB and clutter can sink the best one:
the search draws every path's loss of the block before it prunes (``Decider._open``) and
bounds each pair's SNR after its own loss, so the floor and the window apply to the SNRs
the controller decides on. Checked on real multi-satellite runs with shadowed UTs: the
pruned tables with the floor and the window give the same trace and events, bit for bit,
as every cell of every visible satellite with every pair evaluated; with UTs on the move,
other environments and masks other than the config's too.
"""

import numpy as np
import pandas as pd
import pytest

from leolink.app.scenario import build_scenario
from leolink.config import load_config
from pruning_helpers import trace_and_events

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
WALKER = ROOT / "configs" / "examples" / "walker.toml"


def _run(tmp_path, policy_sets, exhaustive, environment="suburban", moving=False):
    text = WALKER.read_text()
    # Every UT in a shadowed environment (TR 38.811 suburban: LoS sigma up to several dB).
    env = f'\nenvironment = "{environment}"'
    text = text.replace('placement = "center"', 'placement = "center"' + env)
    text = text.replace("count = 3", "count = 3" + env)
    if moving:  # the grid's three UTs by train, each on its own heading
        text = text.replace(
            'kind = "static"\nplacement = "grid"',
            'kind = "constant_velocity"\n'
            'placement = "grid"\nspeed = "train"\nheading_deg = "random"',
        )
    path = tmp_path / "walker_suburban.toml"
    path.write_text(text)
    # The threshold (min_snr_db = 1 dB) in the middle of the SNRs after the environment.
    sets = ["run.duration_s=100", "controller.min_snr_db=1", "output.plots.enabled=false"]
    return trace_and_events(build_scenario(load_config(path, sets + policy_sets)), exhaustive)


@pytest.mark.parametrize(
    "policy_sets",
    [
        ["controller.policy=a3", "controller.a3.offset_db=0", "controller.a3.hysteresis_db=0.5"],
        ["controller.policy=max_snr"],
    ],
    ids=["a3_floor", "max_snr_window"],
)
def test_shadowed_runs_on_the_pruned_tables_equal_every_cell(tmp_path, policy_sets):
    trace, events = _run(tmp_path, policy_sets, exhaustive=False)
    trace_ref, events_ref = _run(tmp_path, policy_sets, exhaustive=True)
    pd.testing.assert_frame_equal(trace, trace_ref)
    pd.testing.assert_frame_equal(events, events_ref)
    # The threshold sits in the middle of the shadowed SNRs: handovers and outages.
    assert events.kind.isin(["beam_handover", "sat_handover"]).sum() >= 3
    assert (events.kind == "outage_end").sum() >= 5


@pytest.mark.parametrize(
    ("environment", "policy_sets"),
    [
        (
            "urban",
            [
                "controller.policy=a3",
                "controller.a3.hysteresis_db=1.0",
                "constellation.min_elevation_deg=15",
            ],
        ),
        ("dense_urban", ["controller.policy=hysteresis", "constellation.min_elevation_deg=20"]),
    ],  # fmt: skip
    ids=["urban_a3_mask15", "dense_urban_hysteresis_mask20"],
)
def test_moving_uts_in_other_environments_and_masks_equal_every_cell(
    tmp_path, environment, policy_sets
):
    trace, events = _run(tmp_path, policy_sets, False, environment, moving=True)
    trace_ref, events_ref = _run(tmp_path, policy_sets, True, environment, moving=True)
    pd.testing.assert_frame_equal(trace, trace_ref)
    pd.testing.assert_frame_equal(events, events_ref)
    assert events.kind.isin(["beam_handover", "sat_handover"]).sum() >= 3
    assert (trace.los == 0.0).any() and (trace.los == 1.0).any()  # blocked and clear paths


def test_the_lookahead_table_carries_the_environment_loss(tmp_path, monkeypatch):
    # The predictive policy's table at t + lookahead keeps each path's environment loss
    # (persisting). Over a 1 ms lookahead nothing moves, so each cell's SNR then equals its
    # SNR now after the environment (1e-3 dB: 1 ms of motion in a main lobe), not its
    # open-country SNR (clutter and shadowing: dB apart). The tables are those the
    # controller receives.
    import leolink.sim.decide as decide

    seen, real_step = [], decide.step

    def spy(t, table, state, policy, *args):
        seen.append((table.snr_db.copy(), args[3].snr_db.copy()))  # now, future
        return real_step(t, table, state, policy, *args)

    monkeypatch.setattr(decide, "step", spy)
    pred = ["controller.policy=predictive", "controller.predictive.lookahead_s=0.001",
            "run.duration_s=20"]  # fmt: skip
    trace, _ = _run(tmp_path, pred, exhaustive=False)
    now = np.concatenate([a.ravel() for a, _ in seen])
    future = np.concatenate([b.ravel() for _, b in seen])
    # Cells within 11 dB of the 1 dB threshold (main lobes; in the side lobes' nulls 1 ms
    # of motion alone moves the SNR by 0.1 dB).
    both = np.isfinite(now) & np.isfinite(future) & (now > -10.0)
    # (predictive keeps only cells above the service threshold: ~50 such cells here)
    assert both.sum() > 30
    np.testing.assert_allclose(future[both], now[both], atol=1e-3)
    # The environment does move the SNRs here: clutter or shadowing of several dB.
    assert (trace.clutter_db.abs() + trace.shadow_db.abs()).max() > 2.0
