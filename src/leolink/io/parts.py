"""The parts of a split run: each part's stream as Parquet, and the whole run's stream
read back from them.

A part of a split run (:mod:`leolink.app.split`) simulates some of the run's UTs and
streams its frames to a :class:`PartWriter`: ``trace.parquet`` (the frames' trace columns,
the UTs numbered within the part), ``events.parquet`` and ``dwells.parquet`` (with the
recorded epoch ``k`` of each row; the dwells still open at the end have ``k = n_epochs``).
The files are renamed into place when the part finishes (:class:`~leolink.io.atomic.PendingFiles`),
so a part that dies leaves only ``*.partial`` files, never a file that looks whole.

:func:`merged_blocks` reads the parts forward, a window of epochs at a time (memory
bounded by :data:`WINDOW_ROWS`, however long the run), and rebuilds the
:class:`~leolink.sim.streams.BlockFrame` s a single process would have streamed: every
epoch's rows by run-wide UT id, the events and dwells of an epoch by UT (each UT's own
order kept). The run's sinks then write the same outputs as a single-process run.

The parts live in ``OUT/.parts-<random>.partial/`` (:func:`parts_folder`) while the run
runs; the run removes it at its end, on an error and on any signal it can catch. A parent
killed outright (SIGKILL, a lost machine) leaves it: the next command that claims ``OUT``
removes it (:func:`remove_stale_parts`, called with the folder locked).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import stat
import tempfile
from pathlib import Path

import numpy as np

from leolink.io.atomic import PendingFiles
from leolink.sim.streams import BlockFrame

__all__ = [
    "PARTS_PREFIX",
    "PART_FILES",
    "WINDOW_ROWS",
    "PartWriter",
    "merged_blocks",
    "parts_folder",
    "remove_stale_parts",
]

#: A split run's parts folder in its output folder: ``.parts-<random>.partial``.
PARTS_PREFIX, PARTS_SUFFIX = ".parts-", ".partial"
_PART = re.compile(r"part-\d{5}")

#: The files of one part.
PART_FILES = ("trace.parquet", "events.parquet", "dwells.parquet")
#: Trace rows of all parts read at once by :func:`merged_blocks` (~40 MiB of columns).
WINDOW_ROWS = 1 << 17
_DTYPES = b"leolink_dtypes"  # schema metadata: each column's numpy dtype
_REBUILT = ("population",)  # trace columns rebuilt from the run's UTs, not stored


def _dtype(values):
    """A column's numpy dtype as stored: ``"str"`` for text (its width varies by block)."""
    dtype = np.asarray(values).dtype
    return "str" if dtype.kind == "U" else dtype.str


def _table(columns):
    """A pyarrow table of numpy columns, their dtypes in its schema's metadata."""
    import pyarrow as pa

    kept = {k: v for k, v in columns.items() if k not in _REBUILT}
    table = pa.table(kept)
    return table.replace_schema_metadata(
        {_DTYPES: json.dumps({k: _dtype(v) for k, v in kept.items()})}
    )


def _epochs_of(ends, k0):
    """The recorded epoch of every row of a block's events (dwells), from their ends."""
    n = int(ends[-1]) if len(ends) else 0
    return k0 + np.searchsorted(np.asarray(ends), np.arange(n), side="right")


def parts_folder(out_dir):
    """A new, empty parts folder in ``out_dir`` (the system's temporary folder if None)."""
    return Path(tempfile.mkdtemp(prefix=PARTS_PREFIX, suffix=PARTS_SUFFIX, dir=out_dir))


def _is_parts_folder(path):
    """A real folder (not a link) with only ``part-NNNNN`` real folders in it."""
    try:
        if not stat.S_ISDIR(os.lstat(path).st_mode):
            return False
        return all(_PART.fullmatch(p.name) and not p.is_symlink() and p.is_dir()
                   for p in path.iterdir())  # fmt: skip
    except OSError:
        return False


def remove_stale_parts(out_dir):
    """Remove the parts folders that a killed split run left in ``out_dir``; call it with
    ``out_dir`` locked (:func:`leolink.io.run_dir.claim_out_dir`): no live command of this
    machine owns them then. Only what :func:`parts_folder` makes is removed (a real folder
    ``.parts-*.partial`` holding ``part-NNNNN`` folders), without following a link
    (``shutil.rmtree``'s own rule); returns the removed folders.
    """
    stale = [p for p in Path(out_dir).glob(f"{PARTS_PREFIX}*{PARTS_SUFFIX}") if _is_parts_folder(p)]
    for path in stale:
        shutil.rmtree(path, ignore_errors=True)
    return stale


class PartWriter:
    """A sink that writes one part's stream to ``folder`` (:data:`PART_FILES`).

    Parameters
    ----------
    folder : path-like, created if missing.
    """

    def __init__(self, folder):
        self.folder = Path(folder)
        self._pending, self._writers, self.n_epochs = None, {}, 0

    def start(self, info):
        self.folder.mkdir(exist_ok=True)  # not its parent: a stopped split run removed it
        self._pending, self._writers, self.n_epochs = PendingFiles(), {}, info.n_epochs
        self._no_events = None  # the events' columns, without rows

    def _write(self, name, columns, last=False):
        """Append rows to ``name``; the file's schema is that of its first rows (an empty
        table's columns may lack their types: it waits, unless it is the ``last``)."""
        import pyarrow.parquet as pq

        table = _table(columns)
        writer = self._writers.get(name)
        if writer is None and (table.num_rows or last):
            native = self._pending.open_native(self.folder / name)
            writer = self._writers[name] = pq.ParquetWriter(native, table.schema)
        if writer is not None:
            writer.write_table(table.cast(writer.schema))

    def block(self, frame):
        self._write("trace.parquet", frame.columns)
        for name, rows, ends in (("events.parquet", frame.events, frame.event_end),
                                 ("dwells.parquet", frame.dwells, frame.dwell_end)):  # fmt: skip
            self._write(name, {**rows, "k": _epochs_of(ends, frame.k0)})
        self._no_events = {**{k: v[:0] for k, v in frame.events.items()}, "k": np.zeros(0, int)}

    def epoch(self, frame):
        """An epoch frame (runs with radio link failure monitoring): a one-epoch block."""
        self._write("trace.parquet", frame.columns)
        for name, rows in (("events.parquet", frame.events), ("dwells.parquet", frame.dwells)):
            self._write(name, {**rows, "k": np.full(len(rows["ut_id"]), frame.k, np.int64)})
        self._no_events = {**{k: v[:0] for k, v in frame.events.items()}, "k": np.zeros(0, int)}

    def finish(self, final):
        k = np.full(len(final.dwells["ut_id"]), self.n_epochs, np.int64)
        self._write("dwells.parquet", {**final.dwells, "k": k}, last=True)
        if "events.parquet" not in self._writers and self._no_events is not None:  # no events
            self._write("events.parquet", self._no_events, last=True)
        for writer in self._writers.values():
            writer.close()
        self._pending.commit()

    def abort(self):
        for writer in self._writers.values():
            try:
                writer.close()
            except Exception:  # noqa: S110  the files are removed next
                pass
        if self._pending is not None:
            self._pending.abort()


class _Reader:
    """One part file read forward in slices of rows (numpy columns, their own dtypes)."""

    def __init__(self, path, batch_rows):
        import pyarrow.parquet as pq

        self._file = pq.ParquetFile(path)
        self._batches = self._file.iter_batches(batch_size=batch_rows)
        self._dtypes = json.loads(self._file.schema_arrow.metadata[_DTYPES])
        self._buffer, self._n = [], 0

    def _more(self):
        batch = next(self._batches, None)
        if batch is None:
            return False
        self._buffer.append(batch)
        self._n += batch.num_rows
        return True

    def _take(self, n):
        import pyarrow as pa

        table = pa.Table.from_batches(self._buffer, schema=self._file.schema_arrow)
        head, rest = table.slice(0, n), table.slice(n)
        self._buffer, self._n = rest.to_batches(), rest.num_rows
        return {name: _numpy(head.column(name), dtype) for name, dtype in self._dtypes.items()}

    def rows(self, n):
        """The next ``n`` rows (fewer at the end of the file)."""
        while self._n < n and self._more():
            pass
        return self._take(min(n, self._n))

    def before(self, k_end):
        """The next rows whose epoch ``k`` is below ``k_end`` (the file is sorted by ``k``)."""
        while self._more_needed(k_end) and self._more():
            pass
        k = np.concatenate([b.column("k").to_numpy() for b in self._buffer]) if self._n else []
        return self._take(int(np.searchsorted(k, k_end, side="left")))

    def _more_needed(self, k_end):
        if not self._n:
            return True
        last = self._buffer[-1].column("k")
        return len(last) == 0 or last[-1].as_py() < k_end


def _numpy(column, dtype):
    values = column.to_numpy(zero_copy_only=False)
    return values.astype(str if dtype == "str" else dtype, copy=False)


def _by_ut(pieces, ids):
    """Rows of several parts' tables (each with ``k`` and part-local ``ut_id``) as one
    table by (``k``, run-wide ``ut_id``), each UT's rows in their order; ``k`` separate."""
    rows = {name: np.concatenate([p[name] for p in pieces]) for name in pieces[0]}
    rows["ut_id"] = np.concatenate([i[p["ut_id"]] for p, i in zip(pieces, ids, strict=True)])
    order = np.lexsort((rows["ut_id"], rows["k"]))  # stable: a UT's rows keep their order
    rows = {name: v[order] for name, v in rows.items()}
    return rows, rows.pop("k")


def _trace(pieces, ids, order, population, n_epoch):
    """The epochs' trace rows of every part, epoch after epoch, each by run-wide UT id."""
    columns = {}
    for name in pieces[0]:
        parts = [
            i[p[name]] if name == "ut_id" else p[name] for p, i in zip(pieces, ids, strict=True)
        ]
        wide = np.concatenate([a.reshape(n_epoch, -1) for a in parts], axis=1)  # parts side by side
        columns[name] = wide[:, order].reshape(-1)
    columns["population"] = np.tile(population, n_epoch)
    return columns


def merged_blocks(folders, ids, population, n_epochs):
    """The run's :class:`~leolink.sim.streams.BlockFrame` s, rebuilt from its parts.

    Parameters
    ----------
    folders : sequence of path-like, each part's folder (:class:`PartWriter`).
    ids : sequence of ndarray of int, each part's run-wide UT ids (increasing), in the
        order of ``folders``; together every UT of the run once.
    population : sequence of str (n_ut,), the population of every UT of the run.
    n_epochs : int, recorded epochs.

    Yields
    ------
    BlockFrame
        Windows of epochs (about :data:`WINDOW_ROWS` rows each), in order; the last item
        is instead the dict of the dwells still open at the end (the ``FinalFrame``'s).
    """
    ids = [np.asarray(i, np.int64) for i in ids]
    order = np.argsort(np.concatenate(ids), kind="stable")
    n_ut = len(order)
    population = np.asarray(population, dtype=object)
    n_window = max(1, WINDOW_ROWS // n_ut)
    readers = [{name: _Reader(Path(f) / name, WINDOW_ROWS) for name in PART_FILES} for f in folders]
    for k0 in range(0, n_epochs, n_window):
        n = min(n_window, n_epochs - k0)
        pieces = [r["trace.parquet"].rows(n * len(i)) for r, i in zip(readers, ids, strict=True)]
        columns = _trace(pieces, ids, order, population, n)
        extra = {}
        for name in ("events.parquet", "dwells.parquet"):
            rows, k = _by_ut([r[name].before(k0 + n) for r in readers], ids)
            extra[name] = (rows, np.searchsorted(k, k0 + 1 + np.arange(n), side="left"))
        t_s = columns["time_s"][::n_ut].copy()
        yield BlockFrame(k0, t_s, n_ut, columns, *_pair(extra))
    final, _ = _by_ut([r["dwells.parquet"].before(n_epochs + 1) for r in readers], ids)
    yield final


def _pair(extra):
    (events, event_end), (dwells, dwell_end) = extra["events.parquet"], extra["dwells.parquet"]
    return events, dwells, event_end, dwell_end
