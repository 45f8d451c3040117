"""Files in and out: the one atomic writer, readers (tracks, TLEs), sinks, plots, report."""

from leolink.io.atomic import (
    atomic_path,
    to_jsonable,
    write_csv_atomic,
    write_json_atomic,
    write_text_atomic,
)

__all__ = [
    "atomic_path",
    "to_jsonable",
    "write_csv_atomic",
    "write_json_atomic",
    "write_text_atomic",
]
