"""The Python examples of docs/extending.md run as written (a documented example that rots
fails here), and what they print is checked against a plain max-SNR run."""

import re
import sys
import types
from pathlib import Path

import pytest

import leolink
from leolink.config import load_config
from leolink.sim.policies import POLICIES

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
