"""Check that a change keeps every example's outputs byte-identical.

    python tools/same_outputs.py --base REV [--keep DIR] [--common]

Runs ``leolink run CONFIG --parquet`` for ``configs/paper.toml`` and every
``configs/examples/*.toml`` twice: with the code and configs of ``REV`` (a temporary git
worktree, its compiled extension built when it has one) and with those of the working
tree (its extension as built: ``python setup.py build_ext --inplace`` after an edit);
then compares ``trace.csv``, ``trace.parquet`` (as tables), ``events.csv`` and
``summary.json`` (without the wall time). Prints one line per config and exits 1 if
anything differs. Speed aside, a refactoring must pass this.

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
        tree / "configs" / "paper.toml",
        *sorted((tree / "configs" / "examples").glob("*.toml")),
    ]


def run_all(tree, out):
    env = dict(os.environ, PYTHONPATH=str(tree / "src"))
    for cfg in configs(tree):
        dest = out / cfg.stem
        cmd = [
            sys.executable,
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


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="git revision to compare against")
    parser.add_argument("--keep", help="keep the outputs in this folder")
    parser.add_argument(
        "--common", action="store_true", help="compare only the columns and keys REV wrote"
    )
    args = parser.parse_args(argv)
    compare = same_common if args.common else same
    work = Path(args.keep or tempfile.mkdtemp(prefix="same_outputs_"))
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
        run_all(base_tree, work / "base")
        run_all(ROOT, work / "head")
    finally:
        subprocess.run(
            ["git", "worktree", "remove", "--force", str(base_tree)], cwd=ROOT, capture_output=True
        )
    bad = 0
    for cfg in configs(ROOT):
        diffs = [
            n
            for n in COMPARED
            if not compare(work / "base" / cfg.stem / n, work / "head" / cfg.stem / n, n)
        ]
        bad += bool(diffs)
        print(f"{cfg.stem:>12}: {'identical' if not diffs else 'DIFFERS: ' + ', '.join(diffs)}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
