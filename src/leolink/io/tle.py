"""Two-line element files: read and checked here, propagated by :mod:`leolink.orbit`."""

from pathlib import Path

from leolink.errors import LeolinkError

__all__ = ["read_tle_file"]


def _tle_checksum_ok(line):
    digits = sum(int(ch) for ch in line[:68] if ch.isdigit()) + line[:68].count("-")
    return line[68].isdigit() and digits % 10 == int(line[68])


def _check_tle_line(path, lineno, line, number):
    template = f"{number} NNNNNC NNNNNAAA ... (69 columns, checksum in column 69)"
    if len(line) < 69 or not line.startswith(f"{number} "):
        raise LeolinkError(
            f"{path}:{lineno}: malformed TLE line {number}: {line!r}; expected {template}"
        )
    if not _tle_checksum_ok(line):
        raise LeolinkError(f"{path}:{lineno}: TLE line {number} checksum fails: {line!r}")


def read_tle_file(path):
    """Read a 2-line or 3-line (named) TLE file.

    Returns
    -------
    list of (name, line1, line2)
        ``name`` is ``""`` for 2-line entries.

    Raises
    ------
    LeolinkError
        Naming the file and line of a malformed TLE.
    """
    lines = [(i + 1, ln.rstrip()) for i, ln in enumerate(Path(path).read_text().splitlines())]
    lines = [(i, ln) for i, ln in lines if ln.strip()]
    out, k = [], 0
    while k < len(lines):
        name = ""
        if not lines[k][1].startswith("1 "):
            name = lines[k][1].strip()
            name = name[2:].strip() if name.startswith("0 ") else name
            k += 1
        if k + 1 >= len(lines):
            lineno = lines[k][0] if k < len(lines) else lines[-1][0]
            raise LeolinkError(f"{path}:{lineno}: incomplete TLE (expected two lines after name)")
        (n1, l1), (n2, l2) = lines[k], lines[k + 1]
        _check_tle_line(path, n1, l1, 1)
        _check_tle_line(path, n2, l2, 2)
        out.append((name, l1, l2))
        k += 2
    return out
