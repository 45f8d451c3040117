"""The ``by_environment`` block of ``summary.json``: outages and handovers per UT environment.

Written only for a run that models TR 38.811 environments (``RunInfo.environment``
non-empty, :mod:`leolink.sim.environment`): the paper's open-country runs keep their
summary as it was. Every figure pools the UTs of one environment:

- ``outage_fraction`` and ``outage_fraction_by_reason`` (``no_satellite``,
  ``below_threshold``, ``blocked`` = recorded epochs in outage for that reason / epochs;
  ``handover`` = the handover interruption time / UT-time), as the overall block;
- ``handovers`` (counts by kind) and ``handovers_per_ut_hour`` = handovers_total /
  (UT-epochs x ``epoch_s`` / 3600 s);
- ``los_fraction`` = epochs whose link (serving, or best in outage) is line of sight /
  epochs with a link.
"""

from __future__ import annotations

import numpy as np

__all__ = ["by_environment"]


def _fraction(num, den):
    return float(num) / float(den) if den else None


def by_environment(environment, acc, counts):
    """``{environment: {...}}`` (module docstring) from a ``SummaryAccumulator``.

    Parameters
    ----------
    environment : sequence of str, shape (n_ut,)
    acc : SummaryAccumulator
        Its per-UT counts (``n_epochs``, ``n_outage``, ``n_no_satellite``,
        ``n_below_threshold``, ``n_blocked``, ``interrupted_s``, ``n_los``, ``n_link``).
    counts : dict of str -> ndarray (n_ut,)
        Events by kind, per UT.
    """
    env = np.asarray(environment, dtype=object)
    out = {}
    for name in dict.fromkeys(env):  # config order of first appearance
        m = env == name
        n = acc.n_epochs[m].sum()
        ut_s = n * acc.epoch_s
        handovers = {k: int(c[m].sum()) for k, c in counts.items()}
        total = handovers["beam_handover"] + handovers["sat_handover"]
        out[str(name)] = {
            "n_ut": int(m.sum()),
            "n_ut_epochs": int(n),
            "outage_fraction": _fraction(acc.n_outage[m].sum(), n),
            "outage_fraction_by_reason": {
                "no_satellite": _fraction(acc.n_no_satellite[m].sum(), n),
                "below_threshold": _fraction(acc.n_below_threshold[m].sum(), n),
                "blocked": _fraction(acc.n_blocked[m].sum(), n),
                "handover": _fraction(acc.interrupted_s[m].sum(), ut_s),
            },
            "handovers": {**handovers, "handovers_total": total},
            "handovers_per_ut_hour": _fraction(total * 3600.0, ut_s),
            "los_fraction": _fraction(acc.n_los[m].sum(), acc.n_link[m].sum()),
        }
    return out


def with_environment(acc, out, counts):
    """``out`` (the summary of ``acc``, a
    :class:`~leolink.io.summary.accumulator.SummaryAccumulator`) with the ``blocked`` outage
    fractions and ``by_environment`` of a run with TR 38.811 environments (else as it was)."""
    if not acc.environment:
        return out
    overall, per_ut = out["overall"], out.get("per_ut", [])  # none beyond 1,000 UTs
    n_all = acc.n_epochs.sum()
    reasons = overall["outage_fraction_by_reason"]
    reasons["blocked"] = acc.n_blocked.sum() / n_all if n_all else None
    with np.errstate(invalid="ignore", divide="ignore"):
        blocked = acc.n_blocked / acc.n_epochs
    for i, row in enumerate(per_ut):
        row["outage_fraction_by_reason"]["blocked"] = blocked[i]
    overall["by_environment"] = by_environment(acc.environment, acc, counts)
    return out
