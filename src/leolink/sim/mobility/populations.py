"""UT populations: one registry of mobility kinds, each with its own parameter model.

A config ``[[population]]`` table names a ``kind`` of :data:`MOBILITY`; its keys are that
kind's parameter model (validated once, when the config is loaded) and its builder turns
them into a motion model of :mod:`leolink.sim.mobility.models`. Placement in the ROI plane is
:mod:`leolink.placement`; headings ``along_track`` / ``against_track`` / ``cross_track``
are relative to the ROI x axis (the satellites' ground track at the ROI centre):
+x, -x, and 90 deg clockwise of the track, i.e. to its right (the paper's +y, leolink's
ROI -y; tests/test_populations.py).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Annotated, Literal, Protocol, runtime_checkable

import numpy as np
from pydantic import Field, model_validator

from leolink.errors import ConfigError
from leolink.land import is_land
from leolink.placement import (
    grid_points,
    has_land,
    lat_lon_grid,
    place_random,
    random_region,
    roi_points_to_geodetic,
)
from leolink.registry import Params, Registry
from leolink.sim.environment import ChannelParams
from leolink.sim.mobility.models import (
    SPEED_PRESETS_M_S,
    ConstantVelocity,
    Static,
    Track,
    Waypoints,
)

__all__ = [
    "GEOGRAPHIC_PLACEMENTS",
    "MOBILITY",
    "MotionModel",
    "PopulationContext",
    "PopulationParams",
]


@runtime_checkable
class MotionModel(Protocol):
    """``n_ut`` terminals whose ``state(t_s)`` is a :class:`~leolink.sim.mobility.models.UTState`.

    A model may also have ``states(times_s)``: the states at many times in one call (each
    array with a leading time axis), equal to ``state`` time after time; the simulator
    uses it for a block of epochs where the class has it (:mod:`leolink.sim.motion`).
    A model whose UTs never move says so with ``moves = False``: their first state then
    holds for the whole run, and the simulator runs no motion process for them.
    """

    n_ut: int

    def state(self, t_s: float): ...


#: Mobility kinds by config name (``population.<i>.kind``).
MOBILITY: Registry[MotionModel] = Registry("population.kind", protocol=MotionModel)


@dataclasses.dataclass(frozen=True)
class PopulationContext:
    """What a population builder needs beyond its own table."""

    center_lat_rad: float
    center_lon_rad: float
    semi_axes_m: tuple[float, float]
    track_heading_rad: float  # azimuth of the ROI x axis at the centre
    rng: np.random.Generator  # the run's generator: random placement and headings
    t0_s: float  # first epoch of the run
    radius_m: float
    time_zero_utc: object = None  # aware datetime of simulation time 0 (run.start_utc), or None


#: Bounds of a recorded or configured fix, by column: (low, high, meaning). Shared by
#: ``[[population]] waypoints`` and the track files (:mod:`leolink.io.tracks`).
FIX_LIMITS = {
    "time_s": (-3.2e9, 3.2e9, "simulation time within +-100 years"),
    "lat_deg": (-90.0, 90.0, "latitude"),
    "lon_deg": (-180.0, 360.0, "longitude"),
    "alt_m": (-11_000.0, 100_000.0, "height between the deepest ocean and 100 km"),
}
#: Largest |x|, |y| of a placement point in the ROI plane [m]: 2 R, 63 deg from the centre.
MAX_ROI_POINT_M = 1.3e7
_RoiCoordinate = Annotated[float, Field(ge=-MAX_ROI_POINT_M, le=MAX_ROI_POINT_M)]


class PopulationParams(Params):
    """Keys every population has."""

    name: str = Field("ut", min_length=1, max_length=64, description="label of the population")
    environment: Literal["open", "rural", "suburban", "urban", "dense_urban"] = Field(
        "open",
        description="3GPP TR 38.811 environment of the UTs: LoS state, shadowing, clutter "
        "('open': the paper's line-of-sight link)",
    )
    channel: ChannelParams | None = Field(
        None, description="the environment's channel settings (none: TR 38.811 defaults)"
    )

    @property
    def n_ut(self) -> int:
        """Number of UTs, -1 if known only once a file is read."""
        return -1


_Lat = Annotated[float, Field(ge=-90.0, le=90.0)]
_Lon = Annotated[float, Field(ge=-180.0, le=180.0)]
_Alt = Annotated[float, Field(ge=-500.0, le=20_000.0)]
#: Placements by latitude and longitude (the others are in the ROI plane).
GEOGRAPHIC_PLACEMENTS = ("sites", "lat_lon_grid", "random_region")


class PlacedParams(PopulationParams):
    """Populations placed in the ROI plane (``center``, ``points``, ``random``, ``grid``)
    or by geography (``sites``, ``lat_lon_grid``, ``random_region``)."""

    count: int = Field(
        1, ge=1, le=10_000_000, description="number of UTs (random/grid/center/random_region)"
    )
    placement: Literal[
        "center", "points", "random", "grid", "sites", "lat_lon_grid", "random_region"
    ] = Field("center", description="where the UTs start")
    lat_deg: list[_Lat] = Field(
        default_factory=list, description="placement = 'sites': latitudes [deg], in [-90, 90]"
    )
    lon_deg: list[_Lon] = Field(
        default_factory=list,
        description="placement = 'sites': longitudes [deg], in [-180, 180]",
    )
    site_names: list[str] = Field(
        default_factory=list, description="placement = 'sites': a name per site (optional)"
    )
    sites_file: str = Field(
        "",
        description="placement = 'sites': CSV with a header name, lat_deg, lon_deg[, alt_m] "
        "(relative to the config), instead of the lists",
    )
    spacing_deg: float = Field(
        1.0, gt=0.0, le=90.0, description="placement = 'lat_lon_grid': row spacing [deg]"
    )
    lat_band_deg: list[_Lat] = Field(
        [-90.0, 90.0],
        min_length=2,
        max_length=2,
        description="lat_lon_grid / random_region: [south, north] latitude limits [deg]",
    )
    lon_range_deg: list[_Lon] = Field(
        [-180.0, 180.0],
        min_length=2,
        max_length=2,
        description="lat_lon_grid / random_region: [west, east] longitude limits [deg]",
    )
    land_only: bool = Field(
        False,
        description="lat_lon_grid / random_region: keep only points on land (Natural Earth "
        "1:50m coastlines)",
    )
    x_m: list[_RoiCoordinate] = Field(
        default_factory=list, description="placement points: ROI-plane x [m]"
    )
    y_m: list[_RoiCoordinate] = Field(
        default_factory=list, description="placement points: ROI-plane y [m]"
    )
    alt_m: _Alt | list[_Alt] = Field(
        0.0,
        description="height above the Earth model (sphere or WGS 84) [m], in [-500, 20000]; "
        "placement = 'sites': one per site",
    )

    @model_validator(mode="after")
    def _points(self):
        if self.placement == "points" and (not self.x_m or len(self.x_m) != len(self.y_m)):
            raise ValueError(
                f"population '{self.name}': placement = 'points' needs x_m and y_m lists of one "
                f"length (got {len(self.x_m)} and {len(self.y_m)})"
            )
        if self.placement == "sites":
            self._check_sites()
        elif isinstance(self.alt_m, list):
            raise ValueError(f"population '{self.name}': alt_m is a list only for sites")
        for key in ("lat_band_deg", "lon_range_deg"):
            low, high = getattr(self, key)
            if not low < high:
                raise ValueError(
                    f"population '{self.name}': {key} = [{low:g}, {high:g}] is an empty "
                    "region; use [low, high] with low < high"
                )
        return self

    def _check_sites(self):
        where = f"population '{self.name}': placement = 'sites'"
        if self.sites_file and (self.lat_deg or self.lon_deg):
            raise ValueError(f"{where} takes sites_file or lat_deg/lon_deg lists, not both")
        if self.sites_file:
            return
        n = len(self.lat_deg)
        lengths = {len(self.lon_deg), *(len(v) for v in (self.site_names,) if v)}
        if isinstance(self.alt_m, list):
            lengths.add(len(self.alt_m))
        if not n or lengths != {n}:
            raise ValueError(
                f"{where} needs lat_deg and lon_deg lists (and alt_m, site_names if given) of "
                f"one length (got {n} latitudes and {len(self.lon_deg)} longitudes)"
            )

    @property
    def n_ut(self) -> int:
        if self.placement == "points":
            return len(self.x_m)
        if self.placement == "sites":
            return len(self.lat_deg) if not self.sites_file else -1
        if self.placement == "lat_lon_grid":
            return -1  # known once the grid (and the land) is drawn
        return self.count


class MovingParams(PlacedParams):
    speed_m_s: float | None = Field(None, ge=0.0, le=1000.0, description="ground speed [m/s]")
    speed: Literal["static", "pedestrian", "car", "train", "ship", "aircraft"] | None = Field(
        None, description="speed preset (m/s: " + ", ".join(
            f"{k} {v:g}" for k, v in SPEED_PRESETS_M_S.items()) + ")"
    )  # fmt: skip
    heading_deg: (
        Annotated[float, Field(ge=-360.0, le=360.0)]
        | Literal["random", "along_track", "against_track", "cross_track"]
    ) = Field(
        "along_track",
        description="heading from north [deg] in [-360, 360], or relative to the ground track",
    )

    @model_validator(mode="after")
    def _speed(self):
        if self.speed_m_s is None and self.speed is None:
            raise ValueError(
                f"population '{self.name}': kind = 'constant_velocity' needs speed_m_s or speed"
            )
        return self


class WaypointsParams(PopulationParams):
    waypoints: list[list[float]] = Field(
        default_factory=list,
        description="rows [time_s, lat_deg, lon_deg, alt_m]; lat in [-90, 90], lon in "
        "[-180, 360], alt in [-11000, 100000] m, times increasing",
    )

    @model_validator(mode="after")
    def _rows(self):
        where = "waypoints"
        if len(self.waypoints) < 2:
            raise ValueError(f"{where}: kind = 'waypoints' needs >= 2 rows")
        for i, row in enumerate(self.waypoints):
            if len(row) != len(FIX_LIMITS):
                raise ValueError(
                    f"{where} row {i} has {len(row)} values; use [time_s, lat_deg, lon_deg, alt_m]"
                )
            for col, value in zip(FIX_LIMITS, row, strict=True):
                low, high, meaning = FIX_LIMITS[col]
                if not low <= value <= high:
                    raise ValueError(
                        f"{where} row {i}, {col} = {value!r} is not allowed: use "
                        f"[{low:g}, {high:g}] ({meaning})"
                    )
            if i and not row[0] > self.waypoints[i - 1][0]:
                raise ValueError(
                    f"{where} row {i}, time_s = {row[0]!r} is not after "
                    f"{self.waypoints[i - 1][0]!r} (row {i - 1}); times must increase"
                )
        return self

    @property
    def n_ut(self) -> int:
        return 1


def _pair(values):
    """``[a, b]`` of two degrees, as the config's other messages write them."""
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def _geographic_points(p, ctx):
    """``(lat_rad, lon_rad, alt_m)`` of a placement by latitude and longitude."""
    if p.placement == "sites":
        return np.radians(p.lat_deg), np.radians(p.lon_deg), np.asarray(p.alt_m, float)
    region = (tuple(p.lat_band_deg), tuple(p.lon_range_deg))
    if p.land_only and not has_land(*region):
        raise ConfigError(
            f"population '{p.name}': land_only = true, but lat_band_deg = {_pair(region[0])} "
            f"x lon_range_deg = {_pair(region[1])} has no land; use a region with some land"
        )
    if p.placement == "random_region":
        lat, lon = random_region(p.count, *region, ctx.rng, land_only=p.land_only)
    else:
        lat, lon = lat_lon_grid(p.spacing_deg, *region)
        if p.land_only:
            on_land = is_land(lat, lon)
            lat, lon = lat[on_land], lon[on_land]
        if not len(lat):
            raise ConfigError(
                f"population '{p.name}': lat_lon_grid with spacing_deg = {p.spacing_deg:g} "
                f"has no point {'on land ' if p.land_only else ''}in lat_band_deg = "
                f"{list(region[0])} x lon_range_deg = {list(region[1])}; use a finer spacing"
            )
    return np.radians(lat), np.radians(lon), p.alt_m


def _start_points(p, ctx):
    """``(lat_rad, lon_rad, alt_m)`` where the population's UTs start."""
    if p.placement in GEOGRAPHIC_PLACEMENTS:
        return _geographic_points(p, ctx)
    rx, ry = ctx.semi_axes_m
    if p.placement == "center":
        x, y = np.zeros(p.count), np.zeros(p.count)
    elif p.placement == "points":
        x, y = np.asarray(p.x_m, float), np.asarray(p.y_m, float)
    elif p.placement == "random":
        x, y = place_random(p.count, rx, ry, ctx.rng)
    else:
        x, y = grid_points(p.count, rx, ry)
    lat, lon = roi_points_to_geodetic(
        x, y, ctx.center_lat_rad, ctx.center_lon_rad, ctx.track_heading_rad, ctx.radius_m
    )
    return lat, lon, p.alt_m


_RELATIVE_HEADING_RAD = {"along_track": 0.0, "against_track": math.pi, "cross_track": math.pi / 2}


def _headings(p, n, ctx):
    if p.heading_deg == "random":
        return ctx.rng.uniform(0.0, 2.0 * np.pi, n)
    if isinstance(p.heading_deg, str):
        return np.full(n, ctx.track_heading_rad + _RELATIVE_HEADING_RAD[p.heading_deg])
    return np.full(n, math.radians(p.heading_deg))


def _static(p, ctx):
    return Static(*_start_points(p, ctx))


def _moving(p, ctx):
    lat, lon, alt = _start_points(p, ctx)
    speed = p.speed_m_s if p.speed_m_s is not None else SPEED_PRESETS_M_S[p.speed]
    if speed == 0.0:
        return Static(lat, lon, alt)
    heading = _headings(p, len(lat), ctx)
    return ConstantVelocity(lat, lon, alt, heading, speed, t0_s=ctx.t0_s, radius_m=ctx.radius_m)


def _waypoints(p, ctx):
    w = np.asarray(p.waypoints, float)
    track = Track(w[:, 0], np.radians(w[:, 1]), np.radians(w[:, 2]), w[:, 3], p.name)
    return Waypoints([track], radius_m=ctx.radius_m)


MOBILITY.add("static", _static, config=PlacedParams, doc="UTs that do not move")
MOBILITY.add(
    "constant_velocity",
    _moving,
    config=MovingParams,
    doc="UTs on great circles at constant speed and height",
)
MOBILITY.add(
    "waypoints", _waypoints, config=WaypointsParams, doc="one UT through configured waypoints"
)
