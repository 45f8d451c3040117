"""The link figures of real runs and of ``leolink budget``, against hand link budgets.

Hand budgets use the paper's Table (P_TX = 15 dBW per beam, T = 24.1 dBK, B = 250 MHz) and
the trace's own geometry and gain columns (themselves recomputed independently in
tests/test_trace_independent.py): ``C/N0 = P_TX + G_TX - FSPL - L_atm + G_RX - T - k``, the
symbol rate ``B / (1 + alpha)``, ``Es/N0 = C/N0 - 10 log10(R_s)``. The MODCOD is chosen by brute
force over the rows of the packaged CSV file, read here with the csv module.
"""

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from leolink.app.run import run
from leolink.config import load_config
from leolink.io.summary.accumulator import OVERALL_RESOLUTION_DB
from leolink.link.acm import LinkFigureParams, link_figure_columns

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"
K_DBW_K_HZ = 10 * math.log10(1.380649e-23)  # Boltzmann, exact SI value
PTX_DBW, T_DBK, B_HZ = 15.0, 24.1, 250e6  # the paper's Table
# The engine's SNR (linear kernels times the path) against the dB sum of the trace columns:
# float rounding only (the columns are rounded to 1e-15 relative in CSV text).
FLOAT_DB = 1e-9
SHORT = ["run.duration_s=60.0", "output.plots.enabled=false"]
# The SNR run: thermal Es/N0, a 0.5 dB implementation margin, 0.3 s handover execution (the
# ACM throughput counts the served part of an epoch) and 0.7 dB of scintillation (a
# constant loss the engine subtracts besides FSPL and atmosphere).
SCINT_DB = 0.7
FIGURE_RUN = [
    *SHORT,
    'modcod.metric="snr"',
    "modcod.implementation_margin_db=0.5",
    "controller.handover_time_s=0.3",
    f"link.scintillation_loss_db={SCINT_DB}",
]


def _csv_table():
    path = ROOT / "src" / "leolink" / "data" / "dvbs2x_modcods.csv"
    lines = [x for x in path.read_text().splitlines() if x and not x.startswith("#")]
    rows = list(csv.DictReader(lines))[1:]  # the units row
    names = [r["name"] for r in rows]
    eta = np.array([float(r["spectral_efficiency_bit_sym"]) for r in rows])
    th = np.array([float(r["esn0_ideal_db"]) for r in rows])
    return names, eta, th


NAMES, ETA, THRESHOLD_DB = _csv_table()


def _brute_force_modcod(esn0_db, margin_db):
    """Name and efficiency of the best allowed row (equality allowed), 'none' / 0 if none."""
    allowed = THRESHOLD_DB[None, :] + margin_db <= esn0_db[:, None]
    score = np.where(allowed, ETA[None, :], -1.0)
    # Highest efficiency; among equal efficiencies the lower threshold (first in sorted order).
    order = np.lexsort((THRESHOLD_DB, -ETA))
    best = order[np.argmax(score[:, order] == score.max(axis=1, keepdims=True), axis=1)]
    ok = allowed.any(axis=1)
    names = np.where(ok, np.asarray(NAMES, dtype=object)[best], "none")
    return names, np.where(ok, ETA[best], 0.0)


@pytest.fixture(scope="module")
def snr_run():
    return run(load_config(PAPER, FIGURE_RUN))


@pytest.fixture(scope="module")
def sinr_run():
    return run(load_config(PAPER, [o for o in FIGURE_RUN if not o.startswith("modcod.metric")]))


def _hand_cn0(tr):
    eirp = PTX_DBW + tr.gain_tx_db
    return eirp - tr.fspl_db - tr.atm_db - SCINT_DB + (tr.gain_rx_db - T_DBK) - K_DBW_K_HZ


def test_eirp_cn0_esn0_margin_equal_a_hand_budget_on_every_row(snr_run):
    tr = snr_run.trace
    link = tr[np.isfinite(tr.snr_db)]
    assert len(link) > 0.9 * len(tr)
    np.testing.assert_allclose(link.eirp_dbw, PTX_DBW + link.gain_tx_db, rtol=0, atol=FLOAT_DB)
    cn0 = _hand_cn0(link)
    np.testing.assert_allclose(link.cn0_dbhz, cn0, rtol=0, atol=FLOAT_DB)
    esn0 = cn0 - 10 * np.log10(B_HZ / 1.2)  # default roll-off 0.2
    np.testing.assert_allclose(link.esn0_db, esn0, rtol=0, atol=FLOAT_DB)
    # Required: the most robust MODCOD (QPSK 2/9, -2.85 dB) plus the 0.5 dB margin.
    np.testing.assert_allclose(link.margin_db, esn0 - (-2.85 + 0.5), rtol=0, atol=FLOAT_DB)
    assert (tr[~np.isfinite(tr.snr_db)].modcod == "none").all()


def test_modcod_is_the_best_the_esn0_allows(snr_run):
    tr = snr_run.trace
    names, _ = _brute_force_modcod(tr.esn0_db.to_numpy(), 0.5)
    assert list(tr.modcod) == list(names)
    assert tr.modcod.nunique() > 5  # the pass sweeps many MODCODs


def test_sinr_metric_takes_es_over_n0_plus_i0(sinr_run, snr_run):
    tr = sinr_run.trace
    ok = np.isfinite(tr.sinr_db)
    np.testing.assert_allclose(
        tr.esn0_db[ok], tr.sinr_db[ok] + 10 * np.log10(1.2), rtol=0, atol=FLOAT_DB
    )
    # C/N0 is thermal whatever the metric: the same as in the SNR run (same scenario).
    np.testing.assert_allclose(tr.cn0_dbhz, snr_run.trace.cn0_dbhz, rtol=0, atol=0)
    names, _ = _brute_force_modcod(tr.esn0_db.to_numpy(), 0.5)
    assert list(tr.modcod) == list(names)


def test_summary_link_block_from_the_trace(snr_run):
    tr, link = snr_run.trace, snr_run.summary["overall"]["link"]
    _, eta = _brute_force_modcod(tr.esn0_db.to_numpy(), 0.5)
    served = 1.0 - tr.interruption_s.to_numpy() / 1.0  # epoch_s = 1
    assert (served < 1.0).sum() > 3  # handover epochs with execution in them
    acm = np.where(np.isfinite(tr.snr_db), eta * B_HZ / 1.2 * served, 0.0)
    tput = link["mean_throughput_bps"]
    assert tput["dvbs2x"] == pytest.approx(acm.mean(), rel=1e-12)
    assert tput["shannon"] == pytest.approx(tr.throughput_bps.fillna(0).mean(), rel=1e-12)
    # Every MODCOD sits above the Shannon bound of its rate: eta R_s <= B log2(1 + SNR).
    ok = np.isfinite(tr.snr_db)
    assert (acm[ok] <= B_HZ * np.log2(1 + 10 ** (tr.snr_db[ok] / 10))).all()
    usage = tr[tr.service != "outage"].modcod.value_counts(normalize=True)
    assert link["modcod_usage"] == pytest.approx(usage.to_dict(), rel=1e-12)
    m = tr.margin_db.dropna()
    # Streamed histogram percentiles: within half a 0.01 dB bin of numpy's.
    half_bin = OVERALL_RESOLUTION_DB / 2 + 1e-9
    assert link["margin_db"]["p50"] == pytest.approx(np.percentile(m, 50), abs=half_bin)
    assert link["margin_db"]["fraction_negative"] == pytest.approx((m < 0).mean(), rel=1e-12)


def test_dvbs2x_throughput_model_fills_throughput_bps(snr_run):
    res = run(load_config(PAPER, [*FIGURE_RUN, 'modcod.throughput_model="dvbs2x"']))
    tr = res.trace
    _, eta = _brute_force_modcod(tr.esn0_db.to_numpy(), 0.5)
    acm = eta * B_HZ / 1.2 * (1.0 - tr.interruption_s)
    ok = np.isfinite(tr.snr_db)
    np.testing.assert_allclose(tr.throughput_bps[ok], acm[ok], rtol=1e-12)
    np.testing.assert_allclose(tr.se_bps_hz[ok], acm[ok] / B_HZ, rtol=1e-12)
    # The summary's Shannon figure is still the paper's, as in the Shannon run.
    shannon = res.summary["overall"]["link"]["mean_throughput_bps"]["shannon"]
    assert shannon == pytest.approx(snr_run.summary["overall"]["mean_throughput_bps"], rel=1e-12)


def test_sinr_service_metric_turns_low_sinr_rows_into_outage(sinr_run):
    threshold = 3.0
    # 0.3 s handover execution: some handover epochs fall below the threshold too
    over = [*SHORT, f"controller.min_snr_db={threshold}", "controller.handover_time_s=0.3"]
    by_snr = run(load_config(PAPER, over)).trace
    by_sinr = run(load_config(PAPER, [*over, 'controller.service_metric="sinr"'])).trace
    low = (by_snr.service != "outage") & ~(by_snr.sinr_db >= threshold)
    assert 0.05 < low.mean() < 0.95
    assert (by_sinr.service[low] == "outage").all()
    assert (by_sinr.outage_reason[low] == "below_threshold").all()
    assert by_sinr.sinr_db[low].isna().all() and by_sinr.throughput_bps[low].isna().all()
    # an outage row loses no time to a handover, also where the controller handed over
    assert ((by_snr.service[low] == "handover") & (by_snr.interruption_s[low] > 0)).sum() > 5
    assert (by_sinr.interruption_s[low] == 0.0).all()
    same = ~low
    assert (by_sinr.service[same] == by_snr.service[same]).all()
    assert (by_sinr.beam_id == by_snr.beam_id).all()  # beams stay the controller's (SNR)


def _figures(esn0_db, margin_db):
    """link_figure_columns with Es/N0 exactly ``esn0_db``: roll-off 0 makes Es/N0 the SNR
    itself (no float sum in between), so table thresholds are hit with equality."""
    snr = np.asarray(esn0_db, float)
    p = LinkFigureParams(15.0, 0.0, B_HZ, 0.0, margin_db, None, "snr")
    out = link_figure_columns(snr, snr, np.zeros(len(snr)), p)
    assert (out["esn0_db"] == snr).all()
    return out


@pytest.mark.parametrize("margin_db", [0.0, 0.75])
def test_modcod_at_every_table_threshold_equality_counts(margin_db):
    esn0 = THRESHOLD_DB + margin_db
    got = _figures(list(esn0), margin_db)
    names, eta = _brute_force_modcod(got["esn0_db"], margin_db)
    from leolink.link.modcod import modcod_table

    table = modcod_table()
    assert [table.names[i] for i in got["modcod"]] == list(names)
    # At its own threshold a row is allowed: the chosen efficiency is at least its own.
    assert (eta >= ETA - 1e-12).all()
    # Just below a threshold that row is no longer allowed.
    below = _figures(list(np.nextafter(esn0, -np.inf)), margin_db)
    chosen = np.array([ETA[i] if i >= 0 else 0.0 for i in below["modcod"]])
    lowest = np.argmin(THRESHOLD_DB)
    assert below["modcod"][lowest] == -1 and chosen[lowest] == 0.0


def _budget(config, elevation_deg):
    out = subprocess.run(
        [sys.executable, "-m", "leolink.cli", "budget", str(config), "--elevation-deg",
         str(elevation_deg), "--json"],
        capture_output=True, text=True, check=True, cwd=ROOT,
    )  # fmt: skip
    return json.loads(out.stdout)


def test_budget_command_equals_a_hand_budget_at_45_deg():
    b = _budget(PAPER, 45.0)
    el, h, r = math.radians(45.0), 1_300_000.0, 6_371_000.0
    d = math.sqrt((r + h) ** 2 - (r * math.cos(el)) ** 2) - r * math.sin(el)
    fspl = 20 * math.log10(4 * math.pi * d * 11.45e9 / 299_792_458.0)
    assert b["fspl_db"] == pytest.approx(fspl, abs=1e-9)
    eirp = PTX_DBW + b["gain_tx_db"]
    g_t = 10 * math.log10(576 + 0.1) - T_DBK  # 24 x 24 UPA, N + 1/K
    cn0 = eirp - fspl - 0.017 + g_t - K_DBW_K_HZ
    assert b["eirp_dbw"] == pytest.approx(eirp, abs=1e-12)
    assert b["g_over_t_db_k"] == pytest.approx(g_t, abs=1e-12)
    assert b["cn0_dbhz"] == pytest.approx(cn0, abs=1e-9)
    assert b["cnr_db"] == pytest.approx(cn0 - 10 * math.log10(B_HZ), abs=1e-9)
    # Es/N0 from the SINR by default (Es / (N0 + I0)); the margin from QPSK 2/9.
    assert b["esn0_metric"] == "sinr"
    assert b["esn0_db"] == pytest.approx(b["sinr_db"] + 10 * math.log10(1.2), abs=1e-12)
    assert b["margin_db"] == pytest.approx(b["esn0_db"] + 2.85, abs=1e-12)
    names, eta = _brute_force_modcod(np.array([b["esn0_db"]]), 0.0)
    assert b["modcod"] == names[0]
    assert b["throughput_dvbs2x_bps"] == pytest.approx(eta[0] * B_HZ / 1.2, rel=1e-12)


CAR = ROOT / "configs" / "examples" / "car.toml"
# car.toml: a pass with links that close no MODCOD at its ends; a 1 dB implementation
# margin and 0.3 s handover execution exercise the margin and the served part of an epoch.
MODCOD_RUN = [
    "output.plots.enabled=false",
    "output.report.enabled=false",
    'modcod.metric="sinr"',
    "modcod.implementation_margin_db=1.0",
    "controller.handover_time_s=0.3",
]


def test_modcod_service_metric_serves_only_where_a_modcod_closes():
    by_snr = run(load_config(CAR, MODCOD_RUN))
    by_modcod = run(load_config(CAR, [*MODCOD_RUN, 'controller.service_metric="modcod"']))
    tr, tm = by_snr.trace, by_modcod.trace
    names, _ = _brute_force_modcod(tr.esn0_db.to_numpy(), 1.0)
    served = tr.service != "outage"
    none = served & (names == "none")
    assert 10 < none.sum() < served.sum()
    assert (tm.service[none] == "outage").all()
    assert (tm.outage_reason[none] == "below_threshold").all()
    assert tm.sinr_db[none].isna().all()
    same = ~none
    assert (tm.service[same] == tr.service[same]).all()
    assert (tm.beam_id == tr.beam_id).all()  # beams stay the controller's (SNR)
    # summary.json: the served time without a MODCOD, in UT-seconds and as a fraction
    served_s = (1.0 - tr.interruption_s)[served]  # epoch_s = 1 s
    want_s = float((1.0 - tr.interruption_s)[none].sum())
    got = by_snr.summary["overall"]["link"]["served_without_modcod"]
    assert got["ut_s"] == pytest.approx(want_s, rel=1e-12)
    assert got["fraction"] == pytest.approx(want_s / served_s.sum(), rel=1e-12)
    assert by_modcod.summary["overall"]["link"]["served_without_modcod"]["ut_s"] == 0.0
    # the report's Outage figure says it, in per cent and UT-seconds
    from leolink.io.report.headline import fmt_si, headline_figures

    outage = {h.label: h for h in headline_figures(by_snr.summary)}["Outage"]
    assert f"{fmt_si(100 * got['fraction'], 2)} % of the served UT-time" in outage.sentence
    assert f"({fmt_si(want_s)} UT-s)" in outage.sentence and outage.warn
