"""Helpers of the reliability tests (issue 19): the CLI in this process, broken inputs."""

from __future__ import annotations

from pathlib import Path

from leolink.cli import main

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "configs" / "paper.toml"
TLE_CONFIG = ROOT / "configs" / "examples" / "tle.toml"
ISS_TLE = ROOT / "configs" / "examples" / "tles" / "iss.tle"
#: No plots, no report: the tests look at exit codes, messages and files.
FAST = ["output.plots.enabled=false", "output.report.enabled=false"]
#: The first line of a system file (/etc/passwd): an error must never print it.
SYSTEM_LINE = "root:x:0:0:root:/root:/bin/bash"


def cli(capsys, *argv):
    """``(exit code, stdout, stderr)`` of ``leolink ARGV`` run in this process."""
    capsys.readouterr()
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def files_in(folder):
    """Every file under ``folder`` (relative, sorted); [] if it does not exist."""
    folder = Path(folder)
    if not folder.exists():
        return []
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if not p.is_dir())


def with_checksum(line68):
    """A TLE line: 68 columns and their modulo-10 checksum."""
    digits = sum(int(c) for c in line68 if c.isdigit()) + line68.count("-")
    return line68 + str(digits % 10)


def iss_lines():
    _, line1, line2 = ISS_TLE.read_text(encoding="utf-8").splitlines()
    return line1, line2


def tle_text(line1=None, line2=None, name="SAT"):
    """A 3-line TLE file: the ISS's, with line 1 or 2 replaced (checksums recomputed)."""
    l1, l2 = iss_lines()
    l1 = with_checksum(line1[:68]) if line1 else l1
    l2 = with_checksum(line2[:68]) if line2 else l2
    return f"{name}\n{l1}\n{l2}\n"


def decayed_tle():
    """The ISS with B* = 0.99999: sgp4 error 6 (decayed) at its epoch."""
    l1, _ = iss_lines()
    return tle_text(line1=l1[:53] + " 99999-0" + l1[61:68])


def eccentric_tle():
    """The ISS with eccentricity 0.99: sgp4 error 4 (semilatus rectum < 0)."""
    _, l2 = iss_lines()
    return tle_text(line2=l2[:26] + "9900000" + l2[33:68])


def garbage_field_tle():
    """Inclination 'x1.6439' (checksum recomputed: valid): sgp4 reads garbage silently."""
    _, l2 = iss_lines()
    return tle_text(line2=l2[:8] + " x1.6439" + l2[16:68])
