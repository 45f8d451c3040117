"""Location, time and ephemeris trigger events for NTN handover, vectorized over UTs.

D1 and D2 (TS 38.331 5.5.4.15 and 5.5.4.15a) compare distances to reference locations,
CondEvent T1 (5.5.4.16) compares the UE time with a threshold derived from the serving
cell's planned end of service; ``Elevation`` and ``TimeToExit`` are leolink events written
in the same entering/leaving form. Each class follows the
:class:`~leolink.sim.handover.triggers.Trigger` protocol and is advanced by
:func:`leolink.sim.handover.triggers.evaluate`; the bookkeeping, the NaN rule and the
:class:`~leolink.sim.handover.triggers.Epoch` fields are documented there.

References
----------
.. [1] 3GPP TS 38.331 V18.5.1, "NR; Radio Resource Control (RRC); Protocol
   specification", 5.5.4.15 Event D1, 5.5.4.15a Event D2, 5.5.4.16 CondEvent T1,
   5.3.5.13.4 conditional reconfiguration evaluation.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from leolink.errors import ConfigError
from leolink.sim.handover.triggers import any_nan, check_param, check_ttt

#: Epoch field of each D1 reference location (:class:`D1`).
D1_REFERENCES = {"beam": "ref_pos_m", "cell": "cell_ref_pos_m", "points": "point_ref_pos_m"}


def _distances_m(epoch, field, who):
    """``(Ml1 (n_ut, 1), Ml2 (n_ut, n_cand))`` [m]: UT to the serving's / each candidate's
    reference location. References: ``(n_cand, 3)`` shared by every UT, or ``(n_ut,
    n_cand, 3)`` per UT (a run's per-UT candidate axes, :mod:`leolink.sim.handover.local_axis`)."""
    ut = epoch.need("ut_pos_m", who)
    ref = epoch.need(field, who)
    diff_m = ut[:, None, :] - (ref if ref.ndim == 3 else ref[None, :, :])
    ml2 = np.sqrt(np.einsum("ijk,ijk->ij", diff_m, diff_m))
    return epoch.at_serving(ml2), ml2


@dataclasses.dataclass(frozen=True)
class D1:
    """Event D1, distance to referenceLocation1 above threshold1 and to referenceLocation2
    below threshold2 (TS 38.331 5.5.4.15); as CondEvent D1, location 1 is the serving
    cell's reference, location 2 the candidate's.

    Entering: D1-1 ``Ml1 - Hys > Thresh1`` and D1-2 ``Ml2 + Hys < Thresh2``; leaving:
    D1-3 ``Ml1 + Hys < Thresh1`` or D1-4 ``Ml2 - Hys > Thresh2`` [m]. Distances are
    straight-line (chord) distances between the given positions; on a sphere the arc
    exceeds the chord by about ``c**3 / (24 R**2)`` (128 m at c = 500 km). Decides the
    cell. Ranks triggered candidates by nearest reference location.

    ``reference`` (:data:`D1_REFERENCES`) says which reference locations it reads:
    "beam" the cells' ground centres now (``Epoch.ref_pos_m``; with body-fixed beams they
    move with the satellite), "cell" the Earth-fixed cells of quasi-Earth-fixed steering
    (``Epoch.cell_ref_pos_m``), "points" the configured referenceLocation1/2 of each
    cell (``Epoch.point_ref_pos_m``). The last two are fixed on the Earth, as TS 38.331
    ``referenceLocation`` is.
    """

    threshold1_m: float = 0.0
    threshold2_m: float = 0.0
    hysteresis_m: float = 0.0
    time_to_trigger_s: float = 0.0
    reference: str = "beam"
    level = "cell"

    @property
    def _field(self):
        return D1_REFERENCES[self.reference]

    @property
    def needs(self):
        return ("ut_pos_m", self._field)

    def __post_init__(self):
        name = type(self).__name__.lower()
        if self.reference not in D1_REFERENCES:
            raise ConfigError(
                f"{name}.reference = {self.reference!r} is not allowed: use one of "
                f"{', '.join(map(repr, D1_REFERENCES))}"
            )
        check_param(f"{name}.threshold1_m", self.threshold1_m, 0.0, "distanceThreshFromReference1")
        check_param(f"{name}.threshold2_m", self.threshold2_m, 0.0, "distanceThreshFromReference2")
        check_param(f"{name}.hysteresis_m", self.hysteresis_m, 0.0, "hysteresisLocation [m]")
        check_ttt(self.time_to_trigger_s)

    def conditions(self, epoch):
        ml1, ml2 = _distances_m(epoch, self._field, type(self).__name__)
        hys = self.hysteresis_m
        enter = (ml1 - hys > self.threshold1_m) & (ml2 + hys < self.threshold2_m)
        leave = (ml1 + hys < self.threshold1_m) | (ml2 - hys > self.threshold2_m)
        return enter, leave | any_nan(ml1, ml2)

    def rank(self, epoch):
        return -_distances_m(epoch, self._field, type(self).__name__)[1]


@dataclasses.dataclass(frozen=True)
class D2(D1):
    """Event D2 (Rel-18), distance to the serving cell's moving reference location above
    threshold1 and to the candidate's moving reference location below threshold2
    (TS 38.331 5.5.4.15a).

    The same inequalities D2-1..D2-4 as D1, on ``Epoch.moving_ref_pos_m``: the reference
    locations at ``t_s`` derived from each satellite's ephemeris (the caller computes
    them). Decides the satellite by default (one moving reference per satellite).
    """

    level = "satellite"
    needs = ("ut_pos_m", "moving_ref_pos_m")  # type: ignore[assignment]
    _field = "moving_ref_pos_m"  # type: ignore[assignment]


@dataclasses.dataclass(frozen=True)
class T1:
    """CondEvent T1, time measured at the UE within a duration from a threshold
    (TS 38.331 5.5.4.16).

    Entering T1-1: ``Mt > Thresh1``; leaving T1-2: ``Mt > Thresh1 + Duration``, with
    ``Thresh1 = (serving cell's planned end of service) - lead_s`` per UT, from
    ``Epoch.service_end_s``. T1-2 implies T1-1, so read literally a cell would re-enter
    the moment it left; leolink lets T1-1 hold only inside the window
    ``Thresh1 < Mt <= Thresh1 + Duration`` (see docs/errata.md). T1 has no
    time-to-trigger (5.3.5.13.4 considers it fulfilled as soon as its entry condition
    holds). It is a timer, not a ranking: triggered
    candidates rank by measurement (NaN, i.e. unusable, candidates are never chosen).
    Decides the satellite by default.
    """

    duration_s: float = 1.0
    lead_s: float = 0.0
    time_to_trigger_s = 0.0
    level = "satellite"
    needs = ("service_end_s", "meas")
    # It reads the end of service at the serving candidate alone (Thresh1): the run looks
    # ahead the serving satellite only (leolink.sim.handover.trigger_run).
    serving_only = ("service_end_s",)

    def __post_init__(self):
        check_param("t1.duration_s", self.duration_s, 0.0, "duration [s]")
        check_param("t1.lead_s", self.lead_s, -math.inf, "lead before the end of service [s]")

    def conditions(self, epoch):
        end = epoch.need("service_end_s", "T1")
        thresh1 = epoch.at_serving(end) - self.lead_s
        t = np.full((epoch.n_ut, np.shape(end)[-1]), float(epoch.t_s))
        leave = (t > thresh1 + self.duration_s) | np.isnan(thresh1)
        enter = (t > thresh1) & ~leave
        return enter, leave

    def rank(self, epoch):
        return epoch.need("meas", "T1")


@dataclasses.dataclass(frozen=True)
class Elevation:
    """Elevation trigger: serving below ``serving_below_rad`` and candidate above
    ``candidate_above_rad`` (a leolink event, not a TS 38.331 one; written like A5).

    Entering: ``El_p + Hys < Thresh1`` and ``El_n - Hys > Thresh2``; leaving:
    ``El_p - Hys > Thresh1`` or ``El_n + Hys < Thresh2`` [rad]. Ranks by elevation.
    Decides the satellite by default (its beams share the elevation).
    """

    serving_below_rad: float = 0.0
    candidate_above_rad: float = 0.0
    hysteresis_rad: float = 0.0
    time_to_trigger_s: float = 0.0
    level = "satellite"
    needs = ("elevation_rad",)

    def __post_init__(self):
        low = -math.pi / 2
        check_param("elevation.serving_below_rad", self.serving_below_rad, low, "[rad]")
        check_param("elevation.candidate_above_rad", self.candidate_above_rad, low, "[rad]")
        check_param("elevation.hysteresis_rad", self.hysteresis_rad, 0.0, "hysteresis [rad]")
        check_ttt(self.time_to_trigger_s)

    def conditions(self, epoch):
        el_n = epoch.need("elevation_rad", "Elevation")
        el_p, hys = epoch.at_serving(el_n), self.hysteresis_rad
        enter = (el_p + hys < self.serving_below_rad) & (el_n - hys > self.candidate_above_rad)
        leave = (el_p - hys > self.serving_below_rad) | (el_n + hys < self.candidate_above_rad)
        return enter, leave | any_nan(el_n, el_p)

    def rank(self, epoch):
        return epoch.need("elevation_rad", "Elevation")


@dataclasses.dataclass(frozen=True)
class TimeToExit:
    """Time-to-exit trigger: hand over to the candidate that stays in service longest
    (a leolink event, written like A3 on the remaining service time).

    With ``R = service_end_s - t_s`` (remaining time above the service threshold, from
    the ephemeris look-ahead): entering ``R_n - Hys > R_p + Off`` and
    ``R_p + Hys < serving_below_s``; leaving ``R_n + Hys < R_p + Off`` or
    ``R_p - Hys > serving_below_s`` [s]. ``serving_below_s = inf`` (default) drops the
    second condition. Ranks by remaining time (the longest wins). Decides the satellite.
    """

    offset_s: float = 0.0
    hysteresis_s: float = 0.0
    time_to_trigger_s: float = 0.0
    serving_below_s: float = math.inf
    level = "satellite"
    needs = ("service_end_s",)

    def __post_init__(self):
        check_param("time_to_exit.offset_s", self.offset_s, -math.inf, "offset [s]")
        check_param("time_to_exit.hysteresis_s", self.hysteresis_s, 0.0, "hysteresis [s]")
        check_ttt(self.time_to_trigger_s)
        if not self.serving_below_s > 0:
            raise ConfigError(
                f"controller.time_to_exit.serving_below_s = {self.serving_below_s!r} is not "
                "allowed; use a value > 0 [s] (or inf)"
            )

    def remaining_s(self, epoch):
        end = epoch.need("service_end_s", "TimeToExit")
        return np.broadcast_to(end, (epoch.n_ut, np.shape(end)[-1])) - epoch.t_s

    def conditions(self, epoch):
        r_n = self.remaining_s(epoch)
        r_p, hys, below = epoch.at_serving(r_n), self.hysteresis_s, self.serving_below_s
        with np.errstate(invalid="ignore"):  # inf - inf where both are beyond the horizon
            enter = (r_n - hys > r_p + self.offset_s) & (r_p + hys < below)
            leave = (r_n + hys < r_p + self.offset_s) | (r_p - hys > below)
        return enter, leave | any_nan(r_n, r_p)

    def rank(self, epoch):
        return self.remaining_s(epoch)
