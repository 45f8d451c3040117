"""leolink.io.arrow: numpy -> Arrow string columns, against pyarrow's own conversion."""

import subprocess
import sys

import numpy as np
import pyarrow as pa
import pytest

from leolink.io.arrow import decoded_array, string_array

NAMES = ["centre", "", "static UTs", "avión", "a"]  # empty, with a space, non-ASCII


@pytest.mark.parametrize("by_take", [False, True])
@pytest.mark.parametrize("n", [0, 1, 17, 30_000])
def test_decoded_array_is_the_strings_of_the_codes(n, by_take):
    """Both gathers: numpy's, and Arrow's take."""
    codes = np.random.default_rng(n).integers(0, len(NAMES), n).astype(np.int32)
    got = decoded_array(codes, NAMES, by_take)
    assert got.type == pa.string()
    assert got.equals(pa.array([NAMES[c] for c in codes], pa.string()))


@pytest.mark.parametrize("by_take", [False, True])
@pytest.mark.parametrize("bad", [-1, len(NAMES)])
def test_decoded_array_refuses_codes_outside_the_names(by_take, bad):
    codes = np.zeros(10, np.int32)
    codes[5] = bad
    with pytest.raises(ValueError, match=r"codes outside 0 \.\. 4"):
        decoded_array(codes, NAMES, by_take)


def test_string_array_is_pyarrows():
    assert string_array(NAMES).equals(pa.array(NAMES, pa.string()))


def test_neither_gather_imports_pandas():
    """``pyarrow.array`` imports pandas (~0.5 s of a small run's start): not used."""
    code = (
        "import sys, numpy as np; from leolink.io.arrow import decoded_array\n"
        "for t in (False, True): decoded_array(np.zeros(10, np.int32), ['a', 'b'], t)\n"
        "print('pandas' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
