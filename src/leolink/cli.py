"""Command line: ``leolink run | coverage | budget | codebook | sweep | compare | report |
validate | passes``.

Errors leolink raises on purpose, and errors of the environment (a folder that cannot
be written, a full disk, an unreachable dask scheduler), are printed as one line (exit
code 2); anything else is a bug and is printed as a short note (exit code 3) unless
``--debug`` is given. SIGINT (Ctrl-C) and SIGTERM stop a command cleanly: finished files
stay, temporary ones are removed, one line says where it stopped (exit 130, 143). A sweep
some of whose points failed writes its table (their ``error`` column) and exits 1.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from leolink.errors import ConfigError, LeolinkError

EXIT_POINTS_FAILED = 1
EXIT_USAGE = 2
EXIT_BUG = 3
EXIT_INTERRUPTED = 130  # 128 + SIGINT
EXIT_TERMINATED = 143  # 128 + SIGTERM
MAX_GRID = 5001  # coverage grid points per axis (25 million points)
OVERWRITE_HELP = "replace an earlier run's files in --out (other files are kept)"


def _config(args):
    from leolink.config import load_config, updated

    overrides = list(args.set or [])
    if getattr(args, "seed", None) is not None:
        overrides.append(f"run.seed={args.seed}")
    cfg = load_config(args.config, overrides)
    if getattr(args, "parquet", False) and "parquet" not in cfg.output.trace.formats:
        formats = ", ".join(f'"{f}"' for f in [*cfg.output.trace.formats, "parquet"])
        cfg = updated(cfg, [f"output.trace.formats=[{formats}]"])
    return cfg


def cmd_validate(args) -> int:
    import math

    from leolink.app.run import run_notes
    from leolink.app.validate import checked_scenario
    from leolink.roi import check_coverage

    cfg = _config(args)
    rx, ry = cfg.roi_semi_axes_m()
    c = cfg.constellation
    verdict = check_coverage(
        rx, ry, c.n_planes, c.sats_per_plane, math.radians(c.inclination_deg), cfg.earth.radius_m
    )
    # What a run checks and builds (files, codebook, ephemeris over the run, populations,
    # tracks): a config that validates also runs (leolink.app.validate).
    scen = checked_scenario(cfg)
    notes, _, _ = run_notes(cfg, scen)
    n_ut = sum(p.n_ut for _, p in scen.populations)  # as placed (grids, land, site files)
    n_pop = len(cfg.population)
    print(f"{args.config}: valid ({n_pop} population{'s' * (n_pop != 1)}, {n_ut:,} UTs)")
    print(verdict.message)
    for note in notes:
        print(note)
    return 0


def cmd_budget(args) -> int:
    from leolink.app.reports import link_budget_at_elevation

    cfg = _config(args)
    budget = link_budget_at_elevation(cfg, args.elevation_deg)
    if args.json:
        print(json.dumps(budget, indent=2))
    else:
        width = max(len(k) for k in budget)
        for key, value in budget.items():
            text = f"{value:.3f}" if isinstance(value, float) else str(value)
            print(f"{key:<{width}}  {text}")
    return 0


def cmd_codebook(args) -> int:
    from leolink.app.reports import codebook_table

    cfg = _config(args)
    if args.plot and Path(args.plot).is_dir():
        raise ConfigError(f"--plot {args.plot} is a folder; give the path of a PNG file")
    info = codebook_table(cfg)
    if args.plot:
        from leolink.io.coverage_plots import plot_codebook

        plot_codebook(cfg, info, Path(args.plot))
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        print(f"oversampling O = {info['oversampling']:.4g}, {len(info['beams'])} beams")
        print(info["design"])
        cols = ["beam_id", "u_x", "u_y", "x_m", "y_m", "lat_deg", "lon_deg"]
        print("  ".join(f"{c:>10}" for c in cols))
        for b in info["beams"]:
            print(
                "  ".join(
                    f"{b[c]:>10.4f}" if isinstance(b[c], float) else f"{b[c]:>10}" for c in cols
                )
            )
    return 0


def cmd_coverage(args) -> int:
    from leolink.app.coverage import run_coverage

    if not 2 <= args.grid <= MAX_GRID:
        raise ConfigError(f"--grid {args.grid} is not allowed; use 2..{MAX_GRID} points per axis")
    if not 0.0 < args.margin <= 10.0:  # also refuses NaN
        raise ConfigError(f"--margin {args.margin} is not allowed; use a number in (0, 10]")
    cfg = _config(args)
    paths = run_coverage(
        cfg,
        Path(args.out),
        n_grid=args.grid,
        margin=args.margin,
        plots=not args.no_plots,
        overwrite=args.overwrite,
    )
    if not args.quiet:
        for p in paths:
            print(p)
    return 0


def cmd_run(args) -> int:
    from leolink.app.progress import progress_bar
    from leolink.app.run import run

    cfg = _config(args)
    with progress_bar("leolink run", enabled=not args.quiet) as progress:
        result = run(cfg, out_dir=Path(args.out), progress=progress, overwrite=args.overwrite)
    for note in result.summary["run"]["notes"]:
        if not args.quiet or note.startswith(("UT ", "satellite ")):  # shown even if quiet
            print(f"note: {note}", file=sys.stderr)
    if not args.quiet:
        o, r = result.summary["overall"], result.summary["run"]
        print(
            f"wrote {args.out}: {r['n_ut']} UTs, {r['n_epochs']} epochs, "
            f"{o['handovers']['beam_handover']} beam and {o['handovers']['sat_handover']} "
            f"satellite handovers, mean SNR {_db(o['snr_db']['mean'])}"
        )
    return 0


def cmd_passes(args) -> int:
    from leolink.app.passes import parse_site, site_passes

    site = parse_site(args.site)
    passes = site_passes(_config(args), site, args.min_elevation_deg)
    if args.json:
        keys = ("sat_id", "rise_utc", "culmination_utc", "set_utc", "max_elevation_deg")
        print(json.dumps([{k: p[k] for k in (*keys, "name", "rise_s", "set_s")} for p in passes]))
        return 0
    print(f"{len(passes)} passes over {args.site}")
    for p in passes:
        when = [p[f"{k}_utc"] or (None if p[f"{k}_s"] is None else f"t={p[f'{k}_s']:.3f} s")
                for k in ("rise", "culmination", "set")]  # fmt: skip
        print(f"{p['name']:>12}  rise {when[0]}  culmination {when[1]}  set {when[2]}  "
              f"max {p['max_elevation_deg']:.2f} deg")  # fmt: skip
    return 0


def _db(value):
    return "n/a (never served)" if value is None else f"{value:.2f} dB"


def cmd_sweep(args) -> int:
    from leolink.app.sweep import run_sweep

    _config(args)  # config mistakes fail here, before any run
    workers = int(args.workers) if str(args.workers).isdigit() else args.workers
    table = run_sweep(
        args.config,
        args.param,
        Path(args.out),
        base_overrides=args.set or [],
        workers=workers,
        progress=not args.quiet,
        resume=args.resume,
        overwrite=args.overwrite,
    )
    if not args.quiet:
        print(table.to_string(index=False))
    failed = int((table["error"] != "").sum()) if "error" in table else 0
    if failed:
        first = table.loc[table["error"] != "", ["point", "error"]].iloc[0]
        print(
            f"leolink: {failed} of {len(table)} sweep points failed (column 'error' of "
            f"sweep.csv); first: {first['point']}: {first['error']}",
            file=sys.stderr,
        )
        return EXIT_POINTS_FAILED
    return 0


def cmd_report(args) -> int:
    import leolink
    from leolink.io.report.rebuild import rebuild_report

    uts = _ut_list(args.uts) if args.uts else None
    built = rebuild_report(
        Path(args.dir),
        series_ut=uts,
        animate=not args.no_animation,
        exports=args.exports,
        version=leolink.__version__,
    )
    if not args.quiet:
        for path in [built["report"], built["animation"], *built["exports"]]:
            if path is not None:
                print(path)
    return 0


def _ut_list(text):
    try:
        uts = [int(u) for u in text.split(",")]
    except ValueError:
        uts = []
    if not uts or min(uts) < 0:
        raise ConfigError(f"--uts = {text!r} is not allowed; use UT ids >= 0, e.g. --uts 0,5")
    return uts


def _version():
    import leolink

    return f"leolink {leolink.__version__}"


def cmd_compare(args) -> int:
    from leolink.app.compare import report_table, run_compare

    _config(args)  # config mistakes fail here, before any run
    policies = list(args.policy or [])
    for group in args.policies or []:
        policies += [p for p in group.split(",") if p.strip()]
    table = run_compare(
        args.config,
        policies,
        Path(args.out),
        base_overrides=args.set or [],
        seeds=args.seeds,
        workers=int(args.workers) if str(args.workers).isdigit() else args.workers,
        progress=not args.quiet,
        resume=args.resume,
        overwrite=args.overwrite,
    )
    if not args.quiet:
        print(report_table(table), end="")
    return 0


def _compare_parser(p):
    p.add_argument(
        "--policy",
        action="append",
        metavar="NAME[,KEY=VALUE...]",
        help="a policy and its parameters (repeatable), e.g. a3,hysteresis_db=2",
    )
    p.add_argument(
        "--policies", action="append", metavar="A,B,...", help="policy names, comma-separated"
    )
    p.add_argument("--seeds", type=int, default=1, help="seeds per policy (run.seed on)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument(
        "--workers",
        default="1",
        help="parallel processes, or dask://HOST:PORT for a dask.distributed cluster",
    )
    p.add_argument("--resume", action="store_true", help="reuse finished runs in --out")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.add_argument("--quiet", action="store_true")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="leolink", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=_version())
    parser.add_argument("--debug", action="store_true", help="show tracebacks of bugs")
    sub = parser.add_subparsers(dest="command", required=True)

    def add(name, func, help_):
        p = sub.add_parser(name, help=help_)
        p.add_argument("config", help="TOML config file (e.g. configs/paper.toml)")
        p.add_argument(
            "--set",
            action="append",
            metavar="SECTION.KEY=VALUE",
            help="override a config value (repeatable)",
        )
        p.set_defaults(func=func)
        return p

    add("validate", cmd_validate, "check a config and the ROI coverage condition")
    p = add("budget", cmd_budget, "link budget term by term at one elevation")
    p.add_argument("--elevation-deg", type=float, required=True, help="elevation [deg]")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p = add("codebook", cmd_codebook, "beams of the configured DFT codebook")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="FILE", help="write a PNG of the footprints")
    p = add("coverage", cmd_coverage, "SNR/SINR/Doppler maps over the ROI at one instant")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--grid", type=int, default=201, help="grid points per axis")
    p.add_argument("--margin", type=float, default=1.1, help="grid extent / ROI semi-axis")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.add_argument("--quiet", action="store_true")
    p = add("run", cmd_run, "run the simulation and write traces, events, summary, plots")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--seed", type=int, help="override run.seed")
    p.add_argument("--parquet", action="store_true", help="also write trace.parquet")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary line")
    p = add("passes", cmd_passes, "rise, culmination and set of every satellite over a site")
    p.add_argument("--site", required=True, metavar="LAT,LON[,ALT]", help="deg, deg, m")
    p.add_argument("--min-elevation-deg", type=float, help="mask (default: the config's)")
    p.add_argument("--json", action="store_true", help="print a JSON list of passes")
    _add_sweep(add("sweep", cmd_sweep, "run a grid of parameter values and tabulate the summaries"))
    _compare_parser(add("compare", cmd_compare, "run policies on the same seeds, compare KPIs"))
    _add_report(sub.add_parser("report", help="rebuild report.html of a run folder, no rerun"))
    return parser


def _add_sweep(p):
    p.add_argument(
        "--param",
        action="append",
        required=True,
        metavar="SECTION.KEY=V1,V2,...",
        help="a parameter and its values (repeatable: the grid is their product)",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument(
        "--workers",
        default="1",
        help="parallel processes, or dask://HOST:PORT for a dask.distributed cluster",
    )
    p.add_argument(
        "--resume", action="store_true", help="reuse finished runs of the same points in --out"
    )
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.add_argument("--quiet", action="store_true")


def _add_report(p):
    p.add_argument("dir", help="output folder of a finished leolink run")
    p.add_argument("--uts", metavar="ID,ID,...", help="UTs of the time plots (default: the run's)")
    p.add_argument("--no-animation", action="store_true", help="do not rewrite footprint.gif")
    p.add_argument("--exports", action="store_true", help="also write run.geojson and run.czml")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_report)


def main(argv=None) -> int:
    from leolink.app.guard import Stopped, environment_error, interruptible, quiet_warnings

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        with interruptible(), quiet_warnings():
            return args.func(args)
    except LeolinkError as exc:
        print(f"leolink: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (Stopped)
        name = exc.signal_name if isinstance(exc, Stopped) else "SIGINT"
        where = "; ".join(getattr(exc, "__notes__", [])) or "before any output was finished"
        print(
            f"leolink: stopped by {name}: {where}; finished files are intact, temporary "
            "files removed",
            file=sys.stderr,
        )
        return EXIT_TERMINATED if name == "SIGTERM" else EXIT_INTERRUPTED
    except OSError as exc:  # the environment: permissions, a full disk, the network
        message = environment_error(exc, getattr(args, "out", None))
        print(f"leolink: error: {message}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:  # a bug: say so briefly
        if args.debug:
            raise
        print(
            f"leolink: internal error: {type(exc).__name__}: {exc} "
            "(this is a bug; rerun with --debug for the traceback)",
            file=sys.stderr,
        )
        return EXIT_BUG


def console(argv=None):
    """The ``leolink`` command (and ``python -m leolink.cli``): :func:`main`, then the
    process's end with its code (:func:`leolink.app.process.end`)."""
    from leolink.app.process import end, start

    start()  # (before numpy's and the models' import: main() imports what it runs)
    end(main(argv))


if __name__ == "__main__":
    console()
