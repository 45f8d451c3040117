"""The config sections with fixed keys (``[run]``, ``[earth]``, ``[constellation]``, ...).

Sections whose keys depend on a chosen kind (terminal, atmosphere, controller policy,
populations, outputs) are built from the registries in :mod:`leolink.config.kinds`.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, BeforeValidator, Field, model_validator

from leolink.constants import EARTH_RADIUS_M, GM_EARTH_M3_S2
from leolink.link.acm import ROLLOFFS
from leolink.link.figures import system_noise_temp_k
from leolink.registry import STRICT_MODEL, whole

_ISO_EXAMPLE = "e.g. 2019-12-09T16:37:29.363Z"
#: Years a UTC instant may fall in: those of Vallado's Julian-date algorithm that sgp4 uses
#: ("valid for years 1900 to 2100"; GMST-1982 is fitted to the same era). Year 0001 was
#: accepted before, and start_s of -100 years overflowed Python's datetime.
UTC_YEARS = (1900, 2100)


def parse_utc(key, text):
    """An ISO 8601 date and time as an aware UTC ``datetime`` (naive text is UTC)."""
    from datetime import UTC, datetime

    try:
        when = datetime.fromisoformat(text)
    except ValueError:
        raise ValueError(
            f"{key} = {text!r} is not allowed: use an ISO 8601 date and time, {_ISO_EXAMPLE}"
        ) from None
    when = when.astimezone(UTC) if when.tzinfo else when.replace(tzinfo=UTC)
    if not UTC_YEARS[0] <= when.year <= UTC_YEARS[1]:
        raise ValueError(
            f"{key} = {text!r} is not allowed: use a date in the years {UTC_YEARS[0]} to "
            f"{UTC_YEARS[1]}, where the sidereal time and sgp4's dates hold"
        )
    return when


__all__ = [
    "MAX_EPOCHS",
    "ConstellationSection",
    "EarthSection",
    "LinkSection",
    "ModcodSection",
    "MultibeamSection",
    "RoiSection",
    "RunSection",
    "SatelliteArraySection",
    "Section",
]

#: Most epochs one run may have (their times alone take 8 bytes each).
MAX_EPOCHS = 1e8
#: Longest time span of a config [s]: 100 years (TLEs are useless long before).
MAX_TIME_S = 3.2e9
#: Largest ROI semi-axis in the ROI plane [m] (central angle 72 deg); the real limit is
#: the visible cap, checked against the orbit (:class:`leolink.config.ConfigBase`).
MAX_ROI_M = 2.0e7
#: Epoch times are ``start_s + k epoch_s``: their float spacing must stay below this
#: fraction of an epoch, and duration and warm-up must be whole epochs to this tolerance.
EPOCH_TOLERANCE = 1e-6


class Section(BaseModel):
    """A config table: unknown keys, NaN/inf and type coercions are refused."""

    model_config = STRICT_MODEL


def _f(default, *, gt=None, ge=None, le=None, lt=None, doc=""):
    return Field(default, gt=gt, ge=ge, le=le, lt=lt, description=doc)


class RunSection(Section):
    seed: int = _f(20201, ge=0, le=2**63 - 1, doc="seed of the run's random generator")
    epoch_s: float = _f(
        1.0, ge=1e-6, le=86_400.0, doc="time step between two controller decisions [s]"
    )
    start_s: float = _f(
        0.0,
        ge=-MAX_TIME_S,
        le=MAX_TIME_S,
        doc="simulation time of the first epoch [s] (+-100 years)",
    )
    duration_s: float = _f(
        120.0, gt=0, le=MAX_TIME_S, doc="simulated time after the warm-up [s] (<= 100 years)"
    )
    warmup_s: float = _f(0.0, ge=0, le=MAX_TIME_S, doc="simulated time before recording starts [s]")
    start_utc: str = _f(
        "",
        doc="UTC instant of the first epoch, ISO 8601, years 1900-2100 (none: TLE runs start "
        "at the first TLE's epoch; needed by tracks with UTC timestamps)",
    )

    def utc_of_time_zero(self):
        """Aware ``datetime`` of simulation time 0 (``start_utc - start_s``), or None."""
        from datetime import timedelta

        if not self.start_utc:
            return None
        return parse_utc("run.start_utc", self.start_utc) - timedelta(seconds=self.start_s)

    @model_validator(mode="after")
    def _check(self):
        if self.start_utc:
            parse_utc("run.start_utc", self.start_utc)
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
        self._check_grid()
        return self

    def _check_grid(self):
        """Whole epochs in the duration and warm-up, and epoch times that float can hold
        (``start_s = 1e17`` would collapse every epoch onto one time)."""
        import math

        for key in ("duration_s", "warmup_s"):
            span = getattr(self, key)
            n = round(span / self.epoch_s)
            if abs(n * self.epoch_s - span) > EPOCH_TOLERANCE * self.epoch_s:
                raise ValueError(
                    f"run.{key} = {span!r} is not allowed: it must be a whole number of epochs "
                    f"(run.epoch_s = {self.epoch_s!r}; {n} epochs give {n * self.epoch_s:g} s)"
                )
        last = max(abs(self.start_s), abs(self.start_s + self.warmup_s + self.duration_s))
        if math.ulp(last) > EPOCH_TOLERANCE * self.epoch_s:
            raise ValueError(
                f"run.start_s = {self.start_s!r} is not allowed with run.epoch_s = "
                f"{self.epoch_s!r}: epoch times near {last:.3g} s are only resolved to "
                f"{math.ulp(last):.3g} s; use a start time closer to 0 or a longer epoch"
            )


class EarthSection(Section):
    model: Literal["sphere", "wgs84"] = _f(
        "sphere",
        doc="shape under the UTs: the paper's sphere, or the WGS 84 ellipsoid (geodetic "
        "positions, ellipsoidal local frames and elevations)",
    )
    radius_m: float = _f(
        EARTH_RADIUS_M,
        gt=6.0e6,
        lt=6.5e6,
        doc="spherical Earth radius [m] (orbits, ROI plane and codebook use it with either model)",
    )
    gm_m3_s2: float = _f(
        GM_EARTH_M3_S2,
        ge=3.9e14,
        le=4.1e14,
        doc="Earth's gravitational parameter [m^3/s^2] (within 2.5 % of 3.986e14)",
    )
    rotation: bool = _f(False, doc="rotate the Earth under the orbits (ECEF frame)")


class ConstellationSection(Section):
    kind: Literal["pass", "walker", "tle"] = _f("pass", doc="how satellites are placed")
    altitude_m: float = _f(1_300_000.0, gt=100_000.0, lt=40_000_000.0, doc="orbit altitude [m]")
    inclination_deg: float = _f(53.0, ge=0.0, le=180.0, doc="orbital plane inclination [deg]")
    n_planes: int = _f(83, ge=1, le=1000, doc="number of orbital planes N_p")
    sats_per_plane: int = _f(53, ge=1, le=1000, doc="satellites per orbital plane N_s")
    phasing: int = _f(1, ge=0, le=999, doc="Walker phasing factor F (< n_planes)")
    pass_time_s: float = _f(
        60.0,
        ge=-MAX_TIME_S,
        le=MAX_TIME_S,
        doc="kind = 'pass': time the satellite is over the ROI centre [s]",
    )
    ascending: bool = _f(True, doc="kind = 'pass': pass on the ascending half of the orbit")
    tle_file: str = _f("", doc="kind = 'tle': path of a file of two-line element sets")
    tle_epoch_utc: str = _f(
        "", doc="kind = 'tle': UTC instant of simulation time 0 (ISO 8601); prefer run.start_utc"
    )
    min_elevation_deg: float = _f(10.0, ge=0.0, le=90.0, doc="lowest usable elevation [deg]")

    @model_validator(mode="after")
    def _check(self):
        if self.tle_epoch_utc:
            parse_utc("constellation.tle_epoch_utc", self.tle_epoch_utc)
        if self.kind == "walker" and self.phasing >= self.n_planes:
            raise ValueError(
                f"constellation.phasing = {self.phasing} is not allowed: the Walker phasing "
                f"factor F must be below constellation.n_planes = {self.n_planes}"
            )
        return self


RoiAxis = Annotated[float, Field(gt=0.0, le=MAX_ROI_M)] | Literal["derived"]


class RoiSection(Section):
    center_lat_deg: float = _f(42.24, ge=-90.0, le=90.0, doc="ROI centre latitude [deg]")
    center_lon_deg: float = _f(-8.72, ge=-180.0, le=360.0, doc="ROI centre longitude [deg]")
    # The defaults are the paper's Table (534.1 x 170.5 km), which its 15 beams cover
    # without holes; "derived" is Sec. 3.1's ROI (534.1 x 272.4 km for the Table's
    # constellation), which 15 RF chains cannot cover (docs/errata.md).
    semi_axis_x_m: RoiAxis = _f(
        534.1e3,
        doc="ROI semi-axis along-track [m] (the Table's), or 'derived' (Sec. 3.1); at most "
        "the visible cap",
    )
    semi_axis_y_m: RoiAxis = _f(
        170.5e3,
        doc="ROI semi-axis cross-track [m] (the Table's), or 'derived' (Sec. 3.1); at most "
        "the visible cap",
    )


class LinkSection(Section):
    freq_hz: float = _f(11.45e9, gt=1e8, lt=1e12, doc="carrier frequency [Hz]")
    bandwidth_hz: float = _f(250e6, ge=1e3, le=1e11, doc="downlink bandwidth [Hz]")
    ptx_dbw: float = _f(
        15.0,
        ge=-100.0,
        le=100.0,
        doc="transmit power [dBW]; per beam unless power_mode = 'split_total'",
    )
    power_mode: Literal["per_beam", "split_total"] = _f("per_beam", doc="meaning of ptx_dbw")
    cable_loss_db: float = _f(0.0, ge=0, le=100.0, doc="loss between transmitter and array [dB]")
    noise_temp_dbk: float = _f(
        24.1, ge=-20.0, le=60.0, doc="receiver noise temperature [dBK] (0.01 K to 1e6 K)"
    )
    rician_k: float = _f(10.0, gt=0, le=1e6, doc="Rician factor K_r (linear)")
    fading: Literal["mean", "rician"] = _f("mean", doc="paper's mean receive gain or random draws")
    reuse_colors: Annotated[Literal[1, 3, 4], BeforeValidator(whole)] = _f(
        1, doc="frequency-reuse colours (1 = full reuse)"
    )
    interference: Literal["serving_satellite", "all_satellites"] = _f(
        "serving_satellite", doc="whose other beams interfere (the paper: the serving satellite's)"
    )
    eirp_density_dbw_mhz: float | None = _f(
        None,
        ge=-100.0,
        le=100.0,
        doc="satellite EIRP density at a beam's peak [dBW/MHz] (TR 38.821 Table 6.1.1.1-1); "
        "when given it sets the power per beam (ptx_dbw = density + 10 log10(B / 1 MHz) - "
        "peak gain + cable loss; power_mode and ptx_dbw are then ignored)",
    )
    antenna_temp_k: float | None = _f(
        None,
        gt=0,
        le=1e6,
        doc="UT antenna temperature [K]; with noise_figure_db it sets the system noise "
        "temperature T_a + 290 (10^(NF/10) - 1) (TR 38.821 Table 6.1.1.1-3); noise_temp_dbk "
        "is then ignored",
    )
    noise_figure_db: float | None = _f(None, ge=0, le=50.0, doc="UT receiver noise figure [dB]")
    scintillation_loss_db: float = _f(
        0.0, ge=0, le=100.0, doc="scintillation loss [dB] (TR 38.811 6.6.6)"
    )
    shadow_margin_db: float = _f(
        0.0, ge=0, le=100.0, doc="shadowing margin [dB] (TR 38.821 6.1.3.2)"
    )
    polarization_loss_db: float = _f(0.0, ge=0, le=100.0, doc="polarization mismatch loss [dB]")
    additional_loss_db: float = _f(0.0, ge=0, le=100.0, doc="any further loss of the budget [dB]")

    @model_validator(mode="after")
    def _check(self):
        if (self.antenna_temp_k is None) != (self.noise_figure_db is None):
            raise ValueError(
                "link.antenna_temp_k and link.noise_figure_db go together: give both (the "
                "system noise temperature from them) or neither (link.noise_temp_dbk)"
            )
        return self

    @property
    def other_loss_db(self) -> float:
        """Scintillation + shadowing margin + polarization + additional losses [dB]."""
        return (
            self.scintillation_loss_db
            + self.shadow_margin_db
            + self.polarization_loss_db
            + self.additional_loss_db
        )

    @property
    def system_noise_temp_dbk(self) -> float:
        """The receiver's noise temperature [dBK]: noise_temp_dbk, or from T_a and NF."""
        if self.antenna_temp_k is None:
            return self.noise_temp_dbk
        t_k = system_noise_temp_k(self.antenna_temp_k, self.noise_figure_db)
        return 10.0 * math.log10(float(t_k))


class ModcodSection(Section):
    rolloff: float = _f(
        0.2,
        ge=0.05,
        le=0.35,
        doc="root-raised-cosine roll-off alpha, one of DVB-S2X's 0.05, 0.1, 0.15, 0.2, 0.25, "
        "0.35: symbol rate B / (1 + alpha)",
    )
    implementation_margin_db: float = _f(
        0.0,
        ge=0.0,
        le=20.0,
        doc="added to every MODCOD's ideal Es/N0 (EN 302 307 Table 13 / 20a are ideal, AWGN) [dB]",
    )
    required_esn0_db: float | None = _f(
        None,
        ge=-30.0,
        le=60.0,
        doc="Es/N0 the link margin is counted from [dB]; none: the most robust MODCOD's "
        "threshold plus the implementation margin",
    )
    metric: Literal["sinr", "snr"] = _f(
        "sinr",
        doc="Es/N0 of the MODCOD and margin from the SINR (interference as noise) or the SNR",
    )
    throughput_model: Literal["shannon", "dvbs2x"] = _f(
        "shannon",
        doc="what throughput_bps and se_bps_hz hold: B log2(1 + SINR) (the paper) or the ACM "
        "MODCOD's eta B / (1 + alpha); the summary gives both",
    )

    @model_validator(mode="after")
    def _check(self):
        if not any(math.isclose(self.rolloff, r) for r in ROLLOFFS):
            raise ValueError(
                f"modcod.rolloff = {self.rolloff!r} is not allowed: use one of "
                f"{', '.join(map(str, ROLLOFFS))} (EN 302 307-1/-2 clause 5.6)"
            )
        return self


class SatelliteArraySection(Section):
    n_x: int = _f(60, ge=1, le=2000, doc="elements along-track")
    n_y: int = _f(72, ge=1, le=2000, doc="elements cross-track")
    n_rf_x: int = _f(5, ge=1, le=2000, doc="RF chains (subarrays) along-track")
    n_rf_y: int = _f(3, ge=1, le=2000, doc="RF chains (subarrays) cross-track")
    oversampling: Annotated[float, Field(gt=0.0, le=100.0)] | Literal["auto"] = _f(
        1.2,
        doc="DFT oversampling factor O in (0, 100], or 'auto' (the most beams the RF chains "
        "can drive)",
    )
    antenna: Literal["hybrid_upa", "circular_aperture"] = _f(
        "hybrid_upa",
        doc="the paper's hybrid UPA and DFT codebook, or the TR 38.811 Sec. 6.4.1 circular "
        "aperture (leolink budget: one beam on the UT; leolink run: the [multibeam] snapshot)",
    )
    aperture_diameter_m: float = _f(
        0.5, gt=0.0, le=100.0, doc="antenna = 'circular_aperture': diameter D = 2a [m]"
    )
    aperture_gain_dbi: float = _f(
        38.5, ge=0.0, le=80.0, doc="antenna = 'circular_aperture': boresight gain G_max [dBi]"
    )
    allow_holes: bool = _f(
        False,
        doc="accept a codebook with holes: O < 1, or a point of the ROI more than 13.26 dB "
        "(a first sidelobe) below every beam's peak",
    )
    phase_bits: Annotated[int, Field(ge=1, le=16)] | None = _f(
        None,
        doc="phase-shifter resolution of the beam weights [bit] (none: ideal phases, the paper)",
    )

    @model_validator(mode="after")
    def _check(self):
        for axis in ("x", "y"):
            n, n_rf = getattr(self, f"n_{axis}"), getattr(self, f"n_rf_{axis}")
            if n % n_rf:
                raise ValueError(
                    f"satellite_array.n_{axis} = {n} is not allowed: it must be a multiple of "
                    f"n_rf_{axis} = {n_rf} (equal subarrays, one per RF chain)"
                )
        return self


class MultibeamSection(Section):
    """``[multibeam]``: the single-satellite snapshot that ``leolink run`` makes of a
    circular-aperture config (TR 38.821 clause 6.1.1, :mod:`leolink.multibeam`)."""

    tiers: int = _f(
        4,
        ge=0,
        le=30,
        doc="satellite_array.antenna = 'circular_aperture': hexagonal tiers of beams around "
        "the central (nadir) beam; TR 38.821 Table 6.1.1.1-5: 4 (61 beams) at reuse 1, 6 "
        "(127 beams) at reuse > 1",
    )
    inner_tiers: int = _f(
        2, ge=0, le=30, doc="tiers whose cells hold the statistics' UTs (TR 38.821: 2, 19 beams)"
    )
    hpbw_deg: float | None = _f(
        None,
        gt=0.0,
        le=90.0,
        doc="3 dB beamwidth the beam spacing sqrt(3) sin(HPBW / 2) comes from [deg] (TR "
        "38.821 Table 6.1.1.1-1: 1.7647 Ka, 4.4127 S); none: the aperture's own",
    )
    uts_per_beam: int = _f(
        500,
        ge=1,
        le=100_000,
        doc="static UTs dropped uniformly per inner cell, on average (TR 38.821: at least 10)",
    )

    @model_validator(mode="after")
    def _check(self):
        if self.inner_tiers > self.tiers:
            raise ValueError(
                f"multibeam.inner_tiers = {self.inner_tiers!r} is not allowed: at most "
                f"multibeam.tiers = {self.tiers!r}"
            )
        return self


class TimingSection(Section):
    """``[timing]``: the NTN timing columns of the trace (:mod:`leolink.timing`)."""

    enabled: bool = _f(
        False,
        doc="add ta_s, common_ta_s, k_offset_ms and doppler_residual_hz to the trace (the "
        "UT's timing advance and Doppler pre-compensation from the believed ephemeris)",
    )
    reference_point: Literal["nadir", "satellite"] = _f(
        "nadir",
        doc="uplink synchronisation reference point (the feeder link is not modelled): "
        "'nadir', common TA = 2 x altitude / c; 'satellite', common TA = 0",
    )
    n_ta_offset: Literal[0, 25600, 39936] = _f(
        0, doc="n-TimingAdvanceOffset in T_c (TS 38.331: n0, n25600, n39936)"
    )
    sib19_validity_s: Literal[5, 10, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60, 120, 180, 240, 900] = (
        _f(
            10,
            doc="export-ntn: ntn-UlSyncValidityDuration of each ephemeris record [s] "
            "(TS 38.331: s5..s60 in 5 s steps, s120, s180, s240, s900)",
        )
    )
