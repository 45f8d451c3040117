"""The Python examples of docs/extending.md run as written (a documented example that rots
fails here), and what they print is checked against a plain max-SNR run."""

import re
import sys
import types
from pathlib import Path

import pytest

import leolink
from leolink.config import load_config
from leolink.sim.handover.policies import POLICIES

DOCS = Path(__file__).resolve().parents[1] / "docs"
PAPER = DOCS.parent / "configs" / "paper.toml"


def _blocks(name):
    return re.findall(r"```python\n(.*?)```", (DOCS / name).read_text(encoding="utf-8"), re.S)


@pytest.fixture
def my_policies(monkeypatch):
    """The first block of docs/extending.md, importable as ``my_policies`` (as the doc says)."""
    module = types.ModuleType("my_policies")
    exec(compile(_blocks("extending.md")[0], "docs/extending.md", "exec"), module.__dict__)
    monkeypatch.setitem(sys.modules, "my_policies", module)
    yield module
    POLICIES.remove("min_dwell")


def test_the_worked_policy_runs_and_hands_over_less_than_max_snr(my_policies, monkeypatch, capsys):
    monkeypatch.chdir(DOCS.parent)
    exec(compile(_blocks("extending.md")[1], "docs/extending.md", "exec"), {})
    printed = capsys.readouterr().out
    plain = leolink.run(load_config(PAPER, ["output.plots.enabled=false"]))
    stay = leolink.run(
        load_config(PAPER, ["controller.policy=min_dwell", "output.plots.enabled=false"])
    )
    assert str(stay.summary["overall"]["handovers"]) in printed
    # Every dwell of max-SNR in the paper pass is ~30 s, longer than 10 s: the same handovers.
    assert stay.summary["overall"]["handovers"] == plain.summary["overall"]["handovers"]
    short = leolink.run(
        load_config(
            PAPER,
            [
                "controller.policy=min_dwell",
                "controller.min_dwell.min_dwell_s=40",
                "output.plots.enabled=false",
            ],
        )
    )
    assert (
        short.summary["overall"]["handovers"]["handovers_total"]
        < plain.summary["overall"]["handovers"]["handovers_total"]
    )


def test_the_documented_refusal(my_policies):
    with pytest.raises(
        leolink.ConfigError, match=r"controller\.min_dwell\.min_dwell_s = -1 is not"
    ):
        load_config(PAPER, ["controller.policy=min_dwell", "controller.min_dwell.min_dwell_s=-1"])


@pytest.fixture
def my_triggers(monkeypatch):
    """The trigger block of docs/extending.md, importable as ``my_triggers``."""
    module = types.ModuleType("my_triggers")
    exec(compile(_blocks("extending.md")[2], "docs/extending.md", "exec"), module.__dict__)
    monkeypatch.setitem(sys.modules, "my_triggers", module)
    yield module
    POLICIES.remove("gated_a3")


def test_the_worked_trigger_runs_and_reduces_to_max_snr_and_to_forced_handovers(
    my_triggers, monkeypatch, capsys
):
    monkeypatch.chdir(DOCS.parent)
    exec(compile(_blocks("extending.md")[3], "docs/extending.md", "exec"), {})
    printed = float(capsys.readouterr().out)
    quiet = ["output.plots.enabled=false", "controller.filter.k=0"]
    plain = leolink.run(load_config(PAPER, quiet))
    gate_open = leolink.run(
        load_config(
            PAPER,
            [
                *quiet,
                "controller.policy=gated_a3",
                "controller.gated_a3.offset_db=0",
                "controller.gated_a3.serving_below_db=1000",
            ],
        )
    )
    assert gate_open.events.equals(plain.events) and gate_open.trace.equals(plain.trace)
    shut = leolink.run(
        load_config(
            PAPER,
            [*quiet, "controller.policy=gated_a3", "controller.gated_a3.serving_below_db=-1000"],
        )
    )
    # Never triggered: a UT changes cell only when its serving cell becomes unusable.
    ev = shut.events
    assert len(ev[ev.kind.str.endswith("handover")]) < len(plain.events)
    assert 0 < printed < plain.summary["overall"]["kpi"]["handover_rate_per_ut_min"]
