"""Visibility benchmark: elevations of many TLE satellites from many sites vs skyfield.

A dense workload: a 550 km, 53 deg Walker shell of ``--sats`` satellites (TLEs built with
sgp4init), ``--sites`` WGS 84 sites on a latitude/longitude grid, ``--times`` epochs 60 s
apart. leolink's :func:`leolink.visibility.tle_elevations_rad` computes every elevation;
skyfield the idiomatic way, ``(satellite - site).at(t).altaz()`` per satellite and site
(vectorized over time), on a subset of the satellites (its rate is per elevation). The
elevations are compared on that subset (aim: within 1e-6 deg).

Run: ``python benchmarks/bench_visibility.py [--quick]``. Prints figures only.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _common import best_of, row

AGREE_DEG = 1e-6  # same TEME -> Earth-fixed rotation (GMST82 of UT1) as skyfield


def walker_tles(n_sat, n_planes=20, altitude_m=550e3, inclination_deg=53.0):
    """``n_sat`` sgp4 Satrec of a Walker shell (circular, epoch 2024-01-01 00:00 UTC)."""
    from sgp4.api import WGS72, Satrec

    mu_km3_s2, radius_km = 398600.8, 6378.135  # WGS 72, sgp4's constants
    a_km = radius_km + altitude_m / 1e3
    n_rad_min = np.sqrt(mu_km3_s2 / a_km**3) * 60.0
    per_plane = -(-n_sat // n_planes)
    sats = []
    for k in range(n_sat):
        plane, slot = divmod(k, per_plane)
        raan = 2 * np.pi * plane / n_planes
        mean_anomaly = 2 * np.pi * (slot + 0.5 * plane / n_planes) / per_plane
        s = Satrec()
        # epoch in days from 1949-12-31 00:00 UT: 2024-01-01 is JD 2460310.5
        s.sgp4init(WGS72, "i", k + 1, 2460310.5 - 2433281.5, 0.0, 0.0, 0.0, 1e-4, 0.0,
                   np.radians(inclination_deg), mean_anomaly, n_rad_min, raan)  # fmt: skip
        sats.append(s)
    return sats


def sites(n_site):
    """``n_site`` sites on a grid over latitudes -60..60 deg and all longitudes."""
    n_lat = max(1, int(np.sqrt(n_site / 2)))
    lat = np.repeat(np.linspace(-60.0, 60.0, n_lat), -(-n_site // n_lat))[:n_site]
    lon = np.tile(np.linspace(-180.0, 180.0, -(-n_site // n_lat), endpoint=False), n_lat)
    return lat, lon[:n_site], np.zeros(n_site)


def _skyfield(sats, lat, lon, seconds):
    from skyfield.api import EarthSatellite, load, wgs84

    ts = load.timescale()
    t = ts.utc(2024, 1, 1, 0, 0, seconds)
    sky = [EarthSatellite.from_satrec(s, ts) for s in sats]
    places = [wgs84.latlon(a, b) for a, b in zip(lat, lon, strict=True)]
    t0 = time.perf_counter()
    out = np.array([[(s - p).at(t).altaz()[0].degrees for s in sky] for p in places])
    return out, time.perf_counter() - t0, np.asarray(t.dut1, float)


def main(argv=None):
    """Figures: ``elevations_per_s`` (leolink), ``skyfield_elevations_per_s``,
    ``speedup_vs_skyfield``, ``max_diff_deg``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    known, _ = ap.parse_known_args([] if argv is None else argv)
    quick = known.quick
    ap.add_argument("--sats", type=int, default=100 if quick else 1000)
    ap.add_argument("--sites", type=int, default=100)
    ap.add_argument("--times", type=int, default=240 if quick else 1440)
    ap.add_argument("--skyfield-sats", type=int, default=3 if quick else 10)
    args = ap.parse_args([] if argv is None else argv)
    from sgp4.api import SatrecArray, jday

    from leolink.visibility import tle_elevations_rad

    sats = walker_tles(args.sats)
    lat, lon, h = sites(args.sites)
    seconds = 60.0 * np.arange(args.times)
    jd0, fr0 = jday(2024, 1, 1, 0, 0, 0.0)
    jd, fr = np.full(seconds.shape, jd0), fr0 + seconds / 86_400.0
    n = args.sats * args.sites * args.times
    print(f"visibility: {args.sites} sites x {args.sats} satellites x {args.times} epochs "
          f"= {n / 1e6:.1f} M elevations")  # fmt: skip
    sky_sats = sats[: args.skyfield_sats]
    ref, dt_sky, dut1 = _skyfield(sky_sats, lat, lon, seconds)
    arr = SatrecArray(sats)
    rad = (np.radians(lat), np.radians(lon), h)
    dt, elev = best_of(lambda: tle_elevations_rad(arr, *rad, jd, fr, ut1_minus_utc_s=dut1))
    diff = float(np.nanmax(np.abs(np.degrees(elev[:, : len(sky_sats)]) - ref)))
    figures = {
        "elevations_per_s": n / dt,
        "skyfield_elevations_per_s": ref.size / dt_sky,
        "max_diff_deg": diff,
    }
    figures["speedup_vs_skyfield"] = (
        figures["elevations_per_s"] / figures["skyfield_elevations_per_s"]
    )
    row("leolink tle_elevations_rad", figures["elevations_per_s"], "elev/s")
    row(f"skyfield ({len(sky_sats)} satellites)", figures["skyfield_elevations_per_s"], "elev/s")
    row("speed-up vs skyfield", figures["speedup_vs_skyfield"], "x", aim=100)
    row("max |leolink - skyfield|", diff, "deg", aim=AGREE_DEG, better="lower")
    return figures


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
