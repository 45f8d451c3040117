"""Suite-wide rules: a skipped test fails the run unless it is declared optional.

A test that needs something the ``test`` extra does not install (the ``dist`` extra's
dask) is marked ``@pytest.mark.optional_extra("dist")`` and may skip; any other skip
(a missing skyfield, a forgotten ``importorskip``) is an error: the session exits 1 and
names the test. ``LEOLINK_ALLOW_SKIPS=1`` relaxes this for a partial local install.
"""

from __future__ import annotations

import os

import pytest

_unexpected: list[str] = []


@pytest.fixture(params=["compiled", "numpy"])
def compiled_and_numpy(request, monkeypatch):
    """The test on the compiled loops (numba: every non-empty call, :mod:`leolink.compiled`)
    and on the numpy code (as ``LEOLINK_JIT=0``): for the modules with both paths
    (``pytestmark = pytest.mark.usefixtures("compiled_and_numpy")``)."""
    import leolink.compiled

    if request.param == "numpy":
        monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    else:
        assert leolink.compiled.use(1)
    return request.param


@pytest.fixture
def blocks_of_64(monkeypatch):
    """Motion blocks of at most 64 epochs whatever the UT count, as every run had before
    small runs got longer blocks (``leolink.sim.motion.BLOCK_UT_EPOCHS``): for the tests
    whose short run must be cut into several blocks. Returns the ``(k0, k1)`` epoch spans
    of the blocks computed, in order (the tests assert the cuts they rely on)."""
    from leolink.sim import motion

    spans, compute = [], motion.MotionBlocks._compute

    def recorded(self, k0, k1):
        spans.append((k0, k1))
        return compute(self, k0, k1)

    monkeypatch.setattr(motion, "MAX_BLOCK_EPOCHS", 64)
    monkeypatch.setattr(motion.MotionBlocks, "_compute", recorded)
    return spans


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "optional_extra(name): needs an opt-in extra; may skip when it is missing"
    )


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.skipped and item.get_closest_marker("optional_extra") is None:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr
        _unexpected.append(f"{item.nodeid}: {reason}")


def pytest_collectreport(report):
    # A module-level ``importorskip`` skips a whole file at collection, before any item
    # (and so before ``pytest_runtest_makereport``) exists: count it here.
    if report.skipped:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr
        _unexpected.append(f"{report.nodeid}: {reason}")


def pytest_sessionfinish(session, exitstatus):
    if _unexpected and not os.environ.get("LEOLINK_ALLOW_SKIPS"):
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter):
    if _unexpected:
        terminalreporter.section("unexpected skips (each fails the run)")
        for line in _unexpected:
            terminalreporter.line(line)
