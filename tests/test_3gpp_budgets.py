"""configs/3gpp/: ``leolink budget CONFIG --elevation-deg 30 --json`` reproduces TR 38.821.

Reference: 3GPP TR 38.821 V16.0.0, Table 6.1.3.3-1 (link budget results, Set-1 LEO-600
downlinks SC6 Ka band / SC9 S band), with the inputs of Tables 6.1.1.1-1 (satellite) and
6.1.1.1-3 (UE); the values and their provenance are in tests/data/tr38821_table_6_1_3_3_1.csv
(cross-checked against a second public transcription, a Sionna TR 38.811 extension's tests:
FSPL 179.0-179.2 dB and 159.0-159.2 dB at 30 deg).
"""

import csv
import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "tr38821_table_6_1_3_3_1.csv"
CONFIGS = {
    "SC6": ROOT / "configs/3gpp/leo600_ka_dl.toml",
    "SC9": ROOT / "configs/3gpp/leo600_s_dl.toml",
}
# The table prints dB to 0.1 dB; the issue asks for 0.1 dB. Our CNR differs by 0.06 dB
# (Ka: 8.56 vs 8.5, the table's own rounding of EIRP 30.02 and G/T 15.86) and 0.02 dB (S).
TABLE_TOLERANCE_DB = 0.1
PRINTED_0_1_DB = 0.05  # a figure printed to 0.1 dB is within 0.05 of the exact one


def _rows():
    with open(DATA) as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    header, _units, *body = rows
    return {r[0]: dict(zip(header, r, strict=True)) for r in body}


ROWS = _rows()
CASES = pytest.mark.parametrize("case", sorted(CONFIGS))


def _budget(case):
    out = subprocess.run(
        [sys.executable, "-m", "leolink.cli", "budget", str(CONFIGS[case]),
         "--elevation-deg", "30", "--json"],
        capture_output=True, text=True, check=True, cwd=ROOT,
    )  # fmt: skip
    return json.loads(out.stdout)


@pytest.fixture(scope="module")
def budgets():
    return {case: _budget(case) for case in CONFIGS}


@CASES
def test_fspl_and_cnr_equal_table_6_1_3_3_1(budgets, case):
    b, row = budgets[case], ROWS[case]
    assert b["elevation_deg"] == float(row["elevation_deg"])
    assert b["fspl_db"] == pytest.approx(float(row["fspl_db"]), abs=TABLE_TOLERANCE_DB)
    assert b["cnr_db"] == pytest.approx(float(row["cnr_db"]), abs=TABLE_TOLERANCE_DB)
    # The budget's SNR (RSS - noise, term by term) is the same CNR (TR 38.821 6.1.3.1).
    assert b["snr_db"] == pytest.approx(b["cnr_db"], abs=1e-9)


@CASES
def test_eirp_and_g_over_t_equal_the_table(budgets, case):
    b, row = budgets[case], ROWS[case]
    assert b["eirp_dbw"] == pytest.approx(float(row["eirp_dbw"]), abs=PRINTED_0_1_DB)
    assert b["g_over_t_db_k"] == pytest.approx(float(row["ut_g_over_t_db_k"]), abs=PRINTED_0_1_DB)
    assert b["eirp_density_dbw_mhz"] == pytest.approx(float(row["eirp_density_dbw_mhz"]), abs=1e-12)
    assert b["gain_tx_db"] == float(row["sat_gain_max_dbi"])  # beam centred on the UT
    losses = sum(float(row[k]) for k in ("scintillation_loss_db", "shadow_margin_db",
                                         "polarization_loss_db", "additional_loss_db"))  # fmt: skip
    assert b["other_loss_db"] == pytest.approx(losses, abs=1e-12)
    assert b["atm_db"] == float(row["atm_loss_db"])


KEYS = {  # config key -> (table column, factor from the table's unit to the config's)
    ("link", "freq_hz"): ("carrier_freq_ghz", 1e9),
    ("link", "bandwidth_hz"): ("bandwidth_mhz", 1e6),
    ("link", "eirp_density_dbw_mhz"): ("eirp_density_dbw_mhz", 1.0),
    ("link", "antenna_temp_k"): ("ut_antenna_temp_k", 1.0),
    ("link", "noise_figure_db"): ("ut_noise_figure_db", 1.0),
    ("link", "scintillation_loss_db"): ("scintillation_loss_db", 1.0),
    ("link", "shadow_margin_db"): ("shadow_margin_db", 1.0),
    ("link", "polarization_loss_db"): ("polarization_loss_db", 1.0),
    ("link", "additional_loss_db"): ("additional_loss_db", 1.0),
    ("constellation", "altitude_m"): ("satellite_altitude_km", 1e3),
    ("satellite_array", "aperture_diameter_m"): ("sat_aperture_diameter_m", 1.0),
    ("satellite_array", "aperture_gain_dbi"): ("sat_gain_max_dbi", 1.0),
}


@CASES
def test_every_input_is_the_tables_and_names_it(case):
    text = CONFIGS[case].read_text()
    cfg, row = tomllib.loads(text), ROWS[case]
    for (section, key), (column, factor) in KEYS.items():
        assert cfg[section][key] == pytest.approx(float(row[column]) * factor, rel=1e-12), key
        line = next(x for x in text.splitlines() if re.match(rf"{key}\s*=", x))
        assert re.search(r"Table 6\.1\.[13]\.\d-\d", line), f"{key}: no table cited: {line}"
    assert cfg["atmosphere"]["fixed"]["loss_db"] == float(row["atm_loss_db"])
    assert cfg["terminal"]["fixed"]["gain_dbi"] == float(row["ut_gain_dbi"])


def test_a_run_of_the_aperture_config_is_refused_in_one_line(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "leolink.cli", "run", str(CONFIGS["SC6"]), "--out", str(tmp_path)],
        capture_output=True, text=True, cwd=ROOT,
    )  # fmt: skip
    assert out.returncode == 2
    assert "satellite_array.antenna = 'circular_aperture' is for leolink budget only" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1
