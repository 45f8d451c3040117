"""KPIs by latitude band (``summary.json``: ``overall.by_latitude``), streamed.

Every UT-epoch counts in the band of its latitude at that epoch (bands of
:data:`BAND_DEG` from -90 deg, a latitude on an edge in the band above it, 90 deg in the
last). Per band, from counts and sums that do not grow with the run:

- ``n_ut_epochs`` and ``ut_minutes`` (UT-epochs x ``epoch_s`` / 60);
- ``handover_rate_per_ut_min``: beam and satellite handovers of UTs while in the band /
  its UT-minutes (:func:`leolink.sim.handover.kpi.handover_rates` with the band in place
  of the UT); an event counts in the band of its UT at the event's epoch;
- ``outage_fraction``: UT-epochs with ``service == outage`` / UT-epochs;
- ``sinr_mean_db``: mean of the finite ``sinr_db`` values (a mean of dB values, as each
  UT's ``sinr_db.mean``), None where there are none.

Bands without a UT-epoch are left out.
"""

from __future__ import annotations

import numpy as np

from leolink.io.summary.stats import running_sum
from leolink.sim.handover.kpi import HANDOVER_KINDS, handover_rates

__all__ = ["BAND_DEG", "LatitudeBands", "band_of"]

#: Width of a latitude band [deg].
BAND_DEG = 10.0
_N_BAND = int(round(180.0 / BAND_DEG))
#: An event's epoch matches a row's within this [s] (both from the same epoch times).
_TIME_TOL_S = 1e-6


def band_of(lat_deg):
    """Band index of each latitude (0: [-90, -80), ..., the last includes 90 deg)."""
    lat = np.asarray(lat_deg, float)
    return np.clip(np.floor((lat + 90.0) / BAND_DEG), 0, _N_BAND - 1).astype(np.int64)


class LatitudeBands:
    """Counts and sums by latitude band of the rows and events of a run.

    Parameters
    ----------
    n_ut : int
    epoch_s : float
        Duration of a UT-epoch [s].
    """

    def __init__(self, n_ut, epoch_s):
        self.epoch_s = float(epoch_s)
        self.n_epochs = np.zeros(_N_BAND, np.int64)
        self.n_outage = np.zeros(_N_BAND, np.int64)
        self.n_handover = np.zeros(_N_BAND, np.int64)
        self.sinr_sum, self.sinr_count = np.zeros(_N_BAND), np.zeros(_N_BAND, np.int64)
        self._last = np.full(n_ut, -1, np.int64)  # each UT's band at its latest row
        self._frame = None  # (times, band per (time, UT)) of the latest rows

    def note_rows(self, time_s, ut, lat_deg):
        """Remember the band of each UT at each of these rows' epochs (the events of the
        same frame are looked up there); returns the rows' bands."""
        band = band_of(lat_deg)
        t = np.asarray(time_s, float).reshape(-1)
        if t.size and np.all(t[1:] >= t[:-1]):  # a block's rows, epoch after epoch: no sort
            first = np.r_[True, t[1:] != t[:-1]]
            times, k = t[first], np.cumsum(first) - 1
        else:
            times, k = np.unique(t, return_inverse=True)
        at = np.full((times.size, self._last.size), -1, np.int8)  # bands < 127
        at[k.reshape(-1), ut] = band
        self._frame = (times, at)
        self._last[ut] = band  # in row order: the latest row of a UT wins
        return band

    def fold(self, band, service_outage, sinr_db):
        """Add rows: their bands, whether each is in outage, their SINR [dB]."""
        self.n_epochs += np.bincount(band, minlength=_N_BAND)
        self.n_outage += np.bincount(band[service_outage], minlength=_N_BAND)
        ok = np.isfinite(sinr_db)
        # added one by one in row order: the same sum however the rows come in chunks
        self.sinr_sum[:] = running_sum(self.sinr_sum, band[ok], sinr_db[ok])
        self.sinr_count += np.bincount(band[ok], minlength=_N_BAND)

    def add_events(self, time_s, ut, kind):
        """Count the handovers among events, each in its UT's band at its epoch (the
        latest row of the UT where the epoch is not among the latest rows; none for a UT
        without rows)."""
        ho = np.isin(np.asarray(kind).astype(str), HANDOVER_KINDS)
        if not ho.any():
            return
        t, u = np.asarray(time_s, float)[ho], np.asarray(ut, np.int64)[ho]
        band = self._last[u]
        if self._frame is not None:
            times, at = self._frame
            # the first frame time not below t - tol: a time just above t matches too
            k = np.clip(np.searchsorted(times, t - _TIME_TOL_S), 0, times.size - 1)
            hit = np.isclose(times[k], t, rtol=0.0, atol=_TIME_TOL_S)
            found = np.where(hit, at[k, u], -1)
            band = np.where(found >= 0, found, band)
        self.n_handover += np.bincount(band[band >= 0], minlength=_N_BAND)

    def summary(self):
        """The ``by_latitude`` list: one dict per band with UT-epochs (module docstring)."""
        seen = np.flatnonzero(self.n_epochs > 0)
        if seen.size == 0:
            return []
        observed_s = self.n_epochs[seen] * self.epoch_s
        events = {"ut_id": np.repeat(np.arange(seen.size), self.n_handover[seen]),
                  "kind": np.full(int(self.n_handover[seen].sum()), HANDOVER_KINDS[0])}  # fmt: skip
        rates = handover_rates(events, observed_s, seen.size, kinds=HANDOVER_KINDS[:1])
        with np.errstate(invalid="ignore", divide="ignore"):
            sinr = self.sinr_sum[seen] / self.sinr_count[seen]
            outage = self.n_outage[seen] / self.n_epochs[seen]
        return [
            {
                "lat_min_deg": -90.0 + b * BAND_DEG,
                "lat_max_deg": -90.0 + (b + 1) * BAND_DEG,
                "n_ut_epochs": int(self.n_epochs[b]),
                "ut_minutes": float(observed_s[i] / 60.0),
                "n_handovers": int(self.n_handover[b]),
                "handover_rate_per_ut_min": float(rates["per_ut"][i]),
                "outage_fraction": float(outage[i]),
                "sinr_mean_db": float(sinr[i]) if self.sinr_count[b] else None,
            }
            for i, b in enumerate(seen)  # output formatting only: at most 18 bands
        ]
