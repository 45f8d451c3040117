"""3GPP TR 38.821 Table 6.1.3.3-1 (Set-1 LEO-600 downlinks) recomputed from the table's inputs.

FSPL from the slant range at 30 deg (spherical Earth, R = 6371 km as in TR 38.811 Sec. 6.6.2),
EIRP from the EIRP density, G/T from the UE gain, antenna temperature and noise figure, and
the CNR of TR 38.821 Sec. 6.1.3.1, all with leolink functions; the reference values are in
tests/data/tr38821_table_6_1_3_3_1.csv (provenance in its header).
"""

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from leolink.antenna.aperture import circular_aperture_gain_db, half_power_beamwidth_rad
from leolink.geometry import slant_range_from_elevation_m
from leolink.link.budget import LinkBudget, fspl_db
from leolink.link.figures import (
    cn0_dbhz,
    cnr_db,
    eirp_dbw,
    eirp_from_density_dbw,
    g_over_t_db_k,
    system_noise_temp_k,
)

DATA = Path(__file__).parent / "data"
TR38821_EARTH_RADIUS_M = 6_371_000.0  # TR 38.811 Sec. 6.6.2, the radius of its slant-range formula
PRINTED_0_1_DB = 0.05  # the table prints dB figures to 0.1 dB
# The CNR budget: the CNR itself is rounded (0.05), and k = -228.6 vs -228.599 (0.001);
# our EIRP and G/T come unrounded from the inputs (the table's own 30.0 dBW / 15.9 dB/K are
# rounded by up to 0.03 / 0.04 dB). The issue asks for 0.1 dB.
CNR_TOLERANCE_DB = 0.1
# TR 38.821 prints the 3 dB beamwidths 0.16 % below 2 asin(1.6163 / ka) (1.7647 vs 1.7676 deg);
# 0.01 deg still tells D = 2a (a = D would halve the beamwidth to 0.88 deg).
BEAMWIDTH_TOLERANCE_DEG = 0.01


def _rows():
    with open(DATA / "tr38821_table_6_1_3_3_1.csv") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    header, _units, *body = rows
    return [dict(zip(header, r, strict=True)) for r in body]


ROWS = {r["case"]: r for r in _rows()}
CASES = pytest.mark.parametrize("case", sorted(ROWS))


def _f(row, key):
    return float(row[key])


def _freq_hz(row):
    return _f(row, "carrier_freq_ghz") * 1e9


def _other_losses_db(row):
    keys = ("atm_loss_db", "shadow_margin_db", "scintillation_loss_db")
    return sum(_f(row, k) for k in (*keys, "polarization_loss_db", "additional_loss_db"))


def _ours(row):
    """EIRP, G/T, FSPL recomputed from the inputs with leolink functions."""
    d_m = slant_range_from_elevation_m(
        np.radians(_f(row, "elevation_deg")),
        _f(row, "satellite_altitude_km") * 1e3,
        radius_m=TR38821_EARTH_RADIUS_M,
    )
    bandwidth_hz = _f(row, "bandwidth_mhz") * 1e6
    t_sys_k = system_noise_temp_k(_f(row, "ut_antenna_temp_k"), _f(row, "ut_noise_figure_db"))
    return dict(
        slant_range_m=float(d_m),
        fspl_db=float(fspl_db(d_m, _freq_hz(row))),
        eirp_dbw=float(eirp_from_density_dbw(_f(row, "eirp_density_dbw_mhz"), bandwidth_hz)),
        g_over_t_db_k=float(g_over_t_db_k(_f(row, "ut_gain_dbi"), noise_temp_k=t_sys_k)),
        t_sys_k=float(t_sys_k),
        bandwidth_hz=bandwidth_hz,
    )


@CASES
def test_fspl_at_30_deg(case):
    row, ours = ROWS[case], _ours(ROWS[case])
    assert 1075e3 < ours["slant_range_m"] < 1076e3  # 600 km at 30 deg: 1075.1 km
    assert ours["fspl_db"] == pytest.approx(_f(row, "fspl_db"), abs=PRINTED_0_1_DB)


@CASES
def test_eirp_from_density_and_g_over_t_from_noise_figure(case):
    row, ours = ROWS[case], _ours(ROWS[case])
    assert ours["eirp_dbw"] == pytest.approx(_f(row, "eirp_dbw"), abs=PRINTED_0_1_DB)
    assert ours["g_over_t_db_k"] == pytest.approx(_f(row, "ut_g_over_t_db_k"), abs=PRINTED_0_1_DB)


@CASES
def test_cnr_from_the_inputs(case):
    row, ours = ROWS[case], _ours(ROWS[case])
    path_loss_db = ours["fspl_db"] + _other_losses_db(row)
    cn0 = cn0_dbhz(ours["eirp_dbw"], path_loss_db, ours["g_over_t_db_k"])
    assert cnr_db(cn0, ours["bandwidth_hz"]) == pytest.approx(
        _f(row, "cnr_db"), abs=CNR_TOLERANCE_DB
    )


@CASES
def test_table_closes_on_its_own_cnr(case):
    # The table's own printed EIRP, G/T and FSPL (a check of the transcription).
    row = ROWS[case]
    path_loss_db = _f(row, "fspl_db") + _other_losses_db(row)
    cn0 = cn0_dbhz(_f(row, "eirp_dbw"), path_loss_db, _f(row, "ut_g_over_t_db_k"))
    assert cnr_db(cn0, _f(row, "bandwidth_mhz") * 1e6) == pytest.approx(
        _f(row, "cnr_db"), abs=CNR_TOLERANCE_DB
    )


@CASES
def test_cnr_equals_link_budget_snr(case):
    # A second way: leolink.link.budget with P_TX = EIRP - G_max, the beam centre (G_max of
    # the TR 38.811 aperture on boresight), the losses lumped into atm_db.
    row, ours = ROWS[case], _ours(ROWS[case])
    gain_tx_db = float(
        circular_aperture_gain_db(
            0.0, _freq_hz(row), _f(row, "sat_aperture_diameter_m"), _f(row, "sat_gain_max_dbi")
        )
    )
    budget = LinkBudget.compute(
        elevation_deg=_f(row, "elevation_deg"),
        slant_range_m=ours["slant_range_m"],
        freq_hz=_freq_hz(row),
        ptx_dbw=ours["eirp_dbw"] - gain_tx_db,
        gain_tx_db=gain_tx_db,
        gain_rx_db=_f(row, "ut_gain_dbi"),
        noise_temp_dbk=10 * np.log10(ours["t_sys_k"]),
        bandwidth_hz=ours["bandwidth_hz"],
        atm_db=_other_losses_db(row),
    )
    eirp = eirp_dbw(budget.ptx_dbw, budget.cable_db, budget.gain_tx_db)
    cn0 = cn0_dbhz(eirp, budget.fspl_db + budget.atm_db, ours["g_over_t_db_k"])
    assert cnr_db(cn0, ours["bandwidth_hz"]) == pytest.approx(budget.snr_db, abs=1e-9)
    assert budget.snr_db == pytest.approx(_f(row, "cnr_db"), abs=CNR_TOLERANCE_DB)


@CASES
def test_satellite_beamwidth_from_aperture_diameter(case):
    row = ROWS[case]
    bw_rad = half_power_beamwidth_rad(_freq_hz(row), _f(row, "sat_aperture_diameter_m"))
    assert np.degrees(bw_rad) == pytest.approx(
        _f(row, "sat_beamwidth_3db_deg"), abs=BEAMWIDTH_TOLERANCE_DEG
    )


# --- Input precision (issue 45's mutation run of link/figures.py, docs/testing.md) -----


# As for the budget (test_budget.py): float32 carries 7 digits (4e-6 dB on a 60 dBW EIRP);
# a figure of float32 values equals, to float64 round-off, the figure of the same (exact)
# values written out here by hand from its definition (T0 = 290 K, k = 1.380649e-23 J/K,
# SI 2019 exact), not the function called again on float64 input: the reference is
# independent of the code, so a wrong formula fails here as well as a float32 computation.
F64_RTOL = 1e-12  # float64 round-off of a few operations; float32 would be ~1e-7
K_DBW_K_HZ = 10 * math.log10(1.380649e-23)  # -228.599 dBW/(K Hz)


def _f32_cases():
    from leolink.link import figures as fig

    db = math.log10  # 10 db(x) [dB]
    return {
        "eirp_dbw": (fig.eirp_dbw, [15.3, 0.7, 38.1], lambda p: p - 0.7 + 38.1),
        "eirp_density_dbw_mhz": (
            fig.eirp_density_dbw_mhz, [53.1, 400e6], lambda e: e - 10 * db(400.0)),
        "eirp_from_density_dbw": (
            fig.eirp_from_density_dbw, [34.1, 400e6], lambda d: d + 10 * db(400.0)),
        "system_noise_temp_k": (
            fig.system_noise_temp_k, [150.3, 1.2], lambda t: t + 290.0 * (10**0.12 - 1)),
        "g_over_t_db_k gain": (
            lambda g: fig.g_over_t_db_k(g, noise_temp_dbk=24.7), [39.7], lambda g: g - 24.7),
        "g_over_t_db_k noise_temp_k": (
            lambda t: fig.g_over_t_db_k(39.7, noise_temp_k=t), [290.7],
            lambda t: 39.7 - 10 * db(t)),
        "g_over_t_db_k noise_temp_dbk": (
            lambda t: fig.g_over_t_db_k(39.7, noise_temp_dbk=t), [24.7], lambda t: 39.7 - t),
        "cn0_dbhz": (
            fig.cn0_dbhz, [60.3, 180.2, 15.9], lambda e: e - 180.2 + 15.9 - K_DBW_K_HZ),
        "cnr_db": (fig.cnr_db, [95.3, 400e6], lambda c: c - 10 * db(400e6)),
        "symbol_rate_baud": (fig.symbol_rate_baud, [400e6, 0.2], lambda b: b / 1.2),
        "symbol_rate_baud rolloff": (
            lambda r: fig.symbol_rate_baud(400e6, r), [0.2], lambda r: 400e6 / (1 + r)),
        "system_noise_temp_k noise figure": (
            lambda f: fig.system_noise_temp_k(150.3, f), [1.2],
            lambda f: 150.3 + 290.0 * (10 ** (f / 10) - 1)),
        "esn0_db": (fig.esn0_db, [95.3, 333e6], lambda c: c - 10 * db(333e6)),
        "ebn0_db": (fig.ebn0_db, [9.7, 2.5], lambda e: e - 10 * db(2.5)),
        "margin_db": (fig.margin_db, [9.7, 6.3], lambda e: e - 6.3),
    }  # fmt: skip


@pytest.mark.parametrize("name", list(_f32_cases()))
def test_float32_figures_are_computed_in_float64(name):
    func, args, by_hand = _f32_cases()[name]
    x32 = np.array([args[0]], dtype=np.float32)
    got = func(x32, *args[1:])
    assert np.asarray(got).dtype == np.float64
    np.testing.assert_allclose(got, by_hand(float(x32[0])), rtol=F64_RTOL)


def test_g_over_t_needs_exactly_one_noise_temperature():
    for kwargs in ({}, {"noise_temp_k": 290.0, "noise_temp_dbk": 24.6}):
        with pytest.raises(TypeError) as err:
            g_over_t_db_k(30.0, **kwargs)
        assert str(err.value) == "g_over_t_db_k needs exactly one of noise_temp_k, noise_temp_dbk"
