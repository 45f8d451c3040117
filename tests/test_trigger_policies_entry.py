"""The trigger policies as the registry builds them: look-ahead horizon, layer-3 filter,
cell offsets and reference points of the build context reach the run they drive.

The scenarios are those of test_trigger_run_geometry.py (hand values, one handover epoch
each), now built through ``POLICIES.build(name, params, context)`` and ``entry.run``.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from leolink.sim.handover.config import (
    A3Config,
    ChoConfig,
    D1Config,
    FilterConfig,
    MeasurementConfig,
    T1Config,
    TimeToExitConfig,
)
from leolink.sim.handover.policies import POLICIES
from leolink.sim.handover.trigger_policies import horizon_s
from service_helpers import TableLinks
from test_trigger_run_geometry import MIN_SNR_DB, N_BEAM, R_M, _engine, _ground, _path


def _run(name, params, context=None):
    entry = POLICIES.build(name, params, context)
    return entry.run(_engine(), MIN_SNR_DB, R_M, None, 1.0)


def test_the_horizon_is_the_largest_of_the_policy_and_its_conditions():
    """300 s without one (the documented default); a condition's own; the largest of a
    CHO's preparation and execution conditions, wherever it is."""
    assert horizon_s(A3Config()) == 300.0
    assert horizon_s(T1Config(horizon_s=120.0)) == 120.0
    cho = ChoConfig(
        prepare={"kind": "time_to_exit", "horizon_s": 50.0},
        execute=[{"kind": "t1", "horizon_s": 80.0}, {"kind": "a3"}],
    )
    assert horizon_s(cho) == 80.0
    cho = ChoConfig(prepare={"kind": "time_to_exit", "horizon_s": 500.0}, execute=[{"kind": "a3"}])
    assert horizon_s(cho) == 500.0
    assert POLICIES.build("time_to_exit", TimeToExitConfig(horizon_s=42.0)).horizon_s == 42.0


def test_a_trigger_policy_is_driven_by_its_run_not_by_choose():
    entry = POLICIES.build("a3", A3Config())
    said = (
        "policy 'a3' keeps per-cell state: the simulator drives it through policy.run(...) "
        "(leolink.sim.handover.trigger_run), not choose()"
    )
    with pytest.raises(TypeError) as raised:
        entry.choose(0.0, np.zeros((1, 1, 1)), None)
    assert str(raised.value) == said


@pytest.mark.parametrize(
    "section,handover_s",
    [
        # fc8 over a 1 s reference period: a = 1/4, beam 1 filtered 0, 2.5, 4.375, 5.78,
        # 6.84, 7.63 dB: above 5 + 2 dB first at t = 5 s.
        (FilterConfig(k=8, reference_period_s=1.0), 5),
        # none: fc4 over 0.2 s (TS 38.331's default, LTE's X): a = 1 - (1/2)^5 = 0.969 at
        # 1 s steps, 9.69 dB at t = 1 s.
        (None, 1),
    ],
)
def test_the_filter_of_the_build_context_filters_the_measurements(section, handover_s):
    """A3(+2 dB) between the beams of one satellite: beam 0 at 5 dB, beam 1 at 0 dB, then
    10 dB from t = 1 s."""
    context = SimpleNamespace(filter=section)
    run = _run("a3", A3Config(offset_db=2.0), context)
    snr = np.full((7, 1, N_BEAM), np.nan)
    snr[:, 0, 0] = 5.0
    snr[:, 0, 1] = [0.0] + [10.0] * 6
    path = _path(run, snr, _ground(0.0)[None], np.zeros((7, 1, 3)))[:, 0]
    assert list(path) == [0] * handover_s + [1] * (7 - handover_s)


def test_the_cell_offsets_of_the_build_context_bias_the_trigger():
    """test_trigger_run_geometry's offsets (satellite 1 +3 dB, its beam 1 -5 dB, cell 0
    -2 dB) from ``[[controller.cell_offsets]]`` entries: the UT goes to cell 2."""
    offsets = [SimpleNamespace(sat_id=s, beam_id=b, offset_db=o)
               for s, b, o in ((1, None, 3.0), (1, 1, -5.0), (0, 0, -2.0))]  # fmt: skip
    run = _run("a3", A3Config(), SimpleNamespace(filter=FilterConfig(k=0), cell_offsets=offsets))
    snr = np.full((3, 1, 2 * N_BEAM), np.nan)
    snr[:, 0, :] = [10.0, 8.5, 6.0, 12.0]
    path = _path(run, snr, _ground(0.0)[None], np.zeros((3, 2, 3)), serving=[0])[:, 0]
    assert path[-1] == 2 and set(path) <= {0, 2}


def test_the_reference_points_of_the_build_context_reach_d1():
    """D1 on points per satellite (test_trigger_run_geometry's): satellite 0's point 0.2
    rad from the UT, satellite 1's 0.05 rad; D1(1,000 km, 500 km) goes to satellite 1."""
    points = ((0, None, _ground(0.2)), (1, None, _ground(0.05)))
    params = D1Config(threshold1_m=1e6, threshold2_m=5e5, reference="points", level="satellite")
    run = _run("d1", params, SimpleNamespace(reference_points=points))
    snr = np.full((3, 1, 2 * N_BEAM), np.nan)
    snr[:, 0, :] = [9.0, 4.0, 3.0, 5.0]
    sats = np.array([[_ground(0.1) * 1.1] * 2] * 3)
    path = _path(run, snr, _ground(0.0)[None], sats)[:, 0]
    assert list(path) == [0, 3, 3]


def test_the_measurement_period_of_the_build_context_delays_the_trigger():
    """``[controller.measurement] period_s = 2``: the UT measures at t = 0, 2, 4 s only and
    holds its values between. Beam 1 rises from 0 to 10 dB at t = 1 s: A3(+2 dB), no
    filter, hands over at t = 1 s measuring every epoch, at t = 2 s every 2 s."""
    snr = np.full((4, 1, N_BEAM), np.nan)
    snr[:, 0, 0] = 5.0
    snr[:, 0, 1] = [0.0, 10.0, 10.0, 10.0]
    for section, first in ((None, 1), (MeasurementConfig(period_s=2.0), 2)):
        context = SimpleNamespace(filter=FilterConfig(k=0), measurement=section)
        run = _run("a3", A3Config(offset_db=2.0), context)
        path = _path(run, snr, _ground(0.0)[None], np.zeros((4, 1, 3)))[:, 0]
        assert list(path) == [0] * first + [1] * (4 - first)


def _t1_handover_s(horizon):
    """The epoch at which T1 through the registry hands the UT from satellite 0 to 1.

    test_service_time.py's scene: one UT, two one-beam satellites 1 s apart in time;
    satellite 0 (12 dB) serves until t = 10 s, satellite 1 (5 dB) all along. T1 (lead
    4 s, duration 3 s): Thresh1 = 10 - 4 = 6 s once the end is known. The run looks ahead
    ``horizon`` epochs from each epoch, so the end at 10 s is known from t = 10 - horizon
    on: the handover is at the first t > 6 s at which it is known, ``max(7, 10 -
    horizon)`` (within the window t <= Thresh1 + 3 s = 9 s)."""
    from leolink.sim.candidates.table import Candidates

    snr = np.full((60, 1, 2), 5.0)
    snr[:10, 0, 0], snr[10:, 0, 0] = 12.0, -30.0

    def future(t_s, sats, uts=True):  # the times (n_t,): a leading time axis
        ut = np.repeat(np.asarray(t_s, float)[:, None, None], 3, axis=2)  # the time in the UT's row
        pos = np.zeros((len(t_s), len(sats), 3))
        pos[..., 0] = sats  # the satellite's index in its row
        return (ut if uts else None), pos, pos.copy()

    def evaluate_pairs(ut_pos_m, sat_pos_m, sat_vel_m_s, ut, sat, ut_up=None, **_):
        k = np.round(ut_pos_m[ut, 0]).astype(int)
        values = snr[k, 0, sat_pos_m[sat, 0].astype(int)][:, None]  # (m, 1 beam)
        return TableLinks(values)

    engine = SimpleNamespace(n_beam=1, codebook=SimpleNamespace(u_xy=np.zeros((1, 2))),
                             beam_ix=None, beam_iy=None, evaluate_pairs=evaluate_pairs)  # fmt: skip
    params = T1Config(duration_s=3.0, lead_s=4.0, horizon_s=horizon)
    run = POLICIES.build("t1", params, SimpleNamespace(filter=FilterConfig(k=0)))
    run = run.run(engine, MIN_SNR_DB, R_M, future, 1.0)
    serving = np.array([-1])
    for k in range(16):
        new = run.target(float(k), Candidates.dense(snr[k]), serving, np.zeros((1, 3)), None, None)
        if serving[0] == 0 and new[0] == 1:
            return k
        serving = new
    return None


@pytest.mark.parametrize("horizon,handover_s", [(300.0, 7), (30.0, 7), (2.0, 8), (1.0, 9)])
def test_the_horizon_epoch_and_future_of_a_t1_policy_reach_its_end_of_service(horizon, handover_s):
    """The registry's T1 looks ahead with the run's future states, the run's epoch and the
    config's horizon: a short horizon learns the end of service late (docstring above)."""
    assert _t1_handover_s(horizon) == handover_s


def test_the_build_context_reaches_the_policy_build():
    """Through the registry: the context's level (``cells.per = "satellite"``) is the
    level of a policy whose config gives none, and D1 on reference points is refused
    when the context has none (a config without a context builds)."""
    from leolink.errors import ConfigError

    assert POLICIES.build("a3", A3Config()).level == "cell"  # A3's own default
    assert POLICIES.build("a3", A3Config(), SimpleNamespace(level="satellite")).level == (
        "satellite"
    )
    params = D1Config(threshold1_m=1e6, threshold2_m=5e5, reference="points")
    POLICIES.build("d1", params)
    with pytest.raises(ConfigError, match=r"controller\.d1\.reference = 'points'"):
        POLICIES.build("d1", params, SimpleNamespace(reference_points=()))
