"""The example configs that ship with leolink, with their TLE and track files.

These files are the one copy of the examples: a clone's ``configs/`` holds links to them
(``configs/paper.toml`` is ``src/leolink/examples/paper.toml``). Every command that takes
a CONFIG also takes an example's name (``leolink run paper --out out/paper``): a file of
that path wins over a name (:func:`resolve`, called by :func:`leolink.config.load_config`).
``leolink examples`` lists them and ``leolink init NAME [DIR]`` copies one
(:func:`copy_example`).
"""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

from leolink.errors import ConfigError, LeolinkError

__all__ = ["EXAMPLES", "copy_example", "example_path", "resolve"]

HERE = Path(__file__).resolve().parent

#: Example name -> one line on what it shows (the file is ``NAME.toml`` in this folder).
EXAMPLES: dict[str, str] = {
    "paper": "the paper's Table: one satellite passing over Vigo, 7 static and moving UTs, 120 s",
    "constellation": "the paper's 4,399-satellite Walker constellation, 1,000 UTs, 600 s",
    "car": "five cars at 30 m/s crossing the ROI in random directions, 120 s",
    "train": "a train at 100 m/s on waypoints through the ROI centre, and a static station",
    "town": "a car through a town (TR 38.811 LoS, shadowing, clutter), in open country, a train",
    "ship": "a ship replayed from a recorded track, Kymeta-like metasurface terminal",
    "aircraft": "three aircraft at 10 km and 250 m/s flying against the satellite track",
    "walker": "a 12 x 10 Walker constellation, 4 static UTs: satellite handovers, 600 s",
    "tle": "the ISS from a real TLE (sgp4, UTC, rotating Earth), 2 static UTs",
    "hysteresis": "the paper's scenario with a hysteresis controller (3 dB, 2 s, 0.1 s handover)",
    "leo600_ka_dl": "3GPP TR 38.821 Set-1 LEO-600 Ka-band downlink to a VSAT (leolink budget)",
    "leo600_s_dl": "3GPP TR 38.821 Set-1 LEO-600 S-band downlink to a handheld (leolink budget)",
    "sls_leo600_set1_ka_reuse1": "TR 38.821 system-level calibration, LEO-600 Set-1 Ka, reuse 1",
    "sls_leo600_set1_ka_reuse3": "TR 38.821 system-level calibration, LEO-600 Set-1 Ka, reuse 3",
    "sls_leo600_set1_s_reuse1": "TR 38.821 system-level calibration, LEO-600 Set-1 S, reuse 1",
    "sls_leo600_set1_s_reuse3": "TR 38.821 system-level calibration, LEO-600 Set-1 S, reuse 3",
    "global": "the paper's 4,399 satellites over UTs on a 2 deg grid over land, 600 s",
    "starlink_like": "a 72 x 22 shell at 550 km, satellites reassigned on a 15 s grid, 300 s",
}


def example_path(name: str) -> Path:
    """The packaged TOML file of example ``name``.

    Raises
    ------
    ConfigError
        ``name`` is not an example (the message lists them).
    """
    if name not in EXAMPLES:
        raise ConfigError(f"{name!r} is not an example; use one of {', '.join(EXAMPLES)}")
    return HERE / f"{name}.toml"


def resolve(config: str | Path) -> Path:
    """The config file that ``config`` names: a path to a file as given, else an example.

    Raises
    ------
    ConfigError
        ``config`` is a bare name (no folder, no ``.toml``) that is neither a file nor an
        example. Any other missing path is returned as it is (its reader says so).
    """
    path = Path(config)
    if path.exists():
        return path
    if str(config) in EXAMPLES:
        return example_path(str(config))
    if len(path.parts) == 1 and not path.suffix:
        raise ConfigError(
            f"{str(config)!r} is neither a config file nor an example; examples (leolink "
            f"examples): {', '.join(EXAMPLES)}"
        )
    return path


def copy_example(name: str, folder: str | Path = ".") -> list[Path]:
    """Copy example ``name`` and the files it reads (``*_file`` keys) into ``folder``.

    Parameters
    ----------
    name : str
        An example's name (a key of :data:`EXAMPLES`).
    folder : str or Path
        Where the copy goes; made if missing. The TLE and track files keep their paths
        relative to the config (``tles/iss.tle``), so the copy runs as it is.

    Returns
    -------
    list of Path
        The files written, the config first.

    Raises
    ------
    LeolinkError
        One of the files exists already: nothing is written.
    """
    source = example_path(name)
    relative = [Path(source.name), *_referenced_files(tomllib.loads(source.read_text("utf-8")))]
    targets = [Path(folder) / r for r in relative]
    existing = [str(t) for t in targets if t.exists()]
    if existing:
        raise LeolinkError(
            f"{existing[0]} exists already; leolink init never overwrites: remove it or "
            "choose another folder"
        )
    for rel, target in zip(relative, targets, strict=True):
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(HERE / rel, target)
    return targets


def _referenced_files(node) -> list[Path]:
    """The relative paths of the ``*_file`` keys (load_config reads them relative to the
    config's folder)."""
    if isinstance(node, dict):
        found = []
        for key, value in node.items():
            if key.endswith("_file") and isinstance(value, str) and value:
                found.append(Path(value))
            else:
                found += _referenced_files(value)
        return found
    if isinstance(node, list):
        return [p for item in node for p in _referenced_files(item)]
    return []
