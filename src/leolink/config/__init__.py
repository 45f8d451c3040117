"""Run configuration: one TOML file, validated once into pydantic models.

The schema is :mod:`leolink.config.schema` (sections with fixed keys) plus the sections
that :mod:`leolink.config.kinds` builds from the registries of the pluggable kinds.
Every mistake is reported once, at the edge, as a :class:`~leolink.errors.ConfigError`
that names the key, the value and what is allowed, e.g.::

    link.bandwidth_hz = 0.0 is not allowed: input should be greater than 0 (downlink bandwidth [Hz])
"""

from __future__ import annotations

import functools
import math
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import tomli_w
from pydantic import Field, ValidationError, create_model, model_validator

from leolink.config import kinds
from leolink.config.messages import reword
from leolink.config.overrides import apply_overrides, loads_toml
from leolink.config.schema import (
    ConstellationSection,
    EarthSection,
    LinkSection,
    ModcodSection,
    MultibeamSection,
    RoiSection,
    RunSection,
    SatelliteArraySection,
    Section,
    TimingSection,
)
from leolink.errors import ConfigError
from leolink.registry import REGISTRIES, generation
from leolink.sim.handover.config import (
    CellOffsetConfig,
    CellsConfig,
    FilterConfig,
    KpiConfig,
    MeasurementConfig,
    ReferencePointConfig,
    RlfConfig,
    SignallingConfig,
    interruption_field,
)
from leolink.textfile import read_text

__all__ = [
    "ConfigBase",
    "apply_overrides",
    "config_model",
    "dump_toml",
    "load_config",
    "parse_config",
    "updated",
]


class ControllerBase(kinds.SelectorSection):
    """``[controller]``: the policy and what every policy shares."""

    handover_time_s: float = interruption_field("service interruption per handover [s]")
    min_snr_db: float = Field(
        -10.0, ge=-100.0, le=100.0, description="below this SNR the UT is in outage [dB]"
    )
    filter: FilterConfig = Field(
        default_factory=FilterConfig,  # type: ignore[arg-type]
        description="layer-3 filter of the trigger policies' measurements (TS 38.331 5.5.3.2)",
    )
    measurement: MeasurementConfig = Field(
        default_factory=MeasurementConfig,  # type: ignore[arg-type]
        description="the trigger policies' measurements: period, error, SMTC, quantity",
    )
    rlf: RlfConfig = Field(
        default_factory=RlfConfig,  # type: ignore[arg-type]
        description="radio link failure on the serving SINR (TS 38.331 5.3.10), any policy",
    )
    cell_offsets: list[CellOffsetConfig] = Field(
        default_factory=list,
        description="cellIndividualOffset Ocn of cells (TS 38.331 5.5.4): added to the cell's "
        "measurement in A3 (Ocn and Ocp), A4, A5 and a2a4's A4; at satellite level a "
        "satellite's offset is its beams' largest",
    )
    reference_points: list[ReferencePointConfig] = Field(
        default_factory=list,
        description="referenceLocation of cells (TS 38.331 D1, Earth-fixed), what d1 with "
        "reference = 'points' measures distances to: entries {sat_id, beam_id (none: every "
        "beam), lat_deg, lon_deg} on the run's Earth; a later entry for a cell wins",
    )
    signalling: SignallingConfig = Field(
        default_factory=SignallingConfig,  # type: ignore[arg-type]
        description="the handover procedure in simulated time: report, command, T304, access",
    )
    service_metric: Literal["snr", "sinr", "modcod"] = Field(
        "snr",
        description="what decides service: the SNR against min_snr_db (the paper; beams and "
        "events), also the serving link's SINR against min_snr_db ('sinr'), or also a MODCOD "
        "of [modcod] closing the link with its implementation margin ('modcod'); a served "
        "epoch that fails counts as outage, below_threshold; beams and events stay on SNR",
    )

    @model_validator(mode="after")
    def _signalling_needs_rlf(self):
        if self.signalling.enabled and not self.rlf.enabled:
            raise ValueError(
                "controller.signalling.enabled = true is not allowed with "
                "controller.rlf.enabled = false: a failed handover re-establishes as after an "
                "RLF; set controller.rlf.enabled = true"
            )
        return self


class LinkBase(LinkSection, kinds.SelectorSection):
    """``[link]``: the budget; ``precoder`` chooses the digital precoder (``[link.<name>]``)."""


class SatelliteArrayBase(SatelliteArraySection, kinds.SelectorSection):
    """``[satellite_array]``: the array; ``active_beams`` chooses the beam selector,
    ``steering`` how the beams point."""


class ConfigBase(Section):
    """A whole run. Sections mirror the TOML tables; see :func:`config_model`."""

    source: str = Field("", exclude=True, description="where the config came from")

    if TYPE_CHECKING:  # sections added by config_model() from the registries (for mypy)
        constellation: Any
        roi: Any
        earth: Any
        link: Any
        scheduler: Any
        cells: Any
        controller: Any
        kpi: Any
        timing: Any

    @model_validator(mode="after")
    def _check(self):
        c = self.constellation
        if c.kind == "pass" and abs(self.roi.center_lat_deg) > min(
            c.inclination_deg, 180.0 - c.inclination_deg
        ):
            raise ValueError(
                f"roi.center_lat_deg = {self.roi.center_lat_deg!r} is not allowed: an orbit "
                f"inclined {c.inclination_deg} deg never passes over it (|lat| <= inclination)"
            )
        if c.kind == "tle" and not c.tle_file:
            raise ValueError("constellation.tle_file is required when constellation.kind = 'tle'")
        self._check_roi_cap()
        level = getattr(self.controller.params, "level", None)
        if self.cells.per == "satellite" and level == "cell":
            raise ValueError(
                f"controller.{self.controller.policy}.level = 'cell' is not allowed with "
                "cells.per = 'satellite': a cell is a satellite; leave level out or use "
                "'satellite'"
            )
        if self.link.precoder != "none" and self.scheduler.kind == "none":
            raise ValueError(
                f"link.precoder = {self.link.precoder!r} is not allowed with scheduler.kind = "
                "'none': a precoder serves one UT per lit beam per slot; use scheduler.kind "
                "= 'round_robin' or 'proportional_fair'"
            )
        a = self.satellite_array
        if self.link.precoder != "none" and (a.steering != "body_fixed" or a.phase_bits):
            what = f"steering = {a.steering!r}" if a.phase_bits is None else "phase_bits"
            raise ValueError(
                f"link.precoder = {self.link.precoder!r} is not allowed with satellite_array."
                f"{what}: the precoded channel uses the codebook's ideal body-fixed beams; "
                "use link.precoder = 'none' or satellite_array.steering = 'body_fixed' "
                "without phase_bits"
            )
        if c.tle_epoch_utc and self.run.start_utc:
            raise ValueError(
                f"constellation.tle_epoch_utc = {c.tle_epoch_utc!r} is not allowed together with "
                f"run.start_utc = {self.run.start_utc!r}: give the start once, as run.start_utc"
            )
        return self

    def _check_roi_cap(self):
        """ROI semi-axes within the cap where a satellite overhead at
        ``constellation.altitude_m`` is above the elevation mask: central angle
        ``theta = acos(R cos(el) / (R + h)) - el``, ``R tan(theta)`` in the ROI plane (the
        central projection of Sec. 3.1); 0.5 % slack for rounded configured values."""
        c, r, radius = self.constellation, self.roi, self.earth.radius_m
        el = math.radians(c.min_elevation_deg)
        theta = math.acos(radius * math.cos(el) / (radius + c.altitude_m)) - el
        cap_m = radius * math.tan(theta)
        for axis in ("x", "y"):
            value = getattr(r, f"semi_axis_{axis}_m")
            if value != "derived" and value > 1.005 * cap_m:
                raise ValueError(
                    f"roi.semi_axis_{axis}_m = {value!r} is not allowed: it must be at most "
                    f"{cap_m:.4g} m, the ROI-plane radius of the cap where a satellite at "
                    f"constellation.altitude_m = {c.altitude_m:g} is above "
                    f"constellation.min_elevation_deg = {c.min_elevation_deg:g}"
                )

    def utc_of_time_zero(self):
        """Aware UTC ``datetime`` of simulation time 0, or None (``run.start_utc``, or the
        older ``constellation.tle_epoch_utc``)."""
        from leolink.config.schema import parse_utc

        if self.constellation.tle_epoch_utc:
            return parse_utc("constellation.tle_epoch_utc", self.constellation.tle_epoch_utc)
        return self.run.utc_of_time_zero()

    def roi_semi_axes_m(self) -> tuple[float, float]:
        """ROI semi-axes [m]: the configured ones; ``"derived"``: the paper's design
        (Sec. 3.1)."""
        from leolink.roi import roi_semi_axes_m

        c, r = self.constellation, self.roi
        rx, ry = roi_semi_axes_m(
            c.n_planes, c.sats_per_plane, math.radians(c.inclination_deg), self.earth.radius_m
        )
        rx = float(rx) if r.semi_axis_x_m == "derived" else r.semi_axis_x_m
        ry = float(ry) if r.semi_axis_y_m == "derived" else r.semi_axis_y_m
        return rx, ry

    def to_dict(self) -> dict[str, Any]:
        """The config as plain data: every default written out; of the per-kind tables,
        the chosen kind's and those the file gave."""
        data = self.model_dump(mode="json", exclude_none=True)
        for name in type(self).model_fields:
            section = getattr(self, name)
            if isinstance(section, kinds.SelectorSection):
                for entry in section.unchosen():
                    if entry not in section.model_fields_set:
                        data[name].pop(entry, None)
        return data


@functools.cache
def _model(gen):
    del gen  # cache key only
    sel = kinds.selector_section
    sections = {
        "run": RunSection,
        "earth": EarthSection,
        "constellation": ConstellationSection,
        "roi": RoiSection,
        "link": sel("LinkSection", REGISTRIES["link.precoder"], "precoder", "none",
                    base=LinkBase, doc="digital precoder F_BB across the lit beams"),
        "modcod": ModcodSection,
        "atmosphere": sel("AtmosphereSection", REGISTRIES["atmosphere.model"], "model", "fixed",
                          doc="atmospheric loss model"),
        "satellite_array": sel("SatelliteArraySection",
                               REGISTRIES["satellite_array.active_beams"], "active_beams",
                               "all", base=sel("SatelliteArraySteering",
                                               REGISTRIES["satellite_array.steering"],
                                               "steering", "body_fixed",
                                               base=SatelliteArrayBase, doc="how the beams point"),
                               doc="which beams each satellite lights each epoch"),
        "scheduler": sel("SchedulerSection", REGISTRIES["scheduler.kind"], "kind", "none",
                         doc="how the UTs of one beam share its time"),
        "terminal": kinds.terminal_section(),
        "ephemeris_error": sel("EphemerisErrorSection", REGISTRIES["ephemeris_error.model"],
                               "model", "none", doc="error of the ephemeris the controller uses"),
        "controller": sel("ControllerSection", REGISTRIES["controller.policy"], "policy",
                          "max_snr", base=ControllerBase, doc="beam selection policy"),
        "output": kinds.output_section(REGISTRIES["output"]),
        "cells": CellsConfig,
        "kpi": KpiConfig,
        "multibeam": MultibeamSection,
        "timing": TimingSection,
    }  # fmt: skip
    fields: dict[str, Any] = {k: (m, Field(default_factory=m)) for k, m in sections.items()}
    fields["population"] = (
        Annotated[list[kinds.population_union()], Field(min_length=1)],  # type: ignore[misc]
        Field(default_factory=lambda: [{"kind": "static"}], validate_default=True),
    )
    return create_model("Config", __base__=ConfigBase, **fields)


def config_model() -> type[ConfigBase]:
    """The current config model (rebuilt when a kind is registered)."""
    kinds.load_owners()  # the installed plugins register before the cache key is read
    return _model(generation())


def parse_config(data: dict, source: str = "") -> ConfigBase:
    """Validate a config given as a dict (as read from TOML)."""
    model = config_model()
    try:
        cfg = model.model_validate(data)
    except ValidationError as exc:
        raise reword(exc, model, source) from None
    return cfg.model_copy(update={"source": source})


#: The longest path and file name a system takes (Linux's PATH_MAX and NAME_MAX).
MAX_PATH_CHARS, MAX_NAME_CHARS = 4096, 255


def _resolve_files(node, base: Path, key=""):
    """Keys ending in ``_file`` are paths relative to the config file's folder."""
    if isinstance(node, dict):
        return {
            k: _file(f"{key}{k}", v, base)
            if k.endswith("_file") and isinstance(v, str) and v
            else _resolve_files(v, base, f"{key}{k}.")
            for k, v in node.items()
        }
    if isinstance(node, list):
        return [_resolve_files(v, base, f"{key}{i}.") for i, v in enumerate(node)]
    return node


def _file(key, value, base):
    longest = max(len(part) for part in Path(value).parts) if Path(value).parts else 0
    if len(value) > MAX_PATH_CHARS or longest > MAX_NAME_CHARS:
        raise ConfigError(
            f"{key} = {value[:40]!r}... ({len(value):,} characters) is not allowed; use a path "
            f"of at most {MAX_PATH_CHARS} characters, each name at most {MAX_NAME_CHARS}"
        )
    return value if Path(value).is_absolute() else str(base / value)


def load_config(path: str | Path, overrides: list[str] | None = None) -> ConfigBase:
    """Read, override and validate a TOML config file, or an example's by its name
    (``"paper"``: :func:`leolink.examples.resolve`; a file of that path wins)."""
    from leolink.examples import resolve

    path = resolve(path)
    text = read_text(path, "config file", ConfigError)
    try:
        data = loads_toml(text, str(path))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    data = _resolve_files(apply_overrides(data, overrides), path.parent)
    if "source" in data:  # the model's own record of the file, not a config key
        raise ConfigError(
            f"{path}: source is not a known key (check the spelling; see docs/config.md)"
        )
    return parse_config(data, source=str(path))


def updated(cfg: ConfigBase, overrides: list[str]) -> ConfigBase:
    """A validated copy of ``cfg`` with ``--set``-style overrides applied."""
    data = cfg.model_dump(mode="json", exclude_none=True)
    return parse_config(apply_overrides(data, overrides), source=cfg.source)


def dump_toml(cfg: ConfigBase) -> str:
    """The resolved config as TOML (every default written out)."""
    return tomli_w.dumps(cfg.to_dict())


def __getattr__(name):  # ``leolink.config.Config``: the current model
    if name == "Config":
        return config_model()
    raise AttributeError(name)
