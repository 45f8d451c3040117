"""Satellite passes over a site: rise, culmination and set, for every satellite at once.

A pass is an interval in which a satellite's elevation is at or above a mask. The
elevation of every satellite is sampled every ``step_s`` over the window; a change of
side of the mask between two samples is refined by bisection, the highest sample of a
pass by golden-section search on its two neighbouring intervals, both to ``tol_s``. A
pass shorter than the step that lies wholly between two samples is not seen (at 5 s, a
LEO pass that grazes the mask by less than ~0.05 deg); a second maximum inside one pass
(an elevation that dips and rises again without crossing the mask) is not reported.
Events outside the window are left out: a pass that began before it has no rise, one
still going at its end no set, and a pass whose highest point is at an edge of the
window no culmination (its ``max_elevation_rad`` is then the highest sample).

References
----------
.. [1] B. Rhodes, Skyfield, ``EarthSatellite.find_events`` (the same three events; the
   tests compare with it).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["Pass", "find_passes"]

#: Golden ratio's inverse, the golden-section search's step.
_INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0
#: Most (time, satellite) evaluations handed to ``elevation_rad`` per call of a refinement.
_REFINE_BLOCK = 256
#: Most sampled times per call (each call propagates every satellite at each time).
_SAMPLE_BLOCK = 128


@dataclasses.dataclass(frozen=True)
class Pass:
    """One pass of satellite ``sat`` [s of simulation time; None outside the window]."""

    sat: int
    rise_s: float | None
    culmination_s: float | None
    set_s: float | None
    max_elevation_rad: float


def find_passes(elevation_rad, window_s, min_elevation_rad, step_s=5.0, tol_s=1e-3):
    """Every pass of every satellite over a site in a time window.

    Parameters
    ----------
    elevation_rad : callable
        ``elevation_rad(t_s)`` with ``t_s`` (n_t,) gives (n_t, n_sat) [rad];
        ``elevation_rad(t_s, sat)`` with ``sat`` (n,) int gives (n,): satellite ``sat[i]``
        at ``t_s[i]``. NaN (a satellite that cannot be propagated) counts as below.
    window_s : (float, float)
        First and last instant [s].
    min_elevation_rad : float
        The mask [rad].
    step_s, tol_s : float
        Sampling step and the events' precision [s].

    Returns
    -------
    list of Pass
        By satellite, then time.
    """
    t = _sample_times(window_s, step_s)
    el = np.concatenate([elevation_rad(t[i : i + _SAMPLE_BLOCK])
                         for i in range(0, len(t), _SAMPLE_BLOCK)])  # fmt: skip
    above = el >= min_elevation_rad
    k, sat = np.nonzero(above[1:] != above[:-1])  # a crossing in (t[k], t[k + 1])
    order = np.lexsort((k, sat))
    k, sat = k[order], sat[order]
    crossing_s = _bisect(elevation_rad, min_elevation_rad, t[k], t[k + 1], sat, above[k, sat],
                         tol_s)  # fmt: skip
    spans = _spans(above, k, sat, crossing_s)
    return _with_culminations(elevation_rad, t, el, spans, tol_s)


def _sample_times(window_s, step_s):
    t0, t1 = float(window_s[0]), float(window_s[1])
    n = max(2, math.ceil((t1 - t0) / step_s - 1e-9) + 1)
    return np.linspace(t0, t1, n)


def _bisect(elevation_rad, mask, lo, hi, sat, up_at_lo, tol_s):
    """The instants in ``(lo, hi)`` where each satellite crosses the mask (vectorized)."""
    lo, hi = lo.astype(float), hi.astype(float)
    while lo.size and np.max(hi - lo) > tol_s:
        mid = 0.5 * (lo + hi)
        up = _at(elevation_rad, mid, sat) >= mask
        same = up == up_at_lo  # the crossing is after mid
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    return 0.5 * (lo + hi)


def _at(elevation_rad, t_s, sat):
    """``elevation_rad(t_s, sat)`` in blocks of :data:`_REFINE_BLOCK`."""
    out = np.empty(len(t_s))
    for i in range(0, len(t_s), _REFINE_BLOCK):
        out[i : i + _REFINE_BLOCK] = elevation_rad(t_s[i : i + _REFINE_BLOCK],
                                                   sat[i : i + _REFINE_BLOCK])  # fmt: skip
    return out


def _spans(above, k, sat, crossing_s):
    """``(sat, first sample, last sample, rise_s, set_s)`` of each pass; samples inclusive."""
    n_t, spans = above.shape[0], []
    starts = np.searchsorted(sat, np.arange(above.shape[1] + 1))
    for s in np.flatnonzero(above.any(axis=0)):  # satellites with a pass
        ks, times = k[starts[s] : starts[s + 1]], crossing_s[starts[s] : starts[s + 1]]
        first, rise, i = 0, None, 0
        if not above[0, s]:
            first, rise, i = int(ks[0]) + 1, float(times[0]), 1
        while True:
            if i >= len(ks):
                spans.append((int(s), first, n_t - 1, rise, None))
                break
            spans.append((int(s), first, int(ks[i]), rise, float(times[i])))
            if i + 1 >= len(ks):
                break
            first, rise, i = int(ks[i + 1]) + 1, float(times[i + 1]), i + 2
    return spans


def _with_culminations(elevation_rad, t, el, spans, tol_s):
    """The passes, with the highest point of each refined where it is inside the window."""
    best = [first + int(np.nanargmax(el[first : last + 1, s])) for s, first, last, _, _ in spans]
    inside = [i for i, b in enumerate(best) if 0 < b < len(t) - 1]
    sat = np.array([spans[i][0] for i in inside], int)
    k = np.array([best[i] for i in inside], int)
    peak_s, peak_rad = _golden_max(elevation_rad, t[k - 1], t[k + 1], sat, tol_s)
    peaks = dict(zip(inside, zip(peak_s, peak_rad, strict=True), strict=True))
    out = []
    for i, (s, _, _, rise, set_) in enumerate(spans):
        top_s, top_rad = peaks.get(i, (None, el[best[i], s]))
        out.append(Pass(s, rise, None if top_s is None else float(top_s), set_, float(top_rad)))
    return out


def _golden_max(elevation_rad, lo, hi, sat, tol_s):
    """Golden-section search of each satellite's maximum in ``[lo, hi]`` (vectorized)."""
    a, b = lo.astype(float), hi.astype(float)
    c, d = b - _INV_PHI * (b - a), a + _INV_PHI * (b - a)
    fc, fd = _at(elevation_rad, c, sat), _at(elevation_rad, d, sat)
    while a.size and np.max(b - a) > tol_s:
        left = fc >= fd  # the maximum is in [a, d]
        a, b = np.where(left, a, c), np.where(left, d, b)
        c_new, d_new = b - _INV_PHI * (b - a), a + _INV_PHI * (b - a)
        probe = np.where(left, c_new, d_new)
        f = _at(elevation_rad, probe, sat)
        c, fc, d, fd = (np.where(left, c_new, d), np.where(left, f, fd),
                        np.where(left, c, d_new), np.where(left, fc, f))  # fmt: skip
    t_max = 0.5 * (a + b)
    return t_max, _at(elevation_rad, t_max, sat)
