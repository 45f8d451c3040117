"""leolink.io.arrow: numpy -> Arrow string columns, against pyarrow's own conversion."""

import subprocess
import sys

import numpy as np
import pyarrow as pa
import pytest

from leolink.io.arrow import TAKE_MIN_CODES, decoded_array, string_array

NAMES = ["centre", "", "static UTs", "avión", "a"]  # empty, with a space, non-ASCII


@pytest.mark.parametrize("n", [0, 1, 17, TAKE_MIN_CODES - 1, TAKE_MIN_CODES, 3 * TAKE_MIN_CODES])
def test_decoded_array_is_the_strings_of_the_codes(n):
    """Both gathers (numpy below TAKE_MIN_CODES, Arrow's take from it on)."""
    codes = np.random.default_rng(n).integers(0, len(NAMES), n).astype(np.int32)
    got = decoded_array(codes, NAMES)
    assert got.type == pa.string()
    assert got.equals(pa.array([NAMES[c] for c in codes], pa.string()))


@pytest.mark.parametrize("n", [10, TAKE_MIN_CODES])
@pytest.mark.parametrize("bad", [-1, len(NAMES)])
def test_decoded_array_refuses_codes_outside_the_names(n, bad):
    codes = np.zeros(n, np.int32)
    codes[n // 2] = bad
    with pytest.raises(ValueError, match=r"codes outside 0 \.\. 4"):
        decoded_array(codes, NAMES)


def test_string_array_is_pyarrows():
    assert string_array(NAMES).equals(pa.array(NAMES, pa.string()))


def test_neither_gather_imports_pandas():
    """``pyarrow.array`` imports pandas (~0.5 s of a small run's start): not used."""
    code = (
        "import sys, numpy as np; from leolink.io.arrow import decoded_array, TAKE_MIN_CODES\n"
        "for n in (10, TAKE_MIN_CODES): decoded_array(np.zeros(n, np.int32), ['a', 'b'])\n"
        "print('pandas' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
