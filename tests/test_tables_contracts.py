"""leolink.io.tables: contracts that mutation testing found unchecked (docs/testing.md).

Row groups at exact multiples of ``chunk_rows``, appends of any size copied once in the
written types, an extra column, append after close, the messages of bad formats and
chunk sizes, a nested output folder, required Parquet columns, and the switch of the
string columns to Arrow's take.
"""

import csv
import hashlib

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from leolink.errors import ConfigError
from leolink.io import tables
from leolink.io.arrow import NUMPY_TYPES, decoded_array
from leolink.io.tables import TRACE_SCHEMA, TableWriter, TraceWriter


def _rows(n, start=0):
    cols = {}
    for f in TRACE_SCHEMA:
        if f.name == "service":
            cols[f.name] = np.array(["served"] * n)
        elif str(f.type).startswith("int"):
            cols[f.name] = np.arange(start, start + n, dtype=np.int64)
        else:
            cols[f.name] = np.linspace(0.0, 1.0, n) + start
    return cols


@pytest.mark.parametrize(("n_rows", "chunk", "groups"), [(6, 3, [3, 3]), (7, 3, [3, 3, 1]),
                                                         (3, 3, [3]), (2, 3, [2])])  # fmt: skip
def test_row_groups_follow_chunk_rows_exactly(tmp_path, n_rows, chunk, groups):
    with TraceWriter(tmp_path, formats=("parquet", "csv"), chunk_rows=chunk) as w:
        for i in range(n_rows):  # one row per append, as a one-UT run
            w.append(_rows(1, start=i))
    meta = pq.ParquetFile(tmp_path / "trace.parquet").metadata
    assert [meta.row_group(i).num_rows for i in range(meta.num_row_groups)] == groups
    assert (tmp_path / "trace.csv").read_text().count("\n") == n_rows + 1
    np.testing.assert_array_equal(pq.read_table(tmp_path / "trace.parquet")["ut_id"], range(n_rows))


@settings(max_examples=60, deadline=None)
@given(
    sizes=st.lists(st.integers(0, 9), max_size=8),
    chunk=st.integers(1, 6),
    both=st.booleans(),
    background=st.booleans(),
)
def test_appends_of_any_size_write_each_row_once_in_the_written_types(
    tmp_path_factory, sizes, chunk, both, background
):
    """Appends of 0 .. 9 rows into chunks of 1 .. 6 rows: the Parquet file holds every row
    once, in order, cast to its types (float32 but for the positions and times, int32
    ids, the service names), in row groups of ``chunk`` rows but the last; and the rows
    are copied at append: overwriting an appended array afterwards changes nothing."""
    tmp = tmp_path_factory.mktemp("t")
    rng = np.random.default_rng(len(sizes) * 7 + chunk)
    formats = ("csv", "parquet") if both else ("parquet",)
    appended = []
    with TraceWriter(tmp, formats=formats, chunk_rows=chunk, background=background) as w:
        for size in sizes:
            cols = {
                f.name: rng.normal(size=size) * 1e3 if str(f.type) == "double"
                else rng.integers(-(2**20), 2**20, size) for f in TRACE_SCHEMA
            }  # fmt: skip
            for name, names in tables._CODED_COLUMNS.items():
                cols[name] = rng.integers(0, len(names), size)
            cols["population"] = rng.choice(["car", "ship"], size)
            w.append(cols)
            appended.append({n: v.copy() for n, v in cols.items()})
            for v in cols.values():  # the writer must have taken its copy already
                v[...] = 0
    got = pq.read_table(tmp / "trace.parquet")
    n_rows = sum(sizes)
    meta = pq.ParquetFile(tmp / "trace.parquet").metadata
    groups = [meta.row_group(i).num_rows for i in range(meta.num_row_groups)]
    want_groups = [chunk] * (n_rows // chunk) + ([n_rows % chunk] if n_rows % chunk else [])
    assert groups == want_groups and got.num_rows == n_rows
    for f in got.schema:
        want = np.concatenate([a[f.name] for a in appended]) if appended else np.zeros(0)
        if f.name in tables._CODED_COLUMNS:
            names = np.array(tables._CODED_COLUMNS[f.name], object)
            assert got[f.name].to_pylist() == names[want.astype(int)].tolist()
        elif f.name == "population":
            assert got[f.name].to_pylist() == want.astype(str).tolist()
        else:
            dtype = NUMPY_TYPES[f.type]
            np.testing.assert_array_equal(got[f.name].to_numpy(), want.astype(dtype))
            assert got[f.name].to_numpy().dtype == dtype


def test_an_extra_column_or_append_after_close_is_refused(tmp_path):
    w = TraceWriter(tmp_path)
    with pytest.raises(ValueError, match=r"unexpected: \['bogus'\]"):
        w.append({**_rows(2), "bogus": np.zeros(2)})
    w.close()
    with pytest.raises(ValueError, match=r"append\(\) after close\(\) or abort\(\)"):
        w.append(_rows(2))
    a = TraceWriter(tmp_path / "other")
    a.abort()
    with pytest.raises(ValueError, match="after close"):
        a.append(_rows(1))


def test_bad_formats_and_chunk_rows_name_the_key(tmp_path):
    with pytest.raises(
        ConfigError, match=r"output formats = \[\]; use some of \['csv', 'parquet'\]"
    ):
        TableWriter(tmp_path, "t", TRACE_SCHEMA, formats=())
    with pytest.raises(ConfigError, match=r"output formats = \['xlsx'\]"):
        TableWriter(tmp_path, "t", TRACE_SCHEMA, formats=("xlsx",))
    with pytest.raises(ConfigError, match=r"output\.chunk_rows = 0 .*rows per chunk"):
        TableWriter(tmp_path, "t", TRACE_SCHEMA, chunk_rows=0)


def test_nested_output_folder_is_created(tmp_path):
    with TraceWriter(tmp_path / "a" / "b" / "c") as w:
        w.append(_rows(2))
    assert (tmp_path / "a" / "b" / "c" / "trace.csv").exists()


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
            cols = _rows(4, start=4 * i)
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


@pytest.mark.parametrize("python_file", [False, True], ids=["pyarrow_file", "python_file"])
@pytest.mark.parametrize("background", [False, True], ids=["inline", "thread"])
@pytest.mark.parametrize("n_rows", [0, 5, 2000])
def test_the_digests_of_a_closed_writer_are_its_files_sha256(
    tmp_path, monkeypatch, n_rows, background, python_file
):
    """A writer hashes its files as they grow (``GrowingDigest``, read back after each
    chunk): once closed, each file's size and the SHA-256 of its bytes read anew, also
    through the buffered Python file of a system without ``/proc/self/fd``."""
    if python_file:
        from leolink.io import atomic

        monkeypatch.setattr(atomic, "_reopen_path", lambda handle: None)
    w = TableWriter(tmp_path, "t", TRACE_SCHEMA, formats=("csv", "parquet"), chunk_rows=64,
                    background=background)  # fmt: skip
    for start in range(0, n_rows, 37):  # chunks cut across appends
        w.append(_rows(min(37, n_rows - start), start=start))
    paths = w.close()
    assert sorted(w.digests) == sorted(paths.values()) and len(paths) == 2
    for path in paths.values():
        data = path.read_bytes()
        assert w.digests[path] == (len(data), hashlib.sha256(data).hexdigest())
    if n_rows:
        assert pq.ParquetFile(paths["parquet"]).metadata.num_row_groups == -(-n_rows // 64)


def test_a_stopped_writer_leaves_no_file_and_no_digest(tmp_path):
    w = TableWriter(tmp_path, "t", TRACE_SCHEMA, formats=("csv", "parquet"), chunk_rows=8)
    w.append(_rows(20))
    w.abort()
    assert list(tmp_path.iterdir()) == [] and w.digests == {}
    assert all(g._file.closed for g in w._growing.values())


def test_parquet_columns_are_required_and_keep_their_nans(tmp_path):
    """The writers' arrays hold no nulls (a missing value is a NaN): the Parquet columns
    say so (REQUIRED, no definition levels to write), and a NaN reads back as a NaN."""
    cols = _rows(5)
    cols["snr_db"] = np.array([1.0, np.nan, 3.0, np.nan, 5.0])
    with TraceWriter(tmp_path, formats=("parquet",)) as w:
        w.append(cols)
    path = tmp_path / "trace.parquet"
    schema = pq.read_metadata(path).schema
    assert {schema.column(i).max_definition_level for i in range(len(schema))} == {0}
    assert not any(f.nullable for f in pq.read_schema(path))
    got = pq.read_table(path, columns=["snr_db"]).column(0)
    assert got.null_count == 0
    np.testing.assert_array_equal(got.to_numpy(), np.float32(cols["snr_db"]))


def test_parquet_floats_are_snappy_of_split_bytes_with_statistics_of_the_keys_only(tmp_path):
    """trace.parquet's encoding (tables.parquet_options): every column snappy, the float
    columns byte-stream-split, min/max statistics on the time and id columns alone; the
    values read back are those appended, NaN included."""
    cols = _rows(300)
    cols["snr_db"][::7] = np.nan
    with TraceWriter(tmp_path, formats=("parquet",)) as w:
        w.append(cols)
    meta = pq.ParquetFile(tmp_path / "trace.parquet").metadata
    group = meta.row_group(0)
    n_split = 0
    for i in range(group.num_columns):
        col = group.column(i)
        name = col.path_in_schema
        assert col.compression == "SNAPPY", name
        split = "BYTE_STREAM_SPLIT" in col.encodings
        assert split == (col.physical_type in ("FLOAT", "DOUBLE")), name
        n_split += split
        has_stats = col.is_stats_set and col.statistics.has_min_max
        assert has_stats == (name in tables.PARQUET_STATISTICS_COLUMNS), name
    assert n_split == sum(str(f.type) in ("float", "double") for f in tables.float32_schema(
        TRACE_SCHEMA))  # fmt: skip
    got = pq.read_table(tmp_path / "trace.parquet")
    np.testing.assert_array_equal(got["snr_db"].to_numpy(), cols["snr_db"].astype(np.float32))
    np.testing.assert_array_equal(got["time_s"].to_numpy(), cols["time_s"])
    assert meta.row_group(0).column(1).statistics.max == 299  # ut_id 0 .. 299


@pytest.mark.parametrize("formats", [("parquet",), ("csv", "parquet"), ("csv",)])
def test_a_large_chunk_fills_the_byte_budget_in_the_buffered_types(tmp_path, formats):
    """A writer asked for more rows than CHUNK_BYTES holds buffers as many rows as fit in
    it, in the types it buffers (float32 for a Parquet-only trace, float64 with a CSV):
    its chunk's arrays never exceed the budget and leave less than one row of it unused."""
    with TraceWriter(tmp_path, formats=formats, chunk_rows=10**8) as w:
        used = sum(a.nbytes for a in w._chunk.values())
        row = used // w.chunk_rows
        assert tables.CHUNK_BYTES - row < used <= tables.CHUNK_BYTES
        assert all(len(a) == w.chunk_rows for a in w._chunk.values())
