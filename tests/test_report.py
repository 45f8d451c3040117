"""report.html: self-contained, opens in a real headless Chromium with every image loaded
and a clean console; its tables carry the summary of a real run."""

import base64
import html
import io
import json
import re
import shutil

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
