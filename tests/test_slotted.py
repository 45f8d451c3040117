"""The slotted policy (sim/handover/slotted.py) and the starlink_like example.

References: the grid is recomputed from the UTC start (seconds past the minute); the
rules are checked on hand-built candidate tables whose answer is read off them; the
example's handover rate is compared with the measured bound of one reassignment per 15 s
slot, <= 4 per UT-minute (Mohan et al., WWW 2024).
"""

from __future__ import annotations

from datetime import datetime

import numpy as np
import pytest

from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.errors import ConfigError
from leolink.io.sinks import MemorySink
from leolink.sim.handover.controller import ControllerState
from leolink.sim.handover.policies import POLICIES
from leolink.sim.handover.slotted import Slotted, slot_boundary
from leolink.sim.runner import run_simulation

NAN = np.nan
N_BEAM = 2  # cells 0, 1: satellite 0; 2, 3: satellite 1; 4, 5: satellite 2


def _state(serving):
    st = ControllerState.initial(len(serving))
    st.serving = np.asarray(serving, np.int64)
    return st


def _policy(rule="max_snr", epoch_s=1.0, utc_offset_s=0.0):
    return Slotted(15.0, 12.0, rule, N_BEAM, epoch_s, utc_offset_s)


@pytest.mark.parametrize(
    "epoch_s, offset_s, expected",
    [
        (1.0, 0.0, [12.0, 27.0, 42.0, 57.0, 72.0]),
        (0.7, 0.0, [12.6, 27.3, 42.0, 57.4, 72.1]),  # the first epoch at or after each
        (1.0, 5.0, [7.0, 22.0, 37.0, 52.0, 67.0]),  # time 0 is 5 s past the minute
    ],
)
def test_boundaries_are_the_first_epochs_at_or_after_the_grid(epoch_s, offset_s, expected):
    times = np.round(np.arange(0.0, 80.0, epoch_s), 9)
    got = [t for t in times if slot_boundary(t, epoch_s, 15.0, 12.0, offset_s)]
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_between_boundaries_the_satellite_is_held_and_its_best_beam_followed():
    snr = np.array([[0.0, 3.0, 20.0, 19.0, NAN, NAN]])  # satellite 1 is far better
    pol = _policy()
    assert pol.choose(13.0, snr, _state([0]))[0] == 1  # held: satellite 0, its best beam
    assert pol.choose(27.0, snr, _state([0]))[0] == 2  # a boundary: the best cell


def test_a_lost_satellite_breaks_the_hold_at_once():
    snr = np.array([[NAN, NAN, 5.0, 9.0, 7.0, NAN], [NAN, NAN, 5.0, 9.0, 7.0, NAN]])
    got = _policy().choose(13.0, snr, _state([0, -1]))  # unusable; none (after an RLF)
    np.testing.assert_array_equal(got, [3, 3])


def test_least_loaded_prefers_the_emptier_satellite_then_snr():
    # UTs 0-2 are on satellite 1, UT 3 on satellite 2: UT 4 goes to satellite 0 though
    # its SNR is the lowest; UT 5 has no cell of satellite 0 and takes satellite 2
    snr = np.array(
        [[1.0, NAN, 9.0, NAN, 5.0, NAN]] * 5 + [[NAN, NAN, 9.0, NAN, 5.0, 6.0]], dtype=float
    )
    state = _state([2, 2, 2, 4, -1, -1])
    got = _policy("least_loaded").choose(12.0, snr, state)
    assert got[4] == 0 and got[5] == 5
    assert list(got[:4]) == [0, 0, 0, 0]  # every UT sees the previous epoch's load


def test_through_slot_prefers_a_satellite_that_still_serves_at_the_next_boundary():
    now = np.array([[10.0, NAN, 6.0, NAN]])
    future = np.array([[NAN, NAN, 4.0, NAN]])  # satellite 0 sets within the slot
    pol = _policy("through_slot")
    assert pol.lookahead_s == 15.0
    assert pol.choose(12.0, now, _state([-1]), future)[0] == 2
    assert _policy("max_snr").choose(12.0, now, _state([-1]))[0] == 0


def test_slotted_is_registered_and_chooses_only_for_a_run():
    assert "slotted" in POLICIES
    bare = POLICIES.build("slotted", POLICIES["slotted"].config())  # as compare's same_as
    with pytest.raises(ValueError, match="n_beam and epoch_s"):
        bare.choose(12.0, np.zeros((1, 2)), _state([0]))


def test_a_bad_rule_is_one_clear_line():
    with pytest.raises(ConfigError, match="controller.slotted.rule"):
        load_config("starlink_like", ["controller.slotted.rule=nearest"])


STARLINK = ["run.duration_s=120"]


def _events(overrides):
    cfg = load_config("starlink_like", [*STARLINK, *overrides])
    scen = build_scenario(cfg)
    mem = MemorySink()
    run_simulation(scen, [mem])
    return mem.events(), mem.trace(), cfg


@pytest.mark.parametrize("start", ["2024-06-01T00:00:00Z", "2024-06-01T00:00:05Z"])
def test_starlink_like_hands_over_on_the_utc_grid_only(start):
    events, trace, cfg = _events([f'run.start_utc="{start}"'])
    handovers = events[events["kind"].isin(["sat_handover", "beam_handover"])]
    n_ut = trace["ut_id"].nunique()
    assert len(handovers) >= n_ut  # every UT changes satellite at least once in 2 min
    second = datetime.fromisoformat(start.replace("Z", "+00:00")).second
    past_minute = (handovers["time_s"].to_numpy() + second) % 60.0
    assert set(np.round(past_minute, 9)) <= {12.0, 27.0, 42.0, 57.0}
    assert (events["kind"] == "beam_switch").any()  # beams follow the UT inside a slot
    rate = len(handovers) / (n_ut * cfg.run.duration_s / 60.0)
    assert rate <= 4.0  # one reassignment per 15 s slot at most: the measured bound
