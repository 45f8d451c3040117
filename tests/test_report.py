"""report.html: self-contained, opens in a real headless Chromium with every image loaded
and a clean console; its tables carry the summary of a real run."""

import base64
import html
import io
import json
import re
import shutil

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from browser_helpers import open_page, require_browser
from leolink.io.report.figures import fig_cdfs
from leolink.io.report.page import build_run_report, build_table_report
from leolink.io.report.rebuild import build_report_from_dir, stats_from_dir
from report_helpers import WALKER, make_run

N_FIGURES = 8  # SNR, timeline, Doppler, angular speed, dwell, CDFs, outage, map


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    out = make_run(tmp_path_factory.mktemp("paper"))
    return out, build_report_from_dir(out, series_ut=[0, 1, 5, 6])


@pytest.fixture(scope="module")
def walker(tmp_path_factory):
    out = make_run(tmp_path_factory.mktemp("walker"), WALKER)
    return out, build_report_from_dir(out, series_ut=[0, 1])


def _img_sources(page):
    return re.findall(r'<img src="([^"]*)"', page)


def test_page_has_no_external_resource(paper):
    page = paper[1]["report"].read_text()
    assert "<script" not in page and "<link" not in page and "@import" not in page
    assert not re.search(r'(src|href)="(https?:)?//', page)
    assert "url(" not in page  # no CSS resource either
    sources = _img_sources(page)
    assert len(sources) == N_FIGURES + 1  # and the embedded animation
    for src in sources:
        kind, data = re.match(r"data:image/(png|gif);base64,(.*)", src).groups()
        with Image.open(io.BytesIO(base64.b64decode(data))) as im:
            assert im.format.lower() == kind and im.size[0] > 100 and im.size[1] > 100
            im.load()  # the whole image decodes, not just its header


FIRST_SCREEN = (1280, 800)  # CSS px: a laptop's browser window, the page as it opens


def test_first_screen_holds_the_header_and_the_headline_figures(paper):
    require_browser()
    state = open_page(paper[1]["report"], width=FIRST_SCREEN[0], height=FIRST_SCREEN[1],
                      selectors=["header h1", "header .meta", ".headline .fig"])  # fmt: skip
    assert state["viewport"] == list(FIRST_SCREEN)
    rects = state["rects"]
    assert len(rects["header h1"]) == 1 and len(rects["header .meta"]) == 1
    assert 5 <= len(rects[".headline .fig"]) <= 6
    for box in (b for boxes in rects.values() for b in boxes):
        assert 0 <= box["top"] and box["bottom"] <= FIRST_SCREEN[1], box
        assert 0 <= box["left"] and box["right"] <= FIRST_SCREEN[0], box


def _headline(page, label):
    """The value shown under a headline figure's label."""
    m = re.search(rf'<div class="label">{re.escape(label)}</div><div class="value">([^<]*)<',
                  page)  # fmt: skip
    return m.group(1)


def test_header_names_the_run_and_headline_figures_are_the_summary_in_human_units(paper):
    out, built = paper
    page = built["report"].read_text()
    summary = json.loads((out / "summary.json").read_text())
    o, run = summary["overall"], summary["run"]
    assert run["scenario"] == "paper" and run["config_file"].endswith("configs/paper.toml")
    meta = re.search(r'<p class="meta">([^<]*)</p>', page).group(1)
    manifest = json.loads((out / "run.json").read_text())
    assert f"leolink {manifest['leolink_version']}" in meta
    assert manifest["finished_utc"][:10] in meta and " UTC" in meta  # the run's date
    assert "config " + html.escape(run["config_file"]) in meta and "simulated in" in meta
    mbit = float(_headline(page, "Throughput per UT").removesuffix(" Mbit/s"))
    assert mbit == pytest.approx(o["mean_throughput_bps"] / 1e6, rel=5e-3)  # 3 digits
    assert float(_headline(page, "Median SINR").removesuffix(" dB")) == pytest.approx(
        o["sinr_db"]["p50"], abs=0.005
    )
    rate = float(_headline(page, "Handovers").removesuffix(" per UT-minute"))
    minutes = run["n_ut"] * (run["end_s"] - run["start_s"]) / 60.0
    assert rate == pytest.approx(o["handovers"]["handovers_total"] / minutes, rel=5e-3)
    khz = float(_headline(page, "Largest Doppler shift").removesuffix(" kHz"))
    assert khz == pytest.approx(o["max_abs_doppler_hz"] / 1e3, rel=5e-3)
    assert _headline(page, "Outage") == "0 %" and o["outage_fraction"] == 0.0


def test_one_mean_dwell_everywhere(paper):
    # The page's headline, its folded table and the histogram legend show summary.json's
    # mean of the complete dwells; the mean of the bin centres (the old legend) differs.
    from leolink.io.report.figures import fig_dwell
    from leolink.io.report.headline import fmt_si

    out, built = paper
    page = built["report"].read_text()
    d = json.loads((out / "summary.json").read_text())["overall"]["dwell"]
    shown = fmt_si(d["mean_s"])
    assert _headline(page, "Mean time in a beam") == f"{shown} s"
    assert f"<td>dwell.mean_s</td><td>{d['mean_s']:.4g}</td>" in page
    stats = stats_from_dir(out)
    assert stats.dwell_mean_s == pytest.approx(d["mean_s"], rel=1e-12)
    edges, counts = stats.dwell_edges_s, stats.dwell_complete
    centres = np.sum(0.5 * (edges[:-1] + edges[1:]) * counts) / counts.sum()
    assert fmt_si(centres) != shown  # the check can tell the two definitions apart
    fig = fig_dwell(edges, counts, stats.dwell_censored, stats.dwell_mean_s)
    legend = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert legend == [f"mean {shown} s"]


def test_each_table_once_and_folded_after_the_figures(paper):
    page = paper[1]["report"].read_text()
    assert page.count("<td>dwell.mean_s</td>") == 1
    assert page.count("<td>kpi.handover_rate_per_ut_min</td>") == 1
    first_details, last_img = page.index("<details>"), page.rindex("<img ")
    assert last_img < first_details  # story first, tables at the end
    assert page.count("<details>") == 4  # summary, run, per UT, config


def test_page_tables_show_the_summary(paper):
    out, built = paper
    page = built["report"].read_text()
    summary = json.loads((out / "summary.json").read_text())
    overall = summary["overall"]
    n_beam = overall["handovers"]["beam_handover"]
    assert re.search(rf"<td>handovers.beam_handover</td><td>{n_beam}</td>", page)
    mean = overall["dwell"]["mean_s"]
    assert f"<td>dwell.mean_s</td><td>{mean:.4g}</td>" in page
    assert page.count("<tr><td>") >= len(summary["per_ut"])  # every UT of a 7-UT run
    config = (out / "config.resolved.toml").read_text()
    assert html.escape(config) in page


def test_report_opens_in_headless_chromium_with_every_image_and_no_console_error(paper):
    require_browser()
    state = open_page(paper[1]["report"])
    assert len(state["images"]) == N_FIGURES + 1
    for img in state["images"]:
        assert img["complete"] and img["width"] > 0 and img["height"] > 0, img
    assert all(state["decoded"])
    assert state["scripts"] == 0 and state["links"] == []
    assert all(r.startswith(("file:", "data:")) for r in state["resources"]), state["resources"]
    errors = [e for e in state["console"] if e["level"] in ("SEVERE", "WARNING")]
    assert errors == []


def test_multi_satellite_report_with_a_linked_animation_opens_offline(walker, tmp_path):
    require_browser()
    out, built = walker
    page_dir = tmp_path / "copy"
    page_dir.mkdir()
    stats = stats_from_dir(out, series_ut=[0, 1])
    shutil.copy(built["animation"], page_dir / "footprint.gif")

    summary = json.loads((out / "summary.json").read_text())
    page = build_run_report(
        page_dir / "report.html",
        summary,
        stats,
        animation_path=page_dir / "footprint.gif",
        embed_max_bytes=0,
    )
    assert 'src="footprint.gif"' in page.read_text()
    state = open_page(page)
    assert len(state["images"]) == N_FIGURES + 1
    assert all(i["complete"] and i["width"] > 0 for i in state["images"])
    assert all(state["decoded"])
    assert [e for e in state["console"] if e["level"] == "SEVERE"] == []


def test_a_missing_linked_file_is_caught_by_the_browser_check(walker, tmp_path):
    # The check itself can fail: a page linking an absent GIF shows a broken image.
    require_browser()
    out, built = walker
    stats = stats_from_dir(out, series_ut=[0])

    summary = json.loads((out / "summary.json").read_text())
    gif = tmp_path / "footprint.gif"
    shutil.copy(built["animation"], gif)
    page = build_run_report(
        tmp_path / "report.html", summary, stats, animation_path=gif, embed_max_bytes=0
    )
    gif.unlink()
    state = open_page(page)
    assert any(i["width"] == 0 for i in state["images"]) and not all(state["decoded"])
    assert any(e["level"] == "SEVERE" for e in state["console"])


def test_table_report_of_two_runs_opens_cleanly(paper, walker, tmp_path):
    require_browser()
    rows = []
    for name, (out, _) in (("paper", paper), ("walker", walker)):
        o = json.loads((out / "summary.json").read_text())["overall"]
        rows.append(
            {
                "run": name,
                "handovers_total": o["handovers"]["handovers_total"],
                "outage_fraction": o["outage_fraction"],
                "sinr_db_mean": o["sinr_db"]["mean"],
            }
        )
    stats = stats_from_dir(paper[0])
    cdfs = {k: stats.cdf(k) for k in ("snr_db", "sinr_db", "throughput_bps")}
    page = build_table_report(
        tmp_path / "compare.html",
        "compare",
        pd.DataFrame(rows),
        [("CDFs", fig_cdfs(cdfs))],
        config_text="[run]\n",
    )
    text = page.read_text()
    assert "<td>paper</td>" in text and "<td>walker</td>" in text
    state = open_page(page)
    assert len(state["images"]) == 1 and state["images"][0]["width"] > 0
    assert [e for e in state["console"] if e["level"] == "SEVERE"] == []


def test_rebuild_uses_saved_statistics_without_the_trace(paper, tmp_path):
    out, _ = paper
    copy = tmp_path / "run"
    shutil.copytree(out, copy)
    stats_from_dir(copy, series_ut=[0, 5]).save(copy / "report_stats.npz")
    (copy / "trace.csv").unlink()  # the rebuild must not need it
    built = build_report_from_dir(copy, exports=True)
    assert len(_img_sources(built["report"].read_text())) == N_FIGURES + 1
    assert [p.name for p in built["exports"]] == ["run.geojson", "run.czml"]
