"""``[cells] per``: a cell is a beam (default) or a satellite, whose beam changes are
``beam_switch`` events (leolink.sim.handover.cells), counted apart from the handovers."""

import numpy as np
import pandas as pd
import pytest

import leolink
from leolink.config import load_config
from leolink.errors import ConfigError

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
WALKER = ROOT / "configs" / "examples" / "walker.toml"
BASE = ["output.plots.enabled=false", "run.duration_s=200"]


def _run(sets):
    return leolink.run(load_config(WALKER, BASE + sets))


def _relabelled(events):
    """Events with the beam handovers named as beam switches."""
    return events.assign(kind=events.kind.replace({"beam_handover": "beam_switch"}))


@pytest.mark.parametrize(
    "policy, level",
    [("max_snr", []), ("a3", ["controller.a3.level=satellite", "controller.filter.k=0"])],
)
def test_satellite_cells_change_the_names_of_beam_changes_not_the_choices(policy, level):
    """max_snr picks the same beams; a3 on satellites picks as a3 at satellite level with
    beam cells. Without interruption the traces are equal and only the kinds differ."""
    beams = _run([f"controller.policy={policy}", *level])
    sats = _run([f"controller.policy={policy}", "cells.per=satellite",
                 *(x for x in level if "level" not in x)])  # fmt: skip
    pd.testing.assert_frame_equal(sats.trace, beams.trace)
    pd.testing.assert_frame_equal(sats.events, _relabelled(beams.events))
    ob, os_ = beams.summary["overall"], sats.summary["overall"]
    assert ob["handovers"]["beam_handover"] > 0
    assert os_["handovers"]["beam_switch"] == ob["handovers"]["beam_handover"]
    assert os_["handovers"]["handovers_total"] == ob["handovers"]["sat_handover"]
    assert os_["kpi"]["beam_switch_count"] == ob["handovers"]["beam_handover"]
    assert os_["kpi"]["handover_rate_per_ut_min"] < ob["kpi"]["handover_rate_per_ut_min"]


def test_a_beam_switch_interrupts_for_its_own_time_and_no_handover_procedure():
    sets = ["cells.per=satellite", "cells.beam_switch_s=0.005", "controller.rlf.enabled=true",
            "controller.rlf.q_out_db=-30", "controller.rlf.q_in_db=-28",
            "controller.signalling.enabled=true"]  # fmt: skip
    res = _run(sets)
    ev, tr = res.events, res.trace.set_index(["time_s", "ut_id"])
    switch = ev[ev.kind == "beam_switch"]
    assert len(switch) > 5
    rows = tr.loc[list(zip(switch.time_s, switch.ut_id, strict=True))]
    np.testing.assert_allclose(rows.interruption_s, 0.005, atol=1e-9)
    # the procedure runs for satellite handovers only
    assert (ev.kind == "measurement_report").sum() == (ev.kind == "sat_handover").sum() > 0
    kpi = res.summary["overall"]["kpi"]
    assert kpi["interruption_s"]["beam_switch"] == pytest.approx(len(switch) * 0.005)
    ho = tr.loc[list(zip(*(ev[ev.kind == "sat_handover"][c] for c in ("time_s", "ut_id")),
                         strict=True))]  # fmt: skip
    assert kpi["interruption_per_handover_s"] == pytest.approx(ho.interruption_s.mean(), abs=1e-9)


def test_a_cell_level_policy_is_refused_when_cells_are_satellites():
    with pytest.raises(ConfigError, match="controller.a3.level = 'cell' is not allowed with "
                       "cells.per = 'satellite'"):  # fmt: skip
        load_config(WALKER, ["controller.policy=a3", "cells.per=satellite",
                             "controller.a3.level=cell"])  # fmt: skip
