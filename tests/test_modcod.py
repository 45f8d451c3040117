"""Tests of leolink.link.modcod: the packaged DVB-S2/S2X table and ACM selection."""

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.link.modcod import (
    ModcodTable,
    modcod_names,
    modcod_spectral_efficiency,
    modcod_table,
    modcod_throughput_bps,
    select_modcod,
)

# The standards print the spectral efficiency to 6 decimals.
PRINTED_6_DECIMALS = 5e-7
N_LDPC_NORMAL = 64800  # normal FECFRAME [bit]
BBHEADER_BITS = 80
PLHEADER_SYMBOLS = 90
SLOT_SYMBOLS = 90
# BCH parity bits of the normal frame, EN 302 307-1 Table 5a (t = 12 unless listed): DVB-S2
# rates 2/3 and 5/6 use t = 10, 8/9 and 9/10 t = 8; every DVB-S2X normal-frame rate t = 12.
S2_BCH_PARITY = {"2/3": 160, "5/6": 160, "8/9": 128, "9/10": 128}
BCH_PARITY_T12 = 192


def _rows():
    t = modcod_table()
    return [
        (name, t.spectral_efficiency_bit_sym[i], t.esn0_ideal_db[i], t.sources[i])
        for i, name in enumerate(t.names)
    ]


def _split(name):
    """'16APSK 3/5-L' -> (bits per symbol 4, Fraction(3, 5))."""
    mod, rate = name.split()
    bits = {"QPSK": 2, "8PSK": 3, "8APSK": 3, "16APSK": 4, "32APSK": 5, "64APSK": 6}
    bits |= {"128APSK": 7, "256APSK": 8}
    return bits[mod], Fraction(rate.removesuffix("-L"))


def test_table_has_both_standards_and_unique_names():
    t = modcod_table()
    assert len(t.names) == len(set(t.names))
    assert sum(s.startswith("EN 302 307-1") for s in t.sources) == 28  # all DVB-S2 MODCODs
    assert sum(s.startswith("EN 302 307-2") for s in t.sources) == 39
    assert modcod_table() is t  # cached


def test_spectral_efficiency_follows_from_the_frame_structure():
    # eta = (K_bch - BBHEADER) / (PLFRAME symbols), EN 302 307-1 clause 5.5.2: the payload
    # is padded to whole 90-symbol slots (128APSK: 64800/7 -> 103 slots = 9270 symbols).
    for name, eta, _, source in _rows():
        m, rate = _split(name)
        s2 = source.startswith("EN 302 307-1")
        parity = S2_BCH_PARITY.get(str(rate), BCH_PARITY_T12) if s2 else BCH_PARITY_T12
        k_bch = int(N_LDPC_NORMAL * rate) - parity
        n_sym = SLOT_SYMBOLS * math.ceil(N_LDPC_NORMAL / (m * SLOT_SYMBOLS)) + PLHEADER_SYMBOLS
        assert eta == pytest.approx((k_bch - BBHEADER_BITS) / n_sym, abs=PRINTED_6_DECIMALS), name


def test_ideal_esn0_lies_above_shannon_and_within_4db():
    # Es/N0 >= 2^R - 1 with R = K_bch / N_data bits per data symbol. LDPC 64800 codes sit
    # 0.7-2 dB above it at low rates; high rates on small constellations are limited by the
    # constellation, not the code (8PSK 9/10: 3.6 dB). A row moved by one modulation order
    # (e.g. QPSK 9/10 given the 8PSK 9/10 threshold, gap 7 dB) fails.
    for name, _, esn0, source in _rows():
        m, rate = _split(name)
        s2 = source.startswith("EN 302 307-1")
        parity = S2_BCH_PARITY.get(str(rate), BCH_PARITY_T12) if s2 else BCH_PARITY_T12
        r_bits = (int(N_LDPC_NORMAL * rate) - parity) / (N_LDPC_NORMAL / m)
        gap_db = esn0 - 10 * np.log10(2.0**r_bits - 1.0)
        assert 0.3 < gap_db < 4.0, (name, gap_db)


def test_threshold_grows_with_code_rate_within_a_constellation():
    # Same constellation (the -L ones apart), same standard: a higher rate needs more Es/N0.
    groups = {}
    for name, _, esn0, source in _rows():
        key = (name.split()[0], name.endswith("-L"), source)
        groups.setdefault(key, []).append((_split(name)[1], esn0))
    for key, rows in groups.items():
        esn0_by_rate = [e for _, e in sorted(rows)]
        assert np.all(np.diff(esn0_by_rate) > 0), key


def test_published_spot_values():
    # EN 302 307-1 Table 13 and EN 302 307-2 Table 20a, typed from the standards' text.
    t = modcod_table()
    for name, eta, esn0 in [
        ("QPSK 1/2", 0.988858, 1.00),
        ("8PSK 9/10", 2.679207, 10.98),
        ("32APSK 9/10", 4.453027, 16.05),
        ("QPSK 13/45", 0.567805, -2.03),
        ("16APSK 3/5-L", 2.370043, 7.41),
        ("256APSK 3/4", 5.900855, 19.57),
    ]:
        i = t.index_of(name)
        assert t.spectral_efficiency_bit_sym[i] == eta
        assert t.esn0_ideal_db[i] == esn0


@pytest.mark.parametrize("margin_db", [0.0, 0.7])
def test_every_table_threshold_selects_at_equality(margin_db):
    # At Es/N0 == threshold + margin the MODCOD is allowed: the selection reaches at least its
    # efficiency; a hair below, it is not allowed any more.
    t = modcod_table()
    thr = t.esn0_ideal_db + margin_db
    at = select_modcod(thr, margin_db=margin_db)
    below = select_modcod(np.nextafter(thr, -np.inf), margin_db=margin_db)
    eta = t.spectral_efficiency_bit_sym
    assert np.all(at >= 0)
    assert np.all(eta[at] >= eta - 1e-12)
    for i in range(len(thr)):  # brute force: best eta over rows with threshold <= x
        for x, got in ((thr[i], at[i]), (np.nextafter(thr[i], -np.inf), below[i])):
            allowed = np.flatnonzero(thr <= x)
            assert got == (-1 if allowed.size == 0 else _brute_best(t, allowed))


def _brute_best(t, allowed):
    """Highest efficiency among ``allowed`` rows, lowest threshold on ties, then file order."""
    keys = [(-t.spectral_efficiency_bit_sym[i], t.esn0_ideal_db[i], i) for i in allowed]
    return min(keys)[2]


def test_named_choices_at_thresholds():
    # Worked by hand from Tables 13 and 20a.
    names = modcod_names(select_modcod([-2.85, -2.351, 7.41, 7.409, 19.57, 40.0, -30.0]))
    assert list(names) == [
        "QPSK 2/9",  # -2.85 dB: exactly its threshold, the only one allowed
        "QPSK 2/9",  # 1 mdB short of QPSK 1/4 (-2.35 dB)
        "16APSK 3/5-L",  # same eta as 16APSK 3/5 (7.80 dB): the lower threshold wins
        "16APSK 5/9-L",  # below 7.41: best is 2.193247 (6.84 dB), above 8PSK 25/36 (7.02 dB)
        "256APSK 3/4",
        "256APSK 3/4",
        "",
    ]


def test_custom_table_ties():
    # Equal thresholds: the higher efficiency wins; equal efficiencies: the lower threshold.
    t = ModcodTable(
        names=("A", "B", "C", "D"),
        spectral_efficiency_bit_sym=np.array([1.0, 1.5, 1.5, 2.0]),
        esn0_ideal_db=np.array([3.0, 3.0, 2.0, 6.0]),
        sources=("test",) * 4,
    )
    got = select_modcod([1.9, 2.0, 3.0, 5.9, 6.0], table=t)
    assert list(modcod_names(got, table=t)) == ["", "C", "C", "C", "D"]
    assert (
        select_modcod(
            3.0,
            table=ModcodTable(("A", "B"), np.array([1.0, 1.5]), np.array([3.0, 3.0]), ("t", "t")),
        )
        == 1
    )


def test_margin_shifts_every_threshold():
    # With margin m, Es/N0 = x + m selects what x selects without margin (x off the
    # 0.01 dB grid of the thresholds, so that rounding of x + m cannot cross one).
    x = np.linspace(-4.0, 22.0, 2601) + 0.005
    np.testing.assert_array_equal(select_modcod(x + 1.5, margin_db=1.5), select_modcod(x))


def test_outage_and_nan():
    idx = select_modcod(np.array([[np.nan, -np.inf], [-2.8501, np.inf]]))
    assert idx.shape == (2, 2)
    assert idx[0, 0] == -1 and idx[0, 1] == -1 and idx[1, 0] == -1
    assert modcod_names(idx[1, 1]) == "256APSK 3/4"
    assert modcod_throughput_bps(idx, 10e6)[0, 0] == 0.0


def test_throughput_is_eta_times_symbol_rate():
    # 16APSK 3/5-L at 40 Mbaud: 2.370043 bit/symbol x 40e6 = 94.80172 Mbit/s.
    i = modcod_table().index_of("16APSK 3/5-L")
    assert modcod_throughput_bps(i, 40e6) == pytest.approx(94.80172e6, rel=1e-12)
    rs = np.array([1e6, 2e6])
    np.testing.assert_allclose(modcod_throughput_bps([i, -1], rs), [2.370043e6, 0.0])
    assert modcod_spectral_efficiency(-1) == 0.0


@settings(max_examples=200, deadline=None)
@given(esn0=st.floats(-10.0, 30.0), margin=st.floats(0.0, 3.0))
def test_selection_is_the_best_allowed_and_below_shannon(esn0, margin):
    t = modcod_table()
    i = int(select_modcod(esn0, margin_db=margin))
    allowed = np.flatnonzero(t.esn0_ideal_db + margin <= esn0)
    assert i == (-1 if allowed.size == 0 else _brute_best(t, allowed))
    if i >= 0:  # ACM never promises more than the AWGN capacity at that Es/N0
        assert t.spectral_efficiency_bit_sym[i] < np.log2(1.0 + 10 ** (esn0 / 10))


def test_selection_is_monotone_in_esn0():
    eta = modcod_spectral_efficiency(select_modcod(np.linspace(-5.0, 25.0, 3001)))
    assert np.all(np.diff(eta) >= 0.0)
