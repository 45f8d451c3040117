"""Screenshot of the paper scenario's report.html, for the README: docs/img/report_paper.png.

Usage: ``python tools/report_screenshot.py [--out DIR]``. Runs ``leolink run
configs/paper.toml`` (its report sink writes the page) and photographs the top of the page
in the system's headless Chromium (the same browser set-up as tests/test_report.py:
Debian's chromium + chromium-driver, driven by Selenium): the first screen, 1280 x 800 CSS
px, as tests/test_report.py checks it (the header and the headline figures).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from browser_helpers import open_page  # noqa: E402
from report_helpers import PAPER, cli  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("/tmp/leolink_report_paper"))
    ap.add_argument("--png", type=Path, default=REPO / "docs" / "img" / "report_paper.png")
    args = ap.parse_args(argv)
    cli("run", PAPER.relative_to(REPO), "--out", args.out, "--quiet", "--overwrite")
    page = args.out / "report.html"
    state = open_page(page, screenshot=args.png, width=1280, height=800)
    bad = [i for i in state["images"] if not i["width"]]
    print(f"{args.png}: {len(state['images'])} images, {len(bad)} not loaded")


if __name__ == "__main__":
    main()
