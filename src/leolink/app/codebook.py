"""The codebook of a config: ``oversampling`` (a number or ``"auto"``), checked for holes.

The physics is :mod:`leolink.antenna.codebook_design`; this module turns a config into a
design and a refusal into one line that names the key, the worst point's loss and what
to change.
"""

from __future__ import annotations

import functools

from leolink.antenna.codebook_design import (
    HOLE_LOSS_DB,
    auto_design,
    design_at,
    smallest_hole_free,
)
from leolink.errors import ConfigError

__all__ = ["codebook_design_from_config", "codebook_from_config"]


def _geometry(cfg):
    a = cfg.satellite_array
    rx, ry = cfg.roi_semi_axes_m()
    return (a.n_x // a.n_rf_x, a.n_y // a.n_rf_y, a.n_rf_x * a.n_rf_y), (
        float(rx),
        float(ry),
        float(cfg.constellation.altitude_m),
        float(cfg.earth.radius_m),
    )


def _roi_text(geometry):
    return f"{geometry[0] / 1e3:.1f} x {geometry[1] / 1e3:.1f} km ROI"


def _hole_text(design):
    """Why a design has holes: its O and its worst point."""
    loss = design.loss
    where = (
        f"its worst point (x = {loss.x_m / 1e3:.0f} km, y = {loss.y_m / 1e3:.0f} km) is "
        f"{loss.loss_db:.1f} dB below the beam peak"
    )
    if not design.overlapping:
        return (
            f"at O = {design.oversampling:.4g} (< 1: each beam's neighbour peaks beyond its "
            f"first null) {where}"
        )
    return (
        f"at O = {design.oversampling:.4g} {where}, more than a beam's first sidelobe "
        f"({HOLE_LOSS_DB} dB)"
    )


def _fix_text(sub, geometry):
    """What would give a codebook without holes."""
    hint = f"with {sub[0]} x {sub[1]}-element subarrays "
    best = smallest_hole_free(sub[0], sub[1], *geometry)
    if best is None:
        return "use smaller subarrays (more RF chains) or a smaller ROI"
    return (
        f"{hint}a codebook without holes needs {best.n_beam} beams (O = "
        f"{best.oversampling:.4g}, worst {best.loss.loss_db:.1f} dB): use at least "
        f"{best.n_beam} RF chains (satellite_array.n_rf_x x n_rf_y), smaller subarrays or a "
        "smaller ROI (roi.semi_axis_x_m, roi.semi_axis_y_m)"
    )


@functools.lru_cache(maxsize=8)
def _auto_design(sub, geometry, allow_holes):
    # A run asks twice (scenario, notes); the search costs ~0.3 s of a small run's start.
    return auto_design(*sub, *geometry, allow_holes=allow_holes)


def _auto(cfg, sub, geometry):
    allow = cfg.satellite_array.allow_holes
    best, largest = _auto_design(sub, geometry, bool(allow))
    if best is not None:
        return best
    raise ConfigError(
        f"satellite_array.oversampling = 'auto' finds no codebook without holes over the "
        f"{_roi_text(geometry)}: the most beams {sub[2]} RF chains can drive is "
        f"{largest.n_beam}, and {_hole_text(largest)}; "
        f"{_fix_text(sub, geometry)}; or set satellite_array.allow_holes = true"
    )


def _fixed(cfg, o, sub, geometry):
    design = design_at(*sub, float(o), *geometry)
    n_rf = sub[2]
    if design.n_beam > n_rf and cfg.satellite_array.active_beams == "all":
        # Each RF chain drives one subarray and so one beam (paper Sec. 2.1): a codebook
        # with more beams than chains cannot be radiated at once; a selector lights at
        # most n_rf of them per epoch.
        raise ConfigError(
            f"satellite_array.oversampling = {o!r} gives {design.n_beam} beams over the "
            f"{_roi_text(geometry)}, but {n_rf} RF chains drive one beam each; "
            'use a smaller oversampling ("auto" picks the most beams the chains can drive), '
            "more RF chains, a smaller ROI, or light at most one beam per chain with "
            "satellite_array.active_beams = 'demand' or 'hopping'"
        )
    if design.n_beam == 0:
        raise ConfigError(
            f"satellite_array.oversampling = {o!r} leaves no beam pointing into the "
            f'{_roi_text(geometry)}; use a larger oversampling or "auto"'
        )
    if design.holes and not cfg.satellite_array.allow_holes:
        best, _ = auto_design(*sub, *geometry)
        fix = (
            f'use oversampling = "auto" ({best.describe()})'
            if best is not None
            else _fix_text(sub, geometry)
        )
        raise ConfigError(
            f"satellite_array.oversampling = {o!r} leaves holes in the {_roi_text(geometry)}: "
            f"{_hole_text(design)}; {fix}; or set satellite_array.allow_holes = true"
        )
    return design


def codebook_design_from_config(cfg):
    """The :class:`~leolink.antenna.codebook_design.CodebookDesign` of the config.

    Raises
    ------
    ConfigError
        More beams than RF chains, no beam in the ROI, or holes (``O < 1`` or a point of
        the ROI more than ``HOLE_LOSS_DB`` below the beam peak) without
        ``satellite_array.allow_holes = true``; or an antenna without a codebook.
    """
    if cfg.satellite_array.antenna != "hybrid_upa":
        raise ConfigError(
            f"satellite_array.antenna = {cfg.satellite_array.antenna!r} is for leolink budget "
            "only: runs, coverage maps and codebooks drive the hybrid UPA ('hybrid_upa'); "
            "a [multibeam] table makes leolink run TR 38.821's one-satellite snapshot"
        )
    sub, geometry = _geometry(cfg)
    o = cfg.satellite_array.oversampling
    return _auto(cfg, sub, geometry) if o == "auto" else _fixed(cfg, o, sub, geometry)


def codebook_from_config(cfg):
    """The pruned DFT codebook of the config (``oversampling = 'auto'`` solved here)."""
    return codebook_design_from_config(cfg).codebook
