"""The 3GPP NTN trigger policies in the policy registry: ``controller.policy = "a3"`` etc.

Each name of :data:`leolink.sim.handover.config.POLICY_CONFIGS` is registered in
:data:`leolink.sim.handover.policies.POLICIES` with its own ``[controller.<name>]`` table. Who
decides what (``level``; any of them can be switched with ``level = "cell"`` or
``"satellite"`` in its table):

=============  ===========  ====================================================
policy         decides      trigger (TS 38.331 clause)
=============  ===========  ====================================================
a3             cell         neighbour offset better than serving (5.5.4.4)
a4             cell         neighbour better than a threshold (5.5.4.5)
a5             cell         serving below thr. 1, neighbour above thr. 2 (5.5.4.6)
d1             cell         distances to the cells' ground centres (5.5.4.15)
d2             satellite    distances to the satellites' nadir points (5.5.4.15a)
t1             satellite    time, from the serving's planned end of service (5.5.4.16)
elevation      satellite    serving below, candidate above (leolink)
time_to_exit   satellite    longest remaining time above the service threshold (leolink)
cho            its first    conditional handover: prepare, then execute (5.3.5.13)
a2a4           cell         A4 measured only while A2 holds (serving below a threshold)
               execution
               condition's
=============  ===========  ====================================================

"Satellite" means: the trigger runs on satellites and the beam is the best (max
filtered SNR) inside the chosen one; inside the serving satellite the beam follows the
best every epoch (beam management, not a handover decision).

These policies keep per-cell state (time-to-trigger runs, triggered cells, layer-3
filters, prepared CHO candidates), so they are not driven by ``choose`` like the
stateless policies of :mod:`leolink.sim.handover.policies`: the simulator asks the policy for a
:class:`~leolink.sim.handover.trigger_run.TriggerRun` (``policy.run(...)``) and hands its target
to the controller. They see every cell at or above the service threshold
(``neighbour_window_db = inf``, ``usable_cells_only = True``): a cell's state must not
depend on whether it was near the best one, and cells below the threshold are not
detected (:mod:`leolink.sim.handover.trigger_run`), so the candidate search leaves them out.
"""

from __future__ import annotations

import functools
import math

from leolink.sim.handover.config import (
    POLICY_CONFIGS,
    FilterConfig,
    build_filter,
    build_measurement,
    build_policy,
)
from leolink.sim.handover.measurement_model import MeasurementRun
from leolink.sim.handover.policies import POLICIES
from leolink.sim.handover.trigger_run import TriggerRun

__all__ = ["TriggerPolicyEntry", "entry", "horizon_s"]

#: Look-ahead horizon when a config gives none [s].
DEFAULT_HORIZON_S = 300.0


def horizon_s(config):
    """The look-ahead horizon of a policy config: the largest ``horizon_s`` in it [s]."""
    found = [getattr(config, "horizon_s", None)]
    for sub in [getattr(config, "prepare", None), *getattr(config, "execute", [])]:
        found.append(getattr(sub, "horizon_s", None))
    found = [h for h in found if h is not None]
    return max(found) if found else DEFAULT_HORIZON_S


class TriggerPolicyEntry:
    """A trigger policy as the registry builds it (module docstring).

    ``inner``: the pure policy (:class:`~leolink.sim.handover.decisions.TriggerPolicy` or
    :class:`~leolink.sim.handover.decisions.ConditionalHandover`); ``l3``: its layer-3 filter;
    ``horizon_s``: look-ahead of ``service_end_s`` [s].
    """

    lookahead_s = 0.0  # no future table: the look-ahead is the policy's own (service_time)
    time_to_trigger_s = 0.0  # the policy owns its time-to-trigger
    neighbour_window_db = math.inf
    usable_cells_only = True  # blind below the service threshold (module docstring)

    def __init__(self, name, inner, l3, horizon, cell_offsets=(), measurement=None, points=()):
        self.name, self.inner, self.l3, self.horizon_s = name, inner, l3, float(horizon)
        self.cell_offsets = tuple(cell_offsets)  # (sat_id, beam_id or None, offset_db)
        self.measurement = measurement  # MeasurementModel, or None (today's measurements)
        self.reference_points = tuple(points)  # (sat_id, beam_id or None, (x, y, z) [m])

    @property
    def level(self):
        return self.inner.level

    def choose(self, t_s, snr_db, state, future_snr_db=None):
        raise TypeError(
            f"policy {self.name!r} keeps per-cell state: the simulator drives it through "
            "policy.run(...) (leolink.sim.handover.trigger_run), not choose()"
        )

    def run(self, engine, min_snr_db, radius_m, future_state, epoch_s):
        """A fresh :class:`~leolink.sim.handover.trigger_run.TriggerRun` for one run."""
        run = TriggerRun(
            self.inner, self.l3, engine, min_snr_db, radius_m, future_state, epoch_s, self.horizon_s
        )
        run.cell_offsets, run.reference_points = self.cell_offsets, self.reference_points
        if self.measurement is not None:
            run.measurement = MeasurementRun(self.measurement, engine.n_beam)
        return run

    def __repr__(self):
        return f"TriggerPolicyEntry({self.name!r}, {self.inner!r}, {self.l3!r})"


def entry(name, policy, context=None, horizon=DEFAULT_HORIZON_S):
    """The registry's object for ``policy`` (a TriggerPolicy or ConditionalHandover), with
    the layer-3 filter of the build context (``[controller.filter]``; fc4 without one) and
    its cell offsets (``[[controller.cell_offsets]]``) and measurement model
    (``[controller.measurement]``, with the ``noise_temp_dbk`` of the context)."""
    section = getattr(context, "filter", None)
    l3 = build_filter(section if section is not None else FilterConfig())
    offsets = [(c.sat_id, c.beam_id, c.offset_db) for c in getattr(context, "cell_offsets", ())]
    section = getattr(context, "measurement", None)
    model = None
    if section is not None:
        model = build_measurement(section, getattr(context, "noise_temp_dbk", math.nan))
    points = getattr(context, "reference_points", ())
    return TriggerPolicyEntry(name, policy, l3, horizon, offsets, model, points)


def _build(name, params, context=None):
    """The registry's builder of policy ``name`` (bound to each name below).

    A module-level function bound with :func:`functools.partial`, not a closure made at
    import: it is looked up when a policy is built, so mutation testing reaches it."""
    return entry(name, build_policy(params, context), context, horizon_s(params))


_DOCS = {
    "a3": "Event A3 (TS 38.331 5.5.4.4): neighbour offset better than serving; decides the cell.",
    "a4": "Event A4 (5.5.4.5): neighbour better than a threshold; decides the cell.",
    "a5": "Event A5 (5.5.4.6): serving below threshold1, neighbour above threshold2; the cell.",
    "d1": "Event D1 (5.5.4.15): distances to the cells' ground centres; decides the cell.",
    "d2": "Event D2 (5.5.4.15a): distances to the satellites' nadir points; the satellite.",
    "t1": "CondEvent T1 (5.5.4.16): serving's planned end of service; decides the satellite.",
    "elevation": "Serving below, candidate above an elevation (leolink); the satellite.",
    "time_to_exit": "Longest remaining service time, ephemeris look-ahead; the satellite.",
    "cho": "Conditional handover (5.3.5.13): prepare candidates, execute on a condition.",
    "a2a4": "Event A4 measured while A2 (5.5.4.3) holds: serving weak, neighbour good; the cell.",
}

for _name, _config in POLICY_CONFIGS.items():
    if _name not in POLICIES:
        POLICIES.add(_name, functools.partial(_build, _name), doc=_DOCS[_name], config=_config)
