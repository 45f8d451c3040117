"""NTN uplink timing and Doppler pre-compensation of a UT from the broadcast ephemeris.

An NR NTN UE (TS 38.300 16.14.2) computes its timing advance and the Doppler of its
service link itself, from its GNSS position and the satellite ephemeris broadcast in
SIB19; with an ephemeris error (:mod:`leolink.ephemeris_error`) the broadcast state is
the *believed* one, so the TA and the Doppler it pre-compensates are off by what the
error moves the range and the range rate. The functions here are that computation; the
monitor (:mod:`leolink.sim.monitor`) calls them on every trace row when ``[timing]`` is on.

Formulas (leolink's choices where the standard leaves one are marked *choice*):

- Timing advance, TS 38.211 4.3.1: ``T_TA = (N_TA + N_TA,offset + N_TA,adj^common +
  N_TA,adj^UE) T_c`` with ``T_c = 1 / (480 kHz * 4096)``. leolink models initial
  access and open-loop pre-compensation: ``N_TA = 0`` (no closed-loop TA command), and
  ``N_TA,adj^UE T_c = 2 d_believed / c``, the service-link round trip the UE computes
  from its position and the believed satellite position (TS 38.213 4.2).
- Common TA (TS 38.213 4.2: ``Delay_common``, the one-way delay between the satellite
  and the uplink synchronisation reference point RP; TS 38.300 16.14.2.1: the common TA
  is the RTT between the RP and the NTN payload). *Choice*: the feeder link is not
  modelled (the satellite stands for the gNB), so the RP lies on the service link, at
  the satellite's nadir (``reference_point = "nadir"``: ``common_ta_s = 2 h / c``, ``h``
  the believed altitude above the sphere) or at the satellite (``"satellite"``: 0). An
  RP on the service side is crossed by both paths, so the network absorbs that RTT and
  the UE advances by the rest: ``ta_s = 2 d_believed / c - common_ta_s + N_TA,offset
  T_c``. (Rel-17's ``ta-Common`` is non-negative because its RP lies on the feeder
  side, where it would add; a run with a feeder link would put its RTT there.)
- K_offset, TS 38.213 (``K_offset = K_cell,offset - K_UE,offset``) and TS 38.300
  16.14.2.1 (it "needs to be larger or equal to the sum of the service link RTT and the
  Common TA"): the cell-specific value, in slots of 15 kHz (``mu_Koffset = 0``, 1 ms),
  the largest TA of the cell rounded up: ``ceil((2 d_max / c - common_ta_s) / 1 ms)``
  with ``d_max`` the slant range at the minimum elevation (the cell's far edge), at
  least 1 (``cellSpecificKoffset`` 1..1023). The UE-specific MAC CE part is not modelled.
- Doppler residual: the UE pre-compensates the service-link Doppler it computes from
  its own position and velocity and the believed satellite state (TS 38.300 16.14.2.2);
  the residual is the true Doppler minus that one, 0 without an ephemeris error.

References
----------
.. [1] 3GPP TS 38.211 V18.7.0, clause 4.3.1 (timing advance).
.. [2] 3GPP TS 38.213 V18.7.0, clause 4.2 (NTN timing, common TA, K_offset).
.. [3] 3GPP TS 38.300 V18.6.0, clause 16.14.2 (NTN uplink timing and frequency).
.. [4] 3GPP TS 38.321 V18.6.0, clause 3 (UE-gNB RTT = UE TA + k_mac).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from leolink.geometry import slant_range_from_elevation_m
from leolink.kinematics import doppler_hz, propagation_delay_s

__all__ = [
    "N_TA_OFFSETS",
    "REFERENCE_POINTS",
    "SLOT_15KHZ_S",
    "TIMING_COLUMNS",
    "T_C_S",
    "TimingParams",
    "believed_range_m",
    "common_ta_drift_s_s",
    "common_ta_s",
    "doppler_residual_hz",
    "k_offset_ms",
    "timing_advance_s",
    "timing_columns",
]

#: Basic time unit of NR, TS 38.211 4.1: ``1 / (480e3 * 4096)`` [s].
T_C_S = 1.0 / (480e3 * 4096)
#: Slot of K_offset (15 kHz subcarrier spacing, ``mu_Koffset = 0``) [s].
SLOT_15KHZ_S = 1e-3
#: ``n-TimingAdvanceOffset`` values (TS 38.331: n0, n25600, n39936) in units of T_c.
N_TA_OFFSETS = (0, 25600, 39936)
#: Where the uplink synchronisation reference point lies (module docstring).
REFERENCE_POINTS = ("nadir", "satellite")


def common_ta_s(sat_pos_m, radius_m, reference_point="nadir"):
    """Common TA: the round trip between the satellite and the reference point [s].

    Parameters
    ----------
    sat_pos_m : array_like, shape (..., 3)
        Believed satellite position, Earth-centred [m].
    radius_m : float
        Radius of the sphere the nadir lies on [m].
    reference_point : {"nadir", "satellite"}

    Returns
    -------
    ndarray, shape (...)
        ``2 h / c`` with ``h = |r| - R`` (nadir), or 0 (satellite) [s].
    """
    if reference_point not in REFERENCE_POINTS:
        raise ValueError(f"reference_point = {reference_point!r}; use one of {REFERENCE_POINTS}")
    r = np.linalg.norm(np.asarray(sat_pos_m, float), axis=-1)
    if reference_point == "satellite":
        return r * 0.0  # (NaN stays NaN: a row without a link)
    return 2.0 * propagation_delay_s(r - radius_m)


def common_ta_drift_s_s(sat_pos_m, sat_vel_m_s, reference_point="nadir"):
    """Rate of :func:`common_ta_s` [s/s] (SIB19 ``ta-CommonDrift``): ``2 (r . v) / (|r| c)``
    (the altitude rate) at the nadir, 0 at the satellite; shapes (..., 3) -> (...)."""
    pos, vel = np.asarray(sat_pos_m, float), np.asarray(sat_vel_m_s, float)
    rate = np.einsum("...k,...k->...", pos, vel) / np.linalg.norm(pos, axis=-1)
    return 2.0 * propagation_delay_s(rate) * (reference_point == "nadir")


def timing_advance_s(believed_range_m, common_s, n_ta_offset=0):
    """Full TA the UE applies, ``2 d_believed / c - common_ta + N_TA,offset T_c`` [s].

    Parameters
    ----------
    believed_range_m : array_like
        Slant range from the UE's GNSS position to the believed satellite position [m].
    common_s : array_like
        :func:`common_ta_s` [s].
    n_ta_offset : int
        ``n-TimingAdvanceOffset`` in T_c (one of :data:`N_TA_OFFSETS`).
    """
    return 2.0 * propagation_delay_s(believed_range_m) - common_s + n_ta_offset * T_C_S


def k_offset_ms(altitude_m, min_elevation_rad, radius_m, common_s, n_ta_offset=0):
    """Cell-specific K_offset [ms = slots at 15 kHz]: the cell's largest TA rounded up.

    Parameters
    ----------
    altitude_m : array_like
        Believed satellite altitude above the sphere [m].
    min_elevation_rad : float
        Minimum elevation: the cell's far edge [rad].
    radius_m : float
        Earth radius [m].
    common_s : array_like
        :func:`common_ta_s` of the same satellites [s].

    Returns
    -------
    ndarray of float (integers), at least 1 (``cellSpecificKoffset`` 1..1023).
    """
    d_max = slant_range_from_elevation_m(min_elevation_rad, altitude_m, radius_m)
    ta_max = timing_advance_s(d_max, common_s, n_ta_offset)
    # 1e-9 slots: a TA on a slot boundary (to float rounding) needs no extra slot
    return np.maximum(1.0, np.ceil(ta_max / SLOT_15KHZ_S - 1e-9))


def doppler_residual_hz(true_doppler_hz, believed, ut_pos_m, ut_vel_m_s, freq_hz):
    """True minus pre-compensated Doppler of the service link [Hz].

    Parameters
    ----------
    true_doppler_hz : array_like, shape (n,)
        Doppler of the true states (the trace's ``doppler_hz``) [Hz].
    believed : tuple of ndarray (n, 3)
        Believed satellite position [m] and velocity [m/s].
    ut_pos_m, ut_vel_m_s : ndarray, shape (n, 3)
        The UE's position and velocity (from GNSS: true) [m], [m/s].
    freq_hz : float
        Carrier frequency [Hz].
    """
    pos, vel = believed
    return np.asarray(true_doppler_hz, float) - doppler_hz(pos, vel, ut_pos_m, ut_vel_m_s, freq_hz)


def believed_range_m(sat_pos_m, ut_pos_m):
    """Slant range from the UE to the believed satellite position [m], shape (n,)."""
    return np.linalg.norm(np.asarray(sat_pos_m, float) - ut_pos_m, axis=-1)


@dataclasses.dataclass(frozen=True)
class TimingParams:
    """What the timing columns need besides the rows' states (``[timing]`` and the run)."""

    reference_point: str
    n_ta_offset: int
    min_elevation_rad: float
    radius_m: float
    freq_hz: float


#: The trace columns of :func:`timing_columns`, in this order, after ``TRACE_COLUMNS``.
TIMING_COLUMNS = ("ta_s", "common_ta_s", "k_offset_ms", "doppler_residual_hz")


def timing_columns(params, ut_pos_m, ut_vel_m_s, believed, true_doppler_hz):
    """The :data:`TIMING_COLUMNS` of rows ``(n,)`` (NaN where ``believed`` is NaN).

    ``ut_pos_m, ut_vel_m_s`` (n, 3): the UTs; ``believed``: the believed satellite
    position and velocity, each (n, 3); ``true_doppler_hz`` (n,).
    """
    pos, vel = believed
    common = common_ta_s(pos, params.radius_m, params.reference_point)
    altitude = np.linalg.norm(pos, axis=-1) - params.radius_m
    return {
        "ta_s": timing_advance_s(believed_range_m(pos, ut_pos_m), common, params.n_ta_offset),
        "common_ta_s": common,
        "k_offset_ms": k_offset_ms(
            altitude, params.min_elevation_rad, params.radius_m, common, params.n_ta_offset
        ),
        "doppler_residual_hz": doppler_residual_hz(
            true_doppler_hz, (pos, vel), ut_pos_m, ut_vel_m_s, params.freq_hz
        ),
    }
