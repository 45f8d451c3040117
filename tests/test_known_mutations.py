"""tools/known_mutations.py stays applicable: each recorded edit still matches the source
exactly once (else the script, and the claim that the suite kills those mutations, rot)."""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("known_mutations", ROOT / "tools/known_mutations.py")
km = importlib.util.module_from_spec(_spec)
sys.modules["known_mutations"] = km  # dataclasses look their module up there
_spec.loader.exec_module(km)


@pytest.mark.parametrize("m", km.MUTATIONS, ids=lambda m: m.name)
def test_mutation_still_applies_and_its_tests_exist(m):
    assert (ROOT / m.path).read_text().count(m.old) == 1
    assert m.old != m.new
    for t in m.tests:
        assert (ROOT / t).exists(), t
