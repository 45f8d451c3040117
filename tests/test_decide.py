"""leolink.sim.decide.Decider._with_serving: the serving cell added to a table row that lacks
it, against the engine's evaluation of that cell's pair afresh."""

import numpy as np
import pytest

from leolink.app.scenario import build_scenario
from leolink.config import load_config
from leolink.sim.decide import Decider, Rules, Sky
from leolink.sim.handover.policies import MaxSnr
from leolink.sim.motion import MotionBlocks

#: The block's stored links and a fresh evaluation of the same pair: the same numpy code.
FRESH_ATOL_DB = 1e-9

CONSTELLATION = "configs/constellation.toml"


#: The constellation's 1,000 UTs (a pruned search: the pairs of satellites below the mask
#: are not evaluated), and the paper's pass as it rises for 200 spread UTs (one satellite:
#: every pair evaluated, below the mask too).
SCENARIOS = {
    "constellation": (CONSTELLATION, ["run.duration_s=4"]),
    "paper_rising": ("configs/paper.toml", ["run.start_s=-400.0", "run.duration_s=4",
                                            "population.1.count=200", "population.1.x_m=[]",
                                            'population.1.placement="random"',
                                            "population.1.y_m=[]"]),
}  # fmt: skip


@pytest.fixture(scope="module", params=list(SCENARIOS))
def decider(request):
    """A decider with the first block of the scenario open."""
    path, sets = SCENARIOS[request.param]
    scen = build_scenario(load_config(path, sets))
    n_ut = sum(p.n_ut for _, p in scen.populations)
    motion = MotionBlocks(scen.ephemeris, scen.populations, scen.times_s, scen.ephemeris.n_sat,
                          n_ut)  # fmt: skip
    rules = Rules(MaxSnr(), scen.min_snr_db, scen.handover_time_s)
    dec = Decider(scen.engine, rules, Sky(scen.min_elevation_rad, scen.radius_m), motion, None)
    dec._open(0)
    return dec


def test_serving_column_is_the_engines_value_of_each_added_cell(decider):
    """Serving cells of every kind: none, in the row (nothing added), another beam of an
    evaluated pair (added, or -1 below the mask), a satellite the search left out (its pair
    evaluated then), a satellite far below the horizon: each added cell's SNR is the
    engine's for that pair evaluated afresh, -1 where that pair is below the mask."""
    blk, nb = decider.block, decider.engine.n_beam
    k, rng = 1, np.random.default_rng(3)
    rows = blk.rows(k)
    table = blk.table.rows(rows)
    n = table.n_ut
    best = blk.best_cell[rows]
    shift = 1 + rng.integers(0, nb - 1, n)  # another beam of the best cell's satellite
    other_beam = np.where(best >= 0, (best // nb) * nb + (best % nb + shift) % nb, -1)
    cone = decider.cones[k]
    random_sat = rng.choice(cone, n) * nb + rng.integers(0, nb, n)
    far = np.setdiff1d(np.arange(decider.mb.sat_pos_m.shape[1]), cone)
    far_sat = rng.choice(far, n) * nb if far.size else random_sat
    serving = np.choose(rng.integers(0, 5, n), [np.full(n, -1), best, other_beam, random_sat,
                                                  far_sat])  # fmt: skip
    got = decider._with_serving(table, rows, serving)
    added = got.cell[:, -1]
    lacking = (serving >= 0) & ~(table.cell == serving[:, None]).any(axis=1)
    fresh, visible = decider._evaluated_snr_db(rows.start + np.flatnonzero(lacking),
                                               serving[lacking])  # fmt: skip
    np.testing.assert_array_equal(added[lacking], np.where(visible, serving[lacking], -1))
    np.testing.assert_allclose(got.snr_db[lacking, -1][visible], fresh[visible], rtol=0,
                               atol=FRESH_ATOL_DB)  # fmt: skip
    assert (added[~lacking] == -1).all()
    assert got.n_slot == table.n_slot + 1
    assert (added >= 0).sum() > 10 and (added[serving < 0] == -1).all()
    assert (added[(serving == best) & (best >= 0)] == -1).all()  # in the row: not added
    # the cases are met: a pair evaluated but below the mask (one satellite: all
    # evaluated), or pairs the search left out (the constellation's pruned search)
    pair = blk.find_pairs(rows.start + np.arange(n), np.maximum(serving, 0) // nb)
    evaluated_low = (serving >= 0) & (pair >= 0) & ~blk.links.visible[np.maximum(pair, 0)]
    left_out = (serving >= 0) & (pair < 0)
    assert evaluated_low.sum() > 10 if decider.mb.sat_pos_m.shape[1] == 1 else left_out.sum() > 10
