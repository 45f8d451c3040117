"""Plug-ins from outside: a pip-installed package registers a kind through the
``leolink.plugins`` entry-point group and ``leolink run`` uses it with no other step.

The package is built here, in a temporary folder: a ``pyproject.toml``, a module that
registers a terminal, and an in-tree PEP 517 backend that writes the wheel (so the test
needs no build tool beyond pip, and no network). It is installed into the interpreter
running the tests and uninstalled afterwards.
"""

from __future__ import annotations

import csv
import subprocess
import sys
import textwrap

import numpy as np
import pytest

DIST = "leolink-test-dish-plugin"
MODULE = "leolink_test_dish_plugin"
KIND = "test_dish"
#: The plugin terminal's gain [dB]: no built-in terminal of configs/paper.toml has it.
DISH_GAIN_DB = 27.25

PLUGIN = f'''
import numpy as np
from pydantic import Field

from leolink.antenna.terminal import TERMINALS
from leolink.registry import Params


class DishConfig(Params):
    gain_db: float = Field({DISH_GAIN_DB}, description="gain towards the satellite [dB]")


@TERMINALS.register("{KIND}", config=DishConfig)
class Dish:
    """A tracking dish (a test plugin): its gain towards the serving satellite."""

    elevation_independent = True
    pattern_lin = None

    def __init__(self, gain_db):
        self.gain_db_ = gain_db

    def gain_db(self, elevation_rad, off_boresight_rad=0.0, error_azimuth_rad=0.0):
        shape = np.broadcast(elevation_rad, off_boresight_rad).shape
        return np.full(shape, self.gain_db_)
'''

PYPROJECT = f"""
[build-system]
requires = []
build-backend = "wheel_backend"
backend-path = ["."]

[project]
name = "{DIST}"
version = "0.1"

[project.entry-points."leolink.plugins"]
dish = "{MODULE}"
"""

# A PEP 517 backend in 20 lines: the module, and the dist-info with the entry point.
BACKEND = f'''
import zipfile

NAME, VERSION = "{MODULE}", "0.1"
INFO = f"{{NAME}}-{{VERSION}}.dist-info"


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    wheel = f"{{NAME}}-{{VERSION}}-py3-none-any.whl"
    files = {{
        f"{{NAME}}.py": open(f"{{NAME}}.py").read(),
        f"{{INFO}}/METADATA": "Metadata-Version: 2.1\\nName: {DIST}\\nVersion: 0.1\\n",
        f"{{INFO}}/WHEEL": "Wheel-Version: 1.0\\nGenerator: test\\nRoot-Is-Purelib: true\\n"
        "Tag: py3-none-any\\n",
        f"{{INFO}}/entry_points.txt": "[leolink.plugins]\\ndish = {MODULE}\\n",
    }}
    files[f"{{INFO}}/RECORD"] = "".join(f"{{n}},,\\n" for n in files) + f"{{INFO}}/RECORD,,\\n"
    with zipfile.ZipFile(f"{{wheel_directory}}/{{wheel}}", "w") as z:
        for name, text in files.items():
            z.writestr(name, text)
    return wheel
'''


def _pip(*args):
    return subprocess.run(
        [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args],
        capture_output=True,
        text=True,
        check=False,
    )


@pytest.fixture
def installed_plugin(tmp_path_factory):
    src = tmp_path_factory.mktemp("plugin")
    (src / "pyproject.toml").write_text(textwrap.dedent(PYPROJECT))
    (src / "wheel_backend.py").write_text(textwrap.dedent(BACKEND))
    (src / f"{MODULE}.py").write_text(textwrap.dedent(PLUGIN))
    got = _pip("install", "--no-deps", "--no-build-isolation", "--no-index", str(src))
    assert got.returncode == 0, got.stderr
    yield
    got = _pip("uninstall", "-y", DIST)
    assert got.returncode == 0, got.stderr


def _leolink(*args):
    """The ``leolink`` command, in a new process (which finds the installed plugins)."""
    return subprocess.run(
        [sys.executable, "-m", "leolink.cli", *args], capture_output=True, text=True, check=False
    )


def test_an_installed_plugin_terminal_is_used_by_leolink_run(installed_plugin, tmp_path):
    out = tmp_path / "run"
    sets = [f"terminal.kind={KIND}", "run.duration_s=4", "output.plots.enabled=false",
            "output.report.enabled=false"]  # fmt: skip
    got = _leolink("run", "configs/paper.toml", "--out", str(out), "--quiet",
                   *(a for s in sets for a in ("--set", s)))  # fmt: skip
    assert got.returncode == 0, got.stderr
    with open(out / "trace.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    served = [float(r["gain_rx_db"]) for r in rows if int(r["sat_id"]) >= 0]
    assert served and np.allclose(served, DISH_GAIN_DB, rtol=0.0, atol=1e-9)
    assert f'kind = "{KIND}"' in (out / "config.resolved.toml").read_text()
    # validate sees it too, and its parameters are checked like a built-in kind's
    got = _leolink("validate", "configs/paper.toml", "--set", f"terminal.kind={KIND}",
                   "--set", f"terminal.{KIND}.gain_db=nan")  # fmt: skip
    assert got.returncode == 2 and f"terminal.{KIND}.gain_db" in got.stderr


def test_without_the_plugin_the_kind_is_refused(tmp_path):
    got = _leolink("validate", "configs/paper.toml", "--set", f"terminal.kind={KIND}")
    assert got.returncode == 2 and f"terminal.kind = '{KIND}' is not allowed" in got.stderr


def test_a_plugin_that_fails_to_load_is_one_line_naming_it(monkeypatch):
    from importlib.metadata import EntryPoint

    from leolink.config import kinds
    from leolink.errors import ConfigError

    broken = EntryPoint("broken", "leolink_no_such_plugin_module", kinds.PLUGIN_GROUP)
    monkeypatch.setattr(kinds.importlib.metadata, "entry_points", lambda group: [broken])
    kinds._load_plugins.cache_clear()
    try:
        with pytest.raises(ConfigError, match=r"^plugin 'broken' \(leolink.plugins entry point "
                           r"'leolink_no_such_plugin_module'\) failed to load: "
                           r"ModuleNotFoundError"):  # fmt: skip
            kinds.load_owners()
    finally:
        monkeypatch.undo()
        kinds._load_plugins.cache_clear()  # the real entry points, next time
