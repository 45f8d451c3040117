"""From a config to the satellites: ephemeris, real time, Earth orientation, the ROI frame.

- ``constellation.kind``: one pass over the ROI centre, a Walker-delta constellation, or
  TLEs (sgp4). TLE runs start at ``run.start_utc`` (or the first TLE's epoch); TEME goes
  to Earth-fixed by GMST82 of UT1, with UT1 - UTC from the IERS table
  (:mod:`leolink.io.earth_orientation`) when it covers the date.
- The ROI frame at the centre (x along-track, for UT placement and relative headings)
  follows a real satellite: for a pass, the configured one (its ``ascending`` flag
  defines that orbit); for Walker and TLE runs, the satellite highest above the centre
  at the first epoch, at the instant of its closest approach on that pass, ascending or
  descending as its ephemeris says (independent of the run's length).
"""

from __future__ import annotations

import dataclasses
import math
from datetime import UTC, datetime, timedelta

import numpy as np

from leolink.geodesy import wgs84_to_ecef
from leolink.geometry import ecef_to_geodetic, enu_basis, geodetic_to_ecef
from leolink.io.earth_orientation import ut1_minus_utc
from leolink.io.tle import read_tle_file
from leolink.orbit import CentralBody, Ephemeris, pass_over, walker_delta
from leolink.roi import closest_overhead_pass

__all__ = [
    "RoiFrame",
    "earth_orientation",
    "ephemeris_from_config",
    "overhead_satellite",
    "roi_center_site",
    "roi_frame",
    "tle_time_zero_utc",
]

_JD_UNIX_EPOCH = 2440587.5


@dataclasses.dataclass(frozen=True)
class RoiFrame:
    """The ROI frame at the centre: ``heading_rad`` (azimuth of x from north, clockwise)
    [rad], from satellite ``sat`` at ``t_s`` [s], ``ascending`` (moving north) or not."""

    heading_rad: float
    sat: int
    t_s: float
    ascending: bool

    def describe(self, names=None):
        name = names[self.sat] if names is not None else str(self.sat)
        way = "ascending" if self.ascending else "descending"
        return (
            f"ROI x axis along the ground track of satellite {name!r} ({way}) at t = "
            f"{self.t_s:.1f} s: heading {math.degrees(self.heading_rad) % 360.0:.2f} deg"
        )


def roi_center_site(cfg):
    """The ROI centre on the configured Earth: position (3,) [m] and local up (3,)."""
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    if cfg.earth.model == "wgs84":
        pos = wgs84_to_ecef(lat, lon, 0.0)
    else:
        pos = geodetic_to_ecef(lat, lon, 0.0, cfg.earth.radius_m)
    return pos, enu_basis(lat, lon)[2]


def _pass_center_rad(cfg):
    """(lat, lon) [rad] of the centre's direction from Earth's centre: the geocentric
    latitude on WGS 84 (a pass is overhead along the radial), the latitude on the sphere."""
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    if cfg.earth.model == "wgs84":
        lat = float(ecef_to_geodetic(wgs84_to_ecef(lat, lon, 0.0))[0])
    return lat, lon


def _pass_elements(cfg, t_pass_s):
    c, e = cfg.constellation, cfg.earth
    lat, lon = _pass_center_rad(cfg)
    return pass_over(
        lat,
        lon,
        t_pass_s,
        c.altitude_m,
        math.radians(c.inclination_deg),
        ascending=c.ascending,
        earth=CentralBody(e.radius_m, e.gm_m3_s2, e.rotation),
    )


def _datetime_of_jd(jd, fr):
    return datetime(1970, 1, 1, tzinfo=UTC) + timedelta(days=(jd - _JD_UNIX_EPOCH) + fr)


def tle_time_zero_utc(cfg, tles=None):
    """UTC ``datetime`` of simulation time 0 of a TLE run: ``run.start_utc - run.start_s``
    (or ``constellation.tle_epoch_utc``), else the first TLE's epoch."""
    when = cfg.utc_of_time_zero()
    if when is not None:
        return when
    from sgp4.api import Satrec

    tles = read_tle_file(cfg.constellation.tle_file) if tles is None else tles
    s = Satrec.twoline2rv(tles[0][1], tles[0][2])
    return _datetime_of_jd(s.jdsatepoch, s.jdsatepochF)


def earth_orientation(cfg, tles=None):
    """UT1 - UTC of a TLE run at its time 0 (:class:`EarthOrientation`), None otherwise."""
    if cfg.constellation.kind != "tle":
        return None
    return ut1_minus_utc(tle_time_zero_utc(cfg, tles))


def ephemeris_from_config(cfg):
    """Satellite ephemeris: one pass over the ROI centre, a Walker constellation, or TLEs."""
    c, e = cfg.constellation, cfg.earth
    if c.kind == "tle":
        from sgp4.api import jday

        tles = read_tle_file(c.tle_file)
        when = tle_time_zero_utc(cfg, tles)
        seconds = when.second + when.microsecond * 1e-6
        jd, fr = jday(when.year, when.month, when.day, when.hour, when.minute, seconds)
        dut1 = earth_orientation(cfg, tles).ut1_minus_utc_s
        return Ephemeris.from_tles(
            tles, jd, fr, earth_rotation=e.rotation, gm_m3_s2=e.gm_m3_s2, ut1_minus_utc_s=dut1
        )
    if c.kind == "walker":
        inc = math.radians(c.inclination_deg)
        el = walker_delta(c.n_planes * c.sats_per_plane, c.n_planes, c.phasing, inc, c.altitude_m)
    else:
        el = _pass_elements(cfg, c.pass_time_s)
    return Ephemeris.from_elements(
        el, earth_rotation=e.rotation, radius_m=e.radius_m, gm_m3_s2=e.gm_m3_s2
    )


def overhead_satellite(cfg):
    """Position, velocity and acceleration, each (1, 3), of a satellite of the configured
    orbit (altitude, inclination, ascending or descending) right over the ROI centre."""
    e = cfg.earth
    eph = Ephemeris.from_elements(
        _pass_elements(cfg, 0.0),
        earth_rotation=e.rotation,
        radius_m=e.radius_m,
        gm_m3_s2=e.gm_m3_s2,
    )
    pos, vel, acc = eph(0.0)
    return pos[0], vel[0], acc[0]


def _heading(cfg, vel_m_s):
    lat, lon = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    east, north, _ = enu_basis(lat, lon)
    v = np.asarray(vel_m_s, float).reshape(3)
    return math.atan2(float(v @ east), float(v @ north)), bool(v @ north > 0.0)


def roi_frame(cfg, ephemeris=None):
    """The :class:`RoiFrame` of the config (module docstring).

    For a pass: the configured satellite at its overhead instant (computed as before this
    frame came from ephemerides, so pass runs are unchanged). Otherwise: the satellite of
    ``ephemeris`` (built from the config if None) highest above the centre at the first
    epoch (``run.start_s``, warm-up included), at the instant of its closest approach on
    that pass (:func:`leolink.roi.closest_overhead_pass`), and its velocity then,
    projected on the centre's horizontal (with Earth rotation on: Earth-fixed, i.e. the
    direction of its ground track).
    """
    c = cfg.constellation
    if c.kind == "pass":
        _, vel, _ = overhead_satellite(cfg)
        heading, asc = _heading(cfg, vel[0])
        return RoiFrame(heading, 0, c.pass_time_s, asc)
    eph = ephemeris_from_config(cfg) if ephemeris is None else ephemeris
    site, up = roi_center_site(cfg)
    sat, t_s, _, vel = closest_overhead_pass(eph, cfg.run.start_s, site, up, cfg.earth.gm_m3_s2)
    heading, asc = _heading(cfg, vel)
    return RoiFrame(heading, sat, t_s, asc)
