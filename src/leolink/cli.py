"""Command line: ``leolink run | coverage | budget | codebook | sweep | compare | report |
validate | examples | init | passes | export-ntn``.

Errors leolink raises on purpose, and errors of the environment (a folder that cannot
be written, a full disk, an unreachable dask scheduler), are printed as one line (exit
code 2); anything else is a bug and is printed as a short note (exit code 3) unless
``--debug`` is given. SIGINT (Ctrl-C), SIGTERM, SIGHUP and SIGXCPU stop a command cleanly:
finished files stay, temporary ones are removed, one line says where it stopped (exit 128 +
the signal's number: 130, 143, 129, 152). A sweep
some of whose points failed writes its table (their ``error`` column) and exits 1.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import zipfile
from pathlib import Path

from leolink.errors import ConfigError, LeolinkError

EXIT_POINTS_FAILED = 1
EXIT_USAGE = 2
EXIT_BUG = 3
EXIT_INTERRUPTED = 130  # 128 + SIGINT
MAX_GRID = 5001  # coverage grid points per axis (25 million points)
#: What ``leolink report`` writes anew (the rest of the folder it reads, checked first).
REPORT_WRITES = ("report.html", "footprint.gif", "run.geojson", "run.czml")
OVERWRITE_HELP = "replace an earlier run's files in --out (other files are kept)"
#: ``leolink --help``: plain text (argparse prints it as is, no reStructuredText).
DESCRIPTION = (
    "Simulate the downlink from LEO satellites with large phased arrays to moving user "
    "terminals, and the beam and satellite handovers their motion forces. "
    "'leolink COMMAND --help' gives a command's options."
)
EPILOG = (
    "Exit codes: 0 done; 1 some sweep points failed; 2 a mistake in the input or the "
    "environment, said in one line; 3 a bug; 130/143/129/152 stopped by "
    "SIGINT/SIGTERM/SIGHUP/SIGXCPU."
)


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

    from leolink.app.multibeam import is_multibeam, snapshot_of_config
    from leolink.app.run import run_notes
    from leolink.app.split import split_workers
    from leolink.app.validate import checked_scenario
    from leolink.roi import check_coverage

    cfg = _config(args)
    if is_multibeam(cfg):  # what run makes of it: the TR 38.821 snapshot's checks
        sat, snap = snapshot_of_config(cfg)
        print(f"{args.config}: valid ({snap.serving.size} UTs in the multibeam snapshot)")
        return 0
    rx, ry = cfg.roi_semi_axes_m()
    c = cfg.constellation
    verdict = check_coverage(
        rx, ry, c.n_planes, c.sats_per_plane, math.radians(c.inclination_deg), cfg.earth.radius_m
    )
    # What a run checks and builds (files, codebook, ephemeris over the run, populations,
    # tracks): a config that validates also runs (leolink.app.validate).
    scen = checked_scenario(cfg, split_workers(*_split(args)))
    notes, _, _ = run_notes(cfg, scen)
    n_ut = sum(p.n_ut for _, p in scen.populations)  # as placed (grids, land, site files)
    n_pop = len(cfg.population)
    print(f"{args.config}: valid ({n_pop} population{'s' * (n_pop != 1)}, {n_ut:,} UTs)")
    print(verdict.message)
    for note in notes:
        print(note)
    return 0


def _split(args):
    """``(workers, parts)`` of ``--workers``, ``--scheduler`` and ``--parts``."""
    if args.scheduler is not None:
        if args.workers != 1:
            raise ConfigError("give --workers N (local processes) or --scheduler ADDRESS, not both")
        return f"dask://{args.scheduler}", args.parts
    return args.workers, args.parts


def _add_split(p):
    """The options of a run split over parts of its UTs (leolink.app.split)."""
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help="split the UTs into parts run on N local processes (same outputs)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="split the UTs into parts run on the dask cluster of this scheduler",
    )
    p.add_argument("--parts", type=int, help="parts of the split (default: 4 per worker)")


def cmd_budget(args) -> int:
    from leolink.app.reports import link_budget_at_elevation

    cfg = _config(args)
    budget = link_budget_at_elevation(cfg, args.elevation_deg)
    if args.json:
        print(json.dumps(budget, indent=2))
        return 0
    note = budget.pop("note", None)
    width = max(len(k) for k in budget)
    for key, value in budget.items():
        text = f"{value:.3f}" if isinstance(value, float) else str(value)
        print(f"{key:<{width}}  {text}")
    if note:
        print(f"note: {note}", file=sys.stderr)
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
    workers, parts = _split(args)
    with progress_bar("leolink run", enabled=not args.quiet) as progress:
        result = run(cfg, out_dir=Path(args.out), progress=progress, overwrite=args.overwrite,
                     workers=workers, parts=parts)  # fmt: skip
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
    from leolink.app.sweep import Execution, run_sweep

    _config(args)  # config mistakes fail here, before any run
    workers = int(args.workers) if str(args.workers).isdigit() else args.workers
    table = run_sweep(
        args.config,
        args.param,
        Path(args.out),
        base_overrides=args.set or [],
        how=Execution(
            workers=workers, progress=not args.quiet, resume=args.resume, overwrite=args.overwrite
        ),
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
    from leolink.io.run_dir import OutputFolderError, lock_out_dir, verify_manifest

    uts = _ut_list(args.uts) if args.uts else None
    if Path(args.dir).is_dir():
        lock_out_dir(args.dir)  # it rewrites files: not while a command writes there
        verify_manifest(args.dir, REPORT_WRITES)  # sizes and SHA-256 of what it reads
    try:
        built = rebuild_report(
            Path(args.dir),
            series_ut=uts,
            animate=not args.no_animation,
            exports=args.exports,
            version=leolink.__version__,
        )
    except (ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:  # a listed file
        # that reads wrong although its checksum matches: run.json was rewritten with it
        raise OutputFolderError(
            f"{args.dir}: a file of the run cannot be read ({type(exc).__name__}: "
            f"{str(exc)[:120]}); rerun it (leolink run ... --overwrite)"
        ) from None
    if not args.quiet:
        for path in [built["report"], built["animation"], *built["exports"]]:
            if path is not None:
                print(path)
    return 0


def cmd_export_ntn(args) -> int:
    import leolink
    from leolink.app.export_ntn import export_ntn

    paths = export_ntn(Path(args.dir), Path(args.out), overwrite=args.overwrite,
                       version=leolink.__version__)  # fmt: skip
    if not args.quiet:
        for path in paths:
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
    from leolink.app.compare import run_compare
    from leolink.app.sweep import Execution

    _config(args)  # config mistakes fail here, before any run
    policies = list(args.policy or [])
    for group in args.policies or []:
        policies += [p for p in group.split(",") if p.strip()]
    run_compare(
        args.config,
        policies,
        Path(args.out),
        base_overrides=args.set or [],
        seeds=args.seeds,
        how=Execution(
            workers=int(args.workers) if str(args.workers).isdigit() else args.workers,
            progress=not args.quiet,
            resume=args.resume,
            overwrite=args.overwrite,
        ),
    )
    if not args.quiet:  # compare.md: the table, its legend, the policies' parameters
        print((Path(args.out) / "compare.md").read_text(encoding="utf-8"), end="")
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
    parser = argparse.ArgumentParser(prog="leolink", description=DESCRIPTION, epilog=EPILOG)
    parser.add_argument("--version", action="version", version=_version())
    parser.add_argument("--debug", action="store_true", help="show tracebacks of bugs")
    sub = parser.add_subparsers(dest="command", required=True)

    def add(name, func, help_):
        p = sub.add_parser(name, help=help_, description=help_[:1].upper() + help_[1:] + ".")
        p.add_argument("config", help="TOML config file, or an example's name (leolink examples)")
        p.add_argument(
            "--set",
            action="append",
            metavar="SECTION.KEY=VALUE",
            help="override a config value (repeatable)",
        )
        p.set_defaults(func=func)
        return p

    _add_split(add("validate", cmd_validate, "check a config and the ROI coverage condition"))
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
    _add_split(p)
    p = add("passes", cmd_passes, "rise, culmination and set of every satellite over a site")
    p.add_argument("--site", required=True, metavar="LAT,LON[,ALT]", help="deg, deg, m")
    p.add_argument("--min-elevation-deg", type=float, help="mask (default: the config's)")
    p.add_argument("--json", action="store_true", help="print a JSON list of passes")
    _add_sweep(add("sweep", cmd_sweep, "run a grid of parameter values and tabulate the summaries"))
    _compare_parser(add("compare", cmd_compare, "run policies on the same seeds, compare KPIs"))
    what = "rebuild report.html of a run folder, no rerun"
    _add_report(sub.add_parser("report", help=what, description=what[0].upper() + what[1:] + "."))
    what = "write a run's per-UT NTN series and a SIB19-like ephemeris (docs/ntn_export.md)"
    p = sub.add_parser("export-ntn", help=what, description=what[0].upper() + what[1:] + ".")
    p.add_argument("dir", metavar="RUN_DIR", help="folder of a finished leolink run")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=cmd_export_ntn)
    _add_examples(sub)
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


def _add_examples(sub):
    p = sub.add_parser("examples", help="list the example configs that ship with leolink")
    p.set_defaults(func=cmd_examples)
    p = sub.add_parser("init", help="copy an example config (and its TLE/track files)")
    p.add_argument("name", help="an example's name (leolink examples)")
    p.add_argument("dir", nargs="?", default=".", help="folder to copy into (default: .)")
    p.set_defaults(func=cmd_init)


def cmd_examples(args) -> int:
    from leolink.examples import EXAMPLES

    width = max(map(len, EXAMPLES))
    for name, what in EXAMPLES.items():
        print(f"{name:<{width}}  {what}")
    return 0


def cmd_init(args) -> int:
    from leolink.examples import copy_example

    written = copy_example(args.name, args.dir)
    print(f"{written[0]}: run it with  leolink run {written[0]} --out out/{args.name}")
    for path in written[1:]:
        print(f"{path}: read by {written[0].name}")
    return 0


def main(argv=None) -> int:
    from leolink.app.guard import (
        Stopped,
        environment_error,
        interruptible,
        out_of_memory,
        quiet_warnings,
    )
    from leolink.compiled import check_environment
    from leolink.io.run_dir import held_out_dirs

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if getattr(args, "out", None) is not None and not args.out.strip():
            raise ConfigError("--out '' is not allowed; give a folder, e.g. --out results")
        check_environment()  # LEOLINK_JIT, LEOLINK_THREADS: before --out is made
        with interruptible(), quiet_warnings(), held_out_dirs():
            return args.func(args)
    except LeolinkError as exc:
        print(f"leolink: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM, SIGHUP, SIGXCPU (Stopped)
        name = exc.signal_name if isinstance(exc, Stopped) else "SIGINT"
        where = "; ".join(getattr(exc, "__notes__", [])) or "before any output was finished"
        print(
            f"leolink: stopped by {name}: {where}; finished files are intact, temporary "
            "files removed",
            file=sys.stderr,
        )
        return exc.exit_code if isinstance(exc, Stopped) else EXIT_INTERRUPTED
    except MemoryError as exc:  # the environment too: the run is larger than the machine
        print(f"leolink: error: {out_of_memory(exc)}", file=sys.stderr)
        return EXIT_USAGE
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
    _exit_on_stop_signals()
    from leolink.app.process import end, start

    start()  # (before numpy's and the models' import: main() imports what it runs)
    code = main(argv)
    _exit_on_stop_signals(after=True)
    end(code)


#: The signals that stop a command (leolink.app.guard handles them inside the command).
STOP_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP", "SIGXCPU")


def _exit_on_stop_signals(after=False):
    """Until :func:`main`'s ``interruptible()`` takes over, a stop signal ends the process at
    once with one line and ``128 + N``: nothing is written yet, and an exception raised in
    the imports (Python's KeyboardInterrupt) printed a traceback or, caught by a library,
    was lost (a run went on for minutes). ``after``: the command is over, the signal is
    ignored while the process flushes its output and exits."""
    import signal

    def stop(signum, frame):
        name = signal.Signals(signum).name
        os.write(2, f"leolink: stopped by {name} before the command started\n".encode())
        os._exit(128 + signum)

    for name in STOP_SIGNALS:
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN if after else stop)


if __name__ == "__main__":
    console()
