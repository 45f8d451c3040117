"""Tests of leolink.link.budget against published link budgets and identities."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.link.budget import (
    LinkBudget,
    db,
    fspl_db,
    interference_dbw,
    lin,
    noise_power_dbw,
    rss_dbw,
    sinr_lin,
    snr_db,
    spectral_efficiency_bps_hz,
    throughput_bps,
)

PRINTED_2_DECIMALS_DB = 0.005  # published to 0.01 dB
P525_CONSTANT_DB = 0.003  # P.525 prints 32.45; exactly 20 log10(4 pi 1e9 / c) = 32.4478


def test_fspl_14ghz_340km():
    # Starlink Ku example: 14 GHz over 340 km -> 166.00 dB.
    assert abs(fspl_db(340e3, 14e9) - 166.00) < PRINTED_2_DECIMALS_DB


def test_fspl_s_band_1203km():
    # 2.185 GHz over 1203.46 km -> 160.85 dB.
    assert abs(fspl_db(1203.46e3, 2.185e9) - 160.85) < PRINTED_2_DECIMALS_DB


def test_fspl_agrees_with_itu_r_p525():
    d_km = np.array([340.0, 1300.0, 3000.0])
    f_mhz = np.array([2185.0, 11_450.0, 30_000.0])
    expected_db = 32.45 + 20 * np.log10(f_mhz) + 20 * np.log10(d_km)
    np.testing.assert_allclose(fspl_db(d_km * 1e3, f_mhz * 1e6), expected_db, atol=P525_CONSTANT_DB)


def test_fspl_doubles_distance_adds_6db():
    assert fspl_db(2e6, 11.45e9) - fspl_db(1e6, 11.45e9) == pytest.approx(20 * np.log10(2))


def test_noise_290k_100mhz():
    # kTB at 290 K over 100 MHz = -93.98 dBm (= -123.98 dBW), textbook value.
    noise_dbm = noise_power_dbw(10 * np.log10(290.0), 100e6) + 30.0
    assert abs(noise_dbm - (-93.98)) < PRINTED_2_DECIMALS_DB


def test_noise_uses_exact_boltzmann():
    # k T B in watts, computed directly.
    noise_w = 1.380649e-23 * 10**2.41 * 250e6
    assert noise_power_dbw(24.1, 250e6) == pytest.approx(10 * np.log10(noise_w), abs=1e-12)


TR38821_ROUNDING_DB = 0.1  # TR 38.821 prints the CNR to 0.1 dB (8.5; 8.58 before rounding)


def test_tr38821_ka_downlink_cnr():
    # 3GPP TR 38.821 Table 6.1.3.3-1 style Ka-band DL: EIRP 30 dBW, G/T 15.9 dB/K,
    # 400 MHz, FSPL 179.1 dB, 0.5 dB atmospheric + 0.3 dB scintillation -> CNR 8.5 dB.
    t_dbk = 24.1  # any noise temperature: G/T fixes G_RX - T
    rss = rss_dbw(30.0, 0.0, 0.0, 0.5 + 0.3, 179.1, 15.9 + t_dbk)
    cnr = snr_db(rss, noise_power_dbw(t_dbk, 400e6))
    assert abs(cnr - 8.58) < 0.01  # the unrounded value (k = -228.6 vs -228.599)
    assert abs(cnr - 8.5) < TR38821_ROUNDING_DB


def test_db_lin_roundtrip():
    x = np.array([1e-20, 1e-3, 1.0, 7.0, 1e6])
    np.testing.assert_allclose(lin(db(x)), x, rtol=1e-12)
    assert db(0.0) == -np.inf


@settings(max_examples=60, deadline=None)
@given(
    s=st.floats(1e-18, 1e-6),
    i=st.floats(0.0, 1e-6),
    n=st.floats(1e-16, 1e-10),
)
def test_sinr_never_exceeds_snr(s, i, n):
    assert sinr_lin(s, i, n) <= s / n * (1 + 1e-12)
    assert sinr_lin(s, 0.0, n) == pytest.approx(s / n)


@settings(max_examples=40, deadline=None)
@given(k=st.integers(1, 20), snr=st.floats(-10.0, 40.0))
def test_k_equal_interferers(k, snr):
    # k interfering beams each as strong as the serving one: SINR = S / (k S + N).
    s_w, n_w = 1.0, lin(-snr)
    expected = 1.0 / (k + n_w)
    assert sinr_lin(s_w, k * s_w, n_w) == pytest.approx(expected, rel=1e-12)
    # Without noise it tends to 1/k: the paper's 4 equal beams give -4.77 dB.
    assert db(sinr_lin(1.0, 3.0, 1e-30)) == pytest.approx(-4.771, abs=1e-3)


def test_interference_sums_other_beams_tx_gain():
    # Two other beams with TX gains 30 and 27 dB: I must equal the power sum of the two
    # beams' RSS, each with the UT's own G_RX (not the paper's swapped labels).
    terms = dict(ptx_dbw=15.0, cable_db=1.0, atm_db=0.1, fspl_db=176.0, gain_rx_db=30.0)
    rss_each_w = lin(rss_dbw(gain_tx_db=np.array([30.0, 27.0]), **terms))
    i_dbw = interference_dbw(gain_tx_other_lin=lin(30.0) + lin(27.0), **terms)
    assert lin(i_dbw) == pytest.approx(rss_each_w.sum(), rel=1e-12)


def test_shannon():
    assert spectral_efficiency_bps_hz(3.0) == pytest.approx(2.0)
    assert throughput_bps(spectral_efficiency_bps_hz(1.0), 250e6) == pytest.approx(250e6)


def test_link_budget_terms_add_up():
    b = LinkBudget.compute(
        elevation_deg=90.0,
        slant_range_m=1300e3,
        freq_hz=11.45e9,
        ptx_dbw=15.0,
        gain_tx_db=10 * np.log10(12 * 24),
        gain_rx_db=33.0,
        noise_temp_dbk=24.1,
        bandwidth_hz=250e6,
        atm_db=0.06,
        cable_db=0.5,
    )
    d = b.as_dict()
    assert list(d)[:3] == ["elevation_deg", "slant_range_m", "fspl_db"]
    # Independent recomputation: Friis in watts.
    lam = 299_792_458.0 / 11.45e9
    prx_w = lin(15.0 - 0.5 - 0.06) * 12 * 24 * lin(33.0) * (lam / (4 * np.pi * 1300e3)) ** 2
    noise_w = 1.380649e-23 * lin(24.1) * 250e6
    assert d["snr_db"] == pytest.approx(10 * np.log10(prx_w / noise_w), abs=1e-9)
    assert d["eirp_dbw"] == pytest.approx(15.0 - 0.5 + 10 * np.log10(288))
    with pytest.raises(AttributeError):
        b.snr_db = 0.0  # frozen


def test_link_budget_reports_every_input_and_term():
    """Each field of the budget ``leolink budget`` prints is the input or term it names
    (a field left out or mixed up would otherwise print silently wrong), and the losses
    default to none."""
    kw = dict(
        elevation_deg=47.5,
        slant_range_m=1.7e6,
        freq_hz=20e9,
        ptx_dbw=12.0,
        gain_tx_db=24.6,
        gain_rx_db=30.1,
        noise_temp_dbk=25.0,
        bandwidth_hz=100e6,
    )
    d = LinkBudget.compute(**kw, atm_db=0.7, cable_db=1.2).as_dict()
    for key in ("elevation_deg", "slant_range_m", "gain_tx_db", "gain_rx_db", "ptx_dbw"):
        assert d[key] == kw[key], key
    assert (d["atm_db"], d["cable_db"]) == (0.7, 1.2)
    lam = 299_792_458.0 / 20e9
    fspl = -20 * np.log10(lam / (4 * np.pi * 1.7e6))  # Friis, not fspl_db
    assert d["fspl_db"] == pytest.approx(fspl, abs=1e-9)
    noise = 10 * np.log10(1.380649e-23 * 10**2.5 * 100e6)
    assert d["noise_dbw"] == pytest.approx(noise, abs=1e-9)
    assert d["rss_dbw"] == pytest.approx(12.0 - 1.2 + 24.6 - 0.7 - fspl + 30.1, abs=1e-9)
    assert d["snr_db"] == pytest.approx(d["rss_dbw"] - noise, abs=1e-9)
    assert all(isinstance(v, float) for v in d.values())
    plain = LinkBudget.compute(**kw).as_dict()
    assert (plain["atm_db"], plain["cable_db"]) == (0.0, 0.0)
    assert plain["rss_dbw"] == pytest.approx(d["rss_dbw"] + 1.9, abs=1e-9)
