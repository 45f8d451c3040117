"""The measurement model of the trigger policies (issue 46): period, error, SMTC, RSRP; and
D1 with Earth-fixed reference locations."""

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import leolink
from leolink.config import load_config
from leolink.link.budget import rsrp_dbm
from leolink.rng import ut_keys
from leolink.sim.candidates.table import Candidates
from leolink.sim.handover.decisions import TriggerPolicy
from leolink.sim.handover.local_axis import LocalAxis
from leolink.sim.handover.measurement_model import MeasurementModel, MeasurementRun, in_smtc_window
from leolink.sim.handover.measurements import L3Filter, L3State
from leolink.sim.handover.trigger_run import TriggerRun
from leolink.sim.handover.triggers import A3
from leolink.sim.handover.triggers_ntn import D1

ROOT = Path(__file__).resolve().parents[1]
WALKER = ROOT / "configs" / "examples" / "walker.toml"
QUIET = ["output.plots.enabled=false"]
NO_FILTER = L3Filter(0, 1.0)  # a = 1: the filtered value is the sample


def _samples(model, keys, n_cand, n_instants, cells=None):
    """The samples (n_instants, n_ut, n_cand) of a constant 0 dB link, filter off."""
    run = MeasurementRun(model, n_beam=1)
    run.ut_keys = keys
    n_ut = len(keys)
    cells = np.tile(np.arange(n_cand), (n_ut, 1)) if cells is None else cells
    filt, out = L3State.initial(n_ut, n_cand), []
    usable = np.ones((n_ut, n_cand), bool)
    for k in range(n_instants):
        filt, meas = run.step(float(k), filt, np.zeros((n_ut, n_cand)), usable, cells, NO_FILTER)
        out.append(meas)
    return np.array(out)


def test_the_error_has_its_sigma_and_is_independent_across_cells_and_instants():
    sigma = 2.5
    e = _samples(MeasurementModel(error_db=sigma), ut_keys(7, 2000), 6, 20)
    n = e.size  # 240 000 samples: the standard error of the std is sigma / sqrt(2 n)
    tol = 6 * sigma / math.sqrt(2 * n)  # 0.0217 dB
    assert abs(e.std() - sigma) < tol and abs(e.mean()) < 6 * sigma / math.sqrt(n)
    assert abs(np.mean(np.abs(e) < sigma) - 0.682689) < 6 * math.sqrt(0.22 / n)  # Gaussian
    flat = e.reshape(20, -1)
    for a, b in ((flat[:-1], flat[1:]), (e[..., 0].ravel(), e[..., 1].ravel())):
        r = np.corrcoef(np.ravel(a), np.ravel(b))[0, 1]
        assert abs(r) < 6 / math.sqrt(np.size(a))  # consecutive instants; two cells


def test_the_real_normal_is_the_real_part_of_the_complex_one():
    from leolink.rng import complex_normal, standard_normal

    keys = ut_keys(3, 1000)
    for counter in (0, 7):
        want = math.sqrt(2.0) * complex_normal(keys, counter).real
        np.testing.assert_allclose(standard_normal(keys, counter), want, rtol=0, atol=1e-12)


def test_the_error_of_a_ut_depends_on_its_key_cell_and_instant_only():
    model = MeasurementModel(error_db=1.0)
    every = _samples(model, ut_keys(11, 40), 5, 4)
    ids = [3, 17, 38]  # a part of a split run: the UTs' own keys
    part = _samples(model, ut_keys(11, None, ids), 5, 4)
    np.testing.assert_array_equal(part, every[:, ids])
    # other slots: each value follows its global cell, not its column
    order = np.array([4, 2, 0, 3, 1])
    moved = _samples(model, ut_keys(11, 40), 5, 4, cells=np.tile(order, (40, 1)))
    np.testing.assert_array_equal(moved[..., np.argsort(order)], every)
    assert not np.allclose(_samples(model, ut_keys(12, 40), 5, 4), every)  # another seed


@pytest.mark.parametrize(
    ("t_s", "inside"),
    [(0.25, True), (0.25 - 1e-6, False), (0.30 - 1e-6, True), (0.30 - 1e-12, False), (2.25, True),
     (2.30 + 1e-12, False), (0.1 * 3 - 0.05, True)],
)  # fmt: skip
def test_smtc_window_boundaries(t_s, inside):
    """[o + j T, o + j T + D) with T = 1 s, D = 50 ms, o = 250 ms; float-rounded epochs."""
    assert bool(in_smtc_window(t_s, [0.25], 1.0, 0.05)[0]) is inside


def _run_a3(model, n_t, dt_s=1.0):
    """Two one-beam satellites; UT 0 served by satellite 0, satellite 1 6 dB better.
    Returns the epochs at which the UT is handed to satellite 1."""
    engine = SimpleNamespace(n_beam=1, codebook=SimpleNamespace(u_xy=np.zeros((1, 2))))
    run = TriggerRun(TriggerPolicy(A3(3.0)), NO_FILTER, engine, -10.0, 6.371e6, None, dt_s, 9.0)
    if model is not None:
        run.measurement = MeasurementRun(model, 1)
    table = Candidates.from_entries(1, np.array([0, 0]), np.array([0, 1]), np.array([0.0, 6.0]))
    switched = []
    for k in range(n_t):
        target = run.target(k * dt_s, table, np.array([0]), None, None, None)
        if target[0] == 1:
            switched.append(k * dt_s)
    return switched


def test_a_cell_outside_its_smtc_window_is_never_measured():
    assert _run_a3(None, 6)[0] == 0.0  # measured at once: A3 fires at the first epoch
    smtc = {"smtc_period_s": 2.0, "smtc_duration_s": 0.5}
    # satellite 1's window [1, 1.5) s, every 2 s: first measured at t = 1
    late = MeasurementModel(**smtc, smtc_offsets=((1, 1.0),))
    assert _run_a3(late, 6)[0] == 1.0
    # window [0.5, 1) s: no integer epoch ever falls in it
    never = MeasurementModel(**smtc, smtc_offsets=((1, 0.5),))
    assert _run_a3(never, 6) == []
    # the same window seen by 0.25 s epochs: measured at 0.5 s
    assert _run_a3(never, 8, 0.25)[0] == 0.5


def test_the_filter_steps_once_per_measurement_period():
    """Samples only at multiples of P = 0.3 s among 0.1 s epochs (float-rounded epoch
    times), held in between; the filter is the recursion on those samples alone."""
    rng = np.random.default_rng(3)
    l3 = L3Filter(4, 0.2)
    run = MeasurementRun(MeasurementModel(period_s=0.3), 1)
    raw = rng.normal(0.0, 3.0, (31, 1, 2))
    usable, cells = np.ones((1, 2), bool), np.array([[0, 1]])
    filt, got = L3State.initial(1, 2), []
    for k in range(31):
        filt, meas = run.step(k * 0.1, filt, raw[k], usable, cells, l3)
        got.append(meas[0])
    a = 1.0 - (1.0 - 2.0 ** (-4 / 4)) ** (0.3 / 0.2)  # 38.331 a = 1/2^(k/4), per 0.3 s
    want, f = [], None
    for k in range(31):
        if k % 3 == 0:  # an instant: 0, 0.3, 0.6, ... s
            f = raw[k, 0] if f is None else (1 - a) * f + a * raw[k, 0]
        want.append(f)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_rsrp_is_the_link_budget_per_resource_element():
    """TR 38.821 Set-1 LEO-600 Ka downlink by hand: EIRP density 34 dBW/MHz over 400 MHz,
    600 km at 20 GHz, a 39.7 dBi UT at 24.1 dBK, 120 kHz subcarriers."""
    c, d_m, f_hz, g_rx, t_dbk, b_hz, scs_hz = 299_792_458.0, 600e3, 20e9, 39.7, 24.1, 400e6, 120e3
    fspl = 20 * math.log10(4 * math.pi * d_m * f_hz / c)  # 174.031 dB
    eirp_re_dbm = 34.0 + 10 * math.log10(scs_hz / 1e6) + 30.0  # 54.792 dBm per RE
    by_hand = eirp_re_dbm - fspl + g_rx  # -79.540 dBm
    assert by_hand == pytest.approx(-79.540, abs=5e-4)
    noise_dbw = t_dbk - 228.5991672 + 10 * math.log10(b_hz)  # kTB
    snr_db = 34.0 + 10 * math.log10(b_hz / 1e6) - fspl + g_rx - noise_dbw
    assert float(rsrp_dbm(snr_db, t_dbk, scs_hz)) == pytest.approx(by_hand, abs=1e-6)


def _run(sets):
    return leolink.run(load_config(WALKER, QUIET + ["run.duration_s=120", *sets]))


def test_defaults_are_todays_run_and_rsrp_shifts_thresholds_by_the_re_noise(tmp_path):
    """A measurement stage that changes nothing (every epoch, SNR) gives today's events;
    A4 on RSRP with its threshold moved by the noise per RE gives A4 on SNR's."""
    a4 = ["controller.policy=a4", "controller.filter.k=3"]
    base = _run([*a4, "controller.a4.threshold_db=-2"])
    same = _run([*a4, "controller.a4.threshold_db=-2", "controller.measurement.period_s=1"])
    pd.testing.assert_frame_equal(same.events, base.events)
    n_re_dbm = 24.1 - 228.5991672 + 10 * math.log10(30e3) + 30  # walker: 24.1 dBK
    rsrp = _run([*a4, f"controller.a4.threshold_db={-2 + n_re_dbm!r}",
                 "controller.measurement.quantity='rsrp'",
                 "controller.measurement.subcarrier_spacing_hz=30000"])  # fmt: skip
    pd.testing.assert_frame_equal(rsrp.events, base.events)
    assert len(base.events) > 50


def test_a_satellite_whose_smtc_window_misses_every_instant_is_never_a_target():
    sets = ["controller.policy=a3", "controller.filter.k=0"]
    base = _run(sets)
    ho = base.events[base.events.kind.isin(["beam_handover", "sat_handover"])]
    sat = int(ho.to_sat.value_counts().index[0])
    smtc = ["controller.measurement.smtc_period_s=1", "controller.measurement.smtc_duration_s=0.5"]
    gated = _run([*sets, *smtc, f"controller.measurement.smtc_offsets=[{{sat_id={sat}, "
                                "offset_s=0.5}]"])  # fmt: skip
    ho_g = gated.events[gated.events.kind.isin(["beam_handover", "sat_handover"])]
    assert (ho.to_sat == sat).sum() >= 3 and (ho_g.to_sat == sat).sum() == 0
    # every satellite inside its window at every epoch: the run is a3's
    open_ = _run([*sets, *smtc])
    pd.testing.assert_frame_equal(open_.events, base.events)


def _d1_run(reference, points=(), cells_m=None, n_beam=2):
    engine = SimpleNamespace(
        n_beam=n_beam, codebook=SimpleNamespace(u_xy=np.zeros((n_beam, 2))),
        steering=SimpleNamespace(cells_m=cells_m),
    )  # fmt: skip
    d1 = D1(400e3, 300e3, 0.0, 0.0, reference)  # (no hysteresis: no state to replay)
    run = TriggerRun(TriggerPolicy(d1), NO_FILTER, engine, -10.0, 6.371e6, None, 1.0, 9.0)
    run.reference_points = points
    return run, d1


def _ground(lat_deg, lon_deg, r=6.371e6):
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    return r * np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], -1)


def test_d1_on_configured_points_against_brute_force_distances():
    """Points for some cells (a whole satellite, one beam, a later entry overriding);
    moving UTs; the chosen target is the triggered cell nearest its point, by loops."""
    n_sat, nb = 4, 2
    pts = {0: (0.0, 0.0), 1: (0.0, 3.0), 2: (2.0, 1.0), 3: (-0.5, 3.5)}
    points = [(0, None, tuple(_ground(*pts[0]))), (1, 0, tuple(_ground(*pts[1]))),
              (1, 1, tuple(_ground(*pts[2]))), (2, None, tuple(_ground(9.0, 9.0))),
              (2, None, tuple(_ground(*pts[3])))]  # fmt: skip
    ref = {0: pts[0], 1: pts[0], 2: pts[1], 3: pts[2], 4: pts[3], 5: pts[3]}  # by global cell
    run, d1 = _d1_run("points", points)
    rng = np.random.default_rng(5)
    n_ut, chosen = 30, []
    for k in range(12):
        ut = _ground(rng.uniform(-1, 3, n_ut), rng.uniform(-1, 4, n_ut))
        cells = np.arange(n_sat * nb)
        table = Candidates.from_entries(
            n_ut, np.repeat(np.arange(n_ut), cells.size), np.tile(cells, n_ut),
            np.zeros(n_ut * cells.size),
        )  # fmt: skip
        serving = np.zeros(n_ut, np.int64)  # cell 0
        got = run.target(float(k), table, serving, ut, None, None)
        for i in range(n_ut):  # brute force: D1-1 and D1-2, the nearest reference wins
            dist = {c: np.linalg.norm(ut[i] - _ground(*p)) for c, p in ref.items()}
            ml1 = dist[0]
            ok = [c for c in dist if c != 0 and ml1 > 400e3 and dist[c] < 300e3]
            want = min(ok, key=lambda c: (dist[c], c)) if ok else 0
            assert got[i] == want, (k, i, dist)
            chosen.append(want)
    assert set(chosen) >= {2, 3, 4}  # each configured point wins somewhere


def test_d1_on_earth_fixed_cells_reads_the_steering_cells():
    cells_m = _ground(np.array([[0.0, 1.0], [2.0, 3.0]]), np.array([[0.0, 0.5], [1.0, 1.5]]))
    run, _ = _d1_run("cell", cells_m=cells_m)
    axis = LocalAxis.union(1, 2, [0, 0], [1, 0])
    usable = np.array([[True, True, True, False]])
    fields = run._fields(0.0, axis, usable, _ground(0.0, 0.0)[None], None, None, None)
    want = np.concatenate([cells_m[0], cells_m[1]])  # satellites 0 and 1, by beam
    want[3] = np.nan  # not usable
    np.testing.assert_array_equal(fields["cell_ref_pos_m"][0], want)


def test_d1_reference_is_checked_against_the_run():
    with pytest.raises(leolink.errors.ConfigError, match=r"controller\.d1\.reference = 'cell'"):
        _run(["controller.policy=d1", "controller.d1.reference='cell'"])
    with pytest.raises(ValueError, match=r"d1\.reference = 'nearest' is not allowed"):
        D1(reference="nearest")
