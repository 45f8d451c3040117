"""The UT's measurement model: when a cell is measured, in which quantity, with what error.

A stage between the candidate table and the layer-3 filter
(:func:`~leolink.sim.handover.measurements.l3_update`) of a trigger policy
(:class:`~leolink.sim.handover.trigger_run.TriggerRun`); ``[controller.measurement]``. With
its defaults (every epoch, no error, no SMTC, SNR) it is not built at all and the run is
today's, event for event.

Measurement instants. With ``period_s = P > 0`` the UT measures at the instants ``k P``
(simulation time, ``k`` integer): an epoch takes a sample when an instant ``k P`` with a
``k`` it has not sampled yet lies at or before it (so with ``epoch_s = P`` every epoch
samples, with ``epoch_s = P / 4`` every fourth). Between instants the filtered values are
held (a cell that stopped being detected still drops out at once: the NaN rule of
:mod:`~leolink.sim.handover.trigger_run`), so the layer-3 filter steps once per sample
(TS 38.331 5.5.3.2: one step per measurement result) with ``dt`` the time since the last
sample: ``P`` when the epochs fall on the multiples of ``P``, ``epoch_s`` when ``P`` is
shorter than an epoch (the sample is the epoch's value: the simulator has none between
epochs). ``P`` plays the
role of TS 38.133's L1 measurement period (9.2.5.2: max(200 ms, 5 SMTC periods) in FR1
without DRX); leolink takes it as given.

SMTC (TS 38.331 SSB-MTC; NTN: Rel-17 ``smtc4list-r17``, up to four SMTCs per carrier that
share periodicity and duration and differ by offset, one per group of satellites). A cell
of satellite ``s`` is measured at an instant ``t`` only if ``t`` lies in the window
``[o_s + j T, o_s + j T + D)`` (``T`` periodicity, ``D`` duration, ``o_s`` the satellite's
offset, ``j`` integer). Outside it the cell gives no sample: its filtered value is held
(``F_n = F_{n-1}``; a cell never measured stays NaN, so it never enters). The serving
cell is gated alike (its SSB is measured in the same windows). The window test is on
the instant, not on an interval: leolink samples the window at its measurement instants,
so ``epoch_s`` (and ``period_s``) must resolve ``T`` for the gating to mean what a UE
does (with 1 s epochs and T = 20 ms every instant has the same phase).

Error. Each sample is ``M + sigma e`` with ``e ~ N(0, 1)`` drawn from a counter-based
generator keyed by (UT key of :func:`leolink.rng.ut_keys`, global cell id, instant number):
reproducible, independent of the UT order, of how the UTs are split into parts and of
the other cells. ``sigma`` is a dB figure: TS 38.133 10.1.2 gives SS-RSRP accuracy
requirements of a few dB (intra-frequency, absolute +-4.5 dB under normal conditions, to
be read as a bound, not a sigma).

Quantity. ``snr`` is the table's SNR [dB]; ``rsrp`` is SS-RSRP per resource element
[dBm] (TS 38.215 5.1.1: the linear average of the power of the resource elements that
carry SSS), from :func:`leolink.link.budget.rsrp_dbm`. A cell's detection (the service
threshold ``controller.min_snr_db``) stays on SNR.

References
----------
.. [1] 3GPP TS 38.331, 5.5.3.2 Layer 3 filtering; 6.3.2 SSB-MTC, MeasObjectNR
   (smtc4list-r17).
.. [2] 3GPP TS 38.133, 9.2.5 (measurement period), 10.1.2 (SS-RSRP accuracy).
.. [3] 3GPP TS 38.215, 5.1.1 SS reference signal received power (SS-RSRP).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from leolink.arrays import KeyTable, nonzero_2d
from leolink.link.budget import rsrp_dbm
from leolink.link.channel_state import pair_keys
from leolink.rng import standard_normal
from leolink.sim.handover.measurements import L3State, l3_update
from leolink.sim.handover.triggers import TIME_TOL_S

__all__ = ["MeasurementModel", "MeasurementRun", "in_smtc_window"]

#: Separates the measurement errors' keys from every other use of the UT keys.
_ERROR_DOMAIN = np.uint64(0x6D656173_6572726F)  # "measerro"


def in_smtc_window(t_s, offset_s, period_s, duration_s):
    """True where ``t_s`` lies in an SMTC window ``[o + j T, o + j T + D)``.

    Parameters
    ----------
    t_s : float [s], the instant.
    offset_s : array_like [s], each satellite's offset ``o``.
    period_s, duration_s : float [s], periodicity ``T`` > 0 and duration ``D``.

    Returns
    -------
    ndarray of bool, the shape of ``offset_s``. Epoch times carry float rounding, so the
    phase is taken ``TIME_TOL_S`` late: an instant on a window's start is inside, one on
    its end outside.
    """
    phase = np.mod(t_s - np.asarray(offset_s, float) + TIME_TOL_S, period_s)
    return phase < duration_s


@dataclasses.dataclass(frozen=True)
class MeasurementModel:
    """``[controller.measurement]``, validated (see the module docstring).

    ``period_s``: measurement period ``P`` [s], 0 = every epoch; ``error_db``: sigma of
    the per-sample error [dB]; ``quantity``: "snr" or "rsrp"; ``noise_temp_dbk`` [dBK]
    and ``subcarrier_spacing_hz`` [Hz]: what RSRP needs; ``smtc_period_s``: ``T`` [s], 0 =
    no SMTC; ``smtc_duration_s``: ``D`` [s]; ``smtc_offset_s``: ``o`` of every satellite
    [s] unless ``smtc_offsets`` (``((sat_id, offset_s), ...)``) gives its own.
    """

    period_s: float = 0.0
    error_db: float = 0.0
    quantity: str = "snr"
    noise_temp_dbk: float = math.nan
    subcarrier_spacing_hz: float = 15e3
    smtc_period_s: float = 0.0
    smtc_duration_s: float = 0.0
    smtc_offset_s: float = 0.0
    smtc_offsets: tuple = ()

    @property
    def is_off(self):
        """Every epoch, no error, no SMTC, SNR: the run without the stage."""
        return (self.period_s, self.error_db, self.smtc_period_s) == (0, 0, 0) and (
            self.quantity == "snr"
        )

    @functools.cached_property
    def _offsets(self):
        return KeyTable([s for s, _ in self.smtc_offsets], [o for _, o in self.smtc_offsets])

    def offsets_s(self, sat_id):
        """Each satellite's SMTC offset [s], the shape of ``sat_id`` (a later entry for a
        satellite wins)."""
        return self._offsets.get(sat_id, self.smtc_offset_s)


class MeasurementRun:
    """The measurement stage of one run: the instant count and the last instant."""

    def __init__(self, model, n_beam):
        self.model, self.n_beam = model, int(n_beam)
        self.ut_keys = None  # (n_ut,) uint64, the UTs' keys: needed when error_db > 0
        self.last_k, self.count = None, 0

    @property
    def needs_ut_keys(self):
        return self.model.error_db > 0

    def _instant(self, t_s):
        """Whether ``t_s`` takes a sample (a new instant ``k P`` at or before it)."""
        if self.model.period_s <= 0:
            return True
        k = math.floor((t_s + TIME_TOL_S) / self.model.period_s)
        if k == self.last_k:
            return False
        self.last_k = k
        return True

    def _sample(self, raw, ut_keys, cells):
        """The quantity with its error at the given (UT, cell) pairs, flat arrays."""
        m = self.model
        value = raw
        if m.quantity == "rsrp":
            value = rsrp_dbm(raw, m.noise_temp_dbk, m.subcarrier_spacing_hz)
        if m.error_db > 0:
            keys = pair_keys(ut_keys ^ _ERROR_DOMAIN, cells[:, None]).ravel()
            value = value + m.error_db * standard_normal(keys, self.count)
        return value

    def step(self, t_s, filt, raw, usable, cells, l3):
        """One epoch: ``(filter state, filtered measurements (n_ut, n_cand))``.

        Parameters
        ----------
        t_s : float [s]
        filt : L3State, the filter carried onto this epoch's axis.
        raw : (n_ut, n_cand) [dB], the table's SNR (NaN: not in the table).
        usable : (n_ut, n_cand) bool, detected (SNR at or above the service threshold).
        cells : (n_ut, n_cand) int64, each local cell's global id (-1: unused slot).
        l3 : L3Filter
        """
        held = np.where(usable, filt.value, np.nan)  # a lost cell drops out at once
        if not self._instant(t_s):
            return L3State(held, filt.t_s), held
        m = self.model
        rows, cols = nonzero_2d(usable)  # only detected cells are measured (and drawn for)
        cell = cells[rows, cols]
        if m.smtc_period_s > 0:
            offsets = m.offsets_s(cell // self.n_beam)
            inside = in_smtc_window(t_s, offsets, m.smtc_period_s, m.smtc_duration_s)
            rows, cols, cell = rows[inside], cols[inside], cell[inside]
        keys = None
        if m.error_db > 0:
            if self.ut_keys is None:
                raise ValueError("MeasurementRun: error_db > 0 needs the UTs' keys (ut_keys)")
            keys = np.asarray(self.ut_keys, np.uint64)[rows]
        sample = np.full(raw.shape, np.nan)
        sample[rows, cols] = self._sample(raw[rows, cols], keys, cell)
        self.count += 1
        state, filtered = l3_update(filt, t_s, sample, l3)
        keep = usable & np.isnan(sample)  # outside its window: no sample, the filter holds
        filtered = np.where(keep, held, filtered)
        return L3State(filtered, state.t_s), filtered
