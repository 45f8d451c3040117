"""TR 38.811 environments inside the simulator (``[[population]] environment``).

Every check reads real run outputs (the trace of ``configs/examples/town.toml`` with its
populations replaced) and compares them with numbers typed from the standard here, not
read from the shipped tables: Table 6.6.1-1 (LoS probability), Table 6.6.2-2 (urban
shadowing and clutter, Ka band), Table 6.6.6.2.1-1 (tropospheric scintillation).
Tolerances: binomial / sampling errors, 4 standard errors unless said.
"""

from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from leolink.app.run import run
from leolink.config import load_config
from leolink.errors import ConfigError
from leolink.link.environment import ENVIRONMENTS
from leolink.sim import motion
from leolink.sim.mobility.populations import PopulationParams

ROOT = Path(__file__).resolve().parents[1]
TOWN = ROOT / "configs" / "examples" / "town.toml"
N_SE = 4.0

# TR 38.811 V15.4.0 Table 6.6.1-1, urban column, 10..90 deg [%].
URBAN_LOS_PERCENT = [24.6, 38.6, 49.3, 61.3, 72.6, 80.5, 91.9, 96.8, 99.2]
# Table 6.6.2-2 (urban), Ka band: sigma_SF LoS 4 dB, NLoS 6 dB; CL [dB] at 10..90 deg.
URBAN_KA_SIGMA_LOS_DB, URBAN_KA_SIGMA_NLOS_DB = 4.0, 6.0
URBAN_KA_CL_DB = [44.3, 39.9, 37.5, 35.8, 34.6, 33.8, 33.3, 33.0, 32.9]
# Table 6.6.6.2.1-1: tropospheric scintillation at 20 GHz [dB], 10..90 deg.
TROPO_20GHZ_DB = [1.08, 0.48, 0.30, 0.22, 0.17, 0.13, 0.12, 0.12, 0.12]
GRID_DEG = np.arange(10.0, 91.0, 10.0)


def _config(tmp_path, populations, overrides=(), name="cfg.toml"):
    head = TOWN.read_text().split("[[population]]")[0]
    path = tmp_path / name
    path.write_text(head + populations)
    return load_config(path, ["output.plots.enabled=false", *overrides])


def _crowd(n, environment="urban", speed_m_s=None, extra=""):
    """``n`` UTs at random points of a 20 x 20 km square around the ROI centre."""
    # A fixed list of points: the crowd of n UTs is the first n of any larger crowd.
    x, y = np.random.default_rng(5).uniform(-10e3, 10e3, (1000, 2))[:n].T
    motion_keys = (
        'kind = "static"'
        if speed_m_s is None
        else f'kind = "constant_velocity"\nspeed_m_s = {speed_m_s}\nheading_deg = "along_track"'
    )
    return f"""[[population]]
name = "crowd"
{motion_keys}
placement = "points"
x_m = {x.round(1).tolist()}
y_m = {y.round(1).tolist()}
environment = "{environment}"
{extra}
"""


@pytest.fixture(scope="module")
def crowd(tmp_path_factory):
    """600 static urban UTs, 4 epochs at about 38 deg elevation (P_LoS 0.58)."""
    cfg = _config(tmp_path_factory.mktemp("crowd"), _crowd(600),
                  ["run.duration_s=4", "run.start_s=-150"])  # fmt: skip
    return run(cfg).trace


def test_population_environments_are_the_link_modules():
    assert PopulationParams.model_fields["environment"].annotation.__args__ == ENVIRONMENTS


def test_los_fraction_over_many_uts_equals_table_6_6_1_1(crowd):
    first = crowd[crowd.time_s == crowd.time_s.min()]
    el = first.elevation_deg.to_numpy()
    assert np.ptp(el) < 1.5  # about one elevation for the whole crowd (20 km square)
    p = np.interp(el, GRID_DEG, URBAN_LOS_PERCENT) / 100.0
    los = first.los.to_numpy()
    assert set(np.unique(los)) <= {0.0, 1.0}
    se = np.sqrt(np.sum(p * (1 - p))) / len(p)
    assert abs(los.mean() - p.mean()) < N_SE * se, (los.mean(), p.mean(), se)


def test_shadowing_std_and_clutter_equal_table_6_6_2_2(crowd):
    first = crowd[crowd.time_s == crowd.time_s.min()]
    los = first.los.to_numpy() == 1.0
    sf = first.shadow_db.to_numpy()
    for mask, sigma in ((los, URBAN_KA_SIGMA_LOS_DB), (~los, URBAN_KA_SIGMA_NLOS_DB)):
        n = mask.sum()
        assert n > 50
        s = sf[mask].std(ddof=1)
        # chi distribution: se of the sample std is sigma / sqrt(2 (n - 1))
        assert abs(s - sigma) < N_SE * sigma / np.sqrt(2 * (n - 1)), (s, sigma, n)
        assert abs(sf[mask].mean()) < N_SE * sigma / np.sqrt(n)
    el = first.elevation_deg.to_numpy()
    expected_cl_db = np.interp(el[~los], GRID_DEG, URBAN_KA_CL_DB)
    np.testing.assert_allclose(first.clutter_db[~los], expected_cl_db, rtol=0, atol=1e-9)
    assert (first.clutter_db[los] == 0.0).all()
    assert (first.scintillation_db == 0.0).all()  # off by default


@pytest.fixture(scope="module")
def town():
    """The town example as it ships (car in town, its twin in open country, train)."""
    res = run(load_config(TOWN, ["output.plots.enabled=false"]))
    return res.summary["overall"], res.trace


def test_environment_losses_enter_snr_and_sinr(town):
    """A car in town and its twin in open country: same geometry, same beam, so
    ``snr_town = snr_open - (shadow + clutter + scintillation)``, and the serving
    satellite's other beams (the interference) lose as much as the signal."""
    t = town[1]
    town, twin = t[t.ut_id == 0].reset_index(), t[t.ut_id == 1].reset_index()
    both = np.isfinite(town.snr_db) & (town.beam_id == twin.beam_id)
    assert both.sum() > 60
    loss = (town.shadow_db + town.clutter_db + town.scintillation_db)[both]
    np.testing.assert_allclose(town.snr_db[both], twin.snr_db[both] - loss, atol=1e-9)
    s_open, sinr_open = 10 ** (twin.snr_db[both] / 10), 10 ** (twin.sinr_db[both] / 10)
    i_open = s_open / sinr_open - 1.0  # interference over noise
    a = 10 ** (-loss / 10)
    np.testing.assert_allclose(town.sinr_db[both], 10 * np.log10(s_open * a / (i_open * a + 1)),
                               atol=1e-9)  # fmt: skip
    assert (twin.los == 1.0).all()
    assert (twin.shadow_db == 0).all() and (twin.clutter_db == 0).all()


def test_town_example_blocked_outages_are_served_in_open_country(town):
    summary, t = town
    by_env = summary["by_environment"]
    assert list(by_env) == ["urban", "open", "rural"]
    assert by_env["open"]["outage_fraction"] == 0.0
    car, twin = t[t.ut_id == 0].reset_index(), t[t.ut_id == 1].reset_index()
    blocked = (car.outage_reason == "blocked").to_numpy()
    assert blocked.sum() >= 3
    assert (twin.service[blocked] == "served").all()
    assert (twin.snr_db[blocked] >= load_config(TOWN).controller.min_snr_db).all()
    assert (car.los[blocked] == 0.0).all()
    urban = by_env["urban"]
    assert urban["outage_fraction_by_reason"]["blocked"] == blocked.mean()
    assert urban["outage_fraction"] == (car.service == "outage").mean()
    assert urban["los_fraction"] == pytest.approx((car.los == 1).mean())
    n_ho = urban["handovers"]["handovers_total"]
    assert urban["handovers_per_ut_hour"] == pytest.approx(n_ho / (len(car) * 1.0 / 3600))


def _lag_pairs(trace):
    """Rows of consecutive epochs of each UT whose link (serving, or best in outage) has
    a state at both (one satellite above the mask: the same path)."""
    t = trace.sort_values(["ut_id", "time_s"])
    a, b = t.iloc[:-1].reset_index(drop=True), t.iloc[1:].reset_index(drop=True)
    same = (a.ut_id == b.ut_id) & (a.n_visible == 1) & (b.n_visible == 1)
    return a[same & np.isfinite(a.los) & np.isfinite(b.los)], b[
        same & np.isfinite(a.los) & np.isfinite(b.los)
    ]


def test_states_decorrelate_along_the_track_as_the_model(tmp_path):
    """Cars at 25 m/s: lag-one correlation of the LoS state and of the shadowing field
    against ``exp(-d / d_corr)`` (TR 38.901 Eq. 7.4-5) with ``d`` the ray's displacement."""
    cfg = _config(tmp_path, _crowd(300, speed_m_s=25.0), ["run.duration_s=12", "run.start_s=-150"])
    a, b = _lag_pairs(run(cfg).trace)
    # The model's displacement: the UT's 25 m plus the piercing point's drift (h = 15 m).
    d = 25.0 * (b.time_s - a.time_s).to_numpy()
    rho_los = np.exp(-d / 50.0)  # urban LoS-state correlation distance [m]
    p = np.interp(a.elevation_deg, GRID_DEG, URBAN_LOS_PERCENT) / 100.0
    thr = stats.norm.ppf(p)
    both_model = np.mean([stats.multivariate_normal([0, 0], [[1, r], [r, 1]]).cdf([q, q])
                          for r, q in zip(rho_los[:200], thr[:200], strict=True)])  # fmt: skip
    both = np.mean((a.los.to_numpy() == 1) & (b.los.to_numpy() == 1))
    se = np.sqrt(both * (1 - both) / len(a))
    assert abs(both - both_model) < N_SE * se + 0.01, (both, both_model)
    los_los = (a.los.to_numpy() == 1) & (b.los.to_numpy() == 1)
    za = a.shadow_db.to_numpy()[los_los] / URBAN_KA_SIGMA_LOS_DB
    zb = b.shadow_db.to_numpy()[los_los] / URBAN_KA_SIGMA_LOS_DB
    r = np.corrcoef(za, zb)[0, 1]
    r_model = np.exp(-25.0 / 37.0)  # LoS shadowing correlation distance [m]
    se_r = (1 - r_model**2) / np.sqrt(len(za))
    assert abs(r - r_model) < N_SE * se_r, (r, r_model, len(za))


def test_same_states_whatever_the_block_length_and_the_other_uts(tmp_path, monkeypatch):
    pops = _crowd(40, speed_m_s=14.0)
    cfg = _config(tmp_path, pops, ["run.duration_s=8"])
    ref = run(cfg).trace
    monkeypatch.setattr(motion, "MAX_BLOCK_EPOCHS", 3)
    short = run(cfg).trace
    cols = ["los", "shadow_db", "clutter_db", "snr_db", "sat_id", "beam_id"]
    assert len(ref) == len(short) and motion.MAX_BLOCK_EPOCHS == 3
    for c in cols:
        np.testing.assert_array_equal(ref[c].to_numpy(), short[c].to_numpy(), err_msg=c)
    # The first ten UTs alone (the same keys: UT i keeps key i): the same states.
    few = run(_config(tmp_path, _crowd(10, speed_m_s=14.0), ["run.duration_s=8"], "few.toml"))
    mine = ref[ref.ut_id < 10]
    for c in cols:
        np.testing.assert_array_equal(few.trace[c].to_numpy(), mine[c].to_numpy(), err_msg=c)


def test_scintillation_column_is_table_6_6_6_2_1_1_scaled_to_the_carrier(tmp_path):
    pops = _crowd(20, environment="open", extra="[population.channel]\nscintillation = true\n")
    t = run(_config(tmp_path, pops, ["run.duration_s=3"])).trace
    scale = (11.45 / 20.0) ** (7 / 12)  # ITU-R P.618-13 frequency law (leolink decision 3)
    expected = np.interp(t.elevation_deg, GRID_DEG, TROPO_20GHZ_DB) * scale
    np.testing.assert_allclose(t.scintillation_db, expected, atol=1e-9)
    assert (t.los == 1.0).all() and (t.shadow_db == 0).all()


def test_open_country_without_scintillation_writes_no_environment_column(tmp_path):
    t = run(_config(tmp_path, _crowd(3, environment="open"), ["run.duration_s=2"])).trace
    assert "los" not in t.columns and "shadow_db" not in t.columns


@pytest.mark.parametrize(
    "extra, message",
    [
        ('environment = "city"', "environment"),
        ('[population.channel]\nband = "x"', "band"),
        ("[population.channel]\nlos_corr_distance_m = -1.0", "los_corr_distance_m"),
    ],
)
def test_bad_environment_settings_name_the_key(tmp_path, extra, message):
    pops = _crowd(2).replace('environment = "urban"\n', "") + extra + "\n"
    with pytest.raises(ConfigError, match=message):
        cfg = _config(tmp_path, pops)
        run(cfg)


def test_scintillation_below_6_ghz_needs_the_geomagnetic_latitude(tmp_path):
    pops = _crowd(2, extra="[population.channel]\nscintillation = true\n")
    cfg = _config(tmp_path, pops, ["link.freq_hz=2.0e9"])
    with pytest.raises(ConfigError, match=r"population\.0\.channel.*geomagnetic_latitude_deg"):
        run(cfg)


def test_scintillation_twice_is_refused(tmp_path):
    pops = _crowd(2, extra="[population.channel]\nscintillation = true\n")
    cfg = _config(tmp_path, pops, ['atmosphere.model="itu_p618"'])
    with pytest.raises(ConfigError, match="itu_p618"):
        run(cfg)


def test_the_environment_leaves_the_search_window_and_floor_as_the_policy_declares():
    """The search draws each path's loss before it prunes (``Decider.with_channel``): no
    margin widens the window or lowers the floor (116-250 dB did once, which evaluated
    every visible pair; ``tests/test_environment_floor.py`` checks the tables exact)."""
    from leolink.app.scenario import build_scenario
    from leolink.sim.decide import Decider, Rules, Sky
    from leolink.sim.environment import ChannelTracker

    sc = build_scenario(load_config(TOWN))
    dec = Decider(sc.engine, Rules(sc.policy, -10.0, 0.0), Sky(0.17, 6.371e6), None, None)
    window, floor = dec.search.window_db, dec.search.floor_db
    dec.with_channel(ChannelTracker(sc.environments, [1, 1, 1], np.zeros(3, np.uint64), 0.17))
    assert (dec.search.window_db, dec.search.floor_db) == (window, floor)


def test_interfering_satellites_paths_keep_their_own_states(tmp_path, monkeypatch):
    """With every satellite interfering (the Walker example: several above the horizon),
    an urban UT's SINR is not the one its open twin's SINR gives when every path
    (interferers included) took the serving path's loss."""
    head = (ROOT / "configs/examples/walker.toml").read_text().split("[[population]]")[0]
    twins = "".join(
        f'[[population]]\nname = "{e}"\nkind = "static"\nplacement = "center"\n'
        f'environment = "{e}"\n'
        for e in ("urban", "open")
    )
    (tmp_path / "w.toml").write_text(head + twins)
    over = ["output.plots.enabled=false", 'link.interference="all_satellites"',
            "run.duration_s=60"]  # fmt: skip
    from leolink.engine import LinkEngine

    factors, real = [], LinkEngine.other_satellites_interference

    def spy(self, snap, s, b, u, *lit):
        # The paths' power over the engine's own path without the UT gain: the factor.
        el, path = snap.elevation_rad, snap.path_lin / 10.0 ** (snap.rx_db / 10.0)
        factors.append(np.where(el > 0.0, snap.path_no_rx_lin / path, 1.0))
        return real(self, snap, s, b, u, *lit)

    monkeypatch.setattr(LinkEngine, "other_satellites_interference", spy)
    t = run(load_config(tmp_path / "w.toml", over)).trace
    f = np.concatenate([x for x in factors if x.shape[1] > 1], axis=1)
    assert len(factors) >= 60 and f.shape[1] > 120  # several satellites per epoch
    assert (f[1] == 1.0).all()  # the open twin's paths lose nothing
    urban_db = -10 * np.log10(f[0])
    assert np.std(urban_db) > 3.0  # each path its own shadowing and LoS state
    car, twin = t[t.ut_id == 0].reset_index(), t[t.ut_id == 1].reset_index()
    both = (np.isfinite(car.snr_db) & (car.beam_id == twin.beam_id)).to_numpy()
    loss = (car.shadow_db + car.clutter_db + car.scintillation_db)[both]
    s, a = 10 ** (twin.snr_db[both] / 10), 10 ** (-loss / 10)
    j = s / 10 ** (twin.sinr_db[both] / 10) - 1.0
    shared = 10 * np.log10(s * a / (j * a + 1))
    np.testing.assert_allclose(car.snr_db[both], twin.snr_db[both] - loss, atol=1e-9)
    assert np.mean(np.abs(car.sinr_db[both] - shared) > 1e-3) > 0.5


#: The compiled loops (numba) and the numpy code round their logarithms differently.
PATHS_ATOL_DB = 1e-9


def test_compiled_loops_and_numpy_agree_with_environments(tmp_path, monkeypatch):
    """The environment's factor rides on the receive power of the links: the compiled loops
    (every call, leolink.compiled) and the numpy path (as ``LEOLINK_JIT=0``) write the same
    trace to PATHS_ATOL_DB."""
    import leolink.compiled

    cfg = _config(tmp_path, _crowd(20, speed_m_s=14.0), ["run.duration_s=6"])
    assert leolink.compiled.use(1)
    fused = run(cfg).trace
    monkeypatch.setattr(leolink.compiled, "use", lambda n: False)
    plain = run(cfg).trace
    assert np.isfinite(fused.shadow_db).all()
    for c in ("snr_db", "sinr_db", "se_bps_hz", "los", "shadow_db", "clutter_db"):
        np.testing.assert_allclose(fused[c].to_numpy(), plain[c].to_numpy(), rtol=0,
                                   atol=PATHS_ATOL_DB, err_msg=c)  # fmt: skip


def test_a_run_over_1000_uts_keeps_blocked_outages_per_ut_and_by_environment(tmp_path):
    """Beyond PER_UT_IN_JSON_MAX UTs summary.json has no per-UT list: the blocked outage
    fractions go to the per-UT table (``per_ut.parquet``), checked against the trace, and
    ``by_environment`` stays in the overall block."""
    from leolink.io.summary.accumulator import PER_UT_IN_JSON_MAX

    assert PER_UT_IN_JSON_MAX == 1000
    pops = _crowd(1000) + _crowd(1, "open").replace('name = "crowd"', 'name = "twin"')
    res = run(_config(tmp_path, pops, ["run.duration_s=2", "run.start_s=-150"]))
    assert "per_ut" not in res.summary
    by_env = res.summary["overall"]["by_environment"]
    assert {k: v["n_ut"] for k, v in by_env.items()} == {"urban": 1000, "open": 1}
    t = res.trace
    blocked = t.outage_reason.eq("blocked").groupby(t.ut_id).mean()
    assert blocked.max() > 0
    np.testing.assert_allclose(res.per_ut.outage_fraction_blocked, blocked, atol=1e-15)
    urban = by_env["urban"]["outage_fraction_by_reason"]["blocked"]
    assert urban == pytest.approx(blocked[:1000].mean(), abs=1e-15)
