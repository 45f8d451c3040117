"""``leolink run`` of a circular-aperture config: the TR 38.821 clause 6.1.1 snapshot.

A config with ``satellite_array.antenna = "circular_aperture"`` describes one satellite
whose beams are TR 38.811 reflector beams on TR 38.821's hexagonal grid (``[multibeam]``),
not the paper's hybrid UPA: there is no codebook, pass or handover, so the run is one
snapshot (:mod:`leolink.multibeam`) of static UTs dropped over the cells, fading off. It
writes ``summary.json`` (``overall.sinr_db``, ``sir_db``, ``snr_db``, ``coupling_loss_db``,
``throughput_bps``: mean, p5, p50, p95 over the UTs of the inner cells), ``snapshot.csv``
(one row per UT), ``config.resolved.toml`` and, last, ``run.json``.
"""

from __future__ import annotations

import math

import numpy as np

import leolink
from leolink.app.scenario import atmosphere_from, terminal_from
from leolink.config import dump_toml
from leolink.errors import ConfigError
from leolink.io.atomic import write_json_atomic, write_text_atomic
from leolink.io.run_dir import claim_out_dir, write_manifest
from leolink.link.budget import spectral_efficiency_bps_hz, throughput_bps

# leolink.multibeam and the aperture (scipy's Bessel function) are imported by the
# functions that need them: leolink.app.run imports this module, and a run of the hybrid
# UPA loads no scipy (tests/test_startup_and_memory.py).

__all__ = ["is_multibeam", "multibeam_satellite", "run_multibeam", "snapshot_of_config"]

#: The percentiles of every statistic of the summary [%].
_PERCENTILES = {"p5": 5.0, "p50": 50.0, "p95": 95.0}


def is_multibeam(cfg):
    """Whether ``leolink run`` of ``cfg`` is the multibeam snapshot: a circular aperture
    with a ``[multibeam]`` table (without one, the aperture is for ``leolink budget``)."""
    return (
        cfg.satellite_array.antenna == "circular_aperture" and "multibeam" in cfg.model_fields_set
    )


def multibeam_satellite(cfg):
    """The :class:`~leolink.multibeam.MultibeamSatellite` of a circular-aperture config.

    Raises
    ------
    ConfigError
        Without ``link.eirp_density_dbw_mhz`` (TR 38.821 gives every beam's EIRP density).
    """
    from leolink.antenna.aperture import half_power_beamwidth_rad
    from leolink.antenna.beam_layout import hex_beam_layout
    from leolink.multibeam import MultibeamSatellite

    link, a, m = cfg.link, cfg.satellite_array, cfg.multibeam
    if link.eirp_density_dbw_mhz is None:
        raise ConfigError(
            "link.eirp_density_dbw_mhz = none is not allowed with satellite_array.antenna = "
            "'circular_aperture' runs: give each beam's EIRP density [dBW/MHz] (TR 38.821 "
            "Table 6.1.1.1-1)"
        )
    hpbw = (math.radians(m.hpbw_deg) if m.hpbw_deg is not None
            else float(half_power_beamwidth_rad(link.freq_hz, a.aperture_diameter_m)))  # fmt: skip
    return MultibeamSatellite(
        layout=hex_beam_layout(m.tiers, hpbw),
        n_colors=link.reuse_colors,
        altitude_m=cfg.constellation.altitude_m,
        radius_m=cfg.earth.radius_m,
        freq_hz=link.freq_hz,
        diameter_m=a.aperture_diameter_m,
        gain_max_dbi=a.aperture_gain_dbi,
        eirp_density_dbw_mhz=link.eirp_density_dbw_mhz,
        bandwidth_hz=link.bandwidth_hz,
        other_loss_db=link.other_loss_db,
    )


def snapshot_of_config(cfg):
    """The satellite and the :class:`~leolink.multibeam.Snapshot` of ``cfg`` (seed
    ``run.seed``)."""
    from leolink.multibeam import CAP_UV_RADIUS_SPACINGS, drop_uts, inner_beam_count, snapshot

    sat, m = multibeam_satellite(cfg), cfg.multibeam
    cap = (m.inner_tiers + CAP_UV_RADIUS_SPACINGS) * sat.layout.spacing_uv
    cell_uv_area = math.sqrt(3.0) / 2.0 * sat.layout.spacing_uv**2  # a hexagon of inradius ABS/2
    n_drop = math.ceil(m.uts_per_beam * math.pi * cap**2 / cell_uv_area)
    ut = drop_uts(np.random.default_rng(cfg.run.seed), n_drop, cap, sat)
    terminal, atmosphere = terminal_from(cfg), atmosphere_from(cfg)
    snap = snapshot(sat, ut, inner_beam_count(m.inner_tiers), cfg.link.system_noise_temp_dbk,
                    terminal.gain_db, atmosphere)  # fmt: skip
    return sat, snap


def _stats(values):
    values = np.asarray(values, dtype=float)
    return {"mean": float(values.mean()),
            **{k: float(np.percentile(values, q)) for k, q in _PERCENTILES.items()}}  # fmt: skip


def _summary(cfg, sat, snap):
    from leolink.multibeam import inner_beam_count

    bw = sat.beam_bandwidth_hz
    rate = throughput_bps(spectral_efficiency_bps_hz(10.0 ** (snap.sinr_db / 10.0)), bw)
    n_ut, n_inner = int(snap.serving.size), inner_beam_count(cfg.multibeam.inner_tiers)
    per_beam = np.bincount(snap.serving, minlength=n_inner)
    notes = [
        f"multibeam snapshot (TR 38.821 6.1.1): {sat.layout.beam_uv.shape[0]} beams, spacing "
        f"{sat.layout.spacing_uv:.5f} on the UV plane, reuse {sat.n_colors}, {n_ut} UTs in "
        f"the inner {n_inner} cells ({per_beam.min()} to {per_beam.max()} per cell)"
    ]
    overall = {
        "n_ut": n_ut,
        "sinr_db": _stats(snap.sinr_db),
        "sir_db": _stats(snap.sir_db),
        "snr_db": _stats(snap.snr_db),
        "coupling_loss_db": _stats(snap.cl_db),
        "throughput_bps": _stats(rate),
        "handovers": {"beam_handover": 0, "sat_handover": 0},
    }
    run = {"n_ut": n_ut, "n_epochs": 1, "n_beam": int(sat.layout.beam_uv.shape[0]), "n_sat": 1,
           "beam_bandwidth_hz": bw, "notes": notes}  # fmt: skip
    return {"overall": overall, "run": run}


def _table(snap):
    """``snapshot.csv``: one row per UT of the inner cells."""
    cols = {
        "ut_id": np.arange(snap.serving.size),
        "beam_id": snap.serving,
        "elevation_deg": np.degrees(snap.elevation_rad),
        "slant_range_m": snap.slant_range_m,
        "coupling_loss_db": snap.cl_db,
        "sir_db": snap.sir_db,
        "snr_db": snap.snr_db,
        "sinr_db": snap.sinr_db,
    }
    rows = zip(*(c.tolist() for c in cols.values()), strict=True)
    return ",".join(cols) + "\n" + "".join(",".join(map(repr, r)) + "\n" for r in rows)


def run_multibeam(cfg, out_dir=None, overwrite=False):
    """Run the snapshot of a circular-aperture config (module docstring).

    Parameters and return as :func:`leolink.app.run.run` (no progress: one snapshot).
    """
    from leolink.app.run import Result

    sat, snap = snapshot_of_config(cfg)  # every check before any file
    summary = _summary(cfg, sat, snap)
    if out_dir is None:
        return Result(summary, None, [])
    out_dir = claim_out_dir(out_dir, overwrite)
    config_text = dump_toml(cfg)
    files = [
        write_text_atomic(out_dir / "snapshot.csv", _table(snap)),
        write_json_atomic(out_dir / "summary.json", summary),
        write_text_atomic(out_dir / "config.resolved.toml", config_text),
    ]
    files.append(write_manifest(out_dir, files, "run", config_text,
                                version=leolink.__version__))  # fmt: skip
    return Result(summary, out_dir, files)
