"""A reproducible random sample of the test functions, for the independent-reference audit.

    python tools/sample_result_tests.py [--n 60] [--seed 45] [--commit a7a9ea3 | --worktree]

Lists every ``def test_`` in ``tests/*.py`` (module-level functions and methods of test
classes, found with :mod:`ast`; a parametrized function counts once) as the files stand at
``--commit`` (read with ``git show``; default: a7a9ea3, the tree the audit of
docs/testing.md sampled) or in the working tree (``--worktree``), sorts them by file and
line, shuffles the list with ``random.Random(seed)`` and prints the first ``n`` as
``rank tests/file::name line``. A larger ``n`` extends the same sample, so drawing more
functions until enough *result tests* are in it keeps the earlier ones; a test added or
removed later changes the shuffle, hence the pinned commit. The script only lists; the
classification (docs/testing.md, "Independent references: a random sample"; the table is
in docs/testing_log.md) is done by reading each test.
"""

from __future__ import annotations

import argparse
import ast
import random
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
AUDITED_COMMIT = "a7a9ea3"


def _sources(commit: str | None) -> list[tuple[str, str]]:
    """``(file name, text)`` of every ``tests/*.py``, at ``commit`` or in the working tree."""
    if commit is None:
        return [(p.name, p.read_text("utf-8")) for p in sorted((ROOT / "tests").glob("*.py"))]
    names = subprocess.run(
        ["git", "-C", str(ROOT), "ls-tree", "--name-only", commit, "tests/"],
        capture_output=True, text=True, check=True,
    ).stdout.split()  # fmt: skip
    out = []
    for name in sorted(n for n in names if n.endswith(".py")):
        text = subprocess.run(
            ["git", "-C", str(ROOT), "show", f"{commit}:{name}"],
            capture_output=True, text=True, check=True,
        ).stdout  # fmt: skip
        out.append((Path(name).name, text))
    return out


def test_functions(sources: list[tuple[str, str]]) -> list[tuple[str, str, int]]:
    """Every test function of ``sources`` as ``(file, qualified name, line)``, sorted."""
    found = []
    for file, text in sorted(sources):
        for node in ast.parse(text).body:
            scopes = [("", node)]
            if isinstance(node, ast.ClassDef):
                scopes = [(node.name + ".", child) for child in node.body]
            for prefix, item in scopes:
                is_function = isinstance(item, ast.FunctionDef | ast.AsyncFunctionDef)
                if is_function and item.name.startswith("test_"):
                    found.append((file, prefix + item.name, item.lineno))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--n", type=int, default=60, help="how many functions to list")
    parser.add_argument("--seed", type=int, default=45, help="seed of random.Random")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--commit", default=AUDITED_COMMIT, help="the tree to sample")
    where.add_argument("--worktree", action="store_true", help="sample the working tree")
    args = parser.parse_args()
    commit = None if args.worktree else args.commit
    population = test_functions(_sources(commit))
    order = list(population)
    random.Random(args.seed).shuffle(order)
    tree = "the working tree" if commit is None else commit
    print(f"# {len(population)} test functions in tests/*.py at {tree}; seed {args.seed}")
    for rank, (file, name, line) in enumerate(order[: args.n], start=1):
        print(f"{rank:3d} tests/{file}::{name} {line}")


if __name__ == "__main__":
    main()
