"""Active beams, beam sharing and the digital precoder wired into runs (issue 14).

Every check reads a real run's trace (or the engine's real snapshot) and recomputes the
figure another way: lit beams per epoch from the trace's served cells, n_sharing by a
pandas group-by, the shared throughput from a run without sharing, the precoded SINR
from explicit steering vectors of the whole 60 x 72 array with numpy.linalg.
"""

from pathlib import Path

import numpy as np
import pytest

from leolink.antenna.array import HybridArray, steering_vector
from leolink.app.scenario import build_scenario
from leolink.config import load_config, updated
from leolink.errors import ConfigError
from leolink.geometry import direction_cosines
from leolink.io.sinks import MemorySink
from leolink.link.precoder import PRECODERS
from leolink.sim.beams.scheduler import SCHEDULERS
from leolink.sim.beams.service import BeamService
from leolink.sim.runner import run_simulation

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"


def _cfg(tmp_path, n_ut=20, sets=()):
    """The paper's pass with ``n_ut`` random static UTs (the issue's drop)."""
    text = PAPER.read_text()
    text = text[: text.index("[[population]]")] + (
        f'[[population]]\nname = "random"\nkind = "static"\nplacement = "random"\ncount = {n_ut}\n'
    )
    path = tmp_path / "p.toml"
    path.write_text(text.replace("uts = [0, 5, 6]", "uts = [0]"))
    return load_config(path, ["run.duration_s=20", "run.start_s=50", *sets])


def _run(cfg):
    scen = build_scenario(cfg)
    mem = MemorySink()
    run_simulation(scen, [mem])
    return scen, mem.trace()


@pytest.fixture(scope="module")
def o2_runs(tmp_path_factory):
    """O = 2 (47 beams, 15 chains) with demand and hopping."""
    tmp = tmp_path_factory.mktemp("o2")
    out = {}
    for sel in ("demand", "hopping"):
        sets = ["satellite_array.oversampling=2.0", f"satellite_array.active_beams={sel}"]
        out[sel] = _run(_cfg(tmp, 40, sets))
    return out


@pytest.mark.parametrize("sel", ["demand", "hopping"])
def test_o2_never_lights_more_beams_than_chains(o2_runs, sel):
    scen, trace = o2_runs[sel]
    assert scen.engine.n_beam == 47
    served = trace[trace.service != "outage"]
    lit_per_epoch = served.groupby("time_s").beam_id.nunique()
    assert lit_per_epoch.max() <= 15
    assert lit_per_epoch.max() >= 8  # the selector does light beams
    if sel == "hopping":  # served beams are those of the pattern row of the epoch
        pattern = scen.selector.pattern
        for t, beams in served.groupby("time_s").beam_id:
            row = int(round((t - 50.0) / 1.0)) % pattern.shape[0]
            assert pattern[row, beams.to_numpy()].all()


def test_o2_all_is_refused_with_the_fix(tmp_path):
    with pytest.raises(ConfigError, match="active_beams = 'demand' or 'hopping'"):
        build_scenario(_cfg(tmp_path, 5, ["satellite_array.oversampling=2.0"]))


def test_hopping_wait_leaves_uts_of_dark_beams_in_outage(o2_runs):
    _, trace = o2_runs["hopping"]
    share = (trace.service == "outage").mean()
    # 4 dwells (ceil(47 / 15)): a UT's own beam is lit one epoch in four.
    assert 0.5 < share < 0.9


def test_only_lit_beams_interfere(tmp_path):
    """serve_pairs with a lit mask = the serving gain over the lit beams' sum (snapshot)."""
    scen = build_scenario(_cfg(tmp_path, 30))
    eng = scen.engine
    pos, vel, acc = scen.ephemeris(np.array([60.0]))
    ut = np.concatenate([p.state(60.0).pos_m for _, p in scen.populations])
    snap = eng.evaluate(ut, pos[0], vel[0])
    g = snap.gain_tx_lin[:, 0, :]  # (n_ut, n_beam)
    beam = np.argmax(g, axis=1)
    rng = np.random.default_rng(3)
    lit = rng.uniform(size=(len(ut), eng.n_beam)) < 0.5
    lit[np.arange(len(ut)), beam] = True
    zeros = np.zeros((len(ut), 3))
    cols = eng.serve_pairs(snap.links, np.arange(len(ut)), beam, zeros, zeros,
                           np.repeat(vel[0], len(ut), 0), zeros, ut_pos_m=ut, lit=lit)  # fmt: skip
    path = snap.path_snr_lin[:, 0]
    sig = g[np.arange(len(ut)), beam]
    interf = np.sum(np.where(lit, g, 0.0), axis=1) - sig
    want = 10 * np.log10(sig * path / (interf * path + 1.0))
    np.testing.assert_allclose(cols["sinr_db"], want, rtol=0, atol=1e-9)
    full = eng.serve_pairs(snap.links, np.arange(len(ut)), beam, zeros, zeros,
                           np.repeat(vel[0], len(ut), 0), zeros, ut_pos_m=ut)  # fmt: skip
    assert np.all(cols["sinr_db"] > full["sinr_db"])  # fewer interferers


@pytest.fixture(scope="module")
def sharing_runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("share")
    return {k: _run(_cfg(tmp, 60, s))[1] for k, s in {
        "none": [], "rr": ["scheduler.kind=round_robin"],
        "pf": ["scheduler.kind=proportional_fair"],
    }.items()}  # fmt: skip


def test_n_sharing_counts_the_uts_of_each_beam(sharing_runs):
    trace = sharing_runs["rr"]
    on = trace[trace.service != "outage"]
    count = on.groupby(["time_s", "sat_id", "beam_id"]).ut_id.transform("size")
    np.testing.assert_array_equal(on.n_sharing.to_numpy(), count.to_numpy())
    assert (trace[trace.service == "outage"].n_sharing == 0).all()
    assert "n_sharing" not in sharing_runs["none"]  # default trace: unchanged columns


def test_round_robin_throughput_is_the_beams_over_n(sharing_runs):
    base, rr = sharing_runs["none"], sharing_runs["rr"]
    np.testing.assert_array_equal(base.beam_id, rr.beam_id)  # the same decisions
    np.testing.assert_allclose(rr.throughput_bps * rr.n_sharing, base.throughput_bps,
                               rtol=1e-12)  # fmt: skip
    # per beam and epoch the shares add up to one beam's time
    on = rr[rr.service == "served"]
    t_share = (on.throughput_bps / base.loc[on.index].throughput_bps).groupby(
        [on.time_s, on.sat_id, on.beam_id]).sum()  # fmt: skip
    np.testing.assert_allclose(t_share, 1.0, rtol=1e-12)


def test_proportional_fair_shares_add_to_one_beam(sharing_runs):
    base, pf = sharing_runs["none"], sharing_runs["pf"]
    on = pf[pf.service == "served"]
    share = on.throughput_bps / base.loc[on.index].throughput_bps
    per_beam = share.groupby([on.time_s, on.sat_id, on.beam_id]).sum()
    np.testing.assert_allclose(per_beam, 1.0, rtol=1e-12)
    # 10 slots: a share is a whole number of slots
    np.testing.assert_allclose(share * 10, np.round(share * 10), atol=1e-9)


def _explicit_se(ut_pos, sat_pos, sat_vel, path, beam, kind, colors, u_beams, lit,
                 idle="silent"):  # fmt: skip
    """Mean log2(1 + SINR) per UT: round robin by hand, explicit a(u)^H F_RF, linalg.

    The lit beams, by ascending id, sit on chains 0, 1, ... (the remaining chains get
    a dummy beam and serve nobody). ``idle = "transmit"``: each lit beam without a UT sends
    a stream to a receiver on its boresight whose path is the slot's mean."""
    array = HybridArray(60, 72, 5, 3)
    on = np.flatnonzero(lit)
    chain_beams = np.zeros((array.n_rf, 2))
    chain_beams[: on.size] = u_beams[on]
    f_rf = array.precoder(chain_beams)
    f_rf = f_rf / np.linalg.norm(f_rf, axis=0)
    chain_of = {int(b): c for c, b in enumerate(on)}
    members = {g: sorted(int(k) for k in np.flatnonzero(beam == g)) for g in set(beam)}
    n_slots = max(len(m) for m in members.values())
    total, count = np.zeros(len(beam)), np.zeros(len(beam))
    empty = [int(g) for g in on if g not in members] if idle == "transmit" else []
    for s in range(n_slots):
        ks = [m[s % len(m)] for m in members.values()]
        rows_beam = [beam[k] for k in ks] + empty
        u = np.vstack([direction_cosines(sat_pos, sat_vel, ut_pos[ks]), u_beams[empty]])
        a = steering_vector(u, 60, 72)
        amp_path = np.sqrt(np.r_[path[ks], np.full(len(empty), np.mean(path[ks]))])
        h = amp_path[:, None] * (a.conj() @ f_rf[:, [chain_of[g] for g in rows_beam]])
        same = colors[rows_beam][:, None] == colors[rows_beam][None, :]
        h = np.where(same, h, 0.0)
        hh = h.conj().T
        if kind == "zf":
            f = hh @ np.linalg.inv(h @ hh)
        elif kind == "zf_normalized":  # each UT's column scaled to unit norm
            f = hh @ np.linalg.inv(h @ hh)
            f = f / np.sqrt(np.sum(np.abs(f) ** 2, axis=0))
        else:  # Peel et al.: alpha = n_ut noise / (n_beam P_RF) = 1 (square problem)
            f = hh @ np.linalg.inv(h @ hh + np.eye(len(rows_beam)))
        f = f * np.sqrt(1.0 / max(np.sum(np.abs(f) ** 2, axis=1)))
        amp = np.abs(h @ f) ** 2
        for i, k in enumerate(ks):
            sinr = amp[i, i] / (amp[i].sum() - amp[i, i] + 1.0)
            total[k] += np.log2(1.0 + sinr)
            count[k] += 1
    return total / count


O2_DEMAND = ["satellite_array.oversampling=2.0", "satellite_array.active_beams=demand"]


@pytest.mark.parametrize(
    "kind, sets, idle",
    [
        ("zf", [], "silent"),
        ("mmse", [], "silent"),
        ("zf", ["link.reuse_colors=3"], "silent"),
        ("zf_normalized", [], "silent"),
        ("mmse", O2_DEMAND, "silent"),
        # idle lit beams transmitting: 25 UTs leave some of the 15 beams empty, and the 15
        # random lit beams of 47 (O = 2) more
        ("zf", [], "transmit"),
        ("mmse", O2_DEMAND, "transmit"),
        ("zf", ["link.reuse_colors=3"], "transmit"),
        ("zf_normalized", O2_DEMAND, "transmit"),
    ],
)
def test_precoded_se_matches_explicit_steering_vectors(tmp_path, kind, sets, idle):
    """The wired precoder (closed-form responses, padded batches, chains of the lit
    beams) = explicit steering vectors of the 60 x 72 array with numpy.linalg, to 1e-9."""
    scen = build_scenario(_cfg(tmp_path, 25, sets))
    eng = scen.engine
    pos, vel, _ = scen.ephemeris(np.array([60.0]))
    ut = np.concatenate([p.state(60.0).pos_m for _, p in scen.populations])
    snap = eng.evaluate(ut, pos[0], vel[0])
    lit = np.ones(eng.n_beam, bool)
    if eng.n_beam > 15:  # 15 of the 47 beams lit, at random
        lit[:] = False
        lit[np.random.default_rng(5).choice(eng.n_beam, 15, replace=False)] = True
    beam = np.argmax(np.where(lit, snap.gain_tx_lin[:, 0, :], -1.0), axis=1)
    zeros = np.zeros((len(ut), 3))
    lit_rows = None if lit.all() else np.broadcast_to(lit, (len(ut), eng.n_beam))
    sat_vel = np.repeat(vel[0], len(ut), 0)
    cols = eng.serve_pairs(snap.links, np.arange(len(ut)), beam, zeros, zeros, sat_vel, zeros,
                           ut_pos_m=ut, lit=lit_rows)  # fmt: skip
    precoder = PRECODERS.build(kind, PRECODERS[kind].config(idle_beams=idle))
    svc = BeamService(eng, SCHEDULERS.build("round_robin"), precoder, HybridArray(60, 72, 5, 3))
    path = snap.path_snr_lin[:, 0]
    inputs = dict(
        ut_pos_m=ut,
        sat_pos_m=np.repeat(pos[0], len(ut), 0),
        sat_vel_m_s=np.repeat(vel[0], len(ut), 0),
        path_snr_lin=path,
        i_other=None,
    )
    served = np.ones(len(ut), bool)
    svc.apply(cols, np.zeros(len(ut), int), beam, served, None if lit.all() else lit[None],
              lambda: inputs)  # fmt: skip
    se = cols["se_bps_hz"] * cols["n_sharing"]  # undo the round-robin share 1/n
    want = _explicit_se(ut, pos[0, 0], vel[0, 0], path, beam, kind, eng.colors,
                        eng.codebook.u_xy, lit, idle)  # fmt: skip
    np.testing.assert_allclose(se, want, rtol=1e-9)
    if idle == "transmit":  # the case has idle lit beams, and they change the SE
        assert set(np.flatnonzero(lit)) - set(beam.tolist())
        silent = _explicit_se(ut, pos[0, 0], vel[0, 0], path, beam, kind, eng.colors,
                              eng.codebook.u_xy, lit)  # fmt: skip
        assert np.max(np.abs(se - silent)) > 1e-3


def test_precoder_needs_a_scheduler(tmp_path):
    with pytest.raises(ConfigError, match="link.precoder = 'zf' is not allowed with scheduler"):
        _cfg(tmp_path, 5, ["link.precoder=zf"])


class _EvenBeams:
    """Light the even beam ids (a test selector, added through the registry alone)."""

    lights_all = False
    dark_fallback = "neighbour"

    def __init__(self, n_beam):
        self.n_beam = n_beam

    def lit(self, k, best_cell, n_sat):
        return np.broadcast_to(np.arange(self.n_beam) % 2 == 0, (n_sat, self.n_beam))


def test_a_selector_plugs_in_through_its_registry(tmp_path):
    from leolink.sim.beams.selectors import BEAM_SELECTORS

    BEAM_SELECTORS.add("even_test", lambda p, c: _EvenBeams(c.n_beam), doc="even beams")
    try:
        _, trace = _run(_cfg(tmp_path, 15, ["satellite_array.active_beams=even_test"]))
    finally:
        BEAM_SELECTORS.remove("even_test")
    served = trace[trace.service != "outage"]
    assert len(served) > 0 and (served.beam_id % 2 == 0).all()
    assert served.sinr_db.notna().all()


def test_four_beam_corners_paper_bound_and_precoders(tmp_path):
    """Paper Sec. 5: at a point four beams cover with equal gain the SINR is at most
    10 log10(1/3) = -4.77 dB without precoder; the 11 other beams (each serving a UT at its
    footprint centre) only lower it. ZF removes the interference; MMSE >= ZF."""
    import sys

    sys.path.insert(0, str(ROOT / "analysis"))
    try:
        from beams_pass import corner_sinr
    finally:
        sys.path.remove(str(ROOT / "analysis"))
    sinr = {k: np.array(v) for k, v in corner_sinr(tmp_path).items()}
    assert len(sinr["none"]) == 8
    assert np.all(sinr["none"] <= 10 * np.log10(1 / 3)) and np.all(sinr["none"] > -7.0)
    assert np.all(sinr["zf"] > sinr["none"] + 5.0)
    assert np.all(sinr["mmse"] >= sinr["zf"] - 1e-9)


def test_ephemeris_error_seam_leaves_residual_interference(tmp_path):
    """The precoder from a believed satellite position: the truth gives back the known-
    channel SE exactly; 5 km off leaves residual interference under ZF."""
    scen = build_scenario(_cfg(tmp_path, 25))
    eng = scen.engine
    pos, vel, _ = scen.ephemeris(np.array([60.0]))
    ut = np.concatenate([p.state(60.0).pos_m for _, p in scen.populations])
    snap = eng.evaluate(ut, pos[0], vel[0])
    beam = np.argmax(snap.gain_tx_lin[:, 0, :], axis=1)
    zeros = np.zeros((len(ut), 3))
    base = eng.serve_pairs(snap.links, np.arange(len(ut)), beam, zeros, zeros,
                           np.repeat(vel[0], len(ut), 0), zeros, ut_pos_m=ut)  # fmt: skip
    svc = BeamService(eng, SCHEDULERS.build("round_robin"), PRECODERS.build("zf"),
                      HybridArray(60, 72, 5, 3))  # fmt: skip
    sat = np.repeat(pos[0], len(ut), 0)
    out = {}
    for name, est in (("known", None), ("true", sat), ("off", sat + [5e3, 0.0, 0.0])):
        cols = {k: v.copy() for k, v in base.items()}
        inputs = dict(
            ut_pos_m=ut,
            sat_pos_m=sat,
            sat_vel_m_s=np.repeat(vel[0], len(ut), 0),
            path_snr_lin=snap.path_snr_lin[:, 0],
            i_other=None,
            sat_pos_est_m=est,
        )
        svc.apply(cols, np.zeros(len(ut), int), beam, np.ones(len(ut), bool), None,
                  lambda inputs=inputs: inputs)  # fmt: skip
        out[name] = cols["se_bps_hz"]
    np.testing.assert_array_equal(out["true"], out["known"])
    # the mismatch leaves residual interference in every slot
    assert out["off"].mean() < out["known"].mean() * (1 - 5e-3)


def test_acm_throughput_is_shared_too(tmp_path):
    """With the DVB-S2X throughput model the MODCOD rate of a UT is its share of the beam's."""
    sets = ["modcod.throughput_model=dvbs2x", "run.duration_s=5"]
    _, base = _run(_cfg(tmp_path, 30, sets))
    _, rr = _run(_cfg(tmp_path, 30, [*sets, "scheduler.kind=round_robin"]))
    on = rr.service == "served"
    assert on.sum() > 100
    np.testing.assert_allclose(
        (rr.throughput_bps * rr.n_sharing)[on], base.throughput_bps[on], rtol=1e-12
    )


def test_a_block_with_no_satellite_in_view_keeps_the_sharing_column(tmp_path):
    """Before the pass (the satellite below every UT's horizon) a scheduled run records
    outage rows with ``n_sharing`` 0 (it stopped with KeyError: 'n_sharing')."""
    cfg = _cfg(tmp_path, 5, ["scheduler.kind=round_robin"])
    cfg = updated(cfg, ["run.start_s=-2000", "run.duration_s=10"])
    _, trace = _run(cfg)
    assert len(trace) == 5 * 10 and (trace.service == "outage").all()
    assert (trace.n_sharing == 0).all() and trace.sat_id.eq(-1).all()
