"""``leolink sweep``: run a grid of config values and tabulate the run summaries.

A parameter is given as ``section.key=v1,v2,...``; each value is parsed as a TOML value
(as ``--set`` does: ``3``, ``0.5``, ``true``, ``"hysteresis"``; a bare word is a string).
The grid is the Cartesian product of the parameters, in the order given (the last
parameter varies fastest). Every point is validated before anything runs, then each
point is one :func:`leolink.app.run.run` into ``out_dir/runs/<point name>``. At the very
end: the table (one row per point: the swept values and the flattened
``summary["overall"]``) as ``sweep.csv`` and ``sweep.json``, ``report.html``, and last the
manifest ``run.json``: an interrupted sweep never leaves a folder that looks finished. A
folder holding an earlier sweep is refused unless ``overwrite`` or ``resume``.

Each run is deterministic from its config (``run.seed``), so the table does not depend on
``workers`` or on the order in which points finish.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
import tomllib
from pathlib import Path

import pandas as pd
import tomli_w

from leolink import examples
from leolink.config.overrides import loads_toml
from leolink.errors import ConfigError, LeolinkError

__all__ = [
    "SWEEP_PLOT_METRICS",
    "Execution",
    "flatten_summary",
    "parse_param",
    "point_name",
    "run_sweep",
]

#: Metrics drawn by ``plot_sweep`` when exactly one parameter is swept.
SWEEP_PLOT_METRICS = (
    "snr_db_mean",
    "sinr_db_mean",
    "beam_handovers",
    "sat_handovers",
    "outage_fraction",
    "mean_throughput_bps",
)
MAX_NAME_CHARS = 120  # point folder names are cut here (the index prefix keeps them unique)
_UNSAFE = re.compile(r"[^A-Za-z0-9._=+-]+")


# --------------------------------------------------------------------------- the grid
def parse_param(spec):
    """Split ``section.key=v1,v2,...`` into the key and its list of values.

    Parameters
    ----------
    spec : str
        E.g. ``"controller.hysteresis_db=0,1.5,3"`` or ``"controller.policy=max_snr,hysteresis"``.

    Returns
    -------
    key : str
    values : list
        Python values as TOML reads them (int, float, bool, str, list).

    Raises
    ------
    ConfigError
        No ``=``, an empty key, an empty value list or an empty value.
    """
    key, sep, raw = spec.partition("=")
    key = key.strip()
    if not sep or not key or any(not part for part in key.split(".")):
        raise ConfigError(f"--param {spec!r} is not allowed: use section.key=v1,v2,...")
    try:  # the whole list as one TOML array handles quoted strings holding commas
        values = loads_toml(f"v = [{raw}]", f"--param {key}")["v"]
    except tomllib.TOMLDecodeError:
        values = [_scalar(item, key) for item in raw.split(",")]
    if not values:
        raise ConfigError(f"--param {key}: no values given; use {key}=v1,v2,...")
    return key, values


def _scalar(item, key):
    """One value as ``--set`` reads it: TOML if it parses, else the bare string."""
    item = item.strip()
    if not item:
        raise ConfigError(f"--param {key}: an empty value in the list is not allowed")
    try:
        return loads_toml(f"v = {item}", f"--param {key}")["v"]
    except tomllib.TOMLDecodeError:
        return item


def _toml_value(value):
    """``value`` written as a TOML literal on one line (round-trips through ``tomllib``)."""
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return tomli_w.dumps({"v": value}).partition("=")[2].strip()


def _text(value):
    """``value`` for a folder name: strings bare, everything else as its TOML literal."""
    return value if isinstance(value, str) else _toml_value(value)


def point_name(index, point, width=4):
    """Filesystem-safe folder name of grid point ``index`` (``point``: ``{key: value}``),
    e.g. ``0003_controller.hysteresis_db=3``: the index zero-padded to ``width`` digits,
    only ``A-Z a-z 0-9 . _ = + -``, at most ``MAX_NAME_CHARS`` characters."""
    body = "_".join(f"{k}={_text(v)}" for k, v in point.items())
    name = _UNSAFE.sub("_", f"{index:0{width}d}_{body}")
    return name[:MAX_NAME_CHARS]


def _grid(params):
    """Parsed parameters -> (keys, list of {key: value} points, Cartesian product)."""
    parsed = [parse_param(spec) for spec in params]
    keys = [k for k, _ in parsed]
    dup = {k for k in keys if keys.count(k) > 1}
    if dup:
        raise ConfigError(f"--param {sorted(dup)[0]} is given twice; give all its values once")
    from leolink.app.sweep_exec import check_runs

    check_runs(math.prod(len(v) for _, v in parsed), "--param " + " x ".join(keys))
    combos = itertools.product(*(values for _, values in parsed))
    return keys, [dict(zip(keys, combo, strict=True)) for combo in combos]


def _overrides(point):
    return [f"{k}={_toml_value(v)}" for k, v in point.items()]


# --------------------------------------------------------------------------- the table
def flatten_summary(overall):
    """One flat row (dict of str to int or float) of ``summary["overall"]`` (``overall``,
    or the same read back from ``summary.json``).

    Nested sections are joined with ``_`` at every level (``snr_db.p5`` -> ``snr_db_p5``,
    ``link.margin_db.p5`` -> ``link_margin_db_p5``; ``link.modcod_usage`` is left out);
    handover counts become plural (``handovers.beam_handover`` -> ``beam_handovers``,
    ``handovers_total`` kept). ``None`` (a statistic of nothing, e.g. the mean dwell
    without a complete dwell) becomes NaN.
    """
    row = {}
    for key, value in overall.items():
        if key == "handovers":
            for kind, count in value.items():
                row[kind if kind.endswith(("s", "total")) else f"{kind}s"] = count
        else:
            _flatten_into(row, key, value)
    return {k: math.nan if v is None else _plain(v) for k, v in row.items()}


def _flatten_into(row, prefix, value):
    # Lists (all dwell times) and the MODCOD usage (keys vary by run) stay in summary.json.
    if isinstance(value, dict):
        for sub, item in value.items():
            if sub != "modcod_usage":
                _flatten_into(row, f"{prefix}_{sub}", item)
    elif not isinstance(value, list):
        row[prefix] = value


def _plain(value):
    return value.item() if hasattr(value, "item") else value


# --------------------------------------------------------------------------- one point
def _run_point(cfg_path, overrides, run_dir, resume):
    """Run (or, with ``resume``, reuse) one point; return its flat metrics row.

    Top-level so that :class:`~concurrent.futures.ProcessPoolExecutor` can pickle it.
    A folder is reused only if it holds a finished run (its ``run.json``, written last)
    of this point's config (the manifest's config hash); otherwise it is run again,
    replacing what an earlier or interrupted run left there.
    """
    import json

    from leolink.app.run import run
    from leolink.config import dump_toml, load_config
    from leolink.io.run_dir import config_sha256, read_manifest

    cfg = load_config(cfg_path, overrides)
    run_dir = Path(run_dir)
    if resume and run_dir.is_dir():
        manifest = read_manifest(run_dir)
        if manifest and manifest.get("config_sha256") == config_sha256(dump_toml(cfg)):
            summary = json.loads((run_dir / "summary.json").read_text("utf-8"))
            return flatten_summary(summary["overall"])
    result = run(cfg, out_dir=run_dir, overwrite=True)  # the sweep owns its runs/ folder
    return flatten_summary(result.summary["overall"])


# --------------------------------------------------------------------------- executors
def _progress_bar(n, enabled, desc="leolink sweep", unit="point"):
    from tqdm.auto import tqdm

    return tqdm(total=n, unit=unit, desc=desc, disable=not enabled, leave=False)


# --------------------------------------------------------------------------- the sweep
def _validated_points(cfg_path, points, base):
    """Check every point as ``leolink validate`` does, before anything runs.

    Returns ``{index: message}`` of the points that fail (they get a row with their
    ``error``, the others run); raises if every point fails (nothing would run).
    """
    from leolink.app.validate import checked_scenario
    from leolink.config import load_config

    errors = {}
    for i, point in enumerate(points):
        try:
            checked_scenario(load_config(cfg_path, base + _overrides(point)))
        except LeolinkError as exc:
            where = ", ".join(f"{k}={_text(v)}" for k, v in point.items())
            errors[i] = f"sweep point {where}: {exc}"
    if len(errors) == len(points):
        raise ConfigError(errors[0] if len(points) == 1 else f"every point fails; {errors[0]}")
    return errors


def _base_overrides(base_overrides, keys, run_plots):
    """The user's overrides, plus ``output.plots.enabled=false`` and
    ``output.report.enabled=false`` unless plots (or that output) were asked for."""
    base = list(base_overrides or [])
    for key in ("output.plots.enabled", "output.report.enabled"):
        asked = key in keys or any(o.partition("=")[0].strip() == key for o in base)
        if not run_plots and not asked:
            base.append(f"{key}=false")
    return base


@dataclasses.dataclass(frozen=True)
class Execution:
    """How a study (:func:`run_sweep`, :func:`leolink.app.compare.run_compare`) runs its
    points and treats its folder.

    Attributes
    ----------
    workers : int or str
        Local processes (``1`` runs in this process), or ``"dask://<scheduler address>"``.
    progress : bool
        Show a progress bar over the points (stderr).
    resume : bool
        Reuse the finished runs (``run.json``) of the same point configs in ``out_dir``.
    overwrite : bool
        Replace an earlier study's files in ``out_dir`` (only leolink's files are removed);
        without it (or ``resume``) such a folder raises ``OutputFolderError``.
    plot : bool
        Draw the study's figures.
    """

    workers: int | str = 1
    progress: bool = True
    resume: bool = False
    overwrite: bool = False
    plot: bool = True


def run_sweep(cfg_path, params, out_dir, base_overrides=None, *, run_plots=False, how=None):
    """Run every point of a parameter grid and tabulate the summaries.

    Parameters
    ----------
    cfg_path : path-like
        TOML config file (e.g. ``configs/paper.toml``), or an example's name (``paper``).
    params : list of str
        ``section.key=v1,v2,...``, one per swept parameter; the grid is their product.
    out_dir : path-like
        Output folder: ``runs/<point name>/`` per point, ``sweep.csv``, ``sweep.json`` and,
        with one parameter, ``sweep_<section>_<key>.png``.
    base_overrides : list of str, optional
        ``section.key=value`` overrides applied to every point (before the swept values).
    run_plots : bool
        Write each run's own plots and report (off by default, for speed; also on if
        ``output.plots.enabled`` / ``output.report.enabled`` is set explicitly in
        ``base_overrides`` or ``params``).
    how : Execution, optional
        Workers, progress bar, resume or overwrite, and the plot of the main metrics
        against the parameter (drawn when exactly one is swept); None: the defaults.

    Returns
    -------
    pandas.DataFrame
        One row per point in grid order: ``point`` (folder name under ``runs/``), the swept
        parameters (columns ``section.key``), the flattened summary (:func:`flatten_summary`).

    Raises
    ------
    ConfigError
        A bad parameter, value list or ``workers``, or an invalid point; before any run.
    """
    from leolink.app.sweep_exec import check_workers, run_jobs

    how = Execution() if how is None else how
    check_workers(how.workers)
    # Absolute paths: workers (dask's, on other machines' working directories) resolve
    # the config's own relative paths from its folder, and write where this process does.
    cfg_path, out_dir = examples.resolve(cfg_path).resolve(), Path(out_dir).absolute()
    keys, points = _grid(params)
    base = _base_overrides(base_overrides, keys, run_plots)
    failed = _validated_points(cfg_path, points, base)

    from leolink.io.run_dir import claim_out_dir

    # An earlier sweep's tables and page go first (resumed: its point runs stay).
    out_dir = claim_out_dir(
        out_dir,
        how.overwrite or how.resume,
        flag="--overwrite (or --resume, to reuse its finished points)",
        keep=("runs",) if how.resume else (),
    )
    width = max(4, len(str(len(points) - 1)))
    names = [point_name(i, p, width) for i, p in enumerate(points)]
    jobs = [
        (i, (str(cfg_path), base + _overrides(p), str(out_dir / "runs" / names[i]), how.resume))
        for i, p in enumerate(points)
        if i not in failed
    ]
    finished: list[int] = []
    with _progress_bar(len(points), how.progress) as bar:
        bar.update(len(failed))
        try:
            rows = run_jobs(
                _run_point, jobs, lambda i: (finished.append(i), bar.update(1)), how.workers
            )
        except KeyboardInterrupt as exc:
            exc.add_note(_stopped_note(finished, len(jobs), names, out_dir))
            raise
    rows.update({i: {"error": message} for i, message in failed.items()})
    table = pd.DataFrame([{"point": names[i], **points[i], **rows[i]} for i in range(len(points))])
    if "error" in table:  # only when a point failed: "" for the others
        table["error"] = table["error"].fillna("").astype(str)
    _write(table, out_dir, cfg_path, (params, keys, base), names, how.plot)
    return table


def _stopped_note(finished, n_jobs, names, out_dir):
    done = ", ".join(names[i] for i in sorted(finished)[:3]) + (" ..." if len(finished) > 3 else "")
    return (
        f"the sweep stopped with {len(finished)} of {n_jobs} points finished"
        + (f" ({done})" if finished else "")
        + f"; {out_dir} has no sweep.csv yet; rerun with --resume to reuse the finished points"
    )


def _write(table, out_dir, cfg_path, spec, names, plot):
    """``sweep.json``, ``sweep.csv``, the plot (one parameter), ``report.html``, and last
    ``run.json`` (the tables, the page and every point's own ``run.json``)."""
    import leolink
    from leolink.app.guard import raise_pending
    from leolink.config import dump_toml, load_config
    from leolink.io.atomic import write_csv_atomic, write_json_atomic
    from leolink.io.report.page import build_table_report
    from leolink.io.run_dir import write_manifest

    params, keys, base = spec
    head = {"config": str(cfg_path), "base_overrides": base, "params": keys}
    files = [
        write_json_atomic(out_dir / "sweep.json", {**head, "points": table.to_dict("records")}),
        write_csv_atomic(table, out_dir / "sweep.csv"),
    ]
    files += _plot(table, out_dir, keys[0]) if plot and len(keys) == 1 else []
    config_text = dump_toml(load_config(cfg_path, base))
    figures = [(p.stem.replace("_", " "), p) for p in files if p.suffix == ".png"]
    notes = f"{len(table)} points; the run of each is in runs/<point>/ (column 'point')."
    page = build_table_report(
        out_dir / "report.html", "leolink sweep report", table, figures, config_text, notes
    )
    ok = list(table["error"] == "") if "error" in table else [True] * len(names)
    runs = [
        out_dir / "runs" / name / "run.json" for name, good in zip(names, ok, strict=True) if good
    ]
    arguments = {"params": list(params), "base_overrides": base}
    raise_pending()  # a stop caught inside a library: no manifest (leolink.app.guard)
    write_manifest(
        out_dir, [*files, page, *runs], "sweep", config_text, arguments, version=leolink.__version__
    )


def _plot(table, out_dir, x):
    """Main metrics vs the swept parameter; skipped if its values mix strings and numbers."""
    from leolink.io.plots import plot_sweep

    kinds = {isinstance(v, str) for v in table[x]}
    if len(kinds) > 1:
        return []
    ys = [y for y in SWEEP_PLOT_METRICS if y in table.columns]
    return plot_sweep(table, out_dir, x, ys)
