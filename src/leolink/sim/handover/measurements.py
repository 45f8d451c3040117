"""Layer-3 filtering of measurements (TS 38.331 5.5.3.2), vectorized over (UT, candidate).

    F_n = (1 - a) F_{n-1} + a M_n,        a = 1 / 2**(k / 4),

with ``F_0 = M_1`` (the first sample initializes the filter) and ``k`` the
``filterCoefficient`` (FilterCoefficient ::= fc0, fc1, ..., fc4 (default), ..., fc19).

Sample rate. The coefficient ``k`` assumes one sample per reference period ``X``: in NR
one intra-frequency L1 measurement period of TS 38.133 (non-DRX), which depends on the
frequency range and the SSB configuration; in LTE (TS 36.331 5.5.3.2) 200 ms. 38.331 asks
the UE to "adapt the filter such that the time characteristics of the filter are
preserved at different input rates". leolink samples once per simulator epoch ``dt``
and uses the coefficient that keeps the memory per unit time:

    a_eff = 1 - (1 - a)**(dt / X),

so ``dt = X`` gives ``a`` and two epochs of ``X / 2`` weigh the past exactly as one of
``X`` does (``reference_period_s`` is ``X``; 0.2 s by default, as in LTE; set it from
TS 38.133 for the configured SSB periodicity).

Domain. The filter runs on the values it is given, in dB/dBm: 38.331 filters in the
domain used to evaluate the reporting criteria (logarithmic for RSRP/RSRQ/SINR).

Unmeasurable cells. A NaN sample resets that (UT, candidate) filter: the output is NaN
and the next finite sample initializes it afresh, as for a newly detected cell (a
leolink decision; the standard does not say what a UE keeps for a cell it lost).

References
----------
.. [1] 3GPP TS 38.331, "NR; Radio Resource Control (RRC); Protocol specification",
   5.5.3.2 Layer 3 filtering; 6.3.2 FilterCoefficient.
.. [2] 3GPP TS 36.331, "E-UTRA; RRC; Protocol specification", 5.5.3.2 (200 ms).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from leolink.errors import ConfigError, require_at_least

#: FilterCoefficient values of TS 38.331 6.3.2 (fc0 ... fc19); fc4 is the default.
FILTER_COEFFICIENTS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 13, 15, 17, 19)
DEFAULT_FILTER_COEFFICIENT = 4
#: The LTE reference sample period of the filter coefficient (TS 36.331 5.5.3.2) [s].
LTE_REFERENCE_PERIOD_S = 0.2


def filter_weight(k, dt_s=None, reference_period_s=LTE_REFERENCE_PERIOD_S):
    """Weight ``a`` of the newest sample (TS 38.331 5.5.3.2), adapted to the sample rate.

    Parameters
    ----------
    k : float
        filterCoefficient (0 disables filtering: ``a = 1``).
    dt_s : float or None
        Time since the previous sample [s]; None means one reference period.
    reference_period_s : float
        The sample period ``X`` that ``k`` assumes [s].

    Returns
    -------
    float
        ``1 / 2**(k / 4)`` for ``dt = X``; ``1 - (1 - a)**(dt / X)`` otherwise.
    """
    a = 2.0 ** (-float(k) / 4.0)
    if dt_s is None:
        return a
    # expm1/log1p: exact where a is close to 1 (small k) and dt/X is small.
    return -math.expm1((dt_s / reference_period_s) * math.log1p(-a)) if a < 1.0 else 1.0


@dataclasses.dataclass(frozen=True)
class L3Filter:
    """Parameters of the layer-3 filter.

    ``k``: filterCoefficient (any value >= 0; the standard allows FILTER_COEFFICIENTS);
    ``reference_period_s``: the sample period ``X`` that ``k`` assumes [s].
    """

    k: float = DEFAULT_FILTER_COEFFICIENT
    reference_period_s: float = LTE_REFERENCE_PERIOD_S

    def __post_init__(self):
        require_at_least("controller.filter.k", self.k, 0.0, "filterCoefficient")
        if not (self.reference_period_s > 0 and math.isfinite(self.reference_period_s)):
            raise ConfigError(
                f"controller.filter.reference_period_s = {self.reference_period_s!r} is not "
                "allowed; use a finite value > 0 [s] (one L1 measurement period)"
            )


@dataclasses.dataclass(frozen=True)
class L3State:
    """Filter state: ``value`` (n_ut, n_cand) = F_{n-1} (NaN: no sample yet or reset);
    ``t_s``: time of the previous update [s] (NaN before the first)."""

    value: np.ndarray
    t_s: float

    @classmethod
    def initial(cls, n_ut, n_cand):
        return cls(np.full((n_ut, n_cand), np.nan), math.nan)


def l3_update(state, t_s, sample, params):
    """Filter the samples of epoch ``t_s``; returns ``(state, filtered)``.

    Parameters
    ----------
    state : L3State
    t_s : float
        Epoch time [s], later than ``state.t_s``.
    sample : ndarray, shape (n_ut, n_cand)
        Physical-layer measurement M_n [dB or dBm]; NaN = not measured.
    params : L3Filter

    Returns
    -------
    (L3State, ndarray (n_ut, n_cand))
        The new state and F_n (equal to the state's value).
    """
    sample = np.asarray(sample, float)
    if math.isnan(state.t_s):
        filtered = sample.copy()  # F_0 = M_1: the first sample initializes the filter
    else:
        dt_s = t_s - state.t_s
        if not dt_s > 0:
            raise ValueError(f"l3_update: epoch t_s = {t_s} is not after the last one {state.t_s}")
        a = filter_weight(params.k, dt_s, params.reference_period_s)
        fresh = np.isnan(state.value)
        filtered = np.where(fresh, sample, (1.0 - a) * state.value + a * sample)
    return L3State(filtered, float(t_s)), filtered
