"""Run configuration: one TOML file, validated into pydantic models.

Every mistake is reported once, at the edge, as a :class:`~leolink.errors.ConfigError`
that names the key, the value and what is allowed, e.g.::

    link.bandwidth_hz = 0.0 is not allowed: must be > 0 (downlink bandwidth [Hz])
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal

import tomli_w
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from leolink.constants import EARTH_RADIUS_M, GM_EARTH_M3_S2
from leolink.errors import ConfigError

__all__ = [
    "Config",
    "apply_overrides",
    "dump_toml",
    "load_config",
    "parse_config",
]


#: Most epochs one run may have (their times alone take 8 bytes each).
MAX_EPOCHS = 1e8


class _Section(BaseModel):
    model_config = ConfigDict(
        extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False
    )


def _f(default, *, gt=None, ge=None, le=None, lt=None, doc=""):
    return Field(default, gt=gt, ge=ge, le=le, lt=lt, description=doc)


class RunSection(_Section):
    seed: int = _f(20201, ge=0, doc="seed of the run's random generator")
    epoch_s: float = _f(1.0, gt=0, doc="time step between two controller decisions [s]")
    start_s: float = _f(0.0, doc="simulation time of the first epoch [s]")
    duration_s: float = _f(120.0, gt=0, doc="simulated time after the warm-up [s]")
    warmup_s: float = _f(0.0, ge=0, doc="simulated time before recording starts [s]")
    trace_formats: list[Literal["csv", "parquet"]] = Field(
        default_factory=lambda: ["csv"], description="trace files to write"
    )
    chunk_rows: int = _f(200_000, ge=1, doc="trace rows buffered before a write")
    plots: bool = _f(True, doc="write PNG plots next to the traces")
    plot_uts: list[int] = Field(default_factory=lambda: [0], description="UTs shown in plots")

    @model_validator(mode="after")
    def _check(self):
        n_epoch = (self.warmup_s + self.duration_s) / self.epoch_s
        if self.duration_s < self.epoch_s:
            raise ValueError(
                f"run.duration_s = {self.duration_s!r} is not allowed: it must be at least one "
                f"epoch (run.epoch_s = {self.epoch_s!r})"
            )
        if n_epoch > MAX_EPOCHS:
            raise ValueError(
                f"run.epoch_s = {self.epoch_s!r} is not allowed: {n_epoch:.3g} epochs; use at "
                f"most {MAX_EPOCHS:.0e} (a longer epoch or a shorter run)"
            )
        return self


class EarthSection(_Section):
    radius_m: float = _f(EARTH_RADIUS_M, gt=6.0e6, lt=6.5e6, doc="spherical Earth radius [m]")
    gm_m3_s2: float = _f(GM_EARTH_M3_S2, gt=0, doc="Earth's gravitational parameter [m^3/s^2]")
    rotation: bool = _f(False, doc="rotate the Earth under the orbits (ECEF frame)")


class ConstellationSection(_Section):
    kind: Literal["pass", "walker", "tle"] = _f("pass", doc="how satellites are placed")
    altitude_m: float = _f(1_300_000.0, gt=100_000.0, lt=40_000_000.0, doc="orbit altitude [m]")
    inclination_deg: float = _f(53.0, ge=0.0, le=180.0, doc="orbital plane inclination [deg]")
    n_planes: int = _f(83, ge=1, doc="number of orbital planes N_p")
    sats_per_plane: int = _f(53, ge=1, doc="satellites per orbital plane N_s")
    phasing: int = _f(1, ge=0, doc="Walker phasing factor F")
    pass_time_s: float = _f(
        60.0, doc="kind = 'pass': time the satellite is over the ROI centre [s]"
    )
    ascending: bool = _f(True, doc="kind = 'pass': pass on the ascending half of the orbit")
    tle_file: str = _f("", doc="kind = 'tle': path of a file of two-line element sets")
    tle_epoch_utc: str = _f("", doc="kind = 'tle': UTC instant of simulation time 0 (ISO 8601)")
    min_elevation_deg: float = _f(10.0, ge=0.0, le=90.0, doc="lowest usable elevation [deg]")

    @model_validator(mode="after")
    def _check(self):
        if self.tle_epoch_utc:
            from datetime import datetime

            try:
                datetime.fromisoformat(self.tle_epoch_utc)
            except ValueError:
                raise ValueError(
                    f"constellation.tle_epoch_utc = {self.tle_epoch_utc!r} is not allowed: use an "
                    "ISO 8601 date and time, e.g. 2019-12-09T20:42:09Z"
                ) from None
        return self


class RoiSection(_Section):
    center_lat_deg: float = _f(42.24, ge=-90.0, le=90.0, doc="ROI centre latitude [deg]")
    center_lon_deg: float = _f(-8.72, ge=-180.0, le=360.0, doc="ROI centre longitude [deg]")
    semi_axis_x_m: float | None = _f(
        None, gt=0, doc="ROI semi-axis along-track [m]; none: derived (Sec. 3.1)"
    )
    semi_axis_y_m: float | None = _f(
        None, gt=0, doc="ROI semi-axis cross-track [m]; none: derived (Sec. 3.1)"
    )


class LinkSection(_Section):
    freq_hz: float = _f(11.45e9, gt=1e8, lt=1e12, doc="carrier frequency [Hz]")
    bandwidth_hz: float = _f(250e6, gt=0, doc="downlink bandwidth [Hz]")
    ptx_dbw: float = _f(
        15.0, doc="transmit power [dBW]; per beam unless power_mode = 'split_total'"
    )
    power_mode: Literal["per_beam", "split_total"] = _f("per_beam", doc="meaning of ptx_dbw")
    cable_loss_db: float = _f(0.0, ge=0, doc="loss between transmitter and array [dB]")
    noise_temp_dbk: float = _f(24.1, doc="receiver noise temperature [dBK]")
    rician_k: float = _f(10.0, gt=0, doc="Rician factor K_r (linear)")
    fading: Literal["mean", "rician"] = _f("mean", doc="paper's mean receive gain or random draws")
    reuse_colors: Literal[1, 3, 4] = _f(1, doc="frequency-reuse colours (1 = full reuse)")
    interference: Literal["serving_satellite", "all_satellites"] = _f(
        "serving_satellite", doc="whose other beams interfere (the paper: the serving satellite's)"
    )


class AtmosphereSection(_Section):
    model: Literal["fixed", "itu_p676", "itu_p618", "paper"] = _f("fixed", doc="loss model")
    fixed_db: float = _f(0.017, ge=0, doc="model = 'fixed': loss at every elevation [dB]")
    exceedance_percent: float = _f(1.0, gt=0, lt=100, doc="model = 'itu_p618': p [%]")
    antenna_diameter_m: float = _f(0.6, gt=0, doc="model = 'itu_p618': terminal diameter [m]")


class SatelliteArraySection(_Section):
    n_x: int = _f(60, ge=1, doc="elements along-track")
    n_y: int = _f(72, ge=1, doc="elements cross-track")
    n_rf_x: int = _f(5, ge=1, doc="RF chains (subarrays) along-track")
    n_rf_y: int = _f(3, ge=1, doc="RF chains (subarrays) cross-track")
    oversampling: float | Literal["auto"] = _f(1.2, doc="DFT oversampling factor O, or 'auto'")

    @model_validator(mode="after")
    def _check(self):
        for axis in ("x", "y"):
            n, n_rf = getattr(self, f"n_{axis}"), getattr(self, f"n_rf_{axis}")
            if n % n_rf:
                raise ValueError(
                    f"satellite_array.n_{axis} = {n} is not allowed: it must be a multiple of "
                    f"n_rf_{axis} = {n_rf} (equal subarrays, one per RF chain)"
                )
        if self.oversampling != "auto" and not self.oversampling > 0:
            raise ValueError(
                f"satellite_array.oversampling = {self.oversampling!r} is not allowed: "
                "use a number > 0 or 'auto'"
            )
        return self


class TerminalSection(_Section):
    kind: Literal["isotropic", "upa", "leaky_wave", "metasurface"] = _f("upa", doc="antenna")
    n_x: int = _f(24, ge=1, doc="UPA/leaky-wave elements along x")
    n_y: int = _f(24, ge=1, doc="UPA/leaky-wave elements along y")
    leakage: float = _f(0.05, gt=0, doc="leaky-wave leakage factor alpha per element")
    peak_gain_db: float = _f(33.0, doc="metasurface peak gain [dB]")
    rolloff: float = _f(1.2, ge=0, doc="metasurface cos-power roll-off")


class ControllerSection(_Section):
    policy: Literal["max_snr", "hysteresis", "predictive"] = _f("max_snr", doc="beam selection")
    hysteresis_db: float = _f(0.0, ge=0, doc="margin a new beam must win by [dB]")
    time_to_trigger_s: float = _f(0.0, ge=0, doc="how long the margin must hold [s]")
    lookahead_s: float = _f(0.0, ge=0, doc="predictive policy: look-ahead [s]")
    handover_time_s: float = _f(0.0, ge=0, doc="service interruption per handover [s]")
    min_snr_db: float = _f(-10.0, doc="below this SNR the UT is in outage [dB]")

    @model_validator(mode="after")
    def _check(self):
        if self.policy == "predictive" and not self.lookahead_s > 0:
            raise ValueError(
                f"controller.lookahead_s = {self.lookahead_s!r} is not allowed with policy "
                "'predictive': it needs a look-ahead > 0 s"
            )
        return self


class PopulationSection(_Section):
    name: str = _f("ut", doc="label of the population")
    kind: Literal["static", "constant_velocity", "waypoints", "track"] = _f("static", doc="motion")
    count: int = _f(1, ge=1, doc="number of UTs (placement random/grid/center)")
    placement: Literal["center", "points", "random", "grid"] = _f("center", doc="where UTs start")
    x_m: list[float] = Field(default_factory=list, description="placement points: ROI-plane x [m]")
    y_m: list[float] = Field(default_factory=list, description="placement points: ROI-plane y [m]")
    alt_m: float = _f(0.0, ge=-500.0, le=20_000.0, doc="altitude above the sphere [m]")
    speed_m_s: float | None = _f(None, ge=0, le=1000.0, doc="ground speed [m/s]")
    speed: Literal["static", "pedestrian", "car", "train", "ship", "aircraft"] | None = _f(
        None, doc="speed preset"
    )
    heading_deg: float | Literal["random", "along_track", "against_track", "cross_track"] = _f(
        "along_track", doc="heading from north [deg], or relative to the satellite ground track"
    )
    waypoints: list[list[float]] = Field(
        default_factory=list,
        description="kind = 'waypoints': rows [time_s, lat_deg, lon_deg, alt_m]",
    )
    track_file: str = _f("", doc="kind = 'track': CSV with time_s, lat_deg, lon_deg, alt_m[, ut]")

    @model_validator(mode="after")
    def _check(self):
        if self.placement == "points" and (not self.x_m or len(self.x_m) != len(self.y_m)):
            raise ValueError(
                f"population '{self.name}': placement = 'points' needs x_m and y_m lists of one "
                f"length (got {len(self.x_m)} and {len(self.y_m)})"
            )
        if self.kind == "constant_velocity" and self.speed_m_s is None and self.speed is None:
            raise ValueError(
                f"population '{self.name}': kind = 'constant_velocity' needs speed_m_s or speed"
            )
        if self.kind == "waypoints" and len(self.waypoints) < 2:
            raise ValueError(f"population '{self.name}': kind = 'waypoints' needs >= 2 rows")
        if self.kind == "track" and not self.track_file:
            raise ValueError(f"population '{self.name}': kind = 'track' needs track_file")
        return self

    @property
    def n_ut(self) -> int:
        if self.kind == "track":
            return -1  # known only once the file is read
        if self.kind == "waypoints":
            return 1
        return len(self.x_m) if self.placement == "points" else self.count


class Config(_Section):
    """A whole run. Sections mirror the TOML tables."""

    run: RunSection = Field(default_factory=RunSection)
    earth: EarthSection = Field(default_factory=EarthSection)
    constellation: ConstellationSection = Field(default_factory=ConstellationSection)
    roi: RoiSection = Field(default_factory=RoiSection)
    link: LinkSection = Field(default_factory=LinkSection)
    atmosphere: AtmosphereSection = Field(default_factory=AtmosphereSection)
    satellite_array: SatelliteArraySection = Field(default_factory=SatelliteArraySection)
    terminal: TerminalSection = Field(default_factory=TerminalSection)
    controller: ControllerSection = Field(default_factory=ControllerSection)
    population: Annotated[list[PopulationSection], Field(min_length=1)] = Field(
        default_factory=lambda: [PopulationSection()]
    )
    source: str = Field("", exclude=True, description="where the config came from")

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
        return self

    # -- derived quantities -------------------------------------------------------
    def roi_semi_axes_m(self) -> tuple[float, float]:
        """ROI semi-axes: the configured ones, else the paper's design (Sec. 3.1)."""
        from leolink.roi import roi_semi_axes_m

        c, r = self.constellation, self.roi
        rx, ry = roi_semi_axes_m(
            c.n_planes, c.sats_per_plane, math.radians(c.inclination_deg), self.earth.radius_m
        )
        rx = r.semi_axis_x_m if r.semi_axis_x_m is not None else float(rx)
        ry = r.semi_axis_y_m if r.semi_axis_y_m is not None else float(ry)
        return rx, ry

    def to_dict(self) -> dict[str, Any]:
        return self.model_dump(mode="json", exclude_none=True)


# -- loading and error wording ---------------------------------------------------


def _loc(loc) -> str:
    parts = []
    for p in loc:
        if isinstance(p, int):
            parts.append(str(p))  # population.0.speed, as --set spells it
        elif p not in ("function-after", "function-before") and not str(p).startswith("literal["):
            parts.append(str(p))
    return ".".join(parts)


def _field_doc(loc) -> str:
    model: Any = Config
    for p in loc:
        if isinstance(p, int) or model is None:
            continue
        fields = getattr(model, "model_fields", {})
        if p not in fields:
            return ""
        info = fields[p]
        ann = info.annotation
        args = getattr(ann, "__args__", ())
        inner = [a for a in (ann, *args) if isinstance(a, type) and issubclass(a, BaseModel)]
        if inner:
            model = inner[0]
            continue
        return info.description or ""
    return ""


def _reword(exc: ValidationError, source: str) -> ConfigError:
    lines = []
    for err in exc.errors():
        where = _loc(err["loc"])
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            lines.append(f"{where} is not a known key (check the spelling; see configs/paper.toml)")
        elif err["type"] == "missing":
            lines.append(f"{where} is required")
        elif err["type"] == "value_error":
            lines.append(msg)
        else:
            doc = _field_doc(err["loc"])
            meaning = f" ({doc})" if doc else ""
            lines.append(f"{where} = {err.get('input')!r} is not allowed: {msg.lower()}{meaning}")
    prefix = f"{source}: " if source else ""
    return ConfigError(prefix + "; ".join(lines))


def parse_config(data: dict, source: str = "") -> Config:
    """Validate a config given as a dict (as read from TOML)."""
    try:
        cfg = Config.model_validate(data)
    except ValidationError as exc:
        raise _reword(exc, source) from None
    return cfg.model_copy(update={"source": source})


def apply_overrides(data: dict, overrides: list[str] | None) -> dict:
    """Apply ``section.key=value`` overrides (value parsed as TOML, else a string).

    Lists of tables are indexed: ``population.0.speed_m_s=30``.
    """
    data = _deepcopy(data)
    for item in overrides or []:
        key, sep, raw = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set {item!r} is not allowed: use section.key=value")
        try:
            value = tomllib.loads(f"v = {raw.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        node = data
        parts = key.strip().split(".")
        for depth, part in enumerate(parts[:-1]):
            if isinstance(node, list):
                _check_table_list(node, item, ".".join(parts[:depth]))
                node = _index(node, part, key)
            else:
                node = node.setdefault(part, {})
            if not isinstance(node, dict | list):
                raise ConfigError(
                    f"--set {item!r} is not allowed: {part!r} holds a value, not a table"
                )
        if isinstance(node, list):
            _check_table_list(node, item, ".".join(parts[:-1]))
            raise ConfigError(f"--set {item!r}: give an index and a key, e.g. population.0.count=3")
        node[parts[-1]] = value
    return data


def _check_table_list(node: list, item: str, name: str):
    if node and not isinstance(node[0], dict):
        raise ConfigError(
            f"--set {item!r} is not allowed: {name} is a list; set it whole, e.g. {name}=[0, 5]"
        )


def _index(node: list, part: str, key: str):
    if not part.isdigit() or int(part) >= len(node):
        raise ConfigError(f"--set {key}: index {part!r} is not allowed; use 0..{len(node) - 1}")
    return node[int(part)]


def _deepcopy(obj):
    if isinstance(obj, dict):
        return {k: _deepcopy(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_deepcopy(v) for v in obj]
    return obj


def load_config(path: str | Path, overrides: list[str] | None = None) -> Config:
    """Read, override and validate a TOML config file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"config file {str(path)!r} does not exist") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"config file {str(path)!r} is not UTF-8 text (byte {exc.start})"
        ) from None
    except OSError as exc:
        raise ConfigError(f"config file {str(path)!r} cannot be read: {exc.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    cfg = parse_config(apply_overrides(data, overrides), source=str(path))
    return _resolve_paths(cfg, path.parent)


def _resolve_paths(cfg: Config, base: Path) -> Config:
    """Make file paths in the config relative to the config file's folder."""
    c = cfg.constellation
    if c.tle_file and not Path(c.tle_file).is_absolute():
        cfg = cfg.model_copy(
            update={"constellation": c.model_copy(update={"tle_file": str(base / c.tle_file)})}
        )
    pops = [
        p.model_copy(update={"track_file": str(base / p.track_file)})
        if p.track_file and not Path(p.track_file).is_absolute()
        else p
        for p in cfg.population
    ]
    return cfg.model_copy(update={"population": pops})


def dump_toml(cfg: Config) -> str:
    """The resolved config as TOML (every default written out)."""
    return tomli_w.dumps(cfg.to_dict())


# -- reference documentation ------------------------------------------------------


def _type_text(annotation) -> str:
    """``float | None`` -> ``float or none``, ``Literal['a', 'b']`` -> ``'a', 'b'``."""
    import typing

    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is Literal:
        return ", ".join(repr(a) for a in args)
    if origin is list:
        return f"list of {_type_text(args[0])}"
    if args and origin is not Annotated:  # a union
        return " or ".join("none" if a is type(None) else _type_text(a) for a in args)
    return getattr(annotation, "__name__", str(annotation))


def _allowed_text(info) -> str:
    bounds = []
    for m in info.metadata:
        for name, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            value = getattr(m, name, None)
            if value is not None:
                bounds.append(f"{sym} {value:g}")
    return ", ".join(bounds)


def reference_markdown() -> str:
    """Every config key with its type, default, bounds and meaning, as Markdown
    (``docs/config.md`` is this text; a test keeps it in step with the models)."""
    lines = [
        "# Config reference",
        "",
        "One TOML file describes a run (`configs/paper.toml` is the paper's Table). Every key",
        "is optional; the defaults are the paper's. Override any key from the command line",
        "with `--set section.key=value` (lists of tables by index: `population.0.count=3`).",
        "Generated from `leolink/config.py` by `python -m leolink.config`.",
        "",
    ]
    sections = [(name, f.annotation) for name, f in Config.model_fields.items() if name != "source"]
    for name, model in sections:
        model = getattr(model, "__args__", [model])[0]  # list[PopulationSection] -> the model
        title = f"[[{name}]]" if name == "population" else f"[{name}]"
        lines += [
            f"## `{title}`",
            "",
            "| key | type | default | allowed | meaning |",
            "|---|---|---|---|---|",
        ]
        for key, info in model.model_fields.items():
            default = info.default_factory() if info.default_factory else info.default
            lines.append(
                f"| `{key}` | {_type_text(info.annotation)} | `{default!r}` | "
                f"{_allowed_text(info)} | {info.description or ''} |"
            )
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":  # python -m leolink.config > docs/config.md
    print(reference_markdown())
