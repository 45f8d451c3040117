"""``ephemeris_errors.csv`` and ``ephemeris_errors.json``: what an ephemeris error cost.

Written only by runs with an ephemeris error (``[ephemeris_error]``): their frames carry
the columns of :data:`leolink.sim.ephemeris_monitor.EPHEMERIS_COLUMNS`; an error-free run
writes nothing (its outputs are the error-free run's). Rows: every UT and epoch with a
link (served or in handover; outage rows are left out). The JSON: the wrong-beam rate
(chosen beam is not the true best beam of the chosen satellite), and percentiles of the
UT pointing error, its gain loss, the SNR loss (true best beam with ideal pointing minus
the served SNR) and the believed-minus-true satellite position.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field

from leolink.io.atomic import write_csv_atomic, write_json_atomic
from leolink.io.sinks import SINKS, SinkParams
from leolink.sim.ephemeris_monitor import EPHEMERIS_COLUMNS
from leolink.sim.handover.controller import SERVICE_OUTAGE

__all__ = ["EphemerisErrorSink", "ephemeris_summary"]

_KEYS = ("time_s", "ut_id", "sat_id", "beam_id", *EPHEMERIS_COLUMNS)
_PERCENTILES = (50, 90, 99)


def ephemeris_summary(rows):
    """Wrong-beam rate and percentiles of the losses of a table of :data:`_KEYS` rows."""
    out = {"rows": len(rows), "wrong_beam_rate": float(rows.wrong_beam.mean())}
    out["wrong_beam_epochs"] = int(rows.wrong_beam.sum())
    for name in ("pointing_error_deg", "pointing_loss_db", "snr_loss_db", "position_error_m"):
        values = rows[name].to_numpy()
        out[name] = {f"p{q}": float(np.percentile(values, q)) for q in _PERCENTILES}
        out[name]["mean"] = float(values.mean())
        out[name]["max"] = float(values.max())
    return out


class EphemerisErrorSink:
    """Collects the ephemeris columns of linked rows; writes them at the end (if any)."""

    def __init__(self, out_dir=None):
        self.out_dir = None if out_dir is None else Path(out_dir)
        self._parts, self.files = [], []

    def start(self, info):
        self._parts = []

    def epoch(self, frame):
        cols = frame.columns
        if "wrong_beam" not in cols:
            return
        keep = np.asarray(cols["service"]) != SERVICE_OUTAGE
        if keep.any():  # numpy pieces: one DataFrame at the end (pandas imported then)
            self._parts.append({k: np.asarray(cols[k])[keep] for k in _KEYS})

    block = epoch  # the rows are joined at the end

    def table(self):
        """The collected rows, a pandas.DataFrame (empty without an ephemeris error)."""
        import pandas as pd

        if not self._parts:
            return pd.DataFrame()
        return pd.DataFrame({k: np.concatenate([p[k] for p in self._parts]) for k in _KEYS})

    def finish(self, final):
        if self.out_dir is None or not self._parts:  # no error: nothing written, no pandas
            return
        rows = self.table()
        rows["true_best_beam_id"] = rows.true_best_beam_id.astype(np.int64)
        rows["wrong_beam"] = rows.wrong_beam.astype(np.int64)
        self.files = [
            write_csv_atomic(rows, self.out_dir / "ephemeris_errors.csv"),
            write_json_atomic(self.out_dir / "ephemeris_errors.json", ephemeris_summary(rows)),
        ]

    def abort(self):
        self._parts = []


class EphemerisErrorParams(SinkParams):
    enabled: bool = Field(
        True, description="write ephemeris_errors.csv / .json (runs with an ephemeris error)"
    )


SINKS.add(
    "ephemeris_errors",
    lambda p, ctx: EphemerisErrorSink(ctx.out_dir),
    config=EphemerisErrorParams,
    doc="wrong beams, pointing and SNR losses of an ephemeris error (CSV, JSON)",
)
