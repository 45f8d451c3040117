"""Runs on the candidate search's pruned tables and on every cell (tests of the pruning)."""

import numpy as np

from leolink.io.sinks import MemorySink
from leolink.sim.runner import run_simulation


def trace_and_events(scen, exhaustive):
    """``(trace, events)`` of ``scen``; ``exhaustive``: the tables hold every visible cell
    (no service-threshold floor, no neighbour window) and every pair of the visibility cone
    is evaluated (no screening), the reference the pruned run must equal bit for bit."""
    if exhaustive:
        scen.policy.usable_cells_only = False
        scen.policy.neighbour_window_db = np.inf  # read by the Decider the run builds
        scen.prune = False
    sink = MemorySink()
    run_simulation(scen, [sink])
    return sink.trace(), sink.events()
