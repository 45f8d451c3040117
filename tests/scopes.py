"""Fixture scope for the tests that share one expensive run among several checks.

Module scope normally (one run, many checks). ``LEOLINK_FIXTURE_SCOPE=function`` (set by
tools/mutation_scores.py) re-runs the fixture for every test, so that mutmut, which maps
each function to the tests that call it, credits every check with the run it uses
(with module scope it credits only the first test of the module).
"""

import os


def shared_run_scope(fixture_name, config):
    return os.environ.get("LEOLINK_FIXTURE_SCOPE", "module")
