"""Validated config tables of the handover policies, the layer-3 filter, RLF and KPIs.

One :class:`leolink.registry.Params` model per policy (``[controller.a3]`` etc.), ready for
``POLICIES.register(name, config=..., build=...)``; :data:`POLICY_CONFIGS` and
:func:`build_policy` are what the registration needs. Degrees appear only here, at the
config edge (``*_deg``), and are converted to radians when the policy is built.

The standard's ASN.1 ranges are given in the descriptions (TS 38.331 6.3.2: Hysteresis
0..15 dB in 0.5 dB steps, a3-Offset -15..15 dB in 0.5 dB steps, TimeToTrigger ms0..ms5120
enumerated, hysteresisLocation 0..327.68 km, distanceThreshFromReference up to
3276.25 km, t1 duration 100 ms steps); leolink accepts any physical value (a continuous
sweep is the point of a simulator) and enforces only signs.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Discriminator, Field, Tag, model_validator

from leolink.errors import ConfigError
from leolink.registry import Params
from leolink.sim.handover.decisions import (
    ConditionalHandover,
    GatedTriggerPolicy,
    TriggerPolicy,
)
from leolink.sim.handover.measurement_model import MeasurementModel
from leolink.sim.handover.measurements import FILTER_COEFFICIENTS, L3Filter
from leolink.sim.handover.procedure import SignallingParams
from leolink.sim.handover.rlf import RlfParams
from leolink.sim.handover.triggers import A2, A3, A4, A5
from leolink.sim.handover.triggers_ntn import D1, D2, T1, Elevation, TimeToExit

Level = Literal["cell", "satellite"] | None
FilterCoefficient = Literal[FILTER_COEFFICIENTS]  # type: ignore[valid-type]
_LEVEL = Field(
    None,
    description="candidate axis: 'cell' decides satellite and beam, 'satellite' decides the "
    "satellite and takes the best beam in it; default: the event's own (cell for a3, a4, "
    "a5, d1; satellite for d2, t1, elevation, time_to_exit)",
)
_TTT = Field(0.0, ge=0, description="time-to-trigger [s] (TS 38.331: ms0..ms5120)")
#: Longest service interruption a config may give one handover or beam switch [s].
MAX_INTERRUPTION_S = 3600.0


def interruption_field(doc):
    """The config field of a service interruption [s]: 0 by default, 0 .. 1 h (the one
    definition of ``controller.handover_time_s`` and ``cells.beam_switch_s``)."""
    return Field(0.0, ge=0.0, le=MAX_INTERRUPTION_S, description=doc)


class A3Config(Params):
    kind: Literal["a3"] = "a3"
    offset_db: float = Field(0.0, description="a3-Offset Off [dB], neighbour over serving")
    hysteresis_db: float = Field(0.0, ge=0, description="hysteresis Hys [dB]")
    time_to_trigger_s: float = _TTT
    level: Level = _LEVEL


class A4Config(Params):
    kind: Literal["a4"] = "a4"
    threshold_db: float = Field(-10.0, description="a4-Threshold, in the trigger quantity's unit")
    hysteresis_db: float = Field(0.0, ge=0, description="hysteresis Hys [dB]")
    time_to_trigger_s: float = _TTT
    level: Level = _LEVEL


class A2A4Config(Params):
    """A4 measured while A2 holds (:class:`~leolink.sim.handover.decisions.GatedTriggerPolicy`)."""

    kind: Literal["a2a4"] = "a2a4"
    a2_threshold_db: float = Field(0.0, description="a2-Threshold: serving below it opens "
                                   "the A4 measurement, above it closes it")  # fmt: skip
    a4_threshold_db: float = Field(3.0, description="a4-Threshold: neighbour above it")
    hysteresis_db: float = Field(0.0, ge=0, description="hysteresis Hys of both events [dB]")
    a2_time_to_trigger_s: float = Field(0.0, ge=0, description="A2's time-to-trigger [s]")
    time_to_trigger_s: float = _TTT
    level: Level = _LEVEL


class A5Config(Params):
    kind: Literal["a5"] = "a5"
    threshold1_db: float = Field(-10.0, description="a5-Threshold1: serving below it")
    threshold2_db: float = Field(-5.0, description="a5-Threshold2: neighbour above it")
    hysteresis_db: float = Field(0.0, ge=0, description="hysteresis Hys [dB]")
    time_to_trigger_s: float = _TTT
    level: Level = _LEVEL


class _DistanceConfig(Params):
    kind: Literal["d1", "d2"]
    threshold1_m: float = Field(
        0.0, ge=0, description="distance to the serving reference above it [m]"
    )
    threshold2_m: float = Field(
        0.0, ge=0, description="distance to the candidate reference below it [m]"
    )
    hysteresis_m: float = Field(0.0, ge=0, description="hysteresisLocation [m]")
    time_to_trigger_s: float = _TTT
    level: Level = _LEVEL


class D1Config(_DistanceConfig):
    kind: Literal["d1"] = "d1"  # type: ignore[assignment]
    reference: Literal["beam", "cell", "points"] = Field(
        "beam",
        description="reference locations: 'beam' each beam's boresight ground point now "
        "(moves with body-fixed beams), 'cell' the Earth-fixed cells of "
        "satellite_array.steering = 'earth_fixed', 'points' the configured "
        "[[controller.reference_points]] (TS 38.331 referenceLocation1/2)",
    )


class D2Config(_DistanceConfig):
    kind: Literal["d2"] = "d2"  # type: ignore[assignment]


class T1Config(Params):
    kind: Literal["t1"] = "t1"
    duration_s: float = Field(1.0, ge=0, description="T1 duration after Thresh1 [s]")
    lead_s: float = Field(
        0.0, description="Thresh1 this long before the serving's end of service [s]"
    )
    horizon_s: float = Field(
        300.0, gt=0, description="look-ahead of the end of service; beyond it: inf [s]"
    )
    level: Level = _LEVEL


class ElevationConfig(Params):
    kind: Literal["elevation"] = "elevation"
    serving_below_deg: float = Field(
        30.0, ge=-90, le=90, description="serving elevation below [deg]"
    )
    candidate_above_deg: float = Field(30.0, ge=-90, le=90, description="candidate above [deg]")
    hysteresis_deg: float = Field(0.0, ge=0, description="hysteresis [deg]")
    time_to_trigger_s: float = _TTT
    level: Level = _LEVEL


class TimeToExitConfig(Params):
    kind: Literal["time_to_exit"] = "time_to_exit"
    offset_s: float = Field(0.0, description="candidate must outlast the serving by this [s]")
    hysteresis_s: float = Field(
        0.0, ge=0, description="hysteresis [s], on the offset and on serving_below_s alike"
    )
    time_to_trigger_s: float = _TTT
    serving_below_s: float | None = Field(
        None,
        gt=0,
        description="only once the serving has less than this minus hysteresis_s left; "
        "leaves above it plus hysteresis_s [s]; none: always",
    )
    horizon_s: float = Field(
        300.0, gt=0, description="look-ahead of the end of service; beyond it: inf [s]"
    )
    level: Level = _LEVEL


#: The event a trigger table without ``kind`` is (the default conditions' event), so that
#: ``--set controller.cho.prepare.offset_db=-3`` amends the default A3 condition.
DEFAULT_TRIGGER_KIND = "a3"


def _trigger_kind(value):
    if isinstance(value, dict):
        return value.get("kind", DEFAULT_TRIGGER_KIND)
    return getattr(value, "kind", None)


TriggerConfig = Annotated[
    Annotated[A3Config, Tag("a3")]
    | Annotated[A4Config, Tag("a4")]
    | Annotated[A5Config, Tag("a5")]
    | Annotated[D1Config, Tag("d1")]
    | Annotated[D2Config, Tag("d2")]
    | Annotated[T1Config, Tag("t1")]
    | Annotated[ElevationConfig, Tag("elevation")]
    | Annotated[TimeToExitConfig, Tag("time_to_exit")],
    Discriminator(_trigger_kind),
]


def _default_prepare() -> TriggerConfig:
    return A3Config.model_validate({})


def _default_execute() -> list[TriggerConfig]:
    return [A3Config.model_validate({"offset_db": 3.0})]


class ChoConfig(Params):
    """Conditional handover; the default conditions are illustrative, not 3GPP values."""

    kind: Literal["cho"] = "cho"
    prepare: TriggerConfig = Field(
        default_factory=_default_prepare,
        description="trigger that prepares a candidate (a table without kind is an a3)",
    )
    execute: list[TriggerConfig] = Field(
        default_factory=_default_execute,
        min_length=1,
        max_length=2,
        description="one or two execution conditions (all must be fulfilled; a table "
        "without kind is an a3)",
    )
    release: Literal[17, 18] = Field(
        18,
        description="3GPP release of the execution rules: at most one of d1, d2, t1 per "
        "candidate; 17 also pairs d1 or t1 with a3, a4 or a5 and has no d2 (TS 38.331 "
        "condExecutionCond)",
    )
    max_prepared: int = Field(8, ge=1, description="prepared candidates per UT (maxNrofCondCells)")
    preparation_delay_s: float = Field(0.0, ge=0, description="network preparation time [s]")
    level: Level = _LEVEL

    @model_validator(mode="after")
    def _execution_rule(self):
        """TS 38.331 condExecutionCond (Rel-18): "The network configures at most one from
        condEventD1, condEventD2 or condEventT1 for the same candidate cell"; Rel-17 (no D2)
        pairs condEventD1 or condEventT1 with condEventA3, A4 or A5 (Rel-18 lets them alone)."""
        kinds = [c.kind for c in self.execute]
        ntn = [k for k in kinds if k in ("d1", "d2", "t1")]
        said = f"controller.cho.execute kinds {kinds} are not allowed"
        if len(ntn) > 1:
            raise ValueError(f"{said}: at most one of d1, d2, t1 per candidate (TS 38.331)")
        if self.release == 17 and "d2" in ntn:
            raise ValueError(f"{said} with release = 17: d2 is Rel-18; use release = 18")
        if self.release == 17 and ntn and not {"a3", "a4", "a5"} & set(kinds):
            raise ValueError(
                f"{said} with release = 17: {ntn[0]} must be paired with a3, a4 or a5 "
                "(TS 38.331 Rel-17); add one, or use release = 18"
            )
        return self


class FilterConfig(Params):
    """``[controller.filter]``: layer-3 filtering (TS 38.331 5.5.3.2)."""

    k: FilterCoefficient = Field(4, description="filterCoefficient (fc0..fc19; 0: off)")
    # 1 ms (below any L1 measurement period of TS 38.133) to 60 s: 1e-300 was taken.
    reference_period_s: float = Field(
        0.2,
        ge=1e-3,
        le=60.0,
        description="sample period the coefficient assumes [s] (L1 period of TS 38.133)",
    )


class SmtcOffsetConfig(Params):
    """One ``[[controller.measurement.smtc_offsets]]`` entry: a satellite's SMTC offset."""

    sat_id: int = Field(ge=0, description="satellite")
    offset_s: float = Field(ge=0, description="its SMTC offset [s], below smtc_period_s")


#: SSB subcarrier spacings of NR (TS 38.211 4.2; SSB: 15, 30 kHz FR1, 120, 240 kHz FR2).
SUBCARRIER_SPACINGS_HZ = (15_000, 30_000, 120_000, 240_000)


class MeasurementConfig(Params):
    """``[controller.measurement]``: the measurement model of the trigger policies
    (:mod:`leolink.sim.handover.measurement_model`); the defaults are today's model:
    every detected cell every epoch, without error, in SNR."""

    quantity: Literal["snr", "rsrp"] = Field(
        "snr",
        description="trigger quantity: the SNR [dB], or SS-RSRP per resource element [dBm] "
        "(TS 38.215 5.1.1); thresholds of a4, a5, a2a4 are then in dBm",
    )
    subcarrier_spacing_hz: Literal[SUBCARRIER_SPACINGS_HZ] = Field(  # type: ignore[valid-type]
        15_000, description="SSB subcarrier spacing [Hz] of the RSRP's resource element"
    )
    period_s: float = Field(
        0.0,
        ge=0,
        le=60.0,
        description="measurement period [s]: samples at its multiples only, the filter "
        "steps once per sample (TS 38.133 9.2.5: >= 200 ms in FR1); 0: every epoch",
    )
    error_db: float = Field(
        0.0,
        ge=0,
        le=30.0,
        description="sigma of each sample's Gaussian error [dB], drawn per UT, cell and "
        "instant (seeded by run.seed)",
    )
    smtc_period_s: float = Field(
        0.0,
        ge=0,
        le=60.0,
        description="SMTC periodicity [s] (SSB-MTC: 5..160 ms); 0: no SMTC, every cell is "
        "measured at every instant",
    )
    smtc_duration_s: float = Field(
        0.005, gt=0, le=60.0, description="SMTC window duration [s] (SSB-MTC: 1..5 ms)"
    )
    smtc_offset_s: float = Field(
        0.0, ge=0, description="SMTC offset of every satellite not in smtc_offsets [s]"
    )
    smtc_offsets: list[SmtcOffsetConfig] = Field(
        default_factory=list,
        description="per-satellite SMTC offsets, entries {sat_id, offset_s} (Rel-17 "
        "smtc4list-r17: the NTN's SMTCs per satellite group)",
    )

    @model_validator(mode="after")
    def _smtc(self):
        if self.smtc_period_s <= 0:
            return self
        p = self.smtc_period_s
        if self.smtc_duration_s > p:
            raise ValueError(
                f"controller.measurement.smtc_duration_s = {self.smtc_duration_s!r} is not "
                f"allowed: use at most smtc_period_s = {p!r} [s]"
            )
        offsets = [("smtc_offset_s", self.smtc_offset_s)]
        offsets += [
            (f"smtc_offsets.{i}.offset_s", o.offset_s) for i, o in enumerate(self.smtc_offsets)
        ]
        for key, value in offsets:
            if value >= p:
                raise ValueError(
                    f"controller.measurement.{key} = {value!r} is not allowed: use 0 <= "
                    f"offset < smtc_period_s = {p!r} [s]"
                )
        return self


class RlfConfig(Params):
    """``[controller.rlf]``: radio link failure (TS 38.331 5.3.10; defaults 9.2.3)."""

    enabled: bool = Field(False, description="monitor the serving SINR and declare RLF")

    q_out_db: float = Field(-8.0, description="out-of-sync below this SINR [dB] (study value)")
    q_in_db: float = Field(-6.0, description="in-sync above this SINR [dB] (study value)")
    t310_s: float = Field(1.0, ge=0, le=6.0, description="T310 [s] (ms0..ms6000)")
    n310: int = Field(1, ge=1, le=20, description="out-of-sync indications to start T310")
    n311: int = Field(1, ge=1, le=10, description="in-sync indications to stop T310")
    reestablishment_s: float = Field(0.2, ge=0, description="RLF to service [s] (placeholder)")


class ReferencePointConfig(Params):
    """One ``[[controller.reference_points]]`` entry: a cell's referenceLocation (D1)."""

    sat_id: int = Field(ge=0, description="satellite of the cell")
    beam_id: int | None = Field(None, ge=0, description="beam of the cell; none: every beam")
    lat_deg: float = Field(ge=-90, le=90, description="latitude [deg] (geodetic on WGS 84)")
    lon_deg: float = Field(ge=-180, le=360, description="longitude [deg]")


class CellOffsetConfig(Params):
    """One ``[[controller.cell_offsets]]`` entry: the cellIndividualOffset of a cell."""

    sat_id: int = Field(ge=0, description="satellite of the cell")
    beam_id: int | None = Field(None, ge=0, description="beam of the cell; none: every beam")
    offset_db: float = Field(
        ge=-24, le=24, description="Ocn [dB] (Q-OffsetRange -24..24 dB, TS 38.331)"
    )


class SignallingConfig(Params):
    """``[controller.signalling]``: the handover procedure in simulated time
    (:mod:`leolink.sim.handover.procedure`); off: a handover takes ``handover_time_s``."""

    enabled: bool = Field(
        False,
        description="report, command, T304 and access in simulated time; the interruption "
        "replaces handover_time_s and a failed handover re-establishes (needs "
        "controller.rlf.enabled)",
    )
    network_processing_s: float = Field(
        0.01, ge=0, description="report received to command sent, preparation included [s]"
    )
    ue_processing_s: float = Field(
        0.01,
        ge=0,
        description="command received to access start [s] (RRC procedure delay, TS 38.133: 10 ms)",
    )
    t304_s: float = Field(
        1.0, description="T304 [s]: 0.05, 0.1, 0.15, 0.2, 0.5, 1, 2 or 10 (TS 38.331)"
    )
    access: Literal["rach", "rach_less"] = Field(
        "rach",
        description="four-step random access, or RACH-less (Rel-18: first uplink on "
        "the configured grant, one way)",
    )
    rach_attempts: int = Field(
        1, ge=1, le=200, description="random accesses until success (preambleTransMax <= 200)"
    )
    rach_processing_s: float = Field(
        0.0, ge=0, description="per attempt, besides its two round trips to the target [s]"
    )


class CellsConfig(Params):
    """``[cells]``: what a cell is (:mod:`leolink.sim.handover.cells`)."""

    per: Literal["beam", "satellite"] = Field(
        "beam",
        description="'beam': every beam is a cell, a beam change is a beam_handover; "
        "'satellite': a satellite is one cell, a beam change inside it is a beam_switch "
        "(L1/L2, not a handover) and the trigger policies compare satellites",
    )
    beam_switch_s: float = interruption_field("service interruption per beam_switch [s]")


class KpiConfig(Params):
    """``[kpi]``."""

    ping_pong_s: float = Field(1.0, gt=0, description="minimum time of stay for ping-pong [s]")
    mro_window_s: float = Field(
        1.0,
        gt=0,
        description="an RLF this soon after a handover's trigger is too early or to a wrong "
        "cell, later too late (TS 38.300 15.5.2.2.2; Tstore_UE_cntxt, set by OAM) [s]",
    )


_TRIGGER_OF = {
    "a3": lambda c: A3(c.offset_db, c.hysteresis_db, c.time_to_trigger_s),
    "a4": lambda c: A4(c.threshold_db, c.hysteresis_db, c.time_to_trigger_s),
    "a5": lambda c: A5(c.threshold1_db, c.threshold2_db, c.hysteresis_db, c.time_to_trigger_s),
    "d1": lambda c: D1(
        c.threshold1_m, c.threshold2_m, c.hysteresis_m, c.time_to_trigger_s, c.reference
    ),
    "d2": lambda c: D2(c.threshold1_m, c.threshold2_m, c.hysteresis_m, c.time_to_trigger_s),
    "t1": lambda c: T1(c.duration_s, c.lead_s),
    "elevation": lambda c: Elevation(
        math.radians(c.serving_below_deg),
        math.radians(c.candidate_above_deg),
        math.radians(c.hysteresis_deg),
        c.time_to_trigger_s,
    ),
    "time_to_exit": lambda c: TimeToExit(
        c.offset_s,
        c.hysteresis_s,
        c.time_to_trigger_s,
        math.inf if c.serving_below_s is None else c.serving_below_s,
    ),
}

#: Policy config models by ``controller.policy`` name.
POLICY_CONFIGS: dict[str, type[Params]] = {
    "a3": A3Config,
    "a4": A4Config,
    "a5": A5Config,
    "d1": D1Config,
    "d2": D2Config,
    "t1": T1Config,
    "elevation": ElevationConfig,
    "time_to_exit": TimeToExitConfig,
    "cho": ChoConfig,
    "a2a4": A2A4Config,
}


def build_trigger(config, context=None, key=None):
    """The trigger event of a validated trigger config; with a build ``context`` (what
    the run has: ``steering``, ``reference_points``), a D1 reference the run cannot give
    is refused, naming ``key`` (the config table)."""
    if config.kind == "d1" and context is not None:
        _check_reference(config, context, key or "controller.d1")
    return _TRIGGER_OF[config.kind](config)


def _check_reference(config, context, key):
    ref = config.reference
    steering = getattr(context, "steering", "body_fixed")
    if ref == "cell" and steering != "earth_fixed":
        raise ConfigError(
            f"{key}.reference = 'cell' is not allowed with satellite_array.steering = "
            f"{steering!r}: Earth-fixed cells need 'earth_fixed' (use 'beam' or 'points')"
        )
    if ref == "points" and not getattr(context, "reference_points", ()):
        raise ConfigError(
            f"{key}.reference = 'points' is not allowed without [[controller.reference_points]]:"
            " give each cell's referenceLocation (sat_id, beam_id, lat_deg, lon_deg)"
        )
    if ref == "cell" and (config.level or getattr(context, "level", None)) == "satellite":
        raise ConfigError(
            f"{key}.reference = 'cell' is not allowed at level 'satellite' (cells.per = "
            "'satellite' or level = 'satellite'): a satellite has no one Earth-fixed cell"
        )


def build_policy(config, context=None):
    """The policy of a validated policy config (the registry's ``build`` hook); a
    ``context.level`` (cells = satellites) is the level where the config gives none."""
    level = config.level or getattr(context, "level", None)
    if config.kind == "a2a4":
        gate = A2(config.a2_threshold_db, config.hysteresis_db, config.a2_time_to_trigger_s)
        trigger = A4(config.a4_threshold_db, config.hysteresis_db, config.time_to_trigger_s)
        return GatedTriggerPolicy(gate, trigger, level)
    if config.kind == "cho":
        return ConditionalHandover(
            build_trigger(config.prepare, context, "controller.cho.prepare"),
            [
                build_trigger(c, context, f"controller.cho.execute.{i}")
                for i, c in enumerate(config.execute)
            ],
            config.max_prepared,
            config.preparation_delay_s,
            level,
        )
    return TriggerPolicy(build_trigger(config, context, f"controller.{config.kind}"), level)


def build_filter(config):
    return L3Filter(config.k, config.reference_period_s)


def build_measurement(config, noise_temp_dbk):
    """The measurement model of ``[controller.measurement]`` (``noise_temp_dbk`` [dBK]:
    the system noise temperature RSRP is counted from), None when it is today's."""
    model = MeasurementModel(
        config.period_s,
        config.error_db,
        config.quantity,
        float(noise_temp_dbk),
        float(config.subcarrier_spacing_hz),
        config.smtc_period_s,
        config.smtc_duration_s,
        config.smtc_offset_s,
        tuple((o.sat_id, o.offset_s) for o in config.smtc_offsets),
    )
    return None if model.is_off else model


def build_rlf(config):
    """The RLF parameters of ``[controller.rlf]``, None when it is not enabled."""
    if not getattr(config, "enabled", True):
        return None
    return RlfParams(**{k: v for k, v in dict(config).items() if k != "enabled"})


def build_signalling(config):
    """The procedure's parameters of ``[controller.signalling]``, None when it is off."""
    if not config.enabled:
        return None
    return SignallingParams(**{k: v for k, v in dict(config).items() if k != "enabled"})
