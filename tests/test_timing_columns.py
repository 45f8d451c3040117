"""Trace timing columns: ``delay_s`` (one way, UT-satellite) and ``delay_rate_s_s``,
recomputed another way for every row of real runs."""

import numpy as np
import pytest

import leolink
from leolink.config import load_config
from leolink.geometry import geodetic_to_ecef

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
C_M_S = 299_792_458.0
NS = 1e-9
# Central differences over 1 s epochs: truncation (dt^2 / 6) |rho'''| / c, with |rho'''| of
# a few m/s^3 for a LEO pass and a vehicle's turns: < 1e-9 s/s (0.3 m/s of range rate); a
# dropped UT velocity (30 m/s cars: 1e-7 s/s) or a flipped sign (1e-5 s/s) is far above.
RATE_TOL_S_S = 1e-9


@pytest.fixture(scope="module")
def walker():
    cfg = load_config(ROOT / "configs" / "examples" / "walker.toml",
                      ["output.plots.enabled=false", "run.duration_s=30"])  # fmt: skip
    return cfg, leolink.run(cfg)


def test_delay_is_the_ephemeris_slant_range_over_c_to_1_ns(walker):
    from leolink.app.scenario import build_scenario

    cfg, res = walker
    tr = res.trace[res.trace.sat_id >= 0]
    eph = build_scenario(cfg).ephemeris
    ut = geodetic_to_ecef(np.radians(tr.lat_deg.to_numpy()), np.radians(tr.lon_deg.to_numpy()),
                          tr.alt_m.to_numpy(), cfg.earth.radius_m)  # fmt: skip
    sat = np.stack([eph(t)[0][0, s] for t, s in zip(tr.time_s, tr.sat_id, strict=True)])
    d_m = np.linalg.norm(sat - ut, axis=-1)
    assert len(tr) > 100
    np.testing.assert_allclose(tr.delay_s, d_m / C_M_S, rtol=0, atol=NS)


def test_delay_rate_is_the_derivative_of_the_delay_for_moving_uts():
    cfg = load_config(ROOT / "configs" / "paper.toml",
                      ["output.plots.enabled=false", "run.duration_s=40"])  # fmt: skip
    tr = leolink.run(cfg).trace
    checked = 0
    for _, g in tr.groupby("ut_id"):
        g = g.sort_values("time_s")
        same = (g.sat_id.shift(1) == g.sat_id) & (g.sat_id.shift(-1) == g.sat_id)
        same &= g.sat_id >= 0
        d, t = g.delay_s.to_numpy(), g.time_s.to_numpy()
        numeric = (d[2:] - d[:-2]) / (t[2:] - t[:-2])
        m = same.to_numpy()[1:-1]
        np.testing.assert_allclose(g.delay_rate_s_s.to_numpy()[1:-1][m], numeric[m],
                                   rtol=0, atol=RATE_TOL_S_S)  # fmt: skip
        checked += m.sum()
    assert checked > 100
