"""configs/3gpp/sls_*.toml: ``leolink run`` reproduces TR 38.821's system-level calibration.

Three references, each with its own tolerance:

1. TR 38.821 Table 6.1.1.2-1, case 6 (Ka, FRF 1): geometry SIR and SINR p5/p50/p95
   (``tests/data/tr38821_table_6_1_1_2_1.csv``; a secondary transcription, see its header).
2. An independent re-implementation, written here from the TR's text and nothing of
   leolink: the satellite over (R + h, 0, 0) in an Earth-centred frame; the beam grid built
   by walking the six neighbour steps out from the centre; the reuse-3 colours as the cosets
   of the sublattice spanned by the two sqrt(3) ABS co-channel steps; the TR 38.811 pattern
   as the Fourier transform of the uniform disk, ``(2 / pi) int sqrt(1 - x^2) cos(u x) dx``
   by Gauss-Chebyshev quadrature (no Bessel function); UTs uniform on the Earth by normalized
   Gaussian vectors (rejection outside the cap); FSPL ``32.45 + 20 log10(f_GHz) +
   20 log10(d_m)`` of TR 38.811 eq. (6.6-2); G/T ``G - NF - 10 log10(T0 + (Ta - T0)
   10^(-NF/10))`` and k = -228.6 dBW/K/Hz of TR 38.821 Sec. 6.1.3.1.
3. The TR's own layout numbers: ABS of Table 6.1.1.1-6 and the beam counts 61 / 127.
"""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from leolink.app.multibeam import multibeam_satellite
from leolink.app.run import run
from leolink.config import load_config

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "tests" / "data" / "tr38821_table_6_1_1_2_1.csv"
CONFIGS = {name: ROOT / "configs" / "3gpp" / f"sls_leo600_set1_{name}.toml"
           for name in ("ka_reuse1", "ka_reuse3", "s_reuse1", "s_reuse3")}  # fmt: skip
PERCENTILES = {"p5": 5.0, "p50": 50.0, "p95": 95.0}

#: The TR's rows average several companies' simulators (their spread is not published) and
#: are printed to 0.1 dB; leolink's percentiles vary by 0.02 dB (std over seeds) with its
#: ~9,400 UTs. 0.25 dB: the printing (0.05) plus a company-to-company spread of ~0.2 dB,
#: the width by which independent re-implementations differ from the table (0.2 dB).
TR_TOLERANCE_DB = 0.25
#: leolink against the independent re-implementation: two independent drops (~9,400 and
#: ~25,000 UTs; percentile std 0.021 and 0.013 dB), so 0.1 dB is 4 standard deviations of
#: their difference; the formulas themselves agree to 0.003 dB (32.45 vs 32.4478 dB, k).
INDEPENDENT_TOLERANCE_DB = 0.1
#: ABS of Table 6.1.1.1-6, printed to 4 decimals.
ABS_PRINTED = 0.5e-4
K_TR_DBW_K_HZ = -228.6
T0_K = 290.0


@pytest.fixture(scope="module")
def summaries(tmp_path_factory):
    out = {}
    for name, path in CONFIGS.items():
        folder = tmp_path_factory.mktemp(name)
        run(load_config(path), out_dir=folder)
        out[name] = json.loads((folder / "summary.json").read_text())
    return out


def _table():
    with open(TABLE) as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    header, _units, *body = rows
    return [dict(zip(header, r, strict=True)) for r in body]


@pytest.mark.parametrize("row", _table(), ids=lambda r: f"case{r['case']}-{r['metric']}")
def test_geometry_sir_and_sinr_equal_table_6_1_1_2_1(summaries, row):
    got = summaries[row["config"].removeprefix("sls_leo600_set1_").removesuffix(".toml")]
    for key in PERCENTILES:
        want = float(row[f"{key}_db"])
        assert got["overall"][row["metric"]][key] == pytest.approx(want, abs=TR_TOLERANCE_DB)


# ----------------------------------------------------------------------------------------
# The independent re-implementation (module docstring, item 2).


def _cfg_numbers(cfg):
    link, a, m = cfg.link, cfg.satellite_array, cfg.multibeam
    return dict(
        h=cfg.constellation.altitude_m, r=cfg.earth.radius_m, f=link.freq_hz,
        d=a.aperture_diameter_m, gmax=a.aperture_gain_dbi, hpbw=math.radians(m.hpbw_deg),
        tiers=m.tiers, colours=link.reuse_colors, eirp_density=link.eirp_density_dbw_mhz,
        bw=link.bandwidth_hz, ta=link.antenna_temp_k, nf=link.noise_figure_db,
        g_rx=cfg.terminal.fixed.gain_dbi, atm=cfg.atmosphere.fixed.loss_db,
    )  # fmt: skip


def _grid_by_walking(tiers, spacing):
    """Beam centres (n, 2) and BFS depth, by stepping to the 6 neighbours from the centre."""
    steps = [spacing * np.array([math.cos(k * math.pi / 3), math.sin(k * math.pi / 3)])
             for k in range(6)]  # fmt: skip
    found = {(0, 0): (np.zeros(2), 0)}
    frontier = [np.zeros(2)]
    for depth in range(1, tiers + 1):
        nxt = []
        for p in frontier:
            for s in steps:
                q = p + s
                key = tuple(np.round(q / spacing * 1000).astype(int))
                if key not in found:
                    found[key] = (q, depth)
                    nxt.append(q)
        frontier = nxt
    pts = np.array([v[0] for v in found.values()])
    return pts, np.array([v[1] for v in found.values()])


def _cosets(points, spacing, n_colours):
    """Colour = coset of the co-channel sublattice (steps sqrt(3) ABS at 30 and 90 deg)."""
    if n_colours == 1:
        return np.zeros(len(points), int)
    assert n_colours == 3
    v1 = math.sqrt(3) * spacing * np.array([math.cos(math.pi / 6), math.sin(math.pi / 6)])
    v2 = math.sqrt(3) * spacing * np.array([0.0, 1.0])
    ab = np.linalg.solve(np.stack([v1, v2], axis=1), points.T).T
    frac = np.mod(np.round(ab[:, 0] * 3), 3)  # 0, 1/3, 2/3 of a sublattice step
    return frac.astype(int)


def _disk_pattern(u):
    """|(2/pi) int_-1^1 sqrt(1 - x^2) cos(u x) dx|^2 (Gauss-Chebyshev of the 2nd kind)."""
    n = 200
    k = np.arange(1, n + 1)
    x = np.cos(k * np.pi / (n + 1))
    w = np.pi / (n + 1) * np.sin(k * np.pi / (n + 1)) ** 2
    table_u = np.linspace(0.0, float(np.max(u)) + 1.0, 40001)
    amp = (2.0 / np.pi) * (np.cos(np.outer(table_u, x)) @ w)
    return np.interp(u, table_u, amp) ** 2


def _uniform_on_cap(rng, n_draw, uv_radius, r, h):
    """Points uniform in area on the sphere around (r, 0, 0), seen within ``uv_radius`` of
    nadir from (r + h, 0, 0): uniform on the tangent plane, projected to the sphere through
    its centre, kept with probability cos^3 of the central angle (the projection's area
    ratio), so no cos-uniform draw like leolink's."""
    eta = math.asin(uv_radius)
    gamma_max = math.asin((r + h) / r * math.sin(eta)) - eta
    rho_max = r * math.tan(gamma_max)
    yz = rng.uniform(-rho_max, rho_max, (n_draw, 2))
    rho = np.hypot(yz[:, 0], yz[:, 1])
    keep = (rho <= rho_max) & (rng.uniform(size=n_draw) < np.cos(np.arctan(rho / r)) ** 3)
    pts = np.column_stack([np.full(keep.sum(), r), yz[keep]])
    return r * pts / np.linalg.norm(pts, axis=1, keepdims=True)


def _independent(cfg, n_draw=50_000, seed=7):
    p = _cfg_numbers(cfg)
    spacing = math.sqrt(3) * math.sin(p["hpbw"] / 2)
    centres, depth = _grid_by_walking(p["tiers"], spacing)
    colour = _cosets(centres, spacing, p["colours"])
    sat = np.array([p["r"] + p["h"], 0.0, 0.0])
    # UV plane: u along +y, v along +z, the boresight axis -x (towards the Earth's centre)
    beams = np.stack([-np.sqrt(1 - np.sum(centres**2, 1)), centres[:, 0], centres[:, 1]], 1)
    ut = _uniform_on_cap(np.random.default_rng(seed), n_draw, 3 * spacing, p["r"], p["h"])
    los = ut - sat
    dist = np.linalg.norm(los, axis=1)
    los = los / dist[:, None]
    cross = np.linalg.norm(np.cross(los[:, None, :], beams[None, :, :]), axis=2)
    theta = np.arctan2(cross, los @ beams.T)
    ka = math.pi * p["d"] * p["f"] / 299_792_458.0
    gain = _disk_pattern(ka * np.sin(theta))
    best = np.argmax(gain, axis=1)
    inner = depth[best] <= 2
    gain, best, dist, ut = gain[inner], best[inner], dist[inner], ut[inner]
    rows = np.arange(best.size)
    same = colour[None, :] == colour[best][:, None]
    signal = gain[rows, best]
    sir = signal / (np.where(same, gain, 0).sum(1) - signal)
    bw = p["bw"] / p["colours"]
    eirp = p["eirp_density"] + 10 * math.log10(bw / 1e6)
    fspl = 32.45 + 20 * math.log10(p["f"] / 1e9) + 20 * np.log10(dist)
    g_t = p["g_rx"] - p["nf"] - 10 * math.log10(T0_K + (p["ta"] - T0_K) * 10 ** (-p["nf"] / 10))
    cnr = eirp + 10 * np.log10(signal) - fspl - p["atm"] + g_t - K_TR_DBW_K_HZ
    cnr = cnr - 10 * math.log10(bw)
    snr = 10 ** (cnr / 10)
    sinr = 1 / (1 / sir + 1 / snr)
    cl = fspl + p["atm"] - p["gmax"] - 10 * np.log10(signal) - p["g_rx"]
    figures = {"sir_db": 10 * np.log10(sir), "sinr_db": 10 * np.log10(sinr), "snr_db": cnr,
               "coupling_loss_db": cl}  # fmt: skip
    return {k: {q: float(np.percentile(v, pc)) for q, pc in PERCENTILES.items()}
            for k, v in figures.items()}  # fmt: skip


@pytest.fixture(scope="module")
def independent():
    return {name: _independent(load_config(path)) for name, path in CONFIGS.items()}


@pytest.mark.parametrize("name", sorted(CONFIGS))
@pytest.mark.parametrize("metric", ["sir_db", "sinr_db", "snr_db", "coupling_loss_db"])
def test_percentiles_equal_an_independent_implementation(summaries, independent, name, metric):
    got, want = summaries[name]["overall"][metric], independent[name][metric]
    for key in PERCENTILES:
        assert got[key] == pytest.approx(want[key], abs=INDEPENDENT_TOLERANCE_DB), key


# ----------------------------------------------------------------------------------------
# The TR's own layout numbers (Tables 6.1.1.1-5 and -6).


# S band: Table 6.1.1.1-6 prints 0.0668 for Set-1 S (HPBW 4.4127 deg) but 0.0667 for Set-2 Ka,
# whose HPBW is the same 4.4127 deg; sqrt(3) sin(2.20635 deg) = 0.066681 (docs/errata.md).
@pytest.mark.parametrize(
    ("name", "abs_uv", "n_beam"),
    [("ka_reuse1", 0.0267, 61), ("ka_reuse3", 0.0267, 127),
     ("s_reuse1", 0.0667, 61), ("s_reuse3", 0.0667, 127)],
)  # fmt: skip
def test_beam_spacing_and_count_equal_tables_6_1_1_1_5_and_6(summaries, name, abs_uv, n_beam):
    sat = multibeam_satellite(load_config(CONFIGS[name]))
    assert sat.layout.spacing_uv == pytest.approx(abs_uv, abs=ABS_PRINTED)
    assert summaries[name]["run"]["n_beam"] == n_beam
    # the 19 inner beams come first: every beam within 2 spacings of nadir, and only they
    radius = np.hypot(*sat.layout.beam_uv.T) / sat.layout.spacing_uv
    assert np.all(radius[:19] < 2.01) and np.all(radius[19:] > 1.99)


@pytest.mark.parametrize("name", ["ka_reuse3", "s_reuse3"])
def test_reuse_3_neighbours_differ_and_co_channel_beams_are_sqrt3_apart(name):
    sat = multibeam_satellite(load_config(CONFIGS[name]))
    uv, colour, s = sat.layout.beam_uv, sat.colors, sat.layout.spacing_uv
    dist = np.linalg.norm(uv[:, None] - uv[None], axis=2) / s
    neighbours = np.isclose(dist, 1.0)
    assert not np.any(neighbours & (colour[:, None] == colour[None]))
    same = (colour[:, None] == colour[None]) & ~np.eye(len(uv), dtype=bool)
    assert np.min(dist[same]) == pytest.approx(math.sqrt(3.0), rel=1e-9)
    assert np.bincount(colour).tolist() in ([43, 42, 42], [42, 43, 42], [42, 42, 43])


def test_cell_vertex_lies_on_the_beams_minus_3_db_contour():
    """ABS / sqrt(3) = sin(HPBW / 2): the corner of a cell is -3 dB from its beam (Table
    6.1.1.1-4's meaning of ABS), the angle by leolink's snapshot, the gain by quadrature."""
    from leolink.multibeam import off_axis_angle_rad

    cfg = load_config(CONFIGS["ka_reuse1"])
    sat = multibeam_satellite(cfg)
    vertex = np.array([[0.0, sat.layout.spacing_uv / math.sqrt(3.0)]])
    theta = off_axis_angle_rad(sat.layout.beam_uv[:1], vertex)[0, 0]
    ka = math.pi * sat.diameter_m * sat.freq_hz / 299_792_458.0
    # The TR's 1.7647 deg is the -3.000 dB width of a 0.5 m aperture at 20 GHz (the
    # half-power, -3.0103 dB, width is 0.16 % wider: docs/errata.md)
    assert 10 * math.log10(float(_disk_pattern(np.array([ka * math.sin(theta)]))[0])) == (
        pytest.approx(-3.000, abs=0.002)
    )


def test_a_ut_at_nadir_has_the_boresight_coupling_loss():
    """CL = FSPL(h) + L_atm - G_max - G_rx at the central beam's centre (TR 38.811 eq. 6.6-2)."""
    from leolink.multibeam import snapshot

    cfg = load_config(CONFIGS["ka_reuse1"])
    sat = multibeam_satellite(cfg)
    ut = np.array([[0.0, 0.0, cfg.earth.radius_m]])

    def vsat(el):
        return np.full_like(el, 39.7)

    def atm(el):
        return np.full_like(el, 0.244)

    snap = snapshot(sat, ut, 19, cfg.link.system_noise_temp_dbk, vsat, atm)
    fspl = 32.45 + 20 * math.log10(20.0) + 20 * math.log10(600e3)
    assert snap.serving.tolist() == [0]
    assert snap.cl_db[0] == pytest.approx(fspl + 0.244 - 38.5 - 39.7, abs=0.005)
