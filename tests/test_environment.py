"""TR 38.811 clause 6.6 tables and lookups (leolink.link.environment).

Expected numbers are typed from 3GPP TR 38.811 V15.4.0 (2020-09): Table 6.6.1-1,
Tables 6.6.2-1 / 6.6.2-2 / 6.6.2-3 and Table 6.6.6.2.1-1, not read from the data files.
"""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from leolink.errors import ConfigError
from leolink.link import environment as env

TABLE_EXACT = 1e-12  # table values are stored as typed: any difference is a transcription error


@pytest.mark.parametrize(
    ("environment", "elevation_deg", "percent"),
    [
        ("dense_urban", 10, 28.2),
        ("dense_urban", 70, 73.8),
        ("urban", 50, 72.6),
        ("urban", 90, 99.2),
        ("suburban", 90, 99.8),
        ("rural", 40, 92.9),
        ("rural", 10, 78.2),
    ],
)
def test_los_probability_table_6_6_1_1(environment, elevation_deg, percent):
    assert env.los_probability(elevation_deg, environment) == pytest.approx(
        percent / 100, abs=TABLE_EXACT
    )


def test_los_probability_interpolates_linearly_and_clamps_below_10_deg():
    # Table 6.6.1-1 urban: 49.3 % at 30 deg, 61.3 % at 40 deg -> 55.3 % at 35 deg.
    assert env.los_probability(35.0, "urban") == pytest.approx(0.553, abs=TABLE_EXACT)
    # Dense urban 80 -> 90 deg: 82.0 -> 98.1 %, a quarter of the way at 82.5 deg.
    assert env.los_probability(82.5, "dense_urban") == pytest.approx(0.86025, abs=TABLE_EXACT)
    # Below the table: the 10-degree row (24.6 %), not an extrapolation.
    assert env.los_probability([0.0, 5.0, 9.99], "urban") == pytest.approx(0.246, abs=TABLE_EXACT)


@given(elevation_deg=st.floats(10.0, 90.0))
def test_interpolated_los_probability_lies_between_neighbouring_rows(elevation_deg):
    grid = np.arange(10.0, 91.0, 10.0)
    dense_urban = np.array([28.2, 33.1, 39.8, 46.8, 53.7, 61.2, 73.8, 82.0, 98.1]) / 100
    i = min(np.searchsorted(grid, elevation_deg, side="right") - 1, 7)
    p = env.los_probability(elevation_deg, "dense_urban")
    assert min(dense_urban[i], dense_urban[i + 1]) - 1e-12 <= p
    assert p <= max(dense_urban[i], dense_urban[i + 1]) + 1e-12


# (environment, band, elevation_deg, sigma_SF LoS, sigma_SF NLoS, CL NLoS) typed from the tables.
TABLE_6_6_2_SPOTS = [
    ("dense_urban", "s", 30, 2.9, 12.4, 29.0),  # Table 6.6.2-1
    ("dense_urban", "s", 90, 1.2, 9.2, 25.5),
    ("dense_urban", "ka", 10, 2.9, 17.1, 44.3),
    ("dense_urban", "ka", 90, 0.6, 12.3, 32.9),
    ("urban", "s", 10, 4.0, 6.0, 34.3),  # Table 6.6.2-2
    ("urban", "s", 60, 4.0, 6.0, 26.2),
    ("urban", "ka", 90, 4.0, 6.0, 32.9),
    ("urban", "ka", 40, 4.0, 6.0, 35.8),
    ("suburban", "s", 40, 0.92, 10.25, 18.28),  # Table 6.6.2-3
    ("suburban", "s", 10, 1.79, 8.93, 19.52),
    ("rural", "ka", 60, 3.1, 10.8, 17.8),
    ("rural", "ka", 90, 0.4, 10.8, 16.8),
    ("rural", "s", 70, 0.85, 10.17, 16.50),
]


@pytest.mark.parametrize(
    ("environment", "band", "el", "sf_los", "sf_nlos", "cl"), TABLE_6_6_2_SPOTS
)
def test_shadowing_and_clutter_tables_6_6_2_1_to_3(environment, band, el, sf_los, sf_nlos, cl):
    assert env.shadow_sigma_db(el, environment, band, True) == pytest.approx(
        sf_los, abs=TABLE_EXACT
    )
    assert env.shadow_sigma_db(el, environment, band, False) == pytest.approx(
        sf_nlos, abs=TABLE_EXACT
    )
    assert env.clutter_loss_db(el, environment, band) == pytest.approx(cl, abs=TABLE_EXACT)


def test_suburban_and_rural_share_table_6_6_2_3():
    el = np.linspace(0.0, 90.0, 37)
    for band in env.BANDS:
        for los in (True, False):
            a = env.shadow_sigma_db(el, "suburban", band, los)
            assert np.array_equal(a, env.shadow_sigma_db(el, "rural", band, los))
        assert np.array_equal(
            env.clutter_loss_db(el, "suburban", band), env.clutter_loss_db(el, "rural", band)
        )


def test_shadow_sigma_selects_state_elementwise():
    # Table 6.6.2-1, S band, 20 deg: 3.4 dB in LoS, 13.9 dB in NLoS.
    sigma = env.shadow_sigma_db([20.0, 20.0], "dense_urban", "s", np.array([True, False]))
    assert sigma == pytest.approx([3.4, 13.9], abs=TABLE_EXACT)


def test_open_environment_is_the_papers_line_of_sight_link():
    el = np.array([5.0, 30.0, 90.0])
    assert np.all(env.los_probability(el, "open") == 1.0)
    assert np.all(env.shadow_sigma_db(el, "open", "ka", False) == 0.0)
    assert np.all(env.clutter_loss_db(el, "open", "ka") == 0.0)


@pytest.mark.parametrize(
    ("name", "table"),
    [
        ("tr38811_los_probability.csv", "Table 6.6.1-1"),
        ("tr38811_shadowing_clutter.csv", "Table 6.6.2-3"),
        ("tr38811_tropospheric_scintillation.csv", "Table 6.6.6.2.1-1"),
    ],
)
def test_data_files_carry_source_version_table_and_units(name, table):
    columns, units, rows, comments = env.read_table(name)
    header = "\n".join(comments)
    assert "3GPP TR 38.811 V15.4.0" in header and table in header
    assert len(units) == len(columns) and units[0] == "deg"
    assert all(len(r) == len(columns) for r in rows)


@pytest.mark.parametrize(
    ("freq_hz", "band"),
    [(2.0e9, "s"), (3.5e9, "s"), (6.0e9, "s"), (6.5e9, "ka"), (11.45e9, "ka"), (20e9, "ka")],
)
def test_band_for_frequency_nearest_on_a_log_scale(freq_hz, band):
    assert env.band_for_frequency(freq_hz) == band
    # The rule is "nearest of 2 GHz and 20 GHz in log frequency".
    nearest = "s" if abs(np.log(freq_hz / 2e9)) < abs(np.log(freq_hz / 20e9)) else "ka"
    assert nearest == band


def test_band_for_frequency_explicit_choice_and_errors():
    assert env.band_for_frequency(11.45e9, "s") == "s"
    assert env.band_for_frequency(2e9, "ka") == "ka"
    with pytest.raises(ConfigError, match=r"band = 'ku' is not allowed"):
        env.band_for_frequency(11.45e9, "ku")
    with pytest.raises(ConfigError, match=r"freq_hz = 200000000000.0 is not allowed"):
        env.band_for_frequency(200e9)
    with pytest.raises(ConfigError, match=r"environment = 'forest' is not allowed"):
        env.los_probability(30.0, "forest")


@pytest.mark.parametrize(("el", "loss_db"), [(10, 1.08), (30, 0.30), (45, 0.195), (90, 0.12)])
def test_tropospheric_scintillation_at_20_ghz_is_table_6_6_6_2_1_1(el, loss_db):
    # 45 deg: halfway between 0.22 (40 deg) and 0.17 (50 deg).
    assert env.tropospheric_scintillation_db(el, 20e9) == pytest.approx(loss_db, abs=TABLE_EXACT)


def test_tropospheric_frequency_scaling_agrees_with_itu_r_p618():
    # Independent: ITU-R P.618-13 clause 2.4.1 via itur, with a 1 cm antenna (no aperture
    # averaging); the ratio between two frequencies is what leolink borrows from it.
    from itur.models import itu618

    def p618_db(f_ghz):
        return itu618.scintillation_attenuation(42.24, -8.72, f_ghz, 30.0, 1.0, 0.01).value

    expected = p618_db(11.45) / p618_db(20.0)
    ratio = env.tropospheric_scintillation_db(30.0, 11.45e9) / env.tropospheric_scintillation_db(
        30.0, 20e9
    )
    assert ratio == pytest.approx(expected, rel=2e-3)  # g(x) of a 1 cm dish is 1 within 0.1 %


def test_ionospheric_scintillation_clause_6_6_6_1_4():
    # P_fluc(4 GHz) = 1.1 dB, (f/4)^-1.5, / sqrt(2): 2.2 dB at 2 GHz near the equator.
    assert env.ionospheric_scintillation_db(2e9, 10.0) == pytest.approx(2.2, abs=1e-9)
    # ns-3 writes the same law as 6.22 / f_GHz^1.5 (6.22 rounds 8.8/sqrt(2) = 6.2225).
    assert env.ionospheric_scintillation_db(3e9, -15.0) == pytest.approx(6.22 / 3**1.5, abs=2e-3)
    # Mid-latitude (the paper's Vigo) and high latitude: none.
    assert env.ionospheric_scintillation_db(2e9, [45.0, -70.0]) == pytest.approx([0.0, 0.0])


def test_scintillation_switches_model_at_6_ghz():
    assert env.scintillation_db(30.0, 20e9) == pytest.approx(0.30, abs=TABLE_EXACT)
    assert env.scintillation_db([30.0, 60.0], 2e9, 0.0) == pytest.approx([2.2, 2.2])
    with pytest.raises(ConfigError, match="geomagnetic_latitude_deg is required"):
        env.scintillation_db(30.0, 2e9)


# --- Written from a mutation run's survivors (issue 45, docs/testing.md) ---------------


def test_the_band_limits_are_inclusive_and_ka_starts_at_the_geometric_mean():
    """0.5-100 GHz both included; Ka from sqrt(2 GHz x 20 GHz) = 6.3246 GHz on (decision 2)."""
    assert env.band_for_frequency(0.5e9) == "s" and env.band_for_frequency(100e9) == "ka"
    for f_hz in (0.5e9 - 1.0, 100e9 + 1.0):
        with pytest.raises(ConfigError, match="freq_hz"):
            env.band_for_frequency(f_hz)
    edge_hz = math.sqrt(2.0e9 * 20.0e9)
    assert env.band_for_frequency(edge_hz) == "ka"
    assert env.band_for_frequency(math.nextafter(edge_hz, 0.0)) == "s"


def test_unknown_environment_lists_the_allowed_ones():
    with pytest.raises(ConfigError) as err:
        env.validate_environment("forest")
    assert str(err.value).endswith("use one of open, rural, suburban, urban, dense_urban")


def test_open_environment_keeps_the_broadcast_shape_of_its_inputs():
    el = np.array([10.0, 45.0, 90.0])
    los = np.array([[True], [False]])
    p_los, clutter = env.los_probability(el, "open"), env.clutter_loss_db(el, "open", "ka")
    assert p_los.shape == clutter.shape == (3,)
    assert p_los.tolist() == [1.0] * 3 and clutter.tolist() == [0.0] * 3
    assert env.shadow_sigma_db(el, "open", "ka", los).shape == (2, 3)
    assert not env.shadow_sigma_db(el, "open", "ka", los).any()


def test_ionospheric_scintillation_includes_the_20_degree_edge_and_6_ghz_is_tropospheric():
    """Clause 6.6.6.1.4: within 20 degrees of the geomagnetic equator, edge included
    (6.22 / 2^1.5 = 2.2 dB at 2 GHz); clause 6.6.6.1 applies below 6 GHz, so 6 GHz itself
    takes the tropospheric model."""
    at_edge = env.ionospheric_scintillation_db(2e9, 20.0)
    assert at_edge == pytest.approx(1.1 * 2**1.5 / math.sqrt(2), rel=1e-12)
    assert env.ionospheric_scintillation_db(2e9, math.nextafter(20.0, 90.0)) == 0.0
    np.testing.assert_allclose(env.scintillation_db(30.0, 6e9, 0.0),
                               env.tropospheric_scintillation_db(30.0, 6e9))  # fmt: skip


@pytest.mark.usefixtures("compiled_and_numpy")
@pytest.mark.parametrize("environment", ["rural", "suburban", "urban", "dense_urban"])
@pytest.mark.parametrize("band", ["s", "ka"])
def test_link_table_values_are_the_single_lookups_bit_for_bit(environment, band):
    """The four values of each link, its grid segment found once (compiled: one loop), are
    the bits of the four single functions (numpy.interp): between and at the tabulated
    rows, below 10 and above 90 degrees."""
    rng = np.random.default_rng(38811)
    rows = np.arange(10.0, 91.0, 10.0)
    el = np.concatenate([
        rng.uniform(-5.0, 95.0, 20_000), rows, np.nextafter(rows, 0.0), np.nextafter(rows, 99.0),
        [-90.0, 0.0, 90.0, 120.0],
    ])  # fmt: skip
    p_los, sigma_los, sigma_nlos, cl_db = env.link_table_values(el, environment, band)
    np.testing.assert_array_equal(p_los, env.los_probability(el, environment))
    np.testing.assert_array_equal(sigma_los, env.shadow_sigma_db(el, environment, band, True))
    np.testing.assert_array_equal(sigma_nlos, env.shadow_sigma_db(el, environment, band, False))
    np.testing.assert_array_equal(cl_db, env.clutter_loss_db(el, environment, band))
