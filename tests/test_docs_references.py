"""docs/model.md and docs/validation.md name real code and real tests.

Every ``tests/…::test_name`` / ``test_x.py::test_name`` they cite must be a test that
exists (parametrized ids stripped), and every ``module.function`` of leolink they cite
must import: a renamed test or function turns this red instead of leaving a stale row.
"""

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ["docs/model.md", "docs/validation.md"]
TEST_REF = re.compile(r"`(?:tests/)?(test_\w+\.py)::(test_\w+)")
CODE_REF = re.compile(r"`((?:[a-z_]+\.)+)([A-Za-z_][A-Za-z0-9_]*)`")


def _refs(pattern):
    out = set()
    for doc in DOCS:
        for m in pattern.finditer((ROOT / doc).read_text()):
            out.add((doc, *m.groups()))
    return sorted(out)


@pytest.mark.parametrize(("doc", "path", "name"), _refs(TEST_REF))
def test_cited_tests_exist(doc, path, name):
    text = (ROOT / "tests" / path).read_text()
    assert re.search(rf"^def {name}\(", text, flags=re.M), f"{doc}: {path}::{name}"


def _code_refs():
    refs = []
    for doc, module, name in _refs(CODE_REF):
        module = module.rstrip(".")
        if name in {"py", "md", "toml", "csv"}:  # a file name, not code
            continue
        if module.split(".")[0] in {"orbit", "link", "kinematics", "roi", "antenna", "geometry",
                                    "placement", "engine", "sim", "io"}:  # fmt: skip
            refs.append((doc, module, name))
    return refs


@pytest.mark.parametrize(("doc", "module", "name"), _code_refs())
def test_cited_functions_exist(doc, module, name):
    parts = f"leolink.{module}.{name}".split(".")
    # The longest importable prefix is the module; the rest are attributes (class.method).
    for i in range(len(parts), 1, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return
    pytest.fail(f"{doc}: {module}.{name} does not import")
