"""Issue 45: a run of one, two or three epochs of every example ends with its pictures.

A one-epoch run of the paper's config (``--set run.duration_s=1``) ended with an internal
error drawing the report's map: every UT track was a single point, the track collection
had no segment, and matplotlib's legend failed on it. Each example config is run here for
1, 2 and 3 recorded epochs with its plots and its report on; the run must finish (exit 0,
``run.json``), record exactly that many epochs, and write every picture it promises.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from leolink.config import load_config
from reliability_helpers import cli, files_in
from test_reliability import EXAMPLES

PICTURES = ["report.html", "snr_time.png", "doppler_time.png", "handovers.png", "dwell_hist.png"]
CASES = [(c, k) for c in EXAMPLES for k in (1, 2, 3)]


@pytest.mark.parametrize(("config", "n_epochs"), CASES, ids=[f"{c.stem}-{k}" for c, k in CASES])
def test_a_run_of_one_two_or_three_epochs_draws_its_report(config, n_epochs, tmp_path, capsys):
    epoch_s = load_config(config).run.epoch_s
    sets = ["run.warmup_s=0", f"run.duration_s={n_epochs * epoch_s!r}",
            "output.plots.enabled=true", "output.report.enabled=true"]  # fmt: skip
    out = tmp_path / "o"
    code, _, err = cli(capsys, "run", config, *[a for s in sets for a in ("--set", s)],
                       "--out", out, "--quiet")  # fmt: skip
    assert (code, err) == (0, "")
    assert {"run.json", *PICTURES} <= set(files_in(out))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["run"]["n_epochs"] == n_epochs
    times = np.unique(_trace(out)["time_s"])
    expected = summary["run"]["start_s"] + np.arange(n_epochs) * epoch_s
    np.testing.assert_allclose(times, expected, rtol=0, atol=1e-9)
    page = (out / "report.html").read_text()
    assert len(re.findall(r'<img src="data:image/(?:png|gif);base64,', page)) >= 2


def _trace(out):
    """The run's trace, whichever format its config writes."""
    if (out / "trace.csv").exists():
        return pd.read_csv(out / "trace.csv", usecols=["time_s"])
    return pd.read_parquet(out / "trace.parquet", columns=["time_s"])
