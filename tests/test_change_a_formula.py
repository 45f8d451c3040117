"""docs/extending.md "Change a formula": the SINR changed in its one place
(:func:`leolink.link.budget.sinr_lin`, Eq. 19) changes the paper run's trace as the new
formula says, with no other edit.

The change is a fixed interference floor ``F`` (linear, in units of the noise):
``S / (I + N + F)``. The engine forms the SINR with the signal as the SNR and the noise
as 1, so each served row must satisfy ``1 / SINR' = 1 / SINR + F / SNR``; the SNR, the
serving cells and the events stay as they were (the controller decides on the SNR).
The function's code is replaced in place, as an edit of its file would replace it; the
run takes the numpy path (the compiled loops are recompiled when a source file changes,
which a replaced code object is not: ``leolink.compiled``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

import leolink.compiled
import leolink.link.budget
from leolink.app.run import run
from leolink.config import load_config

PAPER = Path(__file__).resolve().parents[1] / "configs" / "paper.toml"
FLOOR = 1.0  # the interference floor of the changed formula, in units of the noise
# trace.parquet keeps dB values as float32 (2**-24 relative: 2e-6 dB at 30 dB, 5e-7 of a
# linear value); with F = N the floor's term is as large as 1 / SINR: no cancellation.
RTOL = 1e-5


def _floored(signal_lin, interference_lin, noise_lin):
    """``sinr_lin`` with a fixed interference floor (the edit under test)."""
    return np.float64(signal_lin) / (interference_lin + noise_lin + 1.0)


def _trace(out):
    over = ["output.plots.enabled=false", "output.report.enabled=false",
            'output.trace.formats=["parquet"]', "run.duration_s=30.0"]  # fmt: skip
    run(load_config(PAPER, over), out_dir=out)
    return pd.read_parquet(out / "trace.parquet"), pd.read_csv(out / "events.csv")


def test_an_interference_floor_in_sinr_lin_moves_the_paper_traces_sinr(tmp_path, monkeypatch):
    monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    before, events_before = _trace(tmp_path / "before")
    monkeypatch.setattr(leolink.link.budget.sinr_lin, "__code__", _floored.__code__)
    after, events_after = _trace(tmp_path / "after")

    for column in ("ut_id", "time_s", "sat_id", "beam_id", "snr_db"):
        assert before[column].equals(after[column]), column
    assert events_before.equals(events_after)
    served = np.isfinite(before["sinr_db"].to_numpy())
    assert served.sum() > 100
    old, new, snr = (before["sinr_db"].to_numpy()[served], after["sinr_db"].to_numpy()[served],
                     before["snr_db"].to_numpy()[served])  # fmt: skip
    assert (new < old).all()
    gained = 10.0 ** (-new / 10.0) - 10.0 ** (-old / 10.0)
    np.testing.assert_allclose(gained, FLOOR * 10.0 ** (-snr / 10.0), rtol=RTOL)
    # what follows from the SINR follows it: the spectral efficiency log2(1 + SINR)
    se = after["se_bps_hz"].to_numpy()[served]
    np.testing.assert_allclose(se, np.log2(1.0 + 10.0 ** (new / 10.0)), rtol=RTOL)
