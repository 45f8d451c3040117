"""Open a page in the system's headless Chromium through Selenium (no browser download).

Needs Debian's ``chromium`` and ``chromium-driver`` (``/usr/bin/chromium``,
``/usr/bin/chromedriver``) and the ``selenium`` Python package. Selenium is given the
driver's path, so Selenium Manager never looks for (or downloads) a browser or driver.
Name resolution is mapped to nothing, so a page that tried to fetch anything from the
network would log a load error instead of reaching out.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = shutil.which("chromedriver") or "/usr/bin/chromedriver"
FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-default-apps",
    "--hide-scrollbars",
    "--disable-extensions",
    "--host-resolver-rules=MAP * ~NOTFOUND",
)


def require_browser():
    """Skip (locally) or fail (in CI, where .ci/run installs them) without the browser."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not Path(p).exists()]
    try:
        import selenium  # noqa: F401
    except ImportError:
        missing.append("the selenium package")
    if missing:
        msg = f"headless browser test needs {', '.join(missing)} (apt-get install chromium "
        msg += "chromium-driver; pip install selenium)"
        if os.environ.get("CI"):
            pytest.fail(msg)
        pytest.skip(msg)


def _driver(width, height, profile):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in (*FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}"):
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)


_PAGE_STATE = """
return {
  images: [...document.images].map(i => ({src: i.src.slice(0, 40), complete: i.complete,
                                           width: i.naturalWidth, height: i.naturalHeight})),
  resources: performance.getEntriesByType('resource').map(r => r.name),
  scripts: document.scripts.length,
  links: [...document.querySelectorAll('link')].map(l => l.href),
  title: document.title,
};
"""


def _fit_viewport(driver, width, height):
    """Resize the window so that the page itself (the first screen) is ``width x height``
    CSS px: the window size includes the browser's own bars."""
    inner = driver.execute_script("return [window.innerWidth, window.innerHeight];")
    driver.set_window_size(2 * width - inner[0], 2 * height - inner[1])


_RECTS = """
return Object.fromEntries(arguments[0].map(s => [s, [...document.querySelectorAll(s)].map(
  e => { const r = e.getBoundingClientRect(); return {top: r.top, bottom: r.bottom,
                                                      left: r.left, right: r.right}; })]));
"""


def open_page(html_path, screenshot=None, width=1200, height=1600, selectors=()):
    """Load ``html_path``; return the images' load state (and whether each decodes), the
    fetched resources and the console log (list of ``{"level", "message"}``); optionally
    save a screenshot PNG. ``selectors``: CSS selectors whose elements' bounding boxes
    (CSS px, relative to the top of the page as first shown) are returned as ``rects``,
    with the first screen's size as ``viewport`` (``width x height`` CSS px)."""
    with tempfile.TemporaryDirectory() as profile:
        driver = _driver(width, height, profile)
        try:
            _fit_viewport(driver, width, height)
            driver.get(Path(html_path).resolve().as_uri())
            decoded = driver.execute_async_script(
                "const done = arguments[arguments.length - 1];"
                "Promise.all([...document.images].map(i => i.decode().then(() => true,"
                " () => false))).then(done);"
            )
            state = driver.execute_script(_PAGE_STATE)
            state["console"] = driver.get_log("browser")
            state["decoded"] = decoded  # img.decode() resolved: the whole image decodes
            state["rects"] = driver.execute_script(_RECTS, list(selectors))
            state["viewport"] = driver.execute_script(
                "return [window.innerWidth, window.innerHeight];"
            )
            if screenshot is not None:
                driver.save_screenshot(str(screenshot))
            return state
        finally:
            driver.quit()
