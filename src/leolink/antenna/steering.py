"""Steering modes of the satellite's beams, and the array factor of quantized phases.

Two modes (config ``satellite_array.steering``), registered in :data:`STEERING`:

- ``body_fixed`` (the paper, Sec. 2.1 and 3.2 of [1]; 3GPP TR 38.821's Earth-moving
  cells): beam ``b`` keeps the codebook direction ``u_b`` of the body frame, so its
  footprint sweeps the ground with the satellite.
- ``earth_fixed`` (TR 38.821's quasi-Earth-fixed cells): beam ``b`` is re-steered every
  epoch to a fixed ground cell ``c_b``, the point where the codebook beam ``b`` met the
  ground at a reference instant (or a configured list of cells), while the cell is in the
  satellite's field of regard (above the elevation mask seen from the cell, and at most
  ``field_of_regard_deg`` off nadir); outside it the beam is off (zero gain).

A re-steered DFT beam is the same DFT beam with its centre at the cell's direction
cosines ``v_b = (d . x_body, d . y_body)`` (``d`` the unit satellite -> cell vector): its
gain is still the product of two Dirichlet kernels, ``k_x(u_x - v_bx) k_y(u_y - v_by)``,
now with a centre per satellite and epoch.

Phase shifters of ``b`` bits (``satellite_array.phase_bits``) round each element's
phase ``-pi (n_x v_x + n_y v_y)`` to the nearest multiple of ``2 pi / 2^b``; the gain
is then no longer separable and :func:`quantized_gain_lin` sums the array factor
explicitly. The phase reference is element ``(0, 0)`` of the subarray (the corner, the
element order of :func:`leolink.antenna.array.steering_vector`); a common phase offset
would change which phases round up, so this choice is part of the model
(docs/errata.md).

References
----------
.. [1] J. Palacios et al., "A hybrid beamforming design for massive MIMO LEO
   satellite communications."
.. [2] 3GPP TR 38.821 V16.1.0, Sec. 4.6 (Earth-fixed, quasi-Earth-fixed and
   Earth-moving beams/cells).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from pydantic import Field

from leolink.errors import ConfigError
from leolink.registry import Params, Registry

__all__ = ["STEERING", "BodyFixed", "EarthFixed", "SteeringMode", "quantized_gain_lin"]
__all__ += ["steered_cosines"]

#: Pairs per chunk of the explicit array factor (temporaries of a few MiB).
_AF_CHUNK = 256


@runtime_checkable
class SteeringMode(Protocol):  # pragma: no mutate block (a contract, no code)
    """How the beams point, as seen by the engine.

    ``moves_beams``: whether the beam directions change with the satellite's state (else
    they are the codebook's). ``phase_bits``: phase-shifter resolution [bit], None = ideal.
    ``beam_cosines(sat_pos_m (n_s, 3), sat_axes (n_s, 3, 3), sat_id (n_s,))`` gives the
    beam centres ``(n_s, n_beam, 2)`` and whether each beam is on ``(n_s, n_beam)``.
    """

    moves_beams: bool
    phase_bits: int | None

    def beam_cosines(self, sat_pos_m, sat_axes, sat_id): ...


STEERING: Registry[SteeringMode] = Registry("satellite_array.steering", protocol=SteeringMode)


def _require_bits(phase_bits):
    if phase_bits is not None and not 1 <= phase_bits <= 16:
        raise ConfigError(
            f"satellite_array.phase_bits = {phase_bits!r} is not allowed; use 1 to 16 or "
            "leave it out (ideal phase shifters)"
        )


class BodyFixed:
    """Beams fixed in the body frame: they move with the satellite (the paper)."""

    moves_beams = False

    def __init__(self, beam_u_xy, phase_bits=None):
        _require_bits(phase_bits)
        self.beam_u_xy = np.asarray(beam_u_xy, float)
        self.phase_bits = phase_bits

    def beam_cosines(self, sat_pos_m, sat_axes, sat_id):
        """The codebook's directions for every satellite, every beam on."""
        n_s = len(sat_pos_m)
        v = np.broadcast_to(self.beam_u_xy, (n_s,) + self.beam_u_xy.shape)
        return v, np.ones(v.shape[:2], bool)


def steered_cosines(cells_m, sat_pos_m, sat_axes):
    """Direction cosines of ground cells in the body frames of satellites.

    Parameters
    ----------
    cells_m : ndarray, shape (n_s, n_beam, 3)
        Each satellite's cells (Earth-centred, the frame of the satellites) [m].
    sat_pos_m : ndarray, shape (n_s, 3)
    sat_axes : ndarray, shape (n_s, 3, 3)
        Body frames, rows ``u_x, u_y, u_z`` (:func:`leolink.geometry.body_frame`).

    Returns
    -------
    v : ndarray, shape (n_s, n_beam, 2)
        ``(u_x, u_y)`` of the satellite -> cell direction [-].
    cos_nadir : ndarray, shape (n_s, n_beam)
        Cosine of the cell's angle off nadir (``-u_z``) [-].
    sin_el : ndarray, shape (n_s, n_beam)
        Sine of the satellite's elevation seen from the cell (its radial up) [-].
    """
    d = cells_m - sat_pos_m[:, None, :]
    rho = np.sqrt(np.einsum("sbk,sbk->sb", d, d))
    d = d / rho[..., None]
    v = np.einsum("sbk,sjk->sbj", d, sat_axes[:, :2, :])
    cos_nadir = -np.einsum("sbk,sk->sb", d, sat_axes[:, 2, :])
    up = cells_m / np.sqrt(np.einsum("sbk,sbk->sb", cells_m, cells_m))[..., None]
    sin_el = -np.einsum("sbk,sbk->sb", d, up)
    return v, cos_nadir, sin_el


class EarthFixed:
    """Beams re-steered every epoch to fixed ground cells (3GPP quasi-Earth-fixed).

    Parameters
    ----------
    cells_m : ndarray, shape (n_sat, n_beam, 3) or (1, n_beam, 3)
        Cell ``b`` of each satellite (one row: the same cells for every satellite) [m],
        in the Earth-centred frame of the satellites (Earth-fixed when Earth rotates).
    min_elevation_rad : float
        A cell whose view of the satellite is below this has its beam off.
    field_of_regard_rad : float
        Largest angle off nadir a beam is steered to [rad].
    phase_bits : int or None
    """

    moves_beams = True

    def __init__(self, cells_m, min_elevation_rad, field_of_regard_rad, phase_bits=None):
        _require_bits(phase_bits)
        self.cells_m = np.asarray(cells_m, float)
        self.sin_min_el = float(np.sin(min_elevation_rad))
        self.cos_for = float(np.cos(field_of_regard_rad))
        self.phase_bits = phase_bits

    def beam_cosines(self, sat_pos_m, sat_axes, sat_id):
        """Centres of the re-steered beams and which are on (cell in the field of regard)."""
        rows = np.zeros_like(sat_id) if len(self.cells_m) == 1 else sat_id
        v, cos_nadir, sin_el = steered_cosines(self.cells_m[rows], sat_pos_m, sat_axes)
        with np.errstate(invalid="ignore"):  # NaN cells (a ray that missed): off
            on = (sin_el >= self.sin_min_el) & (cos_nadir >= self.cos_for)
        return np.where(on[..., None], v, 0.0), on


def quantized_gain_lin(u_xy, beam_u_xy, n_x, n_y, phase_bits):
    """Gain of DFT beams whose element phases are rounded to ``phase_bits`` bits.

    ``|sum_n exp(i pi n . u) exp(i Q(-pi n . v))|^2 / (n_x n_y)``, ``Q`` rounding to the
    nearest multiple of ``2 pi / 2^bits`` (None: no rounding, the ideal DFT beam, whose
    sum equals the Dirichlet product of :func:`leolink.antenna.array.upa_gain`).

    Parameters
    ----------
    u_xy : ndarray, shape (m, 2)
        Directions (body-frame cosines) [-].
    beam_u_xy : ndarray, shape (m, n_beam, 2)
        The beam centres each direction is seen by (its satellite's) [-].
    n_x, n_y : int
        Subarray elements along x and y.
    phase_bits : int or None

    Returns
    -------
    ndarray, shape (n_beam, m)
        Linear gain, peak ``n_x n_y`` for ideal phases.
    """
    m, n_beam = beam_u_xy.shape[:2]
    out = np.empty((n_beam, m))
    ix, iy = np.arange(n_x), np.arange(n_y)
    step = None if phase_bits is None else 2.0 * np.pi / 2**phase_bits
    for lo in range(0, m, _AF_CHUNK):
        sl = slice(lo, min(lo + _AF_CHUNK, m))
        v = beam_u_xy[sl]  # (p, b, 2)
        phase = -np.pi * (
            ix[None, None, :, None] * v[..., 0, None, None]
            + iy[None, None, None, :] * v[..., 1, None, None]
        )  # (p, b, n_x, n_y): the weights' phases
        if step is not None:
            phase = step * np.rint(phase / step)
        ex = np.exp(1j * np.pi * ix[None, :] * u_xy[sl, 0, None])  # (p, n_x)
        ey = np.exp(1j * np.pi * iy[None, :] * u_xy[sl, 1, None])  # (p, n_y)
        af = np.einsum("pi,pbij,pj->bp", ex, np.exp(1j * phase), ey)
        out[:, sl] = (af.real**2 + af.imag**2) / (n_x * n_y)
    return out


class EarthFixedConfig(Params):
    reference_time_s: float | None = Field(
        None,
        description="instant whose codebook footprint gives the cells [s] (none: the middle "
        "of the run, the overhead instant of the paper's pass)",
    )
    field_of_regard_deg: float = Field(
        60.0,
        gt=0.0,
        le=90.0,
        description="largest angle off nadir a beam is steered to [deg] (60: a common "
        "phased-array scan limit, leolink's choice; docs/errata.md)",
    )
    cell_lat_deg: list[float] | None = Field(
        None,
        description="configured cells instead of the footprint: latitudes, one per beam "
        "[deg], shared by every satellite",
    )
    cell_lon_deg: list[float] | None = Field(
        None, description="longitudes of the configured cells, one per beam [deg]"
    )


def _build_body_fixed(params, ctx):
    return BodyFixed(ctx.beam_u_xy, ctx.phase_bits)


def _build_earth_fixed(params, ctx):
    """Cells from the footprint at the reference instant, or the configured ones."""
    n_beam = len(ctx.beam_u_xy)
    lat, lon = params.cell_lat_deg, params.cell_lon_deg
    if (lat is None) != (lon is None) or (lat is not None and not len(lat) == len(lon) == n_beam):
        raise ConfigError(
            f"satellite_array.earth_fixed.cell_lat_deg / cell_lon_deg = {lat!r} / {lon!r} "
            f"are not allowed; give both, one value per beam ({n_beam} beams), or neither"
        )
    if lat is not None:
        cells = ctx.ground_points(np.radians(lat), np.radians(lon))[None]
    else:
        t_ref = params.reference_time_s
        t_ref = ctx.default_reference_s if t_ref is None else t_ref
        cells = ctx.footprint_cells(float(t_ref))
    return EarthFixed(
        cells, ctx.min_elevation_rad, np.radians(params.field_of_regard_deg), ctx.phase_bits
    )


STEERING.add(
    "body_fixed",
    _build_body_fixed,
    doc="beams fixed in the body frame, moving with the satellite (the paper)",
)
STEERING.add(
    "earth_fixed",
    _build_earth_fixed,
    config=EarthFixedConfig,
    doc="beams re-steered every epoch to fixed ground cells (3GPP quasi-Earth-fixed)",
)
