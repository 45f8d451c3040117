"""Shared helpers of the figure scripts: command line, output folder, JSON, figures.

Every script is ``python analysis/<name>.py [--fast] [--out DIR]``; it writes PNGs and one
``<name>.json`` of the numbers it compared (paper vs leolink) into ``DIR``
(default ``analysis/out/``) and prints those numbers.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PAPER_CONFIG = REPO / "configs" / "paper.toml"
DEFAULT_OUT = REPO / "analysis" / "out"
DPI = 110


def parse_args(argv, doc):
    """``--fast`` and ``--out DIR`` (created)."""
    p = argparse.ArgumentParser(description=(doc or "").splitlines()[0])
    p.add_argument("--fast", action="store_true", help="small grids / few trials (seconds)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    return args


def paper_config(overrides=None):
    """``configs/paper.toml`` with optional ``section.key=value`` overrides."""
    from leolink.config import load_config

    return load_config(PAPER_CONFIG, overrides)


def figure(n_rows=1, n_cols=1, figsize=(7.0, 5.0), **kw):
    """An Agg figure (no pyplot state) and its 2-D array of axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(n_rows, n_cols, squeeze=False, **kw)


def save(fig, out_dir, name):
    """Write ``out_dir/name`` and return its path."""
    path = Path(out_dir) / name
    fig.savefig(path, dpi=DPI)
    fig.clear()
    return path


def roi_outline(ax, rx_m, ry_m, **kw):
    """Dashed ROI ellipse in km axes."""
    t = np.linspace(0.0, 2.0 * np.pi, 361)
    style = {"color": "black", "linestyle": "--", "linewidth": 1.2}
    style.update(kw)
    ax.plot(rx_m * 1e-3 * np.cos(t), ry_m * 1e-3 * np.sin(t), **style)


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def report(out_dir, name, numbers, pngs):
    """Write ``out_dir/name.json`` ({"numbers", "pngs"}), print the numbers, return the dict."""
    data = _jsonable({"script": name, "numbers": numbers, "pngs": [Path(p).name for p in pngs]})
    path = Path(out_dir) / f"{name}.json"
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    print(f"== {name}")
    for key, value in data["numbers"].items():
        print(f"  {key}: {json.dumps(value)}")
    print(f"  -> {path} and {', '.join(data['pngs'])}")
    return data
