"""SummaryAccumulator by hand: two UTs over four 2 s epochs, every statistic counted here.

UT 0: served at t = 0 (10 dB SNR), in a handover at t = 1 (0.5 s of execution), served
at 2, in a handover at 3 (a row without ``interruption_s``: the whole 2 s epoch). UT 1:
in outage at t = 0 (no satellite) and 1 (below the threshold, SNR 2 dB), then served.
The epochs are numbered 0 to 3 (``time_s``); each lasts ``epoch_s`` = 2 s.
"""

from types import SimpleNamespace

import numpy as np
import pytest

import leolink.io.summary.accumulator as accumulator_module
from leolink.io.summary.accumulator import SummaryAccumulator
from leolink.sim.handover.events import EVENT_KINDS
from leolink.sim.processes import OUTAGE_REASONS

NAN = np.nan
NO_SAT, BELOW = OUTAGE_REASONS.index("no_satellite"), OUTAGE_REASONS.index("below_threshold")
# (t, service, snr, sinr, throughput, doppler, angular speed, interruption, reason, lat, lon)
ROWS = [
    [(0.0, "served", 10.0, 8.0, 1e6, -5.0, 0.1, 0.0, -1, 10.0, 1.0),
     (0.0, "outage", NAN, NAN, NAN, NAN, NAN, 0.0, NO_SAT, -85.0, 2.0)],
    [(1.0, "handover", 12.0, 9.0, 5e5, 7.0, 0.3, 0.5, -1, 11.0, 1.0),
     (1.0, "outage", 2.0, NAN, NAN, NAN, NAN, 0.0, BELOW, -85.0, 2.0)],
    [(2.0, "served", 11.0, 10.0, 2e6, -9.0, 0.2, 0.0, -1, 12.0, 1.0),
     (2.0, "served", 6.0, 5.0, 3e5, 1.0, 0.05, 0.0, -1, -25.0, 2.0)],
    [(3.0, "handover", 9.0, 7.0, 0.0, 3.0, 0.1, None, -1, 13.0, 1.0),
     (3.0, "served", 7.0, 6.0, 4e5, -2.0, 0.02, None, -1, -15.0, 2.0)],
]  # fmt: skip
KEYS = ("time_s", "service", "snr_db", "sinr_db", "throughput_bps", "doppler_hz",
        "angular_speed_deg_s", "interruption_s", "outage_reason", "lat_deg", "lon_deg")  # fmt: skip
EVENTS = [  # time, ut, kind, from (sat, beam), to (sat, beam)
    (0.0, 1, "outage_start", -1, -1, -1, -1),
    (1.0, 0, "beam_handover", 1, 0, 1, 1),
    (2.0, 1, "outage_end", -1, -1, 5, 2),
    (3.0, 0, "beam_handover", 1, 1, 1, 2),
]
EVENT_KEYS = ("time_s", "ut_id", "kind", "from_sat", "from_beam", "to_sat", "to_beam")
# UT 0: a dwell censored by the start, a complete one of 2 s, one censored by the end;
# UT 1: one censored by the end. Given out of order, in two calls.
DWELLS = [
    [(1, 5, 2, 2.0, 4.0, False, True), (0, 2, 0, 3.0, 4.0, False, True)],
    [(0, 1, 1, 1.0, 3.0, False, False), (0, 1, 0, 0.0, 1.0, True, False)],
]
DWELL_KEYS = ("ut_id", "sat_id", "beam_id", "start_s", "end_s", "censored_start", "censored_end")


def _columns(k):
    cols = {key: np.array(c) for key, c in zip(KEYS, zip(*ROWS[k], strict=True), strict=True)}
    cols["ut_id"] = np.array([0, 1])
    if k % 2:  # the service as codes in odd epochs, as names in even ones
        cols["service"] = np.array([("served", "handover", "outage").index(s)
                                    for s in cols["service"]])  # fmt: skip
    if k == 1:  # MODCODs in this epoch only: UT 0's handover row has none
        cols["modcod"] = np.array(["none", "QPSK 1/4"])
    if k == 2:  # the outage reasons by name
        cols["outage_reason"] = np.array(["none", "none"])
    if k == 3:  # an older trace's rows: no interruption_s column
        del cols["interruption_s"]
    else:
        cols["interruption_s"] = cols["interruption_s"].astype(float)
    return cols


def _table(rows, keys):
    return {key: np.array(c) for key, c in zip(keys, zip(*rows, strict=True), strict=True)}


def _fed(monkeypatch, buffer_rows):
    monkeypatch.setattr(accumulator_module, "_POOL_BUFFER", buffer_rows)
    acc = SummaryAccumulator(ping_pong_s=1.0)
    acc.start(SimpleNamespace(n_ut=2, epoch_s=2.0))
    for k in range(4):  # one event an epoch; the first dwells closed at t = 2 s
        events = _table([e for e in EVENTS if e[0] == k], EVENT_KEYS)
        dwells = _table(DWELLS[0], DWELL_KEYS) if k == 2 else {"ut_id": []}
        acc.epoch(SimpleNamespace(columns=_columns(k), events=events, dwells=dwells))
    acc.add_events({"ut_id": np.zeros(0, np.int64), "kind": np.zeros(0, str)})  # no event
    acc.finish(SimpleNamespace(dwells=_table(DWELLS[1], DWELL_KEYS)))
    return acc


@pytest.fixture(params=[1, 3, 1 << 16], ids=["fold-every-row", "fold-every-3", "fold-at-end"])
def acc(request, monkeypatch):
    """The accumulator fed the four epochs, its rows folded every 1 or 3 rows or at the end
    (the statistics must not depend on it)."""
    return _fed(monkeypatch, request.param)


def test_per_ut_table_by_hand(acc):
    t = acc.per_ut_table()
    assert t["ut_id"].tolist() == [0, 1] and t["n_epochs"].tolist() == [4, 4]
    assert (t["lat_deg"].tolist(), t["lon_deg"].tolist()) == ([10.0, -85.0], [1.0, 2.0])
    counts = {k: [0, 0] for k in EVENT_KINDS}
    counts.update(beam_handover=[2, 0], outage_start=[0, 1],
                  outage_end=[0, 1])  # fmt: skip
    for kind, want in counts.items():
        assert t[f"n_{kind}"].tolist() == want, kind
    assert t["n_handovers_total"].tolist() == [2, 0]
    assert t["n_dwell_complete"].tolist() == [1, 0] and t["n_dwell_censored"].tolist() == [2, 1]
    assert t["dwell_mean_s"][0] == 2.0 and t["dwell_median_s"][0] == 2.0
    assert np.isnan(t["dwell_mean_s"][1]) and np.isnan(t["dwell_median_s"][1])
    assert t["outage_fraction"].tolist() == [0.0, 0.5]
    assert t["outage_fraction_no_satellite"].tolist() == [0.0, 0.25]
    assert t["outage_fraction_below_threshold"].tolist() == [0.0, 0.25]
    assert t["outage_fraction_rlf"].tolist() == [0.0, 0.0]
    assert "outage_fraction_blocked" not in t  # no environments
    # 0.5 s, then a whole 2 s epoch (no interruption_s column), over 8 UT-s
    assert t["handover_interruption_fraction"].tolist() == [2.5 / 8, 0.0]
    assert t["snr_mean_db"].tolist() == [42.0 / 4, 15.0 / 3]
    assert t["sinr_mean_db"].tolist() == [34.0 / 4, 11.0 / 2]
    np.testing.assert_allclose(t["snr_p50_db"], [10.5, 6.0], atol=0.05 + 1e-9)
    np.testing.assert_allclose(t["sinr_p95_db"], [9.85, 5.95], atol=0.05 + 1e-9)
    assert t["mean_throughput_bps"].tolist() == [3.5e6 / 4, 7e5 / 4]  # NaN counts as 0
    assert t["max_abs_doppler_hz"].tolist() == [9.0, 2.0]
    assert t["max_angular_speed_deg_s"].tolist() == [0.3, 0.05]
    # every UT observed: the KPI columns (2 handovers in 8 s = 2/15 min: 15 per UT-min)
    assert t["handover_rate_per_ut_min"].tolist() == [15.0, 0.0]
    assert t["rlf_count"].tolist() == [0, 0]


def test_dwell_table_is_sorted_by_ut_then_start(acc):
    d = acc.dwell_table()
    assert d["ut_id"].tolist() == [0, 0, 0, 1]
    assert d["start_s"].tolist() == [0.0, 1.0, 3.0, 2.0]
    assert d["duration_s"].tolist() == [1.0, 2.0, 1.0, 2.0]
    assert d["sat_id"].tolist() == [1, 1, 2, 5]
    assert d["censored_end"].tolist() == [False, False, True, True]


def test_overall_summary_by_hand(acc):
    out = acc.summary()
    o = out["overall"]
    assert (o["n_ut"], o["n_ut_epochs"]) == (2, 8)
    assert o["handovers"]["beam_handover"] == 2 and o["handovers"]["handovers_total"] == 2
    assert o["handovers"]["outage_end"] == 1 and o["handovers"]["rlf"] == 0
    assert o["dwell"] == {"n_complete": 1, "complete_s": [2.0], "n_censored": 3,
                          "mean_s": 2.0, "median_s": 2.0}  # fmt: skip
    assert o["outage_fraction"] == 2 / 8
    assert o["outage_fraction_by_reason"] == {"no_satellite": 1 / 8, "below_threshold": 1 / 8,
                                              "handover": 2.5 / 16, "rlf": 0.0}  # fmt: skip
    assert o["handover_interruption_fraction"] == 2.5 / 16
    assert o["snr_db"]["mean"] == 57.0 / 7 and o["sinr_db"]["mean"] == 45.0 / 6
    assert o["snr_db"]["p50"] == pytest.approx(9.0, abs=0.005 + 1e-9)  # of 2, 6, 7, 9, 10, 11, 12
    assert o["mean_throughput_bps"] == 4.2e6 / 8
    assert (o["max_abs_doppler_hz"], o["max_angular_speed_deg_s"]) == (9.0, 0.3)
    kpi = o["kpi"]
    assert kpi["handover_rate_per_ut_min"] == 2 / (16 / 60)
    # RLF epochs 0; outage 2 epochs of 2 s; the handovers' 2.5 s
    assert kpi["interruption_s"] == {"handover": 2.5, "rlf": 0.0, "outage": 4.0}
    bands = [(b["lat_min_deg"], b["n_ut_epochs"], b["n_handovers"], b["outage_fraction"])
             for b in o["by_latitude"]]  # fmt: skip
    assert bands == [(-90.0, 2, 0, 1.0), (-30.0, 1, 0, 0.0), (-20.0, 1, 0, 0.0), (10.0, 4, 2, 0.0)]
    # MODCODs at t = 1 only: UT 0's handover row (2 - 0.5 s served), without one; UT 1's
    # is an outage
    assert o["link"]["modcod_usage"] == {"none": 1.0}
    assert o["link"]["served_without_modcod"] == {"fraction": 1.0, "ut_s": 1.5}
    assert "by_environment" not in o


def test_per_ut_records_of_the_summary(acc):
    per_ut = acc.summary()["per_ut"]
    assert [r["ut_id"] for r in per_ut] == [0, 1]
    assert per_ut[0]["dwell"]["complete_s"] == [2.0] and per_ut[1]["dwell"]["complete_s"] == []
    assert [c["start_s"] for c in per_ut[0]["dwell"]["censored"]] == [0.0, 3.0]
    assert per_ut[1]["dwell"]["mean_s"] is None  # NaN written as null
    assert per_ut[0]["kpi"]["handover_rate_per_ut_min"] == 15.0
    assert per_ut[1]["outage_fraction_by_reason"]["no_satellite"] == 0.25
    assert per_ut[0]["snr_db"]["mean"] == 10.5 and "link" in per_ut[0]


def test_the_summary_is_fixed_at_finish(acc):
    first = acc.summary()
    acc.add_events(_table([(9.0, 0, "beam_handover", 2, 0, 2, 1)], EVENT_KEYS))
    assert acc.summary() is first


@pytest.mark.parametrize("how", ["constructed", "started"])
def test_environments_add_the_blocked_fraction_and_los(how, monkeypatch):
    """UT 0 (urban): two rows in line of sight; UT 1 (rural): one blocked outage (no
    link: NaN), one row without. Fed in two folds (the counts add up)."""
    monkeypatch.setattr(accumulator_module, "_POOL_BUFFER", 1)
    if how == "constructed":
        acc = SummaryAccumulator(2, epoch_s=1.0, environment=("urban", "rural"))
    else:
        acc = SummaryAccumulator()
        acc.start(SimpleNamespace(n_ut=2, epoch_s=1.0, environment=("urban", "rural")))
    blocked = OUTAGE_REASONS.index("blocked")
    cols = {"ut_id": np.array([0, 1, 0, 1]), "service": np.array([0, 2, 0, 0]),
            "snr_db": np.array([5.0, NAN, 6.0, 7.0]), "sinr_db": np.array([5.0, NAN, 6.0, 7.0]),
            "throughput_bps": np.ones(4), "doppler_hz": np.zeros(4),
            "angular_speed_deg_s": np.zeros(4), "outage_reason": np.array([-1, blocked, -1, -1]),
            "los": np.array([1.0, NAN, 1.0, 0.0])}  # fmt: skip
    acc.add_trace({k: v[:2] for k, v in cols.items()})
    acc.add_trace({k: v[2:] for k, v in cols.items()})
    t = acc.per_ut_table()
    assert t["outage_fraction_blocked"].tolist() == [0.0, 0.5]
    env = acc.summary()["overall"]["by_environment"]
    assert env["urban"]["los_fraction"] == 1.0 and env["rural"]["los_fraction"] == 0.0
    assert env["rural"]["outage_fraction_by_reason"]["blocked"] == 0.5


def test_an_unobserved_ut_leaves_the_kpis_empty():
    acc = SummaryAccumulator(2, epoch_s=1.0)
    cols = {"ut_id": np.array([0]), "service": np.array(["served"]), "snr_db": np.array([5.0]),
            "sinr_db": np.array([5.0]), "throughput_bps": np.ones(1), "doppler_hz": np.zeros(1),
            "angular_speed_deg_s": np.zeros(1)}  # fmt: skip
    acc.add_trace(cols)
    t = acc.per_ut_table()
    assert "handover_rate_per_ut_min" not in t
    assert t["n_dwell_complete"].tolist() == [0, 0]  # no dwell: an empty table
    assert np.isnan(t["lat_deg"]).all() and np.isnan(t["lon_deg"]).all()  # no positions
    out = acc.summary()
    assert out["overall"]["kpi"] == {} and out["per_ut"][1]["kpi"] == {}
    assert out["overall"]["by_latitude"] == []


def _one_row(ut=0, service="served", t=0.0, **extra):
    cols = {"ut_id": np.array([ut]), "time_s": np.array([t]), "service": np.array([service]),
            "snr_db": np.array([5.0]), "sinr_db": np.array([5.0]), "throughput_bps": np.ones(1),
            "doppler_hz": np.zeros(1), "angular_speed_deg_s": np.zeros(1)}  # fmt: skip
    cols.update({k: np.asarray(v) for k, v in extra.items()})
    return cols


#: One UT: beam 0 -> 1 of satellite 1 at 10 s, an RLF in beam 1 at 10.5 s, service back in
#: beam 2 of satellite 1 at 11 s (TS 38.300: a wrong cell; the source satellite when cells
#: are satellites: too early).
MRO_EVENTS = _table(
    [(10.0, 0, "beam_handover", 1, 0, 1, 1), (10.5, 0, "rlf", 1, 1, -1, -1),
     (11.0, 0, "outage_end", -1, -1, 1, 2)],
    EVENT_KEYS,
)  # fmt: skip


@pytest.mark.parametrize("level", [None, "satellite"])
def test_defaults_and_the_kpi_settings_reach_the_kpis(level):
    """No UT by default; 1 s epochs (a handover row without interruption_s: 1 s), 1 s
    ping-pong time and MRO window, MRO on cells (sat, beam) unless configured."""
    assert SummaryAccumulator().summary()["overall"]["n_ut"] == 0
    kwargs = {} if level is None else {"mro_level": level, "mro_window_s": 2.0}
    acc = SummaryAccumulator(1, **kwargs)
    acc.add_trace(_one_row(service="handover"))
    acc.add_events(MRO_EVENTS)
    kpi = acc.summary()["overall"]["kpi"]
    assert kpi["interruption_s"]["handover"] == 1.0
    assert (kpi["ping_pong_s"], kpi["mro_window_s"]) == (1.0, 1.0 if level is None else 2.0)
    counted = {k for k in ("too_early_count", "wrong_cell_count", "too_late_count") if kpi[k]}
    assert counted == ({"wrong_cell_count"} if level is None else {"too_early_count"})
    assert acc.per_ut_table()["wrong_cell_count"].tolist() == [int(level is None)]


def test_an_event_in_a_block_counts_in_the_band_of_its_own_epoch():
    """A block of two epochs: UT 0 at 5 deg at t = 0 and 15 deg at t = 1; its handover at
    t = 0 counts in the 0-10 deg band, not in the band of its later row."""
    acc = SummaryAccumulator(1)
    rows = _one_row(t=0.0, lat_deg=[5.0], lon_deg=[0.0])
    rows = {k: np.r_[v, v] for k, v in rows.items()}
    rows["time_s"], rows["lat_deg"] = np.array([0.0, 1.0]), np.array([5.0, 15.0])
    acc.add_trace(rows)
    acc.add_events(_table([(0.0, 0, "beam_handover", 1, 0, 1, 1)], EVENT_KEYS))
    bands = [(b["lat_min_deg"], b["n_handovers"]) for b in acc.summary()["overall"]["by_latitude"]]
    assert bands == [(0.0, 1), (10.0, 0)]


def test_statistics_follow_events_added_after_a_first_look():
    """Without ``finish`` the summary is recomputed: an event added after a first table
    counts in the next (the cached KPIs are dropped)."""
    acc = SummaryAccumulator(1)
    acc.add_trace(_one_row())
    assert acc.per_ut_table()["handover_rate_per_ut_min"].tolist() == [0.0]
    acc.add_events(_table([(0.0, 0, "beam_handover", 1, 0, 1, 1)], EVENT_KEYS))
    assert acc.per_ut_table()["handover_rate_per_ut_min"].tolist() == [60.0]


def test_nothing_recorded_has_no_fractions_and_given_dwells_are_used():
    acc = SummaryAccumulator(2)
    o = acc.summary()["overall"]
    assert o["outage_fraction"] is None and o["mean_throughput_bps"] is None
    acc = SummaryAccumulator(1)
    acc.add_trace(_one_row())
    acc.add_dwells(_table([(0, 1, 0, 0.0, 4.0, False, False)], DWELL_KEYS))
    assert acc.per_ut_table()["n_dwell_complete"].tolist() == [1]
    empty = {k: np.zeros(0) for k in (*DWELL_KEYS, "duration_s")}
    assert acc.per_ut_table(dwells=empty)["n_dwell_complete"].tolist() == [0]


def test_1000_uts_are_still_written_per_ut():
    assert len(SummaryAccumulator(1000).summary()["per_ut"]) == 1000
    assert "per_ut" not in SummaryAccumulator(1001).summary()


def test_rlf_epochs_and_the_dwell_median():
    """2 s epochs: an outage epoch re-establishing after an RLF, one with no satellite,
    one served: 2 s of RLF interruption, 2 s of other outage. Complete dwells of 1 and
    3 s: median 2 s."""
    acc = SummaryAccumulator(1, epoch_s=2.0)
    for k, (service, reason) in enumerate([("outage", "rlf"), ("outage", "no_satellite"),
                                           ("served", "none")]):  # fmt: skip
        acc.add_trace(_one_row(service=service, t=float(k), outage_reason=[reason]))
    acc.add_dwells(_table([(0, 1, 0, 0.0, 1.0, False, False), (0, 1, 1, 1.0, 4.0, False, False)],
                          DWELL_KEYS))  # fmt: skip
    assert acc.summary()["overall"]["kpi"]["interruption_s"] == {
        "handover": 0.0, "rlf": 2.0, "outage": 2.0}  # fmt: skip
    assert acc.per_ut_table()["dwell_median_s"].tolist() == [2.0]
