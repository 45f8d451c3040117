"""Scripts in examples/ run and print what their stored output says (as SimPy checks its
documentation examples): an example that rots fails here."""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("script", sorted(EXAMPLES.glob("*.py")), ids=lambda p: p.name)
def test_example_prints_its_stored_output(script):
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout == script.with_suffix(".out").read_text()
