"""leolink.io.arrow: numpy -> Arrow string columns, against pyarrow's own conversion and
the strings a writer was given."""

import csv
import subprocess
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from leolink.io import tables
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


@pytest.mark.parametrize("after", [0, 5, 10**9])  # take from the start, from row 6, never
def test_a_writer_switching_to_take_writes_the_same_strings(tmp_path, monkeypatch, after):
    """TableWriter gathers its string columns by Arrow's take once it has written
    TAKE_AFTER_ROWS rows: the CSV and Parquet strings are those appended, either way."""
    monkeypatch.setattr(tables, "TAKE_AFTER_ROWS", after)
    flags = []  # by_take of each string column's gather, in order

    def recorded(codes, names, by_take=False):
        flags.append(by_take)
        return decoded_array(codes, names, by_take)

    monkeypatch.setattr(tables, "decoded_array", recorded)
    rng = np.random.default_rng(after)
    services = ["served", "handover", "outage"]
    want = []
    with tables.TraceWriter(tmp_path, formats=("parquet", "csv"), chunk_rows=3) as w:
        for i in range(5):
            cols = _trace_rows(4, start=4 * i)
            cols["service"] = np.array(rng.choice(services, 4))
            want += cols["service"].tolist()
            w.append(cols)
    assert pq.read_table(tmp_path / "trace.parquet")["service"].to_pylist() == want
    with open(tmp_path / "trace.csv", newline="") as f:
        assert [row["service"] for row in csv.DictReader(f)] == want
    # 20 rows in chunks of 3: 7 chunks, each gathering its string columns twice (CSV,
    # Parquet); take from the first chunk that starts at or after `after` rows.
    per_chunk = len(flags) // 7
    starts = np.repeat(np.arange(7) * 3, per_chunk)
    assert len(flags) == 7 * per_chunk and per_chunk > 0
    np.testing.assert_array_equal(flags, starts >= after)


def _trace_rows(n, start):
    cols = {}
    for f in tables.TRACE_SCHEMA:
        if str(f.type).startswith("int"):
            cols[f.name] = np.arange(start, start + n, dtype=np.int64)
        else:
            cols[f.name] = np.linspace(0.0, 1.0, n) + start
    return cols
