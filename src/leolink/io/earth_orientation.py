"""UT1 - UTC from the IERS table that skyfield bundles (its ``iers.npz``).

TLEs are propagated by sgp4 in TEME; the Earth-fixed frame follows by the rotation
GMST82(UT1) (Vallado et al. 2006, AIAA 2006-6753, Sec. "TEME"). UT1 differs from UTC by
up to 0.9 s (leap seconds keep it so), i.e. up to 0.9 s x 465 m/s = 0.42 km of rotation
on the ground at the equator. Inside the table's span leolink uses its value (the last
months of the table are IERS predictions); outside it takes 0 and says so.

Polar motion (up to ~0.5 arcsec, ~15 m on the ground) is neglected, as skyfield does
unless a polar-motion table is loaded.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np

__all__ = ["EarthOrientation", "ut1_minus_utc"]

#: UT1 - UTC never exceeds this (ITU-R TF.460-6: leap seconds keep |DUT1| < 0.9 s).
MAX_DUT1_S = 0.9
#: Earth's equatorial surface speed [m/s] (omega x a = 7.292115e-5 x 6378137 m).
EQUATOR_SPEED_M_S = 465.1


@dataclass(frozen=True)
class EarthOrientation:
    """``ut1_minus_utc_s`` [s] at an instant, where it came from, and a sentence."""

    ut1_minus_utc_s: float
    known: bool
    note: str


@functools.cache
def _table():
    """(skyfield timescale, first and last UTC day of its IERS table), or None.

    The timescale is built as ``skyfield.api.load.timescale(builtin=True)`` builds it
    (skyfield's ``Loader.timescale``), from ``skyfield.timelib`` alone: ``skyfield.api``
    would also import its loaders, ephemerides and star catalogues (~45 ms of a 10-UT
    run's 0.8 s). tests/test_real_time.py checks the two give the same UT1 - UTC.
    """
    try:
        from skyfield.functions import load_bundled_npy
        from skyfield.timelib import Timescale
    except ImportError:
        return None
    arrays = load_bundled_npy("iers.npz")
    tt = arrays["tt_jd_minus_arange"] + np.arange(arrays["tt_jd_minus_arange"].size)
    delta_t_s = (arrays["delta_t_1e7"] / 1e7).round(7)
    j2000 = datetime(2000, 1, 1, 12, tzinfo=UTC)  # JD 2451545.0 (TT; 64 s from UTC: irrelevant)
    first, last = (j2000 + timedelta(days=float(d) - 2451545.0) for d in (tt[0], tt[-1]))
    return Timescale((tt, delta_t_s), arrays["leap_dates"], arrays["leap_offsets"]), first, last


def ut1_minus_utc(when_utc):
    """UT1 - UTC at an aware UTC ``datetime``.

    Returns
    -------
    EarthOrientation
        The table's value inside its span; 0 with ``known = False`` outside it (or if
        skyfield is not installed), the note then giving the size of the error.
    """
    table = _table()
    day = when_utc.strftime("%Y-%m-%d")
    error = (
        f"the Earth rotation angle may be off by up to {MAX_DUT1_S} s (up to "
        f"{MAX_DUT1_S * EQUATOR_SPEED_M_S / 1e3:.2f} km on the ground at the equator)"
    )
    if table is None:
        return EarthOrientation(
            0.0, False, f"UT1-UTC unknown (skyfield not installed): 0 used; {error}"
        )
    ts, first, last = table
    if not first <= when_utc <= last:
        return EarthOrientation(
            0.0,
            False,
            f"UT1-UTC unknown on {day} (the IERS table bundled with skyfield covers "
            f"{first:%Y-%m-%d} to {last:%Y-%m-%d}): 0 used; {error}",
        )
    t = ts.from_datetime(when_utc)
    dut1 = float(t.dut1)
    return EarthOrientation(
        dut1, True, f"UT1-UTC = {dut1:+.4f} s on {day} (IERS, skyfield's bundled table)"
    )
