"""The monitor's paths the paper's pass does not take (sim/monitor.py), on real runs.

- UTs that never see a satellite beside UTs that are served, in the same motion blocks:
  their rows have no link (NaN), the others are those of a run without them;
- a Walker constellation (several satellites serve in one block): each row's Doppler is
  ``-f/c d(range)/dt`` of the ephemeris' own positions, by central differences;
- fading inside an environment: the fading factor of each row is the one of the same UT
  and epoch in open country (the draws are per UT and epoch), on top of the
  environment's loss;
- fading with scan loss: each row's factor is its draw over the mean of its own receive
  gain.
"""

from pathlib import Path

import numpy as np

from leolink.app.run import run
from leolink.app.scenario import ephemeris_from_config
from leolink.config import load_config
from leolink.constants import SPEED_OF_LIGHT_M_S
from leolink.geometry import geodetic_to_ecef

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"
WALKER = ROOT / "configs" / "examples" / "walker.toml"
TOWN = ROOT / "configs" / "examples" / "town.toml"
QUIET = ["output.plots.enabled=false"]
GEOMETRY = ("elevation_deg", "slant_range_m", "gain_tx_db", "fspl_db", "snr_db", "doppler_hz")


def _with_populations(tmp_path, base, populations, overrides=()):
    head = base.read_text().split("[[population]]")[0]
    path = tmp_path / "cfg.toml"
    path.write_text(head + populations)
    return load_config(path, [*QUIET, *overrides])


FAR = """[[population]]
name = "near"
kind = "static"
placement = "points"
x_m = [0.0, 200000.0]
y_m = [0.0, -100000.0]

[[population]]
name = "far"
kind = "static"
placement = "points"
x_m = [0.0]
y_m = [4000000.0]
"""


def test_a_ut_without_any_satellite_in_view_has_no_link_beside_served_uts(tmp_path):
    """A UT 4,000 km cross-track never sees the pass above the 10 deg mask (its ground
    range at 10 deg is 2,794 km): every column of its link is NaN, while the two UTs near
    the centre, in the same blocks, get the links of a run without it."""
    cfg = _with_populations(tmp_path, PAPER, FAR, ["run.duration_s=60.0"])
    tr = run(cfg).trace
    far, near = tr[tr.ut_id == 2], tr[tr.ut_id < 2]
    assert (far.n_visible == 0).all() and (far.sat_id == -1).all()
    for col in GEOMETRY:
        assert far[col].isna().all(), col
    assert (far.outage_reason == "no_satellite").all()
    assert near.snr_db.notna().all()
    alone = run(_with_populations(tmp_path, PAPER, FAR.split("\n\n")[0] + "\n",
                                  ["run.duration_s=60.0"])).trace  # fmt: skip
    for col in GEOMETRY:
        np.testing.assert_array_equal(near[col].to_numpy(), alone[col].to_numpy())


def test_walker_doppler_of_every_row_is_the_range_rate_of_its_satellite():
    """Walker (several satellites in one block): each served row's Doppler against
    ``-f/c (|s(t + h) - u| - |s(t - h) - u|) / 2h`` of the ephemeris (static UTs, no
    Earth rotation); h = 1 ms, truncation ~h^2/6 d3(range)/dt3, far below 0.01 Hz."""
    cfg = load_config(WALKER, [*QUIET, "run.duration_s=120.0"])
    tr = run(cfg).trace
    served = tr[tr.sat_id >= 0]
    assert served.sat_id.nunique() >= 2
    eph = ephemeris_from_config(cfg)
    lat, lon = np.radians(served.lat_deg.to_numpy()), np.radians(served.lon_deg.to_numpy())
    ut = geodetic_to_ecef(lat, lon, served.alt_m.to_numpy())
    t, sat = served.time_s.to_numpy(), served.sat_id.to_numpy()
    h = 1e-3
    rho = []
    for d in (h, -h):
        pos = np.stack([eph(np.array([ti + d]))[0][0, si] for ti, si in zip(t, sat, strict=True)])
        rho.append(np.linalg.norm(pos - ut, axis=1))
    expected = -cfg.link.freq_hz / SPEED_OF_LIGHT_M_S * (rho[0] - rho[1]) / (2 * h)
    np.testing.assert_allclose(served.doppler_hz.to_numpy(), expected, atol=0.01)


SUBURBAN = """[[population]]
name = "crowd"
kind = "static"
placement = "points"
x_m = [0.0, 5000.0, -5000.0, 0.0, 8000.0, -3000.0]
y_m = [0.0, 0.0, 2000.0, -4000.0, 6000.0, -7000.0]
environment = "{env}"
"""


def test_fading_inside_an_environment_is_the_open_country_fading(tmp_path):
    """Per row, ``snr(fading) - snr(mean)`` in a suburban environment equals the same
    difference in open country (same UTs, epochs and seed: the same draws), wherever both
    are served by the same beam; the environment's loss is there too."""
    over = ["run.duration_s=40.0", "run.start_s=-20.0"]
    fade, env = 'link.fading="rician"', "suburban"
    out = {}
    for name in ("open", env):
        for f in (False, True):
            cfg = _with_populations(tmp_path, TOWN, SUBURBAN.format(env=name),
                                    [*over, fade] if f else over)  # fmt: skip
            out[name, f] = run(cfg).trace
    d_open = out["open", True].snr_db - out["open", False].snr_db
    d_env = out[env, True].snr_db - out[env, False].snr_db
    same = (out["open", True].beam_id == out[env, True].beam_id) & d_open.notna() & d_env.notna()
    same &= out[env, False].beam_id == out[env, True].beam_id
    assert same.sum() > 100
    assert (d_open[same].abs() > 1e-3).mean() > 0.9  # the draws move the SNR
    np.testing.assert_allclose(d_env[same], d_open[same], rtol=0, atol=1e-9)
    # ... on top of the environment's own loss (shadowing, clutter): the SNRs differ
    loss = out["open", False].snr_db[same] - out[env, False].snr_db[same]
    assert (loss.abs() > 0.1).mean() > 0.5


def test_fading_of_every_row_is_its_draw_over_the_mean_of_its_own_receive_gain():
    """Scan loss on (the receive gain differs row by row): each row's SNR with fading
    minus without is ``10 log10(|sqrt(N) + g / sqrt(K)|^2 / (N + 1/K))`` (paper Sec. 4.1)
    with ``N`` the row's own mean receive gain and ``g`` the run's draw for that UT and
    epoch (counter-based, ``leolink.rng``); float rounding only (1e-9 dB)."""
    from leolink.rng import complex_normal, ut_keys

    over = [*QUIET, "run.duration_s=30.0", "run.start_s=-15.0", "terminal.upa.scan_loss=true"]
    cfg = load_config(PAPER, over)
    mean = run(cfg).trace
    fading = run(load_config(PAPER, [*over, 'link.fading="rician"'])).trace
    ok = mean.snr_db.notna() & fading.snr_db.notna()
    assert ok.sum() > 100 and mean.gain_rx_db[ok].nunique() > 100
    n_ut = mean.ut_id.max() + 1
    epoch = np.round((mean.time_s - mean.time_s.min()) / cfg.run.epoch_s).astype(int)
    keys = ut_keys(cfg.run.seed, n_ut)
    g = np.array([complex_normal(keys[[u]], k)[0] for u, k in zip(mean.ut_id, epoch, strict=True)])
    n, k = 10 ** (mean.gain_rx_db.to_numpy() / 10), cfg.link.rician_k
    factor_db = 10 * np.log10(np.abs(np.sqrt(n) + g / np.sqrt(k)) ** 2 / (n + 1 / k))
    got = (fading.snr_db - mean.snr_db).to_numpy()
    np.testing.assert_allclose(got[ok], factor_db[ok], rtol=0, atol=1e-9)
