"""The handover KPIs of ``summary.json`` (``overall.kpi`` and each UT's ``kpi``), streamed.

:class:`KpiAccumulator` is fed by :class:`~leolink.io.summary.accumulator.SummaryAccumulator` every
recorded epoch: it keeps the serving-change events (handovers, outages, RLFs; a few per
UT-minute) and two fixed-bin histograms, so its memory does not grow with the trace.
The definitions are those of :mod:`leolink.sim.handover.kpi` (handover rate per UT-minute,
ping-pong after TR 36.839, time of stay without censored stays); besides them:

- ``sinr_db_percentiles`` / ``throughput_bps_percentiles``: p1 ... p99 over **all**
  UT-epochs, an unserved epoch counting as SINR -inf and throughput 0 b/s (the served
  part of a handover epoch counts its throughput pro rata, as in the trace). A SINR
  percentile that falls among unserved epochs is -inf, written ``null``;
  ``unserved_fraction`` says how many there are. Resolution: 0.01 dB and 100 kb/s
  (a percentile is within half a bin of numpy's on the same samples), over -60 to 80
  dB and 0 to 10 Gb/s: a percentile among samples beyond them is -inf or +inf.
  ``sinr_db_percentiles_served``: the same over the served UT-epochs only (the link
  quality a served UT sees, without the outage).
- ``interruption_s``: UT-time without service by cause [s]: ``handover`` (execution
  times), ``rlf`` (re-establishment, whole epochs), ``outage`` (no usable candidate);
  ``interruption_per_handover_s``: the handover part per handover.
- the mobility robustness counts of TS 38.300 15.5.2.2.2 (``handover_failure_count``,
  ``too_early_count``, ``too_late_count``, ``wrong_cell_count``; window ``[kpi]
  mro_window_s``): :func:`leolink.sim.handover.kpi.mro_classes`.
"""

from __future__ import annotations

import numpy as np

from leolink.sim.handover.kpi import handover_rates, mro_classes, ping_pong_mask, summarize
from leolink.sim.histograms import PercentileHistogram

__all__ = ["KpiAccumulator"]

# (not beam_switch: a change inside one cell changes no cell of the KPIs)
_KEPT = ("beam_handover", "sat_handover", "outage_start", "outage_end", "rlf", "handover_failure")
_COLUMNS = ("time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat", "to_beam")
# The SINR histograms' (lo, hi, resolution) [dB]: one grid, so both take the same slots.
_SINR_BINS_DB = (-60.0, 80.0, 0.01)


class KpiAccumulator:
    """Serving-change events and SINR/throughput histograms of one run."""

    def __init__(self, n_ut, ping_pong_s=1.0, mro_window_s=1.0, mro_level="cell",
                 beam_switch_s=None):  # fmt: skip
        self.n_ut, self.ping_pong_s = int(n_ut), float(ping_pong_s)
        self.mro_window_s, self.mro_level = float(mro_window_s), mro_level
        self.beam_switch_s = beam_switch_s  # cells are satellites (None: beams)
        self.n_beam_switch = np.zeros(self.n_ut, np.int64)
        self._events = []
        self.sinr = PercentileHistogram(*_SINR_BINS_DB)
        self.sinr_served = PercentileHistogram(*_SINR_BINS_DB)  # served UT-epochs only
        self.throughput = PercentileHistogram(0.0, 1.0e10, 1.0e5, unserved_value=0.0)
        self.n_samples = 0
        self.n_unserved = 0

    def add_trace(self, columns):
        sinr = np.asarray(columns["sinr_db"], float)
        slots, unserved = self.sinr.slots(sinr), np.isnan(sinr)
        self.sinr.add_slots(slots)
        self.sinr_served.add_slots(slots[~unserved])
        self.throughput.add(np.asarray(columns["throughput_bps"], float))
        self.n_samples += sinr.size
        self.n_unserved += int(unserved.sum())

    def add_events(self, events):
        kind = np.asarray(events["kind"]).astype(str)
        switch = np.asarray(events["ut_id"], np.int64)[kind == "beam_switch"]
        self.n_beam_switch += np.bincount(switch, minlength=self.n_ut)
        keep = np.isin(kind, _KEPT)
        if keep.any():
            self._events.append({k: np.asarray(events[k])[keep] for k in _COLUMNS})

    def events(self):
        """The kept events as one table (dict of arrays)."""
        if not self._events:
            empty = {k: np.zeros(0, np.int64) for k in _COLUMNS}
            empty["time_s"], empty["kind"] = np.zeros(0), np.zeros(0, str)
            return empty
        return {k: np.concatenate([e[k] for e in self._events]) for k in _COLUMNS}

    def summary(self, dwells, observed_s, interruption_s):
        """``(overall, per_ut)``: the ``overall.kpi`` dict and one dict per UT.

        ``dwells``: the run's dwell table; ``observed_s`` (n_ut,) [s]: recorded time of
        each UT; ``interruption_s``: ``{"handover", "rlf", "outage"}`` totals [s].
        """
        events = self.events()
        if self.n_ut == 0 or not np.all(np.asarray(observed_s) > 0):
            return {}, [{} for _ in range(self.n_ut)]
        overall = summarize(events, dwells, observed_s, self.n_ut, self.ping_pong_s,
                            self.mro_window_s, self.mro_level)  # fmt: skip
        n_ho = int(np.isin(events["kind"], ("beam_handover", "sat_handover")).sum())
        if self.beam_switch_s is not None:
            interruption_s = self._beam_switches(overall, interruption_s, observed_s)
        overall.update(
            interruption_s=interruption_s,
            interruption_per_handover_s=interruption_s["handover"] / n_ho if n_ho else None,
            unserved_fraction=self.n_unserved / self.n_samples if self.n_samples else None,
            sinr_db_percentiles=self.sinr.summary(),
            sinr_db_percentiles_served=self.sinr_served.summary(),
            throughput_bps_percentiles=self.throughput.summary(),
        )
        rates = handover_rates(events, observed_s, self.n_ut)
        ut = np.asarray(events["ut_id"], np.int64)
        pp = np.bincount(ut[ping_pong_mask(events, self.ping_pong_s)], minlength=self.n_ut)
        rlf = np.bincount(ut[events["kind"] == "rlf"], minlength=self.n_ut)
        classes = mro_classes(events, self.mro_window_s, self.mro_level)
        mro = {f"{k}_count": np.bincount(ut[m], minlength=self.n_ut) for k, m in classes.items()}
        per_ut = [
            {
                "handover_rate_per_ut_min": float(rates["per_ut"][i]),
                "ping_pong_count": int(pp[i]),
                "rlf_count": int(rlf[i]),
                **{name: int(count[i]) for name, count in mro.items()},
            }
            for i in range(self.n_ut)  # output formatting only
        ]
        if self.beam_switch_s is not None:
            for i, row in enumerate(per_ut):  # output formatting only
                row["beam_switch_count"] = int(self.n_beam_switch[i])
        return overall, per_ut

    def _beam_switches(self, overall, interruption_s, observed_s):
        """Cells are satellites: the beam switches counted apart from the handovers, their
        interruption (``beam_switch_s`` each: exact while a switch ends within its epoch)
        taken out of the handovers'."""
        n = int(self.n_beam_switch.sum())
        switch_s = n * self.beam_switch_s
        overall.update(
            beam_switch_count=n,
            beam_switch_rate_per_ut_min=n / (np.sum(observed_s) / 60.0),
            interruption_per_beam_switch_s=self.beam_switch_s if n else None,
        )
        return {**interruption_s, "handover": max(interruption_s["handover"] - switch_s, 0.0),
                "beam_switch": switch_s}  # fmt: skip
