"""The one validation path: what ``leolink validate`` checks is what ``leolink run`` needs.

:func:`checked_scenario` is called by :func:`leolink.app.run.run` (and so by every sweep
point) and by ``leolink validate``: the files a config names must exist, the scenario is
built (codebook, ephemeris, terminals, populations: track and GPX files are read, TLE
files parsed) and the ephemeris is propagated over the run's epochs
(:func:`ephemeris_health`). A config that validates therefore runs, and a config that
``run`` refuses is refused by ``validate`` with the same line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from leolink.errors import ConfigError

__all__ = [
    "HEALTH_SAMPLES",
    "TLE_AGE_NOTE_DAYS",
    "check_files",
    "check_report_uts",
    "checked_scenario",
    "ephemeris_health",
]

#: Most instants at which the ephemeris is propagated to look for sgp4 errors: every
#: epoch of a run up to this many, else a regular sample of them. sgp4's errors come and
#: go (a near-parabolic orbit fails near perigee only: error 4 for tens of seconds per
#: revolution), so a run longer than this may hide a short failure between samples; the
#: run itself then serves no UT from that satellite at those epochs (NaN positions).
HEALTH_SAMPLES = 20_001
#: ... and at most this many satellite states in all (a large constellation is sampled
#: more coarsely: ~1 s of sgp4), but never fewer than 201 instants.
HEALTH_STATES = 5_000_000
_BLOCK_STATES = 1_000_000  # satellite states per propagation call (bounded memory)
#: A TLE this many days from the run is noted (sgp4 errors grow by ~1-3 km per day).
TLE_AGE_NOTE_DAYS = 30.0
_MAX_LISTED = 5


def check_files(cfg):
    """Files a config refers to must exist (checked before anything is built)."""
    c = cfg.constellation
    if c.kind == "tle" and not Path(c.tle_file).is_file():
        raise ConfigError(f"constellation.tle_file = {c.tle_file!r} does not exist")
    for i, p in enumerate(cfg.population):
        for key in ("track_file", "sites_file"):
            path = getattr(p, key, "")
            if path and not Path(path).is_file():
                raise ConfigError(f"population.{i}.{key} = {path!r} does not exist")


def _sample(times_s, n_sat):
    n = max(201, min(HEALTH_SAMPLES, HEALTH_STATES // max(n_sat, 1)))
    times_s = np.asarray(times_s, float)
    if len(times_s) <= n:
        return times_s
    return times_s[np.linspace(0, len(times_s) - 1, n).round().astype(int)]


def _failures(ephemeris, times_s):
    """``[(satellite, first failing time [s], sgp4 code)]`` over ``times_s``."""
    t = _sample(times_s, ephemeris.n_sat)
    step = max(1, _BLOCK_STATES // max(ephemeris.n_sat, 1))
    err = np.concatenate([ephemeris.state(t[i : i + step])[3] for i in range(0, len(t), step)])
    out = []
    for sat in np.flatnonzero(err.any(axis=0)):
        k = int(np.argmax(err[:, sat] != 0))
        out.append((int(sat), float(t[k]), int(err[k, sat])))
    return out


def _describe(ephemeris, failures):
    from sgp4.api import SGP4_ERRORS

    parts = [
        f"{ephemeris.names[sat]!r} first at t = {t_s:.1f} s (sgp4 error {code}: "
        f"{SGP4_ERRORS.get(code, 'unknown')})"
        for sat, t_s, code in failures[:_MAX_LISTED]
    ]
    more = f" and {len(failures) - _MAX_LISTED} more" if len(failures) > _MAX_LISTED else ""
    return "; ".join(parts) + more


def _age_note(cfg, tles):
    from sgp4.api import Satrec

    from leolink.app.orbits import tle_time_zero_utc

    t0 = tle_time_zero_utc(cfg, tles).timestamp() + cfg.run.start_s
    ages = []
    for name, l1, l2 in tles:
        s = Satrec.twoline2rv(l1, l2)
        epoch = (s.jdsatepoch + s.jdsatepochF - 2440587.5) * 86400.0
        ages.append((abs(epoch - t0) / 86400.0, name or str(s.satnum)))
    age, name = max(ages)
    if age <= TLE_AGE_NOTE_DAYS:
        return []
    return [
        f"satellite TLEs are up to {age:.0f} days from the run's start ({name!r}): sgp4 "
        "positions drift by kilometres per day away from a TLE's epoch"
    ]


def ephemeris_health(cfg, ephemeris, times_s):
    """Notes on the satellites that sgp4 cannot propagate over ``times_s``.

    Returns
    -------
    list of str
        One note naming the failing satellites (which, from when, which sgp4 error), and
        one when the TLEs are far from the run; empty for orbits that are not TLEs.

    Raises
    ------
    ConfigError
        Every satellite fails at some epoch of the run: no run can serve anyone.
    """
    if cfg.constellation.kind != "tle":
        return []
    from leolink.io.tle import read_tle_file

    failures = _failures(ephemeris, times_s)
    where = f"constellation.tle_file = {cfg.constellation.tle_file!r}"
    if failures and len(failures) == ephemeris.n_sat:
        raise ConfigError(
            f"{where}: sgp4 cannot propagate any of its {ephemeris.n_sat} satellite(s) over "
            f"the run: {_describe(ephemeris, failures)}; use TLEs of epochs near the run "
            "(run.start_utc)"
        )
    notes = _age_note(cfg, read_tle_file(cfg.constellation.tle_file))
    if failures:
        notes.append(
            f"satellite {len(failures)} of {ephemeris.n_sat} fail in sgp4 at some epochs and "
            f"serve no UT then: {_describe(ephemeris, failures)}"
        )
    return notes


def checked_scenario(cfg, split=None):
    """The :class:`~leolink.sim.runner.Scenario` of ``cfg``, after every check a run needs
    (``split``: ``(workers, parts)`` of a split run, :func:`leolink.app.split.split_workers`:
    its UTs must not be coupled, :func:`leolink.app.split.check_split`).

    Raises
    ------
    LeolinkError
        A missing or unreadable file, a codebook the RF chains cannot drive, satellites
        that all fail in sgp4, ...: one line naming the key or the file and line.
    """
    from leolink.app.scenario import build_scenario

    check_files(cfg)
    scen = build_scenario(cfg)
    ephemeris_health(cfg, scen.ephemeris, scen.times_s)
    check_report_uts(cfg, sum(pop.n_ut for _, pop in scen.populations))
    if split is not None:
        from leolink.app.split import check_split, split_flag

        check_split(cfg, scen, split_flag(*split))
    return scen


def check_report_uts(cfg, n_ut):
    """``output.report.uts`` are UT ids of the run (``n_ut`` UTs): the rule the report's
    sink applies when it starts (:class:`leolink.io.report.sink.ReportSink`), checked
    before the run so that ``validate`` says it too, in the same words."""
    report = cfg.output.report
    if report.enabled and any(not 0 <= u < n_ut for u in report.uts):
        raise ConfigError(
            f"output.report.uts = {list(report.uts)!r} is not allowed; "
            f"UT ids of this run are 0 to {n_ut - 1}"
        )
