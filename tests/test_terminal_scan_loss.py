"""Flat-panel scan loss of the UPA and leaky-wave terminals, against explicit array sums.

The reference is computed element by element: the panel lies in the UT's east-north plane,
the satellite at elevation ``el`` due east (the frame of ``antenna.panel.pointing_offsets``),
the beam steered at a direction ``d`` higher in elevation (a pointing error); the gain is
``|sum_mn w_mn^* a_mn(v)|^2 / sum |w_mn|^2`` times the element power pattern ``cos(theta_v)^q``
with ``cos(theta_v) = v . up = sin(el)`` (no Dirichlet kernel, no leolink antenna function).
"""

import numpy as np
import pytest

from leolink.antenna.terminal import LeakyWave, UPATerminal
from leolink.app.run import run
from leolink.config import load_config

N = 12  # 12 x 12 panel: explicit sums stay cheap, side lobes still matter
K_RICIAN = 10.0
Q_PAPER = 1.2  # the paper's Sec. 2.1 Kymeta roll-off factor, the default q


def _explicit_gain(el_rad, err_rad, n, q, taper=0.0):
    """Explicit array sum towards the satellite times cos(theta)^q, beam off by ``err_rad``."""
    v = np.array([np.cos(el_rad), 0.0, np.sin(el_rad)])  # satellite due east
    b = np.array([np.cos(el_rad + err_rad), 0.0, np.sin(el_rad + err_rad)])  # beam
    m, k = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    amp = np.exp(-taper * m) * np.exp(-taper * k)  # leaky wave: e^{-a m} e^{-a k}
    w = amp * np.exp(1j * np.pi * (m * b[0] + k * b[1]))
    a = np.exp(1j * np.pi * (m * v[0] + k * v[1]))
    af = np.abs(np.sum(np.conj(w) * a)) ** 2 / np.sum(np.abs(w) ** 2)
    return af * v[2] ** q


ELEVATIONS_DEG = [10.0, 25.0, 40.0, 60.0, 89.0]


@pytest.mark.parametrize("el_deg", ELEVATIONS_DEG)
@pytest.mark.parametrize("err_deg", [0.0, 2.0, 7.0])
@pytest.mark.parametrize("q", [Q_PAPER, 2.0])
def test_upa_scan_loss_equals_explicit_array_factor_times_element(el_deg, err_deg, q):
    el, err = np.radians(el_deg), np.radians(err_deg)
    upa = UPATerminal(N, N, K_RICIAN, scan_loss=True, element_exponent=q)
    expected = _explicit_gain(el, err, N, q) + 1.0 / K_RICIAN  # the diffuse term keeps 1/K
    assert upa.gain_lin(el, err, 0.0) == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize("el_deg", ELEVATIONS_DEG)
@pytest.mark.parametrize("err_deg", [0.0, 3.0])
def test_leaky_wave_scan_loss_equals_explicit_tapered_sum(el_deg, err_deg):
    el, err, a = np.radians(el_deg), np.radians(err_deg), 0.05
    lw = LeakyWave(N, N, a, scan_loss=True, element_exponent=Q_PAPER)
    assert lw.gain_lin(el, err, 0.0) == pytest.approx(
        _explicit_gain(el, err, N, Q_PAPER, taper=a), rel=1e-10
    )


def test_scan_loss_at_low_elevation_in_db():
    # 24 x 24 at 20 deg: 27.60 dB (N + 1/K) without; N sin(20)^1.2 + 1/K = 22.01 dB with.
    el = np.radians(20.0)
    off = UPATerminal(24, 24, K_RICIAN)
    on = UPATerminal(24, 24, K_RICIAN, scan_loss=True)
    assert off.gain_db(el) == pytest.approx(10 * np.log10(576.1), abs=1e-12)
    assert on.gain_db(el) == pytest.approx(10 * np.log10(576 * np.sin(el) ** 1.2 + 0.1), abs=1e-12)
    assert off.elevation_independent and not on.elevation_independent


@pytest.fixture(scope="module")
def scan_run():
    cfg = load_config(
        "configs/paper.toml",
        ["terminal.upa.scan_loss=true", "run.duration_s=40.0", "output.plots.enabled=false"],
    )
    return run(cfg).trace


def test_run_trace_gain_rx_follows_the_element_factor(scan_run):
    """Every served row of a real run: gain_rx_db = 10 log10(576 sin(el)^1.2 + 1/K)."""
    tr = scan_run[scan_run.sat_id >= 0]
    el = np.radians(tr.elevation_deg.to_numpy())
    expected = 10 * np.log10(576 * np.sin(el) ** Q_PAPER + 1.0 / K_RICIAN)
    np.testing.assert_allclose(tr.gain_rx_db, expected, rtol=0, atol=1e-9)
    assert tr.gain_rx_db.max() - tr.gain_rx_db.min() > 0.3  # the elevation does vary


def _bearing_rad(lat1, lon1, lat2, lon2):
    """Initial great-circle bearing from point 1 to point 2 [rad] (spherical trigonometry)."""
    dlon = lon2 - lon1
    y = np.sin(dlon) * np.cos(lat2)
    x = np.cos(lat1) * np.sin(lat2) - np.sin(lat1) * np.cos(lat2) * np.cos(dlon)
    return np.arctan2(y, x)


TILTED = [
    "terminal.upa.scan_loss=true",
    "run.duration_s=30.0",
    "output.plots.enabled=false",
    "population.0.panel_tilt_deg=30.0",  # UT 0 (centre): normal 30 deg towards north
    "population.0.panel_azimuth_deg=0.0",
    "population.2.panel_tilt_deg=20.0",  # UT 5 (car, cross-track): towards its motion
    'population.2.panel_azimuth_deg="motion"',
]


@pytest.fixture(scope="module")
def tilted_run():
    return run(load_config("configs/paper.toml", TILTED)).trace


def _expected_gain_db(tr, normal_enu):
    el, az = np.radians(tr.elevation_deg.to_numpy()), np.radians(tr.azimuth_deg.to_numpy())
    v = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=-1)
    cos_theta = np.clip(np.einsum("rk,rk->r", v, normal_enu), 0.0, None)
    return 10 * np.log10(576 * cos_theta**Q_PAPER + 1.0 / K_RICIAN)


def test_tilted_static_panel_sees_the_satellite_off_its_own_normal(tilted_run):
    tr = tilted_run[(tilted_run.ut_id == 0) & (tilted_run.sat_id >= 0)]
    tilt = np.radians(30.0)
    normal = np.tile([0.0, np.sin(tilt), np.cos(tilt)], (len(tr), 1))  # tilted to the north
    np.testing.assert_allclose(tr.gain_rx_db, _expected_gain_db(tr, normal), rtol=0, atol=1e-9)
    flat = 10 * np.log10(576 * np.sin(np.radians(tr.elevation_deg)) ** Q_PAPER + 0.1)
    assert np.abs(tr.gain_rx_db - flat).max() > 0.5  # the tilt matters on this pass


def test_vehicle_panel_tilts_towards_its_motion(tilted_run):
    car = tilted_run[tilted_run.ut_id == 5].sort_values("time_s")
    lat, lon = np.radians(car.lat_deg.to_numpy()), np.radians(car.lon_deg.to_numpy())
    # Heading from the trace's own track, central differences (great-circle bearing).
    heading = _bearing_rad(lat[:-2], lon[:-2], lat[2:], lon[2:])
    rows = car.iloc[1:-1]
    tilt = np.radians(20.0)
    normal = np.stack(
        [np.sin(tilt) * np.sin(heading), np.sin(tilt) * np.cos(heading),
         np.full(heading.shape, np.cos(tilt))], axis=-1,
    )  # fmt: skip
    served = rows.sat_id.to_numpy() >= 0
    # The bearing of a 60 m chord differs from the heading by < 1e-6 rad: < 1e-5 dB here.
    np.testing.assert_allclose(
        rows.gain_rx_db[served], _expected_gain_db(rows, normal)[served], rtol=0, atol=1e-5
    )


def test_turning_a_flat_panel_keeps_its_gain():
    over = ["terminal.upa.scan_loss=true", "run.duration_s=10.0", "output.plots.enabled=false"]
    flat = run(load_config("configs/paper.toml", over)).trace
    turned = run(load_config("configs/paper.toml", [*over, "population.1.panel_azimuth_deg=17.0"]))
    np.testing.assert_allclose(turned.trace.gain_rx_db, flat.gain_rx_db, rtol=0, atol=1e-12)
