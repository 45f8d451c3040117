"""Read the files of ``leolink export-ntn`` with the standard library only (docs/ntn_export.md).

Runs the paper's pass for 20 s with ``[timing]`` on and a 2 km along-track ephemeris
error, exports it, then reads ``ntn_series.csv`` (per-UT delay, TA, Doppler) and
``sib19_ephemeris.json`` (the record valid at a given time) as a channel emulator or an
NTN stack would.

python examples/read_ntn_export.py [RUN_DIR EXPORT_DIR]  (default: a temporary folder)
"""

import csv
import json
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "paper.toml"
SETS = ["run.duration_s=20", "timing.enabled=true", 'run.start_utc="2025-03-01T10:00:00Z"',
        "ephemeris_error.model=rtn", "ephemeris_error.rtn.along_track_offset_m=2000",
        "output.plots.enabled=false", "output.report.enabled=false"]  # fmt: skip


def leolink(*args):
    subprocess.run([sys.executable, "-c", "from leolink.cli import console; console()", *args],
                   check=True, capture_output=True)  # fmt: skip


def series_by_ut(path):
    """``{ut_id: [row, ...]}`` of ``ntn_series.csv``: each UT's rows are one block."""
    out = defaultdict(list)
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            out[int(row["ut_id"])].append(row)
    return out


def record_at(doc, sat_id, t_s):
    """The ephemeris record of ``sat_id`` valid at ``t_s`` (epoch <= t < epoch + validity)."""
    for r in doc["records"]:
        if r["sat_id"] == sat_id and r["epoch_s"] <= t_s < r["epoch_s"] + r["validity_s"]:
            return r
    return None


def main(run_dir, export_dir):
    sets = [a for s in SETS for a in ("--set", s)]
    leolink("run", str(CONFIG), "--out", str(run_dir), "--quiet", "--overwrite", *sets)
    leolink("export-ntn", str(run_dir), "--out", str(export_dir), "--quiet", "--overwrite")
    uts = series_by_ut(Path(export_dir) / "ntn_series.csv")
    print(f"{len(uts)} UTs; UT 0 every 5 s:")
    print(f"{'t [s]':>6} {'sat':>3} {'delay [ms]':>10} {'TA [ms]':>8} {'common [ms]':>11} "
          f"{'K_off':>5} {'Doppler [kHz]':>13} {'residual [Hz]':>13}")  # fmt: skip
    for row in uts[0][::5]:
        print(f"{float(row['time_s']):6.1f} {row['sat_id']:>3} {float(row['delay_s']) * 1e3:10.4f} "
              f"{float(row['ta_s']) * 1e3:8.4f} {float(row['common_ta_s']) * 1e3:11.4f} "
              f"{row['k_offset_ms']:>5} {float(row['doppler_hz']) / 1e3:13.3f} "
              f"{float(row['doppler_residual_hz']):13.1f}")  # fmt: skip
    doc = json.loads((Path(export_dir) / "sib19_ephemeris.json").read_text())
    r = record_at(doc, int(uts[0][0]["sat_id"]), 12.0)
    print(f"SIB19 ({doc['format']}, {doc['frame']}, time zero {doc['time_zero_utc']}): "
          f"{len(doc['records'])} records; at t = 12 s satellite {r['sat_id']}: epoch "
          f"{r['epoch_s']:.0f} s, valid {r['validity_s']:.0f} s, altitude "
          f"{(sum(x * x for x in r['position_m']) ** 0.5 - 6371e3) / 1e3:.1f} km, "
          f"ta-Common {r['ta_common_s'] * 1e3:.4f} ms, K_offset {r['k_offset_ms']} ms")  # fmt: skip


if __name__ == "__main__":
    if len(sys.argv) == 3:
        main(Path(sys.argv[1]), Path(sys.argv[2]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp) / "run", Path(tmp) / "ntn")
