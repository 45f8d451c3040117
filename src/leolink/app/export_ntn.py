"""``leolink export-ntn RUN_DIR --out DIR``: a run's NTN series and SIB19-like ephemeris.

For channel emulators and NTN stacks (docs/ntn_export.md has the format):

- ``ntn_series.csv``: the trace's service-link series per UT (rows sorted by ``ut_id``,
  then ``time_s``): delay, delay rate, Doppler and its rate, path loss, SNR and SINR, and
  with ``[timing]`` the TA, common TA, K_offset and residual Doppler
  (:data:`SERIES_COLUMNS`, :data:`leolink.timing.TIMING_COLUMNS`);
- ``sib19_ephemeris.json``: for every satellite that served, one record per validity
  period in which it served: its broadcast (believed, ephemeris errors included) position
  and velocity at the record's epoch, ``ta-Common`` and its drift, the cell's K_offset and
  the validity (``ntn-UlSyncValidityDuration``), as SIB19's ``NTN-Config-r17`` carries them
  (TS 38.331 6.3.1: ``ephemerisInfo`` ``positionVelocity``, ``ta-Info``, ``epochTime``);
- ``run.json``, the manifest, last.

The run folder is only read (and checked against its manifest); nothing else is touched.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from leolink.io.run_dir import OutputFolderError, read_manifest, verify_manifest
from leolink.timing import TIMING_COLUMNS, common_ta_drift_s_s, common_ta_s, k_offset_ms

__all__ = ["SERIES_COLUMNS", "SIB19_FORMAT", "export_ntn", "sib19_records"]

#: Trace columns of ``ntn_series.csv`` (then ``time_utc`` and the timing columns if the
#: run has them).
SERIES_COLUMNS = (
    "time_s", "ut_id", "sat_id", "beam_id", "service", "elevation_deg", "slant_range_m",
    "delay_s", "delay_rate_s_s", "doppler_hz", "doppler_rate_hz_s", "fspl_db", "atm_db",
    "snr_db", "sinr_db",
)  # fmt: skip
#: ``format`` of ``sib19_ephemeris.json``.
SIB19_FORMAT = "leolink-sib19/1"


def _trace(run_dir):
    """The series columns of the run's trace (Parquet if it has one), sorted per UT."""
    parquet, csv = run_dir / "trace.parquet", run_dir / "trace.csv"
    wanted = set(SERIES_COLUMNS) | {"time_utc", *TIMING_COLUMNS}
    if parquet.exists():
        import pyarrow.parquet as pq

        names = [c for c in pq.ParquetFile(parquet).schema_arrow.names if c in wanted]
        df = pd.read_parquet(parquet, columns=names)
    else:
        df = pd.read_csv(csv, usecols=lambda c: c in wanted)
    order = [*SERIES_COLUMNS, "time_utc", *TIMING_COLUMNS]
    df = df[[c for c in order if c in df.columns]]
    return df.sort_values(["ut_id", "time_s"], kind="stable").reset_index(drop=True)


def _finished_run(run_dir):
    """The manifest of a finished ``leolink run`` folder; one line and exit 2 otherwise."""
    manifest = read_manifest(run_dir) if run_dir.is_dir() else None
    has_trace = (run_dir / "trace.csv").is_file() or (run_dir / "trace.parquet").is_file()
    if manifest is None or manifest.get("command") != "run" or not has_trace:
        raise OutputFolderError(
            f"RUN_DIR {run_dir} is not a finished leolink run folder (no run.json of "
            "`leolink run` with a trace); give the --out folder of a run"
        )
    verify_manifest(run_dir)
    return manifest


def sib19_records(cfg, served, ephemeris):
    """The SIB19-like ephemeris records of the satellites that served.

    Parameters
    ----------
    cfg : the run's config (``[timing]``, ``[constellation]``, ``[earth]``).
    served : DataFrame with ``time_s`` and ``sat_id`` of the served rows.
    ephemeris : callable ``t_s (n,) -> (pos, vel, acc)``, each (n, n_sat, 3): the
        believed (broadcast) ephemeris.

    Returns
    -------
    list of dict, sorted by satellite then epoch: ``sat_id``, ``epoch_s``,
    ``position_m``, ``velocity_m_s``, ``ta_common_s``, ``ta_common_drift_s_s``,
    ``k_offset_ms``, ``validity_s``.
    """
    t = cfg.timing
    validity = float(t.sib19_validity_s)
    t0 = cfg.run.start_s
    k = np.floor((served["time_s"].to_numpy() - t0) / validity + 1e-9).astype(np.int64)
    pairs = np.unique(np.stack([served["sat_id"].to_numpy(np.int64), k], axis=1), axis=0)
    if pairs.size == 0:
        return []
    ks = np.unique(pairs[:, 1])
    pos, vel, _ = ephemeris(t0 + ks * validity)
    row = np.searchsorted(ks, pairs[:, 1])
    p, v = pos[row, pairs[:, 0]], vel[row, pairs[:, 0]]
    radius = cfg.earth.radius_m
    common = common_ta_s(p, radius, t.reference_point)
    drift = common_ta_drift_s_s(p, v, t.reference_point)
    min_el = math.radians(cfg.constellation.min_elevation_deg)
    kof = k_offset_ms(np.linalg.norm(p, axis=-1) - radius, min_el, radius, common, t.n_ta_offset)
    return [
        {
            "sat_id": int(s),
            "epoch_s": float(t0 + kk * validity),
            "position_m": p[i].tolist(),
            "velocity_m_s": v[i].tolist(),
            "ta_common_s": float(common[i]),
            "ta_common_drift_s_s": float(drift[i]),
            "k_offset_ms": int(kof[i]),
            "validity_s": validity,
        }
        for i, (s, kk) in enumerate(pairs)
    ]


def _sib19(cfg, series):
    """The ``sib19_ephemeris.json`` document of a run's config and series."""
    from leolink.app.orbits import ephemeris_from_config
    from leolink.app.scenario import estimated_ephemeris

    true = ephemeris_from_config(cfg)
    believed = estimated_ephemeris(cfg, true) or true
    served = series[series["sat_id"] >= 0]
    utc0 = cfg.utc_of_time_zero()
    return {
        "format": SIB19_FORMAT,
        "frame": "ecef" if cfg.earth.rotation else "inertial",
        "time_zero_utc": None if utc0 is None else utc0.isoformat(),
        "reference_point": cfg.timing.reference_point,
        "feeder_link": "not modelled (the satellite stands for the gNB)",
        "ephemeris_error": cfg.ephemeris_error.model,
        "units": {
            "epoch_s": "s of simulation time (UTC: time_zero_utc + epoch_s)",
            "position_m": "m",
            "velocity_m_s": "m/s",
            "ta_common_s": "s",
            "ta_common_drift_s_s": "s/s",
            "k_offset_ms": "slots of 15 kHz (1 ms)",
            "validity_s": "s",
        },
        "records": sib19_records(cfg, served, believed),
    }


def export_ntn(run_dir, out_dir, overwrite=False, version=""):
    """Write ``ntn_series.csv``, ``sib19_ephemeris.json`` and ``run.json`` of the run in
    ``run_dir`` to ``out_dir``; return the paths (module docstring)."""
    from leolink.config import dump_toml, load_config
    from leolink.io.atomic import write_csv_atomic, write_json_atomic
    from leolink.io.run_dir import claim_out_dir, write_manifest

    run_dir = Path(run_dir)
    _finished_run(run_dir)
    cfg = load_config(run_dir / "config.resolved.toml")
    series = _trace(run_dir)
    document = _sib19(cfg, series)
    if Path(out_dir).resolve() == run_dir.resolve():
        raise OutputFolderError(f"--out {out_dir} is the run folder; give another folder")
    out = claim_out_dir(out_dir, overwrite)
    paths = [
        write_csv_atomic(series, out / "ntn_series.csv"),
        write_json_atomic(out / "sib19_ephemeris.json", document),
    ]
    arguments = {"run_dir": str(run_dir)}
    paths.append(write_manifest(out, paths, "export-ntn", dump_toml(cfg), arguments,
                                version=version))  # fmt: skip
    return paths
