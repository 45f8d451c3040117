"""The engine's serving paths that a run takes and the paper's pass does not, against
explicit per-UT link budgets.

The reference is written from the paper's equations, one UT at a time, with no leolink
antenna or geometry function: the satellite beams by explicit steering-vector sums in the
body frame (x along the velocity's part across the radius, z radial, y = z x x), the UT's
24 x 24 UPA steered at its serving satellite in its own panel's direction cosines, the
flat-panel element factor ``N sin(el_panel)^q + 1/K`` of the serving link (scan loss on),
``(4 pi rho f / c)^2`` for the free-space loss and a cosecant atmosphere written here.
The UTs are given local frames (``ut_enu``) whose up is 1 deg off the radial one and
whose east is turned 20 deg, and panels tilted 25 deg: a path that falls back to the
sphere's radial frame or to a flat panel is off by much more than the tolerance.
"""

import math
import warnings

import numpy as np
import pytest

from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.constants import BOLTZMANN_J_K, SPEED_OF_LIGHT_M_S
from leolink.engine import SERVE_COLUMNS, SERVE_GEOMETRY_COLUMNS, LinkEngine
from leolink.geometry import geodetic_to_ecef
from scopes import shared_run_scope

WALKER = "configs/examples/walker.toml"
COLUMNS = SERVE_COLUMNS + SERVE_GEOMETRY_COLUMNS
N_UT = 40
K_RICIAN, Q, N_UT_X = 10.0, 1.2, 24  # walker.toml's UPA, the default scan exponent
# dB figures recomputed in float64 from the same inputs: rounding only (~1e-12 dB); the
# tolerance is 1e-6 dB, far below the 1 deg and 20 deg frame offsets (>= 1e-2 dB).
DB = 1e-6


class Cosecant:
    """An elevation-dependent atmosphere, ``A / sin(el)`` (flat-Earth air mass), A = 0.3 dB."""

    constant_db = None

    def __call__(self, elevation_rad):
        return 0.3 / np.sin(np.maximum(elevation_rad, 1e-3))


def _rotate(v, axis, angle_rad):
    """Rodrigues' rotation of the rows ``v`` about the unit ``axis`` (per row)."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    dot = np.sum(v * axis, axis=-1, keepdims=True)
    return v * c + np.cross(axis, v) * s + axis * dot * (1 - c)


def _frames(ut):
    """Local frames of the UTs (rows east, north, up), up 1 deg off the radial direction
    and east turned 20 deg about it; and panels tilted 25 deg towards their x axis."""
    r = ut / np.linalg.norm(ut, axis=1, keepdims=True)
    east = np.stack([-ut[:, 1], ut[:, 0], np.zeros(len(ut))], 1)
    east /= np.linalg.norm(east, axis=1, keepdims=True)
    north = np.cross(r, east)
    # up tilted 1 deg towards north (an exaggerated geodetic normal), the frame with it
    up = _rotate(r, east, math.radians(-1.0))
    n2 = _rotate(north, east, math.radians(-1.0))
    e2 = _rotate(east, up, math.radians(-20.0))  # east turned 20 deg towards north
    n2 = _rotate(n2, up, math.radians(-20.0))
    enu = np.stack([e2, n2, up], 1)
    # panel: x tilted 25 deg down, normal 25 deg up from local up towards x
    x = _rotate(e2, n2, math.radians(25.0))
    normal = _rotate(up, n2, math.radians(25.0))
    panel = np.stack([x, np.cross(normal, x), normal], 1)
    assert np.allclose(np.einsum("uij,ukj->uik", panel, panel), np.eye(3), atol=1e-12)
    return enu, panel


def _upa(u_xy, n_x, n_y):
    """Explicit half-wavelength UPA steering vectors, element (i, j) = exp(-i pi (i ux + j uy))."""
    i, j = np.meshgrid(np.arange(n_x), np.arange(n_y), indexing="ij")
    return np.exp(-1j * np.pi * (np.multiply.outer(u_xy[..., 0], i.ravel())
                                 + np.multiply.outer(u_xy[..., 1], j.ravel())))  # fmt: skip


@pytest.fixture(scope=shared_run_scope)
def walker():
    """Walker engine (113 beams, 3 reuse colours, UPA with scan loss, every satellite
    interfering) rebuilt with the cosecant atmosphere; 4 satellites (the 3 highest over
    the ROI centre and one below the horizon of every UT); 40 UTs with their frames."""
    over = ['link.interference="all_satellites"', "link.reuse_colors=3",
            "terminal.upa.scan_loss=true"]  # fmt: skip
    cfg = load_config(WALKER, over)
    sc = build_scenario(cfg)
    e = sc.engine
    eng = LinkEngine(e.codebook, e.terminal, e.params, Cosecant(), colors=e.colors,
                     other_satellites=True)  # fmt: skip
    pos, vel, acc = (a[0] for a in sc.ephemeris(137.0))
    lat0, lon0 = math.radians(cfg.roi.center_lat_deg), math.radians(cfg.roi.center_lon_deg)
    c0 = geodetic_to_ecef(lat0, lon0)
    sin_el = (pos - c0) @ (c0 / np.linalg.norm(c0)) / np.linalg.norm(pos - c0, axis=1)
    order = np.argsort(-sin_el)
    sats = np.concatenate([order[:3], order[-1:]])
    rng = np.random.default_rng(21)
    ut = geodetic_to_ecef(lat0 + np.radians(rng.uniform(-3, 3, N_UT)),
                          lon0 + np.radians(rng.uniform(-4, 4, N_UT)))  # fmt: skip
    enu, panel = _frames(ut)
    return eng, ut, enu, panel, pos[sats], vel[sats], acc[sats], rng


def _tx_gains(cb, beams, sat_pos_m, sat_vel_m_s, d):
    """Every beam's gain of the satellite's array toward a UT (``d``: the unit vector from
    the UT to the satellite), explicit steering vectors in its body frame (z radial, x
    along the velocity's horizontal part); ``beams`` = ``_upa`` of the codebook."""
    z = sat_pos_m / np.linalg.norm(sat_pos_m)
    x = sat_vel_m_s - (sat_vel_m_s @ z) * z
    x /= np.linalg.norm(x)
    a = _upa(np.array([-d @ x, -d @ np.cross(z, x)]), cb.n_sub_x, cb.n_sub_y)
    return np.abs(beams.conj() @ a) ** 2 / (cb.n_sub_x * cb.n_sub_y)


def _reference(eng, ut, enu, panel, sp, sv, s, b, lit=None):
    """Per UT: the received power of every (satellite, beam) [W] (zero where dark, or for
    another colour than the serving beam's, or below the UT's horizon), and the serving
    link's elevation, panel elevation, azimuth, slant range and atmosphere."""
    p, cb = eng.params, eng.codebook
    beams = _upa(np.asarray(cb.u_xy, float), cb.n_sub_x, cb.n_sub_y)  # (n_beam, n_el)
    ptx_w = 10 ** ((p.ptx_dbw - p.cable_loss_db - p.other_loss_db) / 10)
    out = []
    for i in range(len(ut)):
        e, n, up = enu[i]
        px, py, pn = panel[i]
        d_s = (sp[s[i]] - ut[i]) / np.linalg.norm(sp[s[i]] - ut[i])
        w = _upa(np.array([d_s @ px, d_s @ py]), N_UT_X, N_UT_X)
        powers = np.zeros((len(sp), eng.n_beam))
        for k in range(len(sp)):
            los = sp[k] - ut[i]
            rho = np.linalg.norm(los)
            d = los / rho
            el = math.asin(d @ up)
            if el <= 0:
                continue
            g_tx = _tx_gains(cb, beams, sp[k], sv[k], d)
            if k == s[i]:  # the serving link: element factor of the angle above the panel
                g_rx = N_UT_X**2 * math.sin(math.asin(d @ pn)) ** Q + 1 / K_RICIAN
                serving = dict(el=el, el_panel=math.asin(d @ pn), rho=rho, g_rx=g_rx,
                               az=math.atan2(d @ e, d @ n), g_tx=g_tx[b[i]])  # fmt: skip
            else:  # another satellite: the UT array factor off its beam, plus 1/K
                a_ut = _upa(np.array([d @ px, d @ py]), N_UT_X, N_UT_X)
                g_rx = np.abs(a_ut.conj() @ w) ** 2 / N_UT_X**2 + 1 / K_RICIAN
            loss = (4 * np.pi * rho * p.freq_hz / SPEED_OF_LIGHT_M_S) ** 2
            loss *= 10 ** (0.3 / math.sin(el) / 10)
            same = eng.colors == eng.colors[b[i]]
            on = same if lit is None else same & lit[k]
            if k == s[i]:
                on[b[i]] = True  # the signal: lit by definition
            powers[k] = np.where(on, ptx_w * g_tx * g_rx / loss, 0.0)
        out.append((powers, serving))
    return out


def _served(snap, eng):
    """Each UT's best visible satellite (by path SNR) and a random beam of it."""
    path = np.nan_to_num(snap.path_snr_lin, nan=-1.0)
    s = np.argmax(path, axis=1)
    ok = snap.visible[np.arange(snap.n_ut), s]
    return s, ok


def _check_rows(cols, ref, s, b, eng, rows):
    p = eng.params
    bw = p.bandwidth_hz / (eng.colors.max() + 1)
    noise_w = BOLTZMANN_J_K * 10 ** (p.noise_temp_dbk / 10) * bw
    for i in rows:
        powers, sv = ref[i]
        signal = powers[s[i], b[i]]
        sinr = signal / (powers.sum() - signal + noise_w)
        fspl = 20 * math.log10(4 * math.pi * sv["rho"] * p.freq_hz / SPEED_OF_LIGHT_M_S)
        expected = {
            "elevation_deg": math.degrees(sv["el"]),
            "slant_range_m": sv["rho"],
            "gain_tx_db": 10 * math.log10(sv["g_tx"]),
            "gain_rx_db": 10 * math.log10(sv["g_rx"]),
            "fspl_db": fspl,
            "atm_db": 0.3 / math.sin(sv["el"]),
            "snr_db": 10 * math.log10(signal / noise_w),
            "sinr_db": 10 * math.log10(sinr),
            "throughput_bps": bw * math.log2(1 + sinr),
            "azimuth_deg": math.degrees(sv["az"]) % 360.0,
        }
        for name, value in expected.items():
            tol = 1e-6 * abs(value) if name in ("slant_range_m", "throughput_bps") else DB
            assert cols[name][i] == pytest.approx(value, abs=tol), (name, i)


@pytest.mark.parametrize("tilted", [True, False], ids=["tilted", "flat"])
def test_given_frames_tilted_panels_and_other_satellites_equal_a_per_ut_budget(walker, tilted):
    """``evaluate`` with ``ut_enu`` (and ``ut_panel``), then ``serve``: elevation and
    visibility from the given up, the serving gain from the tilted panel, the azimuth in
    the given frame, the atmosphere at the elevation, the other satellites' beams of the
    serving colour through the panel's array factor (a flat panel: the given frame's
    east and north), none from below the horizon."""
    eng, ut, enu, panel, sp, sv, sa, rng = walker
    if not tilted:
        panel = enu
    snap = eng.evaluate(ut, sp, sv, ut_enu=enu, ut_panel=panel if tilted else None)
    s, ok = _served(snap, eng)
    b = rng.integers(0, eng.n_beam, N_UT)
    sat_idx = np.where(ok, s, -1)
    zero = np.zeros((N_UT, 3))
    cols = eng.serve(snap, sat_idx, b, zero, zero, sv, sa)
    ref = _reference(eng, ut, enu, panel, sp, sv, s, b)
    served = np.flatnonzero(ok)
    assert served.size > 20
    # every UT sees the last satellite below its horizon, and at least two above it
    assert (snap.elevation_rad[:, 3] < 0).all() and (snap.elevation_rad[:, :3] > 0).all()
    _check_rows(cols, ref, s, b, eng, served)
    for name in COLUMNS:
        assert np.isnan(cols[name][~ok]).all(), name


def test_lit_beams_alone_interfere_from_every_satellite(walker):
    """Active beams: ``serve_pairs`` with ``lit`` rows and the other satellites'
    interference of their lit beams only (the serving beam always lit, as a run does)."""
    eng, ut, enu, panel, sp, sv, sa, rng = walker
    snap = eng.evaluate(ut, sp, sv, ut_enu=enu, ut_panel=panel)
    s, ok = _served(snap, eng)
    b = rng.integers(0, eng.n_beam, N_UT)
    lit = rng.random((len(sp), eng.n_beam)) < 0.3
    u = np.arange(N_UT)
    i_other = eng.other_satellites_interference(snap, s, b, u, lit)
    rows_lit = lit[s]
    rows_lit[u, b] = True
    zero = np.zeros((N_UT, 3))
    cols = eng.serve_pairs(snap.links, np.where(ok, s * N_UT + u, -1), b, zero, zero, sv[s],
                           sa[s], i_other=i_other, ut_pos_m=ut, ut_enu=enu,
                           lit=rows_lit)  # fmt: skip
    ref = _reference(eng, ut, enu, panel, sp, sv, s, b, lit)
    _check_rows(cols, ref, s, b, eng, np.flatnonzero(ok))
    # no beam lit anywhere but the serving one: no interference at all, SINR = SNR
    dark = np.zeros_like(lit)
    i0 = eng.other_satellites_interference(snap, s, b, u, dark)
    assert (i0 == 0).all()


def _alone(eng, steering=None):
    """The walker engine with the default of ``other_satellites`` (the paper's: only the
    serving satellite's beams interfere), or with a steering mode."""
    return LinkEngine(eng.codebook, eng.terminal, eng.params, eng.atmosphere, colors=eng.colors,
                      steering=steering)  # fmt: skip


def test_two_satellites_the_other_one_interferes(walker):
    """Two satellites, both above every UT's horizon: the other one's beams count."""
    eng, ut, enu, panel, sp, sv, sa, rng = walker
    sp, sv, sa = sp[:2], sv[:2], sa[:2]
    snap = eng.evaluate(ut, sp, sv, ut_enu=enu)
    s, ok = _served(snap, eng)
    b = rng.integers(0, eng.n_beam, N_UT)
    zero = np.zeros((N_UT, 3))
    cols = eng.serve(snap, np.where(ok, s, -1), b, zero, zero, sv, sa)
    ref = _reference(eng, ut, enu, enu, sp, sv, s, b)
    assert all((r[0][1 - si] > 0).any() for r, si in zip(ref, s, strict=True))
    _check_rows(cols, ref, s, b, eng, np.flatnonzero(ok))


def test_one_satellite_unserved_uts_are_nan_and_the_others_unchanged(walker):
    """One satellite, half the UTs unserved (-1): NaN in every column of theirs, and the
    served rows as in the reference (nothing from other satellites: there are none)."""
    eng, ut, enu, panel, sp, sv, sa, rng = walker
    snap = eng.evaluate(ut, sp[:1], sv[:1], ut_enu=enu)
    b = rng.integers(0, eng.n_beam, N_UT)
    sat_idx = np.where(np.arange(N_UT) % 2 == 0, 0, -1)
    zero = np.zeros((N_UT, 3))
    cols = eng.serve(snap, sat_idx, b, zero, zero, sv[:1], sa[:1])
    ref = _reference(eng, ut, enu, enu, sp[:1], sv[:1], np.zeros(N_UT, int), b)
    served = np.flatnonzero((sat_idx == 0) & snap.visible[:, 0])
    assert served.size > 10
    _check_rows(cols, ref, np.zeros(N_UT, int), b, eng, served)
    for name in COLUMNS:
        assert np.isnan(cols[name][sat_idx < 0]).all(), name


def test_no_satellite_gives_a_nan_row_per_ut(walker):
    eng, ut, enu, panel, sp, sv, sa, rng = walker
    none = np.zeros((0, 3))
    snap = eng.evaluate(ut, none, none, ut_enu=enu)
    zero = np.zeros((N_UT, 3))
    cols = eng.serve(snap, np.full(N_UT, -1), np.zeros(N_UT, int), zero, zero, none, none)
    assert set(cols) == set(COLUMNS)
    for name in COLUMNS:
        assert cols[name].shape == (N_UT,) and np.isnan(cols[name]).all(), name


def test_fading_scales_the_signal_and_its_satellites_interference(walker):
    """``rx_fading_lin`` f multiplies the received power of the serving satellite's beams,
    signal and interference alike: SNR f S / N, SINR f S / (f I + N); by default the other
    three satellites do not interfere."""
    eng, ut, enu, panel, sp, sv, sa, rng = walker
    eng = _alone(eng)
    snap = eng.evaluate(ut, sp, sv, ut_enu=enu)
    s, ok = _served(snap, eng)
    b = rng.integers(0, eng.n_beam, N_UT)
    f = rng.uniform(0.05, 3.0, N_UT)
    zero = np.zeros((N_UT, 3))
    cols = eng.serve(snap, np.where(ok, s, -1), b, zero, zero, sv, sa, rx_fading_lin=f)
    p = eng.params
    noise_w = BOLTZMANN_J_K * 10 ** (p.noise_temp_dbk / 10) * p.bandwidth_hz / 3
    ref = _reference(eng, ut, enu, enu, sp, sv, s, b)
    for i in np.flatnonzero(ok):
        powers = ref[i][0][s[i]]  # the serving satellite's beams only
        sig = powers[b[i]]
        assert cols["snr_db"][i] == pytest.approx(10 * math.log10(f[i] * sig / noise_w), abs=DB)
        sinr = f[i] * sig / (f[i] * (powers.sum() - sig) + noise_w)
        assert cols["sinr_db"][i] == pytest.approx(10 * math.log10(sinr), abs=DB)


def test_earth_fixed_beams_take_their_own_cells_and_an_off_beam_serves_nothing(walker):
    """Quasi-Earth-fixed cells, one set per satellite: ``evaluate`` on two of four
    satellites with their ``sat_id`` steers each at its own cells (the explicit DFT beam
    centred at the cell's body-frame cosines), not at those of rows 0 and 1."""
    from leolink.antenna.steering import EarthFixed

    eng, ut, enu, panel, sp, sv, sa, rng = walker
    cb = eng.codebook
    # each satellite's cells: 113 ground points spread over the UTs' area, one in four
    # 25 deg further north (out of view: that beam is off)
    far = np.where(np.arange(eng.n_beam) % 4 == 0, 25.0, 0.0)
    lat = np.radians(42.24 + far + rng.uniform(-3, 3, (4, eng.n_beam)))
    lon = np.radians(-8.72 + rng.uniform(-4, 4, (4, eng.n_beam)))
    cells = geodetic_to_ecef(lat, lon)
    ef = EarthFixed(cells, math.radians(25.0), math.radians(70.0))
    steered = _alone(eng, steering=ef)
    pick = np.array([2, 1])
    snap = steered.evaluate(ut, sp[pick], sv[pick], sat_id=pick)
    _off_beam_serves_nothing_quietly(steered, snap, sv[pick], sa[pick])
    for j, k in enumerate(pick):
        expected = _steered_gains(cb, ut, sp[k], sv[k], sp[k], sv[k], cells[k])
        np.testing.assert_allclose(snap.gain_tx_lin[:, j, :], expected, rtol=1e-9, atol=1e-9)
    # Beams steered by believed states 20 km along-track (the ephemeris-error runs): the
    # cells' cosines from the believed position and frame, the UTs' from the true ones.
    k = 2
    est_pos = sp[k] + 20e3 * sv[k] / np.linalg.norm(sv[k])
    m = np.arange(N_UT)
    one = slice(k, k + 1)
    links = steered.evaluate_pairs(
        ut, sp[one], sv[one], m, np.zeros(N_UT, int), sat_id=[k], steer=(est_pos[None], sv[one])
    )
    expected = _steered_gains(cb, ut, sp[k], sv[k], est_pos, sv[k], cells[k])
    np.testing.assert_allclose((links.kx * links.ky).T, expected, rtol=1e-9, atol=1e-9)
    assert not np.allclose(expected, _steered_gains(cb, ut, sp[k], sv[k], sp[k], sv[k], cells[k]))


def _frame(pos, vel):
    z = pos / np.linalg.norm(pos)
    x = vel - (vel @ z) * z
    x /= np.linalg.norm(x)
    return x, np.cross(z, x), z


def _steered_gains(cb, ut, pos, vel, steer_pos, steer_vel, cells):
    """Explicit gains (n_ut, n_beam) of beams re-steered at ``cells`` by a satellite that
    believes it is at ``steer_pos`` moving along ``steer_vel``, seen from UTs ``ut``."""
    x, y, z = _frame(steer_pos, steer_vel)
    d = cells - steer_pos
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    v = np.stack([d @ x, d @ y], 1)  # beam centres (n_beam, 2)
    up = cells / np.linalg.norm(cells, axis=1, keepdims=True)
    on = (-np.sum(d * up, 1) >= math.sin(math.radians(25.0))) & (
        -d @ z >= math.cos(math.radians(70.0))
    )
    assert 0 < on.sum() < len(cells)
    x, y, _ = _frame(pos, vel)
    rel = ut - pos
    u = np.stack([rel @ x, rel @ y], 1) / np.linalg.norm(rel, axis=1)[:, None]
    g = np.abs(_upa(u, cb.n_sub_x, cb.n_sub_y).conj() @ _upa(v, cb.n_sub_x, cb.n_sub_y).T)
    return np.where(on[None, :], g**2 / (cb.n_sub_x * cb.n_sub_y), 0.0)


def _off_beam_serves_nothing_quietly(eng, snap, sv, sa):
    """A UT served by a beam that is off (zero gain): -inf dB, zero throughput, the
    geometry finite, and no floating-point warning (log10(0) is the answer, not an error)."""
    off = np.flatnonzero(snap.gain_tx_lin[0, 0, :] == 0.0)
    assert off.size > 0
    n = snap.n_ut
    beam = np.full(n, off[0])
    zero = np.zeros((n, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cols = eng.serve(snap, np.zeros(n, int), beam, zero, zero, sv, sa)
    ok = snap.visible[:, 0] & (snap.gain_tx_lin[:, 0, off[0]] == 0.0)
    assert ok.sum() > 10
    for name in ("gain_tx_db", "snr_db", "sinr_db"):
        assert (cols[name][ok] == -np.inf).all(), name
    assert (cols["throughput_bps"][ok] == 0.0).all()
    assert np.isfinite(cols["elevation_deg"][ok]).all()


@pytest.mark.parametrize("cosecant", [False, True], ids=["fixed", "cosecant"])
def test_one_beam_one_pair_and_an_unserved_row_closed_form(cosecant):
    """The smallest call: one beam at nadir, one (UT, satellite) pair and a row without a
    link. The served row is the closed form at the beam's peak, G_TX = n_x n_y, with a
    1.5 dB cable loss and 0.7 dB of other losses; the other row is NaN (its placeholder
    pair and beam must exist: there is one of each). Through ``serve`` with a second
    satellite below the horizon and every satellite interfering: the same. With the
    cosecant atmosphere (no constant loss: each pair's elevation is read), 0.3 dB at
    nadir, taken off the SNR. The Doppler rate of a UT accelerating towards the
    satellite, by hand."""
    from leolink.antenna.codebook import Codebook
    from leolink.antenna.terminal import Isotropic
    from leolink.engine import LinkParams
    from leolink.link.atmosphere import FixedLoss

    r_m, h_m, n = 6_371_000.0, 1_300_000.0, 12
    cb = Codebook(np.zeros((1, 2)), np.arange(1), 1.2, n, n)
    params = LinkParams(11.45e9, 250e6, 15.0, 1.5, 24.1, 0.0, other_loss_db=0.7)
    atm = Cosecant() if cosecant else FixedLoss(0.0)
    eng = LinkEngine(cb, Isotropic(), params, atm, other_satellites=True)
    sat = np.array([[0.0, 0.0, r_m + h_m], [0.0, 0.0, -(r_m + h_m)]])
    vel = np.array([[7000.0, 0.0, 0.0], [7000.0, 0.0, 0.0]])
    ut = np.array([[0.0, 0.0, r_m]])
    links = eng.evaluate_pairs(ut, sat[:1], vel[:1], np.array([0]), np.array([0]))
    assert (links.ut == [0]).all() and (links.sat == [0]).all()
    zero = np.zeros((2, 3))
    fspl = 20 * math.log10(4 * math.pi * h_m * 11.45e9 / SPEED_OF_LIGHT_M_S)
    noise = 24.1 + 10 * math.log10(BOLTZMANN_J_K * 250e6)
    atm_db = 0.3 if cosecant else 0.0  # 0.3 dB / sin(90 deg)
    snr = 15.0 - 1.5 - 0.7 + 10 * math.log10(n * n) - fspl - atm_db - noise
    two = np.repeat(ut, 2, 0)
    # The UT accelerates up at a = 9.81 m/s^2 under the satellite, which moves across at
    # v: rho(t)^2 = (v t)^2 + (h - a t^2 / 2)^2, so rho'' = v^2 / h - a at t = 0.
    up = np.array([[0.0, 0.0, 9.81]] * 2)
    rate = -(11.45e9 / SPEED_OF_LIGHT_M_S) * (7000.0**2 / h_m - 9.81)  # -f / c rho''
    by_pairs = eng.serve_pairs(links, np.array([0, -1]), np.array([0, -1]), zero, up,
                               vel[[0, 0]], zero, ut_pos_m=two)  # fmt: skip
    by_snap = eng.serve(eng.evaluate(two, sat, vel), np.array([0, -1]), np.array([0, -1]),
                        zero, up, vel, np.zeros((2, 3)))  # fmt: skip
    for cols in (by_pairs, by_snap):
        assert cols["gain_tx_db"][0] == pytest.approx(10 * math.log10(n * n), abs=1e-9)
        assert cols["snr_db"][0] == pytest.approx(snr, abs=1e-9)
        assert cols["sinr_db"][0] == pytest.approx(snr, abs=1e-9)  # no other beam in view
        assert cols["elevation_deg"][0] == pytest.approx(90.0, abs=1e-9)
        assert cols["atm_db"][0] == pytest.approx(atm_db, abs=1e-9)
        assert cols["gain_rx_db"][0] == 0.0  # isotropic
        assert cols["doppler_hz"][0] == pytest.approx(0.0, abs=1e-6)  # across the line
        assert cols["doppler_rate_hz_s"][0] == pytest.approx(rate, rel=1e-9)
        for name in COLUMNS:
            assert np.isnan(cols[name][1]), name
