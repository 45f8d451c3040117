"""Tests of leolink.link.figures against published link budgets, a hand budget and identities."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.antenna.aperture import aperture_peak_gain_dbi
from leolink.link.budget import LinkBudget
from leolink.link.figures import (
    cn0_dbhz,
    cnr_db,
    ebn0_db,
    eirp_dbw,
    eirp_density_dbw_mhz,
    eirp_from_density_dbw,
    esn0_db,
    g_over_t_db_k,
    margin_db,
    symbol_rate_baud,
    system_noise_temp_k,
)
from leolink.link.modcod import modcod_names, modcod_table, modcod_throughput_bps, select_modcod

PRINTED_0_1_DB = 0.05  # published to 0.1 dB
# Published budgets use k = -228.6 dBW/K/Hz; leolink the exact -228.599 (0.001 dB apart).
HAND_DB = 1e-3  # the hand budget below is typed to 4 decimals


# --- Published example 1: EURASIP J. Wireless Commun. Netw. 2020:59 (doi 10.1186/s13638-020-
# 01674-9), Table 1 "Primary user link budget (QPSK coded FEC R = 1/2)", 2200 MHz: EIRP 38.3 dBm,
# FSL 162.2 dB, depointing 10 dB, E.S. antenna 5 m / 50 % -> 38.2 dBi, T_sys 130 K,
# C/N0 81.8 dBHz, 3.4 Mbit/s -> Eb/N0 16.5 dB, demodulation losses 6 dB, required 7 dB,
# margin 3.5 dB.
def test_published_cn0_ebn0_and_margin():
    gt = g_over_t_db_k(38.2, noise_temp_k=130.0)
    cn0 = cn0_dbhz(38.3 - 30.0, 162.2 + 10.0, gt)
    assert cn0 == pytest.approx(81.8, abs=PRINTED_0_1_DB)
    # QPSK rate 1/2 carries 1 bit/symbol: 3.4 Mbit/s is 3.4 Mbaud and Es/N0 = Eb/N0.
    es = esn0_db(81.8, 3.4e6)  # from the published C/N0, so roundings do not stack
    assert ebn0_db(es, 1.0) == pytest.approx(16.5, abs=PRINTED_0_1_DB)
    assert margin_db(es, 7.0 + 6.0) == pytest.approx(3.5, abs=PRINTED_0_1_DB)
    # The same table's earth-station gain, from aperture size and efficiency.
    assert aperture_peak_gain_dbi(2.2e9, 5.0, 0.5) == pytest.approx(38.2, abs=PRINTED_0_1_DB)


# --- Published example 2: FCC IBFS SAT-AMD-20060727-00083, Schedule S, Table 8 (handheld CDMA
# return link): EIRP -1.0 dBW, FSL 190.5 dB, atmosphere 0.1 dB, propagation margin 7.5 dB,
# satellite gain 43.0 dBi, T_sys 26.0 dBK -> G/T 17.0 dB/K, C/N0 46.5 dBHz.
def test_published_fcc_return_link():
    gt = g_over_t_db_k(43.0, noise_temp_dbk=26.0)
    assert gt == pytest.approx(17.0, abs=1e-12)
    assert cn0_dbhz(-1.0, 190.5 + 0.1 + 7.5, gt) == pytest.approx(46.5, abs=PRINTED_0_1_DB)


# --- Published example 3: T. Pratt, C. Bostian, J. Allnutt, "Satellite Communications", 2nd ed.,
# Wiley 2003, Example 4.3.4: 30 m earth-station antenna, 68 % efficiency, 4150 MHz -> 60.6 dB;
# T_sys 79 K -> G/T 41.6 dB/K; in heavy rain 88 K -> 41.2 dB/K.
def test_published_earth_station_g_over_t():
    gain = aperture_peak_gain_dbi(4.15e9, 30.0, 0.68)
    assert gain == pytest.approx(60.6, abs=PRINTED_0_1_DB)
    assert g_over_t_db_k(60.6, noise_temp_k=79.0) == pytest.approx(41.6, abs=PRINTED_0_1_DB)
    assert g_over_t_db_k(60.6, noise_temp_k=88.0) == pytest.approx(41.2, abs=PRINTED_0_1_DB)


def test_hand_budget_tr38821_ka_with_dvbs2x_acm():
    # TR 38.821 Set-1 LEO-600 Ka DL inputs, worked by hand (calculator), roll-off 0.1 and a
    # 0.5 dB implementation margin:
    #   EIRP  = 4 dBW/MHz + 10 log10(400)                     = 30.0206 dBW
    #   T_sys = 150 + 290 (10^0.12 - 1)                       = 242.2945 K (23.8434 dBK)
    #   G/T   = 39.7 - 23.8434                                = 15.8566 dB/K
    #   C/N0  = 30.0206 - (179.1 + 0.5 + 0.3) + 15.8566 + 228.5992 = 94.5763 dBHz
    #   CNR   = 94.5763 - 86.0206                             = 8.5557 dB
    #   R_s   = 400 MHz / 1.1                                 = 363.6364 Mbaud (85.6067 dBHz)
    #   Es/N0 = 94.5763 - 85.6067                             = 8.9697 dB
    #   ACM: thresholds <= 8.4697 dB: best is 16APSK 2/3-L (8.43 dB, 2.635236 bit/symbol);
    #   margin = 8.9697 - (8.43 + 0.5) = 0.0397 dB;
    #   throughput 2.635236 x 363.6364e6 = 958.268 Mbit/s
    eirp = eirp_from_density_dbw(4.0, 400e6)
    t_sys = system_noise_temp_k(150.0, 1.2)
    gt = g_over_t_db_k(39.7, noise_temp_k=t_sys)
    cn0 = cn0_dbhz(eirp, 179.1 + 0.5 + 0.3, gt)
    rs = symbol_rate_baud(400e6, 0.1)
    es = esn0_db(cn0, rs)
    assert eirp == pytest.approx(30.0206, abs=HAND_DB)
    assert t_sys == pytest.approx(242.2945, abs=1e-3)
    assert gt == pytest.approx(15.8566, abs=HAND_DB)
    assert cn0 == pytest.approx(94.5763, abs=HAND_DB)
    assert cnr_db(cn0, 400e6) == pytest.approx(8.5557, abs=HAND_DB)
    assert rs == pytest.approx(363.6364e6, rel=1e-7)
    assert es == pytest.approx(8.9697, abs=HAND_DB)
    i = select_modcod(es, margin_db=0.5)
    assert modcod_names(i) == "16APSK 2/3-L"
    required = modcod_table().esn0_ideal_db[i] + 0.5
    assert margin_db(es, required) == pytest.approx(0.0397, abs=HAND_DB)
    assert modcod_throughput_bps(i, rs) == pytest.approx(958.268e6, rel=1e-6)


def test_g_over_t_matches_the_tr38821_expression():
    # TR 38.821 Table 6.1.1.1-3 writes G/T = G - NF - 10 log10(T0 + (Ta - T0) 10^(-NF/10)).
    g, nf, ta = (
        np.array([39.7, 0.0, 30.0]),
        np.array([1.2, 7.0, 3.0]),
        np.array([150.0, 290.0, 50.0]),
    )
    tr_form = g - nf - 10 * np.log10(290.0 + (ta - 290.0) * 10 ** (-nf / 10))
    ours = g_over_t_db_k(g, noise_temp_k=system_noise_temp_k(ta, nf))
    np.testing.assert_allclose(ours, tr_form, atol=1e-12)
    np.testing.assert_allclose(ours[:2], [15.9, -31.6], atol=PRINTED_0_1_DB)  # VSAT, handheld


def test_g_over_t_needs_exactly_one_temperature():
    with pytest.raises(TypeError, match="exactly one"):
        g_over_t_db_k(30.0)
    with pytest.raises(TypeError, match="exactly one"):
        g_over_t_db_k(30.0, noise_temp_k=290.0, noise_temp_dbk=24.6)
    assert g_over_t_db_k(30.0, noise_temp_k=10**2.41) == pytest.approx(30.0 - 24.1)


def test_eirp_and_density():
    assert eirp_dbw(15.0, 1.0, 24.59) == pytest.approx(38.59)
    # 34 dBW/MHz over 30 MHz (TR 38.821 S band) = 48.77 dBW, and back.
    assert eirp_from_density_dbw(34.0, 30e6) == pytest.approx(48.7712, abs=1e-4)
    b = np.array([1e6, 30e6, 400e6])
    np.testing.assert_allclose(eirp_density_dbw_mhz(eirp_from_density_dbw(4.0, b), b), 4.0)
    # Per MHz over 1 MHz is the EIRP itself.
    assert eirp_density_dbw_mhz(30.0, 1e6) == 30.0


def test_esn0_is_cnr_plus_rolloff():
    # Es/N0 = C/(N0 R_s) = CNR over B + 10 log10(1 + alpha) when R_s = B / (1 + alpha).
    cn0, b = 90.0, 250e6
    for alpha in (0.0, 0.05, 0.2, 0.35):
        es = esn0_db(cn0, symbol_rate_baud(b, alpha))
        assert es == pytest.approx(cnr_db(cn0, b) + 10 * np.log10(1 + alpha), abs=1e-12)
    assert symbol_rate_baud(36e6, 0.2) == pytest.approx(30e6)  # 36 MHz at alpha = 0.2


def test_ebn0_from_esn0():
    # 8PSK 3/4 (2.228124 bit/symbol) at Es/N0 = 7.91 dB: Eb/N0 = 7.91 - 3.4794 = 4.4306 dB.
    assert ebn0_db(7.91, 2.228124) == pytest.approx(4.4306, abs=1e-4)


def test_margin_sign():
    assert margin_db(10.0, 8.0) == 2.0
    assert margin_db(np.array([5.0, 9.0]), 8.0).tolist() == [-3.0, 1.0]


@settings(max_examples=100, deadline=None)
@given(
    ptx=st.floats(-10.0, 30.0),
    cable=st.floats(0.0, 3.0),
    gtx=st.floats(0.0, 45.0),
    grx=st.floats(-5.0, 45.0),
    t_dbk=st.floats(15.0, 32.0),
    d_km=st.floats(300.0, 3000.0),
    f_ghz=st.floats(1.0, 40.0),
    atm=st.floats(0.0, 5.0),
    b_mhz=st.floats(0.1, 800.0),
)
def test_cnr_equals_link_budget_snr(ptx, cable, gtx, grx, t_dbk, d_km, f_ghz, atm, b_mhz):
    # Second way: C/N0 - 10 log10 B over the figures == the RSS - noise of leolink.link.budget.
    b = LinkBudget.compute(
        elevation_deg=45.0,
        slant_range_m=d_km * 1e3,
        freq_hz=f_ghz * 1e9,
        ptx_dbw=ptx,
        gain_tx_db=gtx,
        gain_rx_db=grx,
        noise_temp_dbk=t_dbk,
        bandwidth_hz=b_mhz * 1e6,
        atm_db=atm,
        cable_db=cable,
    )
    eirp = eirp_dbw(ptx, cable, gtx)
    assert eirp == pytest.approx(b.eirp_dbw, abs=1e-12)
    cn0 = cn0_dbhz(eirp, b.fspl_db + atm, g_over_t_db_k(grx, noise_temp_dbk=t_dbk))
    assert cnr_db(cn0, b_mhz * 1e6) == pytest.approx(b.snr_db, abs=1e-9)


def test_broadcasting_shapes():
    eirp = np.zeros((3, 1, 1))
    loss = np.full((1, 4, 1), 180.0)
    gt = np.full((1, 1, 5), 10.0)
    assert cn0_dbhz(eirp, loss, gt).shape == (3, 4, 5)
    assert esn0_db(np.zeros((2, 3)), np.array([1e6, 2e6, 4e6])).shape == (2, 3)
