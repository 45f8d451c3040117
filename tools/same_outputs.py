"""Check that a change keeps every example's outputs: identical, or equal within a tolerance.

    python tools/same_outputs.py (--base REV | --base-out DIR) [--keep DIR] [--common]
                                 [--rtol R --atol A] [--python PY]

Runs ``leolink run CONFIG --parquet`` for every ``configs/*.toml`` (the paper's pass and
its constellation) and every ``configs/examples/*.toml`` twice: with the code and configs
of ``REV`` (a temporary git worktree, its compiled extension built when it has one) and
with those of the working tree; then compares ``trace.csv``, ``trace.parquet`` (as
tables), ``events.csv`` and ``summary.json`` (without the wall time). Prints one line per
config and exits 1 if anything differs. Speed aside, a refactoring must pass this.
``--base-out DIR``: the base's outputs already written there (``DIR/<config stem>/``, e.g.
by another checkout's ``leolink run``) instead of running ``REV``.

``--rtol``/``--atol``: numbers are equal when ``|a - b| <= atol + rtol |b|`` (NaN equal to
NaN, infinities exact), text cells and the rows' number exactly: for changes that round
differently (another order of a sum, a compiled loop) but must not change a decision (a
beam, a handover, an event). Without them, CSV files must be byte-identical.

``--common``: when the output contract grew (new trace columns, summary keys), compare
only what ``REV`` wrote: its trace columns, cell by cell as text (CSV) or exactly
(Parquet), its event rows, and its summary keys (recursively; new keys are ignored).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMPARED = ("trace.csv", "events.csv", "summary.json", "trace.parquet")


def configs(tree):
    return [
        *sorted((tree / "configs").glob("*.toml")),
        *sorted((tree / "configs" / "examples").glob("*.toml")),
    ]


def run_all(tree, out, python=sys.executable):
    env = dict(os.environ, PYTHONPATH=str(tree / "src"))
    for cfg in configs(tree):
        dest = out / cfg.stem
        cmd = [
            python,
            "-m",
            "leolink.cli",
            "run",
            str(cfg),
            "--out",
            str(dest),
            "--parquet",
            "--quiet",
        ]
        subprocess.run(cmd, env=env, check=True, cwd=tree)


def _summary(path):
    data = json.loads(path.read_text())
    data.get("run", {}).pop("wall_time_s", None)
    data.get("run", {}).pop("config_file", None)  # (the base's is in its own worktree)
    return data


def _subset(base, head):
    """Whether every key of ``base`` is in ``head`` with an equal value (recursively)."""
    if isinstance(base, dict):
        return isinstance(head, dict) and all(
            k in head and _subset(v, head[k]) for k, v in base.items()
        )
    if isinstance(base, list):
        return (
            isinstance(head, list)
            and len(base) == len(head)
            and all(_subset(x, y) for x, y in zip(base, head, strict=True))
        )
    return base == head


def same_common(a, b, name):
    """Equal on what the base file ``a`` holds (see the module docstring)."""
    if not a.exists() or not b.exists():
        return a.exists() == b.exists()
    if name == "summary.json":
        return _subset(_summary(a), _summary(b))
    import pandas as pd

    if name == "trace.parquet":
        import pyarrow.parquet as pq

        base = pq.read_table(a).to_pandas()
        return base.equals(pq.read_table(b, columns=list(base.columns)).to_pandas())
    base = pd.read_csv(a, dtype=str, keep_default_na=False)
    head = pd.read_csv(b, dtype=str, keep_default_na=False)
    return set(base.columns) <= set(head.columns) and base.equals(head[list(base.columns)])


def same(a, b, name):
    if not a.exists() or not b.exists():
        return a.exists() == b.exists()
    if name == "summary.json":
        return _summary(a) == _summary(b)
    if name == "trace.parquet":
        import pyarrow.parquet as pq

        return pq.read_table(a).to_pandas().equals(pq.read_table(b).to_pandas())  # NaN == NaN
    return a.read_bytes() == b.read_bytes()


def _close_numbers(x, y, rtol, atol):
    """Element-wise equality of two arrays within the tolerance (NaN == NaN)."""
    import numpy as np

    x, y = np.asarray(x, float), np.asarray(y, float)
    return x.shape == y.shape and bool(np.all(np.isclose(x, y, rtol, atol, equal_nan=True)))


def _close_values(x, y, rtol, atol):
    """JSON values equal, numbers within the tolerance (recursively)."""
    if isinstance(x, dict):
        return (
            isinstance(y, dict)
            and x.keys() == y.keys()
            and all(_close_values(v, y[k], rtol, atol) for k, v in x.items())
        )
    if isinstance(x, list):
        return (
            isinstance(y, list)
            and len(x) == len(y)
            and all(_close_values(u, v, rtol, atol) for u, v in zip(x, y, strict=True))
        )
    numbers = (int, float)
    if isinstance(x, numbers) and isinstance(y, numbers) and not isinstance(x, bool):
        return _close_numbers(x, y, rtol, atol)
    return x == y


def _close_tables(x, y, rtol, atol):
    """Data frames with the same columns and rows; numeric columns within the tolerance,
    the others equal."""
    import pandas as pd

    if list(x.columns) != list(y.columns) or len(x) != len(y):
        return False
    for c in x.columns:
        numeric = pd.api.types.is_numeric_dtype(x[c]) and pd.api.types.is_numeric_dtype(y[c])
        if numeric and not pd.api.types.is_bool_dtype(x[c]):
            if not _close_numbers(x[c].to_numpy(float), y[c].to_numpy(float), rtol, atol):
                return False
        elif not x[c].equals(y[c]):
            return False
    return True


def close(a, b, name, rtol, atol):
    """:func:`same` within the tolerance (the module docstring)."""
    if not a.exists() or not b.exists():
        return a.exists() == b.exists()
    if name == "summary.json":
        return _close_values(_summary(a), _summary(b), rtol, atol)
    import pandas as pd

    if name == "trace.parquet":
        return _close_tables(pd.read_parquet(a), pd.read_parquet(b), rtol, atol)
    return _close_tables(pd.read_csv(a), pd.read_csv(b), rtol, atol)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    base = parser.add_mutually_exclusive_group(required=True)
    base.add_argument("--base", help="git revision to compare against")
    base.add_argument("--base-out", help="the base's outputs, already written: DIR/<stem>/")
    parser.add_argument("--keep", help="keep the outputs in this folder")
    parser.add_argument(
        "--common", action="store_true", help="compare only the columns and keys REV wrote"
    )
    parser.add_argument("--rtol", type=float, help="relative tolerance of numbers")
    parser.add_argument("--atol", type=float, help="absolute tolerance of numbers")
    parser.add_argument("--python", default=sys.executable, help="the interpreter of the runs")
    args = parser.parse_args(argv)
    compare = same_common if args.common else same
    if args.rtol is not None or args.atol is not None:
        rtol, atol = args.rtol or 0.0, args.atol or 0.0

        def compare(a, b, name):
            return close(a, b, name, rtol, atol)

    work = Path(args.keep or tempfile.mkdtemp(prefix="same_outputs_"))
    if args.base_out:
        run_all(ROOT, work / "head", args.python)
        return report(Path(args.base_out), work / "head", compare)
    base_tree = work / "base_tree"
    if not base_tree.exists():
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(base_tree), args.base],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
    try:
        if (base_tree / "setup.py").exists():  # the compiled loops of that revision, built
            subprocess.run([sys.executable, "setup.py", "-q", "build_ext", "--inplace"],
                           cwd=base_tree, check=True, capture_output=True)  # fmt: skip
        run_all(base_tree, work / "base", args.python)
        run_all(ROOT, work / "head", args.python)
    finally:
        subprocess.run(
            ["git", "worktree", "remove", "--force", str(base_tree)], cwd=ROOT, capture_output=True
        )
    return report(work / "base", work / "head", compare)


def report(base, head, compare):
    """One line per config; 1 if anything differs."""
    bad = 0
    for cfg in configs(ROOT):
        diffs = [n for n in COMPARED if not compare(base / cfg.stem / n, head / cfg.stem / n, n)]
        bad += bool(diffs)
        print(f"{cfg.stem:>14}: {'same' if not diffs else 'DIFFERS: ' + ', '.join(diffs)}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
