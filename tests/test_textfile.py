"""Every reader of a user's text file gives the same one-line errors (leolink/textfile.py)."""

from __future__ import annotations

import pytest

from leolink.config import load_config
from leolink.errors import LeolinkError
from leolink.io.tle import read_tle_file
from leolink.io.tracks import read_track_csv, read_track_gpx

READERS = [
    ("config file", load_config),
    ("TLE file", read_tle_file),
    ("track file", read_track_csv),
    ("GPX file", lambda p: read_track_gpx(p, None)),
]


@pytest.mark.parametrize(("what", "read"), READERS, ids=[w for w, _ in READERS])
def test_missing_binary_and_unreadable_files_name_the_file(tmp_path, what, read):
    with pytest.raises(LeolinkError, match=f"^{what} '.*nope' does not exist$"):
        read(tmp_path / "nope")
    binary = tmp_path / "bin"
    binary.write_bytes(b"ok\n\xff\xfe")
    with pytest.raises(LeolinkError, match=f"^{what} '.*bin' is not UTF-8 text \\(byte 3\\)$"):
        read(binary)
    with pytest.raises(LeolinkError, match=f"^{what} '.*' cannot be read: Is a directory$"):
        read(tmp_path)
