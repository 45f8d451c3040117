"""Config tables of the handover policies: defaults build, values reach the events,
mistakes are refused with the key."""

import math

import pytest
from pydantic import ValidationError

from leolink.sim.handover.config import (
    POLICY_CONFIGS,
    A3Config,
    ChoConfig,
    ElevationConfig,
    FilterConfig,
    KpiConfig,
    RlfConfig,
    TimeToExitConfig,
    build_filter,
    build_policy,
    build_rlf,
)
from leolink.sim.handover.decisions import ConditionalHandover, TriggerPolicy
from leolink.sim.handover.triggers import A3, A4
from leolink.sim.handover.triggers_ntn import T1, Elevation, TimeToExit


@pytest.mark.parametrize("name", sorted(POLICY_CONFIGS))
def test_every_policy_builds_from_its_defaults(name):
    policy = build_policy(POLICY_CONFIGS[name]())
    assert isinstance(policy, ConditionalHandover if name == "cho" else TriggerPolicy)
    assert policy.level in ("cell", "satellite")


def test_values_reach_the_event():
    policy = build_policy(A3Config(offset_db=2.5, hysteresis_db=1.0, time_to_trigger_s=0.32))
    assert policy.trigger == A3(2.5, 1.0, 0.32) and policy.level == "cell"
    policy = build_policy(A3Config(level="satellite"))
    assert policy.level == "satellite"


def test_degrees_stop_at_the_config_edge():
    trig = build_policy(ElevationConfig(serving_below_deg=20.0, candidate_above_deg=35.0)).trigger
    assert trig == Elevation(math.radians(20.0), math.radians(35.0), 0.0, 0.0)


def test_time_to_exit_without_a_serving_threshold_is_unbounded():
    assert build_policy(TimeToExitConfig()).trigger.serving_below_s == math.inf
    assert build_policy(TimeToExitConfig(serving_below_s=30.0)).trigger == TimeToExit(
        0.0, 0.0, 0.0, 30.0
    )


def test_cho_tables_nest_their_conditions():
    cfg = ChoConfig.model_validate(
        {
            "prepare": {"kind": "a4", "threshold_db": -100.0},
            "execute": [{"kind": "a3", "offset_db": 3.0}, {"kind": "t1", "duration_s": 5.0}],
            "max_prepared": 4,
        }
    )
    cho = build_policy(cfg)
    assert cho.prepare == A4(-100.0) and cho.execute == (A3(3.0), T1(5.0))
    assert cho.max_prepared == 4


@pytest.mark.parametrize(
    "model, data, loc",
    [
        (A3Config, {"hysteresis_db": -1.0}, "hysteresis_db"),
        (A3Config, {"time_to_trigger": 0.1}, "time_to_trigger"),  # misspelt key
        (A3Config, {"offset_db": math.nan}, "offset_db"),
        (ChoConfig, {"execute": []}, "execute"),
        (ChoConfig, {"prepare": {"kind": "a9"}}, "prepare"),
        (FilterConfig, {"k": 10}, "k"),  # not a FilterCoefficient value
        (RlfConfig, {"n310": 0}, "n310"),
        (KpiConfig, {"ping_pong_s": 0.0}, "ping_pong_s"),
    ],
)
def test_mistakes_are_refused_naming_the_key(model, data, loc):
    with pytest.raises(ValidationError) as err:
        model.model_validate(data)
    assert loc in str(err.value.errors()[0]["loc"])


def test_filter_and_rlf_tables_build_their_parameters():
    assert build_filter(FilterConfig(k=8, reference_period_s=0.1)).k == 8
    assert build_rlf(RlfConfig(t310_s=2.0)) is None  # off unless enabled
    p = build_rlf(RlfConfig(enabled=True, t310_s=2.0, n310=6, n311=2))
    assert (p.t310_s, p.n310, p.n311, p.q_out_db, p.q_in_db) == (2.0, 6, 2, -8.0, -6.0)


@pytest.mark.parametrize(
    "release, kinds",
    [(18, ["t1"]), (18, ["d2"]), (17, ["t1", "a4"]), (17, ["a3", "d1"]), (17, ["a3"])],
)
def test_cho_execution_rule_admits_what_each_release_allows(release, kinds):
    cfg = ChoConfig.model_validate({"release": release, "execute": [{"kind": k} for k in kinds]})
    assert [t.kind for t in cfg.execute] == kinds
