"""``leolink compare``: the same scenario under several policies, on the same seeds.

A policy is given as ``NAME`` or ``NAME,KEY=VALUE,...`` (``KEY`` relative to
``controller.<NAME>``, e.g. ``a3,hysteresis_db=2,time_to_trigger_s=0.5`` or
``cho,prepare.offset_db=-2``, or a full key starting with a section, ``kpi.ping_pong_s``).
Every policy runs on the seeds ``run.seed``, ``run.seed + 1``, ... (``seeds`` of them):
a seed fixes the UT placement, headings and fading draws, which do not depend on the
policy, so every policy sees identical UT tracks, ephemeris and fading. Runs go to
``out_dir/runs/<policy>__seed<seed>`` (through the machinery of :mod:`leolink.app.sweep`:
validated first, serial, local processes or dask). A folder holding an earlier compare is
refused unless ``overwrite`` or ``resume``.

Outputs (written at the end, the manifest ``run.json`` last, as for a run):

- ``compare_runs.csv``: one row per (policy, seed), the flattened overall summary;
- ``compare.csv``: one row per policy, column ``policy``, ``n_seeds``, and for every
  numeric summary column its mean over seeds and ``<column>_std`` (sample standard
  deviation); a column empty for every policy (every ``_std`` with one seed, a KPI no
  run reports) is left out;
- ``compare.md``: the main KPIs as a table (mean +- std), with a legend (rates, counts
  and fractions named as such; SINR over the served UT-epochs) and every policy's
  parameters in effect;
- ``compare_kpis.png``, ``compare_tradeoff.png``, ``compare_sinr_cdf.png`` (the SINR of
  every UT-epoch of every seed, read back from each run's trace);
- ``run.json``: the files above and every run's own ``run.json``, with sizes and SHA-256.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from leolink import examples
from leolink.app.guard import raise_pending
from leolink.app.sweep import Execution, _base_overrides, _progress_bar, _run_point
from leolink.errors import ConfigError

__all__ = ["MAIN_KPIS", "parse_policy", "policy_conditions", "policy_twins", "run_compare"]

#: (column of compare.csv, heading, scale, format, legend) of the report table: rates per
#: UT-minute, counts per run, fractions in [0, 1], as each heading says.
MAIN_KPIS = (
    ("kpi_handover_rate_per_ut_min", "handovers /UT-min", 1.0, "{:.3f}",
     "handovers (beam and satellite) per UT-minute: a rate"),
    ("kpi_handover_rate_per_ut_min_by_kind_sat_handover", "sat handovers /UT-min", 1.0,
     "{:.3f}", "satellite changes per UT-minute: a rate"),
    ("kpi_ping_pong_count", "ping-pongs (cell)", 1.0, "{:.1f}",
     "handovers back to the cell left less than kpi.ping_pong_s before: a count per run"),
    ("kpi_ping_pong_fraction", "ping-pong fraction (cell)", 1.0, "{:.3f}",
     "ping-pongs (cell) / handovers: a fraction in [0, 1]"),
    ("kpi_ping_pong_fraction_satellite", "ping-pong fraction (sat)", 1.0, "{:.3f}",
     "the same on satellites (a return to the satellite left): a fraction in [0, 1]"),
    ("kpi_rlf_count", "RLFs", 1.0, "{:.1f}", "radio link failures: a count per run"),
    ("kpi_handover_failure_count", "handover failures", 1.0, "{:.1f}",
     "handovers that failed (T304, target below Q_out): a count per run"),
    ("kpi_too_early_count", "too early", 1.0, "{:.1f}",
     "too-early handovers (TS 38.300 15.5.2.2.2, window kpi.mro_window_s): a count per run"),
    ("kpi_too_late_count", "too late", 1.0, "{:.1f}", "too-late handovers: a count per run"),
    ("kpi_mean_time_of_stay_s_beam", "stay beam [s]", 1.0, "{:.1f}",
     "mean time of stay in a beam, completed stays only [s]"),
    ("kpi_mean_time_of_stay_s_satellite", "stay sat [s]", 1.0, "{:.1f}",
     "mean time of stay on a satellite, completed stays only [s]"),
    ("outage_fraction", "outage fraction", 1.0, "{:.4f}",
     "unserved UT-epochs / UT-epochs: a fraction in [0, 1]"),
    ("kpi_sinr_db_percentiles_served_p5", "served SINR p5 [dB]", 1.0, "{:.2f}",
     "5th percentile of the SINR of the served UT-epochs (outage left out) [dB]"),
    ("kpi_sinr_db_percentiles_served_p50", "served SINR p50 [dB]", 1.0, "{:.2f}",
     "median SINR of the served UT-epochs [dB]"),
    ("mean_throughput_bps", "throughput [Mb/s]", 1e-6, "{:.1f}",
     "mean throughput per UT-epoch, unserved epochs at 0 [Mb/s]"),
)  # fmt: skip
_SAFE = re.compile(r"[^A-Za-z0-9._=+-]+")


def parse_policy(spec):
    """``NAME[,KEY=VALUE...]`` -> ``(label, overrides)``; the label is the spec itself."""
    parts = [p.strip() for p in spec.split(",")]
    name = parts[0]
    if not name or not name.isidentifier():
        raise ConfigError(f"--policy {spec!r} is not allowed: use NAME or NAME,KEY=VALUE,...")
    overrides = [f"controller.policy={name}"]
    for part in parts[1:]:
        key, sep, value = part.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--policy {spec!r}: {part!r} is not KEY=VALUE")
        key = key.strip()
        if key.split(".")[0] not in _sections():  # relative to [controller.<name>]
            key = f"controller.{name}.{key}"
        overrides.append(f"{key}={value.strip()}")
    return spec, overrides


def _sections():
    from leolink.config import config_model

    return set(config_model().model_fields)


def _behaviour(cfg):
    """What decides a run's rows: the policy a config's parameters make (a policy's
    ``same_as()``, else itself with its parameters) and every other key of the config."""
    ctl = cfg.controller
    name, params = ctl.chosen, ctl.params.model_dump(mode="json")
    simpler = getattr(ctl.build(), "same_as", lambda: None)()
    if simpler is not None:
        name, params = simpler, getattr(ctl, simpler).model_dump(mode="json")
    rest = cfg.model_dump(mode="json")
    for key in ("policy", *ctl.registry.names()):  # every policy's own table
        rest["controller"].pop(key, None)
    return json.dumps([name, params, rest], sort_keys=True), name


def policy_twins(cfg_path, specs, base=()):
    """One line for each policy of ``specs`` whose parameters make it the same policy as
    an earlier one in the list, or as a simpler one (``hysteresis`` with 0 dB and 0 s is
    ``max_snr``): its rows would repeat that policy's."""
    from leolink.config import load_config

    seen, lines = {}, []
    for label, overrides in map(parse_policy, specs):
        key, name = _behaviour(load_config(cfg_path, [*base, *overrides]))
        if key in seen:
            lines.append(f"policy {label} is identical to {seen[key]} (the same parameters "
                         f"in effect): its rows will repeat {seen[key]}'s")  # fmt: skip
        elif name != label.split(",")[0]:
            lines.append(f"policy {label} with these parameters is {name}: its rows will be "
                         f"{name}'s")  # fmt: skip
        seen.setdefault(key, label)
    return lines


def _jobs(cfg_path, specs, seeds, base, out_dir, resume):
    """Validated (policy label, seed, job) triples."""
    from leolink.config import load_config

    base_seed = load_config(cfg_path, base).run.seed
    labels = [parse_policy(s) for s in specs]
    if len({lab for lab, _ in labels}) != len(labels):
        raise ConfigError("--policy: a policy is given twice")
    rows = []
    for label, overrides in labels:
        for k in range(seeds):
            seed = base_seed + k
            full = [*base, *overrides, f"run.seed={seed}"]
            try:
                load_config(cfg_path, full)
            except ConfigError as exc:
                raise ConfigError(f"policy {label}: {exc}") from None
            run_dir = out_dir / "runs" / _SAFE.sub("_", f"{label}__seed{seed}")
            rows.append((label, seed, (str(cfg_path), full, str(run_dir), resume)))
    return rows


def _aggregate(runs):
    """compare.csv from compare_runs.csv: mean and std over seeds, policies in order;
    a column empty for every policy (a spread of one seed, a KPI no run has) is left out."""
    numeric = [c for c in runs.columns if c not in ("policy", "seed", "run")]
    numeric = [c for c in numeric if pd.api.types.is_numeric_dtype(runs[c])]
    groups = runs.groupby("policy", sort=False)
    mean, std = groups[numeric].mean(), groups[numeric].std(ddof=1)
    table = pd.concat([mean, std.add_suffix("_std")], axis=1)
    table = table.loc[:, table.notna().any()]
    table.insert(0, "n_seeds", groups.size())
    return table.reset_index()


def _cdfs(runs):
    """SINR CDF per policy from the runs' traces (all seeds pooled); {} without traces."""
    from leolink.io.compare_plots import sinr_cdf

    out = {}
    for label, group in runs.groupby("policy", sort=False):
        parts = []
        for run_dir in map(Path, group["run"]):
            if (run_dir / "trace.parquet").exists():
                parts.append(pd.read_parquet(run_dir / "trace.parquet", columns=["sinr_db"]))
            elif (run_dir / "trace.csv").exists():
                parts.append(pd.read_csv(run_dir / "trace.csv", usecols=["sinr_db"]))
        if parts:
            out[label] = sinr_cdf(pd.concat(parts)["sinr_db"].to_numpy(float))
    return out


def report_table(table, conditions=None):
    """``compare.md``: the main KPIs of ``compare.csv`` as a Markdown table (mean +- std
    over seeds), a legend of its columns and, with ``conditions`` (``{policy: text}``),
    every policy's parameters in effect. A KPI empty for every policy is left out."""
    cols = [c for c in MAIN_KPIS if c[0] in table.columns and table[c[0]].notna().any()]
    lines = ["| policy | " + " | ".join(c[1] for c in cols) + " |"]
    lines.append("|" + "---|" * (len(cols) + 1))
    for _, row in table.iterrows():
        cells = []
        for col, _, scale, fmt, _ in cols:
            text = "" if pd.isna(row[col]) else fmt.format(row[col] * scale)
            std = row.get(f"{col}_std")
            if text and std is not None and np.isfinite(std):
                text += " ± " + fmt.format(std * scale)
            cells.append(text)
        lines.append(f"| {row['policy']} | " + " | ".join(cells) + " |")
    n = sorted(set(int(v) for v in table["n_seeds"])) if "n_seeds" in table else [1]
    spread = "mean ± sample standard deviation over" if max(n) > 1 else "one run per policy,"
    lines += ["", f"Legend ({spread} {'/'.join(map(str, n))} seed(s)):", ""]
    lines += [f"- **{head}**: {legend}" for _, head, _, _, legend in cols]
    if conditions:
        lines += ["", "Policies (the parameters in effect):", ""]
        lines += [f"- **{label}**: `{text}`" for label, text in conditions.items()]
    return "\n".join(lines) + "\n"


def policy_conditions(cfg_path, specs, base=()):
    """``{label: text}``: each policy's name and its ``[controller.<name>]`` table in
    effect (every condition of a CHO, every threshold), as compact JSON."""
    from leolink.config import load_config

    out = {}
    for label, overrides in map(parse_policy, specs):
        ctl = load_config(cfg_path, [*base, *overrides]).controller
        params = json.dumps(ctl.params.model_dump(mode="json"))
        out[label] = f"{ctl.chosen} {params}"
    return out


def run_compare(cfg_path, policies, out_dir, base_overrides=None, seeds=1, *, how=None):
    """Run every policy on the same seeds and tabulate their KPIs (module docstring).

    Parameters
    ----------
    cfg_path : path-like, the scenario (a TOML file, or an example's name).
    policies : list of str, ``NAME[,KEY=VALUE...]`` each (at least one).
    out_dir : path-like
    base_overrides : list of str, ``section.key=value`` applied to every run.
    seeds : int >= 1, seeds per policy (``run.seed`` on).
    how : :class:`~leolink.app.sweep.Execution`, optional: workers, progress bar, resume
        (reuse finished runs of the same config), overwrite (an earlier compare's files in
        ``out_dir``), the figures; None: the defaults.

    Returns
    -------
    pandas.DataFrame, ``compare.csv``.
    """
    from leolink.app.sweep_exec import check_runs, check_workers, run_jobs
    from leolink.io.atomic import write_csv_atomic, write_text_atomic
    from leolink.io.run_dir import claim_out_dir

    if not policies:
        raise ConfigError("compare: give at least one --policy")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ConfigError(f"--seeds {seeds!r} is not allowed; use an integer >= 1")
    how = Execution() if how is None else how
    check_runs(len(policies) * seeds, f"--seeds {seeds} x {len(policies)} policies")
    check_workers(how.workers)
    cfg_path, out_dir = examples.resolve(cfg_path).resolve(), Path(out_dir).absolute()
    base = _base_overrides(base_overrides, [], False)
    triples = _jobs(cfg_path, list(policies), seeds, base, out_dir, how.resume)
    for line in policy_twins(cfg_path, list(policies), base):
        warnings.warn(line, UserWarning, stacklevel=2)
    out_dir = claim_out_dir(
        out_dir,
        how.overwrite or how.resume,
        flag="--overwrite (or --resume, to reuse its finished runs)",
        keep=("runs",) if how.resume else (),
    )
    jobs = [(i, job) for i, (_, _, job) in enumerate(triples)]
    with _progress_bar(len(jobs), how.progress, "leolink compare", "run") as bar:
        rows = run_jobs(_run_point, jobs, lambda i: bar.update(1), how.workers)
    failed = [(triples[i][0], row["error"]) for i, row in sorted(rows.items()) if "error" in row]
    if failed:
        raise ConfigError(f"policy {failed[0][0]}: {failed[0][1]}")
    runs = pd.DataFrame(
        [
            {"policy": label, "seed": seed, "run": job[2], **rows[i]}
            for i, (label, seed, job) in enumerate(triples)
        ]
    )
    table = _aggregate(runs)
    report = report_table(table, policy_conditions(cfg_path, policies, base))
    files = [write_csv_atomic(runs, out_dir / "compare_runs.csv"),
             write_text_atomic(out_dir / "compare.md", report)]  # fmt: skip
    if how.plot:
        from leolink.io.compare_plots import plot_compare

        files += plot_compare(table, out_dir, _cdfs(runs))
    files.append(write_csv_atomic(table, out_dir / "compare.csv"))
    _manifest(out_dir, cfg_path, base, list(policies), seeds, files, runs["run"])
    return table


def _manifest(out_dir, cfg_path, base, policies, seeds, files, run_dirs):
    """``run.json``, last: the tables, the plots and every run's own ``run.json``."""
    import leolink
    from leolink.config import dump_toml, load_config
    from leolink.io.run_dir import MANIFEST, write_manifest

    runs = [Path(d) / MANIFEST for d in run_dirs]
    arguments = {"policies": policies, "seeds": seeds, "base_overrides": base}
    raise_pending()  # a stop caught inside a library: no manifest (leolink.app.guard)
    write_manifest(out_dir, [*files, *runs], "compare",
                   dump_toml(load_config(cfg_path, base)), arguments,
                   version=leolink.__version__)  # fmt: skip
