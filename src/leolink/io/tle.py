"""Two-line element files: read and checked here, propagated by :mod:`leolink.orbit`.

Every line is checked column by column against the format (CelesTrak, "FAQs: Two-Line
Element Set Format"; the fields and their columns are :data:`_LINE1_FIELDS` and
:data:`_LINE2_FIELDS`): sgp4's own parser reads a garbage field as 0 or as part of a
number and never says so, and the modulo-10 checksum does not catch every garbage field.
Errors name the file, the line, the field and its columns, never the line's text (the
file could be anything a config points at).
"""

import re

from leolink.errors import LeolinkError
from leolink.textfile import read_text

__all__ = ["TleFileError", "read_tle_file"]


class TleFileError(LeolinkError, ValueError):
    """A TLE file that leolink cannot read (names file, line and field)."""


_INT = r"[ 0-9]*[0-9]"
_FLOAT = r" *[+-]?[0-9]*\.[0-9]+"
_EXP = r"[ +-][0-9]{5}[+-][0-9]"  # implied decimal point and exponent: " 38792-4"
#: (first column, last column, name, pattern, low, high) of each field, 1-based columns.
_LINE1_FIELDS = (
    (3, 7, "satellite number", r"[0-9A-Z][0-9 ]{3}[0-9]", None, None),
    (8, 8, "classification", r"[UCS ]", None, None),
    (19, 20, "epoch year", r"[0-9]{2}", None, None),
    (21, 32, "epoch day", r"[ 0-9]{3}\.[0-9]{8}", 1.0, 367.0),
    (34, 43, "first derivative of mean motion", r"[ +-]\.[0-9]{8}|[ +-]0\.[0-9]{7}", None, None),
    (45, 52, "second derivative of mean motion", _EXP, None, None),
    (54, 61, "B* drag term", _EXP, None, None),
    (63, 63, "ephemeris type", r"[0-9 ]", None, None),
    (65, 68, "element set number", r" *[0-9]*", None, None),
)
_LINE2_FIELDS = (
    (3, 7, "satellite number", r"[0-9A-Z][0-9 ]{3}[0-9]", None, None),
    (9, 16, "inclination [deg]", _FLOAT, 0.0, 180.0),
    (18, 25, "right ascension of the ascending node [deg]", _FLOAT, 0.0, 360.0),
    (27, 33, "eccentricity (decimal point assumed)", r"[0-9]{7}", None, None),
    (35, 42, "argument of perigee [deg]", _FLOAT, 0.0, 360.0),
    (44, 51, "mean anomaly [deg]", _FLOAT, 0.0, 360.0),
    (53, 63, "mean motion [rev/day]", _FLOAT, 0.0, 20.0),
    (64, 68, "revolution number", r" *" + _INT + "|     ", None, None),
)
_COMPILED = {
    n: tuple((a, b, name, re.compile(pat), lo, hi) for a, b, name, pat, lo, hi in fields)
    for n, fields in ((1, _LINE1_FIELDS), (2, _LINE2_FIELDS))
}


def _tle_checksum_ok(line):
    digits = sum(int(ch) for ch in line[:68] if ch.isdigit()) + line[:68].count("-")
    return line[68].isdigit() and digits % 10 == int(line[68])


def _check_tle_line(path, lineno, line, number):
    where = f"{path}:{lineno}: TLE line {number}"
    if len(line) != 69 or not line.startswith(f"{number} ") or not line.isascii():
        raise TleFileError(
            f"{where} is malformed ({len(line)} columns); expected 69 ASCII columns "
            f"starting with '{number} ', checksum in column 69"
        )
    for first, last, name, pattern, low, high in _COMPILED[number]:
        text = line[first - 1 : last]
        if not pattern.fullmatch(text):
            raise TleFileError(f"{where}, columns {first}-{last} ({name}): not a valid value")
        if low is not None and not low <= float(text) <= high:
            raise TleFileError(
                f"{where}, columns {first}-{last} ({name}): {float(text)!r} is out of "
                f"[{low:g}, {high:g}]"
            )
    if not _tle_checksum_ok(line):
        raise TleFileError(f"{where}: checksum (column 69) fails")


def _lines(path):
    text = read_text(path, "TLE file", TleFileError)
    lines = [(i + 1, ln.rstrip()) for i, ln in enumerate(text.splitlines())]
    return [(i, ln) for i, ln in lines if ln.strip()]


def read_tle_file(path):
    """Read a 2-line or 3-line (named) TLE file.

    Returns
    -------
    list of (name, line1, line2)
        ``name`` is ``""`` for 2-line entries.

    Raises
    ------
    TleFileError
        Naming the file, the line and the field of a malformed TLE, or an empty file.
    """
    lines = _lines(path)
    out, k = [], 0
    while k < len(lines):
        name = ""
        if not lines[k][1].startswith("1 "):
            name = lines[k][1].strip()
            name = name[2:].strip() if name.startswith("0 ") else name
            if len(name) > 80 or not name.isprintable():
                raise TleFileError(
                    f"{path}:{lines[k][0]}: not a TLE: expected a name (at most 80 "
                    "printable characters) or line 1"
                )
            k += 1
        if k + 1 >= len(lines):
            lineno = lines[k][0] if k < len(lines) else lines[-1][0]
            raise TleFileError(f"{path}:{lineno}: incomplete TLE (expected two lines after name)")
        (n1, l1), (n2, l2) = lines[k], lines[k + 1]
        _check_tle_line(path, n1, l1, 1)
        _check_tle_line(path, n2, l2, 2)
        if l1[2:7] != l2[2:7]:
            raise TleFileError(
                f"{path}:{n2}: TLE line 2 is of satellite {l2[2:7].strip()}, line 1 "
                f"(line {n1}) of {l1[2:7].strip()}"
            )
        out.append((name, l1, l2))
        k += 2
    if not out:
        raise TleFileError(f"{path}: no TLE in the file (it is empty)")
    return out
