"""Output folders: recognise another run's files, replace them only when asked, and the
manifest ``run.json`` that marks a finished run.

A leolink output folder is recognisable by its ``run.json`` or by the names leolink writes
(:data:`KNOWN_NAMES`, :data:`KNOWN_PATTERNS`). :func:`claim_out_dir` refuses a folder that
holds such files unless ``overwrite``, which removes only regular files leolink wrote: those
a manifest it wrote lists (``run.json``, or ``run.unfinished.json`` of a stopped run), each
reached without following a symbolic link, inside the folder, its SHA-256 still the listed
one. A file with one of leolink's names that is not such a file (a user's ``report.html``,
a file changed since, a link, the ``*.partial`` file of a killed writer) is left alone and
named in the one-line refusal; a user's notes of another name are never looked at.

One command at a time per folder: :func:`claim_out_dir` takes an exclusive ``fcntl.flock``
on ``DIR/.leolink.lock`` (holding the pid) before it looks at the folder, kept until
:func:`held_out_dirs` ends (the command line holds it for the whole command); a second
command is refused with one line naming the holder's pid. The kernel drops the lock of a
process that died, so a lock file a killed command left (a dead pid) is taken again.

:func:`write_manifest` is called last by every command: ``run.json`` holds the leolink
version, the command, the SHA-256 of the resolved config and every file written (path
relative to the folder, size in bytes, SHA-256). A folder without it is not a finished run:
an interrupted run leaves none (its files may be complete, the run is not) but lists those
it finished in ``run.unfinished.json``, so the next run into that folder is refused with a
message naming the files, and ``--overwrite`` clears them.
"""

from __future__ import annotations

import contextlib
import fnmatch
import hashlib
import json
import os
import stat
from datetime import UTC, datetime
from pathlib import Path

from leolink.errors import LeolinkError
from leolink.io.atomic import PARTIAL_SUFFIX, write_json_atomic

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "KNOWN_NAMES",
    "LOCK",
    "MANIFEST",
    "UNFINISHED",
    "OutputFolderError",
    "claim_out_dir",
    "config_sha256",
    "file_sha256",
    "held_out_dirs",
    "lock_out_dir",
    "owned_files",
    "read_manifest",
    "verify_manifest",
    "write_manifest",
]

MANIFEST = "run.json"
#: The manifest of a run stopped after some of its files were finished (no ``run.json``).
UNFINISHED = "run.unfinished.json"
MANIFEST_VERSION = 1
#: The lock file of an output folder in use (:func:`claim_out_dir`): the holder's pid.
LOCK = ".leolink.lock"
_HELD: dict[Path, int] = {}  # lock file -> descriptor holding its flock
#: Files the commands write at the top of their folder (run, coverage, sweep).
KNOWN_NAMES = frozenset(
    {
        MANIFEST,
        UNFINISHED,
        "trace.csv",
        "trace.parquet",
        "events.csv",
        "events.parquet",
        "summary.json",
        "per_ut.parquet",
        "dwells.parquet",
        "config.resolved.toml",
        "report.html",
        "report_stats.npz",
        "footprint.gif",
        "run.geojson",
        "run.czml",
        "snr_time.png",
        "doppler_time.png",
        "dwell_hist.png",
        "handovers.png",
        "coverage.csv",
        "coverage_beams.png",
        "coverage_snr.png",
        "coverage_sinr.png",
        "coverage_se.png",
        "coverage_doppler.png",
        "coverage_angular_speed.png",
        "coverage_cuts.png",
        "sweep.csv",
        "sweep.json",
        "compare.csv",
        "compare_runs.csv",
        "compare.md",
    }
)
#: Name patterns of files a command writes (sweep and compare plots).
KNOWN_PATTERNS = ("sweep_*.png", "compare_*.png")
_RUNS = "runs"  # sweep: one run folder per grid point
_CHUNK = 1 << 20


class OutputFolderError(LeolinkError):
    """An output folder that holds another run's files, or a manifest that cannot be used."""


def file_sha256(path):
    """SHA-256 (hex) of a file, read in 1 MiB blocks."""
    return GrowingDigest(path).finish()[1]


class GrowingDigest:
    """SHA-256 of a file that is only ever appended to, read back as it grows.

    Its writer calls :meth:`update` after its writes (on its own thread, the hashing then
    overlaps the run instead of following it: the 316 MiB trace of ``bench_sim`` took
    0.22 s to hash at the end) and :meth:`finish` once the file is closed. A sequential
    writer (CSV, Parquet) never rewrites a byte, so what was read is the finished file.
    """

    def __init__(self, path):
        self._file, self._sha, self.n_bytes = open(path, "rb"), hashlib.sha256(), 0  # noqa: SIM115

    def update(self):
        """Hash what was appended since the last call."""
        while block := self._file.read(_CHUNK):
            self._sha.update(block)
            self.n_bytes += len(block)

    def finish(self):
        """``(size [bytes], SHA-256 hex)`` of the whole (closed) file."""
        try:
            self.update()
        finally:
            self.close()
        return self.n_bytes, self._sha.hexdigest()

    def close(self):
        self._file.close()


def config_sha256(config_text):
    """SHA-256 (hex) of the resolved config's text (UTF-8)."""
    return hashlib.sha256(config_text.encode("utf-8")).hexdigest()


def read_manifest(out_dir, name=MANIFEST):
    """``run.json`` (or ``name``) of a folder as a dict, or None when there is none.

    Raises
    ------
    OutputFolderError
        The file exists but is not a leolink manifest.
    """
    path = Path(out_dir) / name
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text("utf-8"))
        if not isinstance(data, dict) or not isinstance(data["files"], list):
            raise TypeError
        [str(f["path"]) for f in data["files"]]
    except (ValueError, KeyError, TypeError) as exc:
        raise OutputFolderError(
            f"{path} is not a leolink manifest ({type(exc).__name__}); move it away or remove it"
        ) from None
    return data


def _inside(out_dir, rel):
    """``out_dir / rel`` if it stays inside ``out_dir`` (no absolute path, no ``..``)."""
    rel_path = Path(rel)
    if rel_path.is_absolute() or ".." in rel_path.parts or not rel_path.parts:
        raise OutputFolderError(
            f"{Path(out_dir) / MANIFEST} lists {rel!r}, which is outside its folder; "
            "leolink removes only files inside the folder"
        )
    return Path(out_dir) / rel_path


def _regular_file(out_dir, rel):
    """``out_dir / rel`` when each of its folders below ``out_dir`` is a real folder and it
    is a regular file, none of them a symbolic link (``os.lstat`` of each component: a
    link planted in the folder never leads a removal outside it); else None."""
    path = _inside(out_dir, rel)
    here = Path(out_dir)
    for part in path.relative_to(out_dir).parts:
        here = here / part
        try:
            mode = os.lstat(here).st_mode
        except OSError:
            return None
        if not (stat.S_ISREG(mode) if here == path else stat.S_ISDIR(mode)):
            return None
    return path


def _sha256_no_follow(path):
    """SHA-256 of a regular file opened with ``O_NOFOLLOW`` (never a link's target)."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    sha = hashlib.sha256()
    with os.fdopen(fd, "rb") as handle:
        while block := handle.read(_CHUNK):
            sha.update(block)
    return sha.hexdigest()


def _mismatch(folder, entry):
    """Why the file a manifest ``entry`` lists is not what leolink wrote (not a regular
    file reached without a link, another size or SHA-256), or None when it is."""
    path = _regular_file(folder, entry["path"])
    if path is None:
        return "is missing or not a regular file"
    size = os.lstat(path).st_size
    if size != entry.get("bytes"):
        return f"has {size:,} bytes where run.json lists {entry.get('bytes')}"
    try:
        same = _sha256_no_follow(path) == entry.get("sha256")
    except OSError:
        same = False
    return None if same else "has another SHA-256 than run.json lists"


def _verified(folder, manifest):
    """The files ``manifest`` (of ``folder``) lists that are still what leolink wrote."""
    return [folder / e["path"] for e in manifest["files"] if _mismatch(folder, e) is None]


def verify_manifest(out_dir, rewritten=()):
    """Check that every file ``run.json`` lists is still what leolink wrote (a regular file
    reached without a link, of the listed size and SHA-256), before a command reads them;
    but the names in ``rewritten``, which the command writes anew.

    Raises
    ------
    OutputFolderError
        No ``run.json``, or the first file that is missing, changed or damaged.
    """
    out_dir = Path(out_dir)
    manifest = read_manifest(out_dir)
    if manifest is None:
        return None
    for entry in manifest["files"]:
        why = None if entry["path"] in rewritten else _mismatch(out_dir, entry)
        if why is None:
            continue
        raise OutputFolderError(
            f"{out_dir / entry['path']} {why}: the folder was changed or damaged since its run; "
            "rerun it (leolink run ... --overwrite)"
        )
    return manifest


def _known(name):
    """A name leolink writes, or the temporary file of one (``NAME.<hex>.partial`` of
    :mod:`leolink.io.atomic`, ``footprint.partial.gif`` of the animation)."""
    if name.endswith(PARTIAL_SUFFIX):
        name = name[: -len(PARTIAL_SUFFIX)].rpartition(".")[0]
    elif name == "footprint.partial.gif":
        return True
    return name in KNOWN_NAMES or any(fnmatch.fnmatchcase(name, p) for p in KNOWN_PATTERNS)


def _real_dir(path):
    try:
        return stat.S_ISDIR(os.lstat(path).st_mode)
    except OSError:
        return False


def _known_in(folder):
    if not _real_dir(folder):
        return []
    return sorted(p for p in folder.iterdir() if _known(p.name) and not _real_dir(p))


def _folders(out_dir):
    """``out_dir`` and a sweep's or compare's point folders ``runs/*/`` (real folders)."""
    runs = out_dir / _RUNS
    subs = sorted(p for p in runs.iterdir() if _real_dir(p)) if _real_dir(runs) else []
    return [out_dir, *subs]


def owned_files(out_dir):
    """Files of leolink runs in ``out_dir``, as ``(verified, others)``, each sorted.

    ``verified``: the files a manifest (``run.json``, or ``run.unfinished.json`` of a
    stopped run) lists and that are still what leolink wrote (:func:`_verified`), and
    each manifest all of whose files are. ``others``: any other file with one of leolink's
    names (:data:`KNOWN_NAMES`, also in ``runs/*/``), or that a manifest lists and that is
    not (or no longer) leolink's: a user's ``report.html``, a changed file, a link.
    """
    out_dir = Path(out_dir)
    verified, named = set(), set()
    for folder in _folders(out_dir):
        named.update(_known_in(folder))
        for name in (MANIFEST, UNFINISHED):
            if (manifest := read_manifest(folder, name)) is None:
                continue
            mine = _verified(folder, manifest)
            verified.update(mine)
            listed = [_inside(folder, e["path"]) for e in manifest["files"]]
            named.update(p for p in listed if p not in mine and os.path.lexists(p))
            if len(mine) == len(listed) and _regular_file(folder, name) is not None:
                verified.add(folder / name)
    return sorted(verified), sorted(named - verified)


def _describe(out_dir, files):
    manifest = read_manifest(out_dir)
    if manifest is not None:
        what, version = manifest.get("command", "run"), manifest.get("leolink_version")
        return f"the files of a finished 'leolink {what}' (run.json of leolink {version})"
    return f"files of an unfinished leolink run (no run.json: {_names(out_dir, files)})"


def _names(out_dir, files):
    names = ", ".join(str(p.relative_to(out_dir)) for p in files[:4])
    return names + (f" and {len(files) - 4} more" if len(files) > 4 else "")


def lock_out_dir(out_dir):
    """Take ``out_dir``'s lock (:data:`LOCK`, ``fcntl.flock``: the kernel drops it when its
    holder dies, so a lock file a killed command left is simply taken again), held until
    :func:`held_out_dirs` ends; one this process holds already is held once."""
    path = Path(out_dir) / LOCK
    key = path.absolute()
    if fcntl is None or key in _HELD:  # (no flock on Windows: no lock there)
        return
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
            os.close(fd)
            raise OutputFolderError(
                f"--out {out_dir} is in use by another leolink command (pid {holder}, lock "
                f"file {path}); wait for it to end or choose another folder"
            ) from None
        if _same_file(fd, path):  # not the file of a holder that removed it meanwhile
            break
        os.close(fd)
    _HELD[key] = fd
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())


def _same_file(fd, path):
    try:
        return os.path.samestat(os.fstat(fd), os.lstat(path))
    except FileNotFoundError:
        return False


@contextlib.contextmanager
def held_out_dirs():
    """The output folders claimed inside the block (:func:`claim_out_dir`) stay locked
    until it ends: their lock files are then removed and the locks released."""
    before = set(_HELD)
    try:
        yield
    finally:
        for key in [k for k in _HELD if k not in before]:
            with contextlib.suppress(OSError):
                os.unlink(key)  # first: a waiting command then finds a new file
            os.close(_HELD.pop(key))


def claim_out_dir(out_dir, overwrite=False, flag="--overwrite", keep=()):
    """Make ``out_dir`` ready for a new run; returns it as a Path.

    Parameters
    ----------
    out_dir : path-like
        Created if missing. A folder with only other files (not leolink's) is used as is.
    overwrite : bool
        Remove the files of an earlier run first: only the regular files a manifest lists
        whose size and SHA-256 still match it (:func:`owned_files`), never through a
        symbolic link; without it such files make this raise.
    flag : str
        How the caller's user asks for ``overwrite`` (named in the message).
    keep : sequence of str
        Paths relative to ``out_dir`` to leave in place (a resumed sweep keeps ``runs``).

    Raises
    ------
    OutputFolderError
        ``out_dir`` is in use by another command (:func:`lock_out_dir`), is a file, or holds an
        earlier run's files and ``overwrite`` is off, or
        holds files with leolink's names that leolink did not write (left alone, named).
    """
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputFolderError(f"--out {out_dir} is a file; give a folder")
    if out_dir.is_symlink() and not out_dir.exists():
        raise OutputFolderError(
            f"--out {out_dir} is a link to {os.readlink(out_dir)!r}, which does not exist; "
            "create that folder or give another one"
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    lock_out_dir(out_dir)  # before looking: no other command writes or removes here meanwhile
    from leolink.io.parts import remove_stale_parts

    remove_stale_parts(out_dir)  # a killed split run's parts: locked, no one else's
    mine, others = (
        [p for p in group if not _kept(p, out_dir, keep)] for group in owned_files(out_dir)
    )
    if not mine and not others:
        return out_dir
    if not overwrite:
        raise OutputFolderError(
            f"--out {out_dir} holds {_describe(out_dir, mine + others)}; rerun with {flag} to "
            "replace it (only leolink's files are removed), or choose another folder"
        )
    if others:  # (a manifest is named last: the files are why it cannot be trusted)
        others.sort(key=lambda p: (p.name in (MANIFEST, UNFINISHED), p))
        raise OutputFolderError(
            f"--out {out_dir} holds {_names(out_dir, others)}, not written by leolink or changed "
            "since (not in its run.json with that size and SHA-256, or behind a link): left "
            "alone; move them away or choose another folder"
        )
    manifests = [p for p in mine if p.name in (MANIFEST, UNFINISHED)]
    for path in [p for p in mine if p not in manifests] + manifests:  # manifests last
        path.unlink(missing_ok=True)
    if not _kept(out_dir / _RUNS, out_dir, keep):
        for sub in _folders(out_dir)[1:]:
            _rmdir_if_empty(sub)
        _rmdir_if_empty(out_dir / _RUNS)
    return out_dir


def _kept(path, out_dir, keep):
    rel = path.relative_to(out_dir)
    return any(rel == Path(k) or Path(k) in rel.parents for k in keep)


def _rmdir_if_empty(folder):
    if _real_dir(folder) and not any(folder.iterdir()):
        folder.rmdir()


def write_manifest(
    out_dir, files, command, config_text, arguments=None, *, version, digests=None, name=MANIFEST
):
    """Write ``run.json`` last: the leolink version, ``command``, the config's SHA-256 and
    every file of ``files`` (inside ``out_dir``) with its size and SHA-256.

    Parameters
    ----------
    out_dir : path-like
    files : iterable of path-like
        Files the command wrote, as it wrote them (absolute, or relative to the current
        directory like ``out_dir``); duplicates and ``run.json`` itself are dropped.
    command : str
        ``"run"``, ``"coverage"``, ``"sweep"``, ...
    config_text : str
        The resolved config (its hash identifies the run).
    arguments : dict, optional
        Command arguments that change the outputs besides the config (e.g. the grid).
    version : str
        ``leolink.__version__`` (passed in: ``io`` does not import the package root).
    digests : dict, optional
        ``{path: (size [bytes], SHA-256 hex)}`` known already (a writer's
        :class:`GrowingDigest`), used where the file still has that size.
    name : str
        :data:`MANIFEST`, or :data:`UNFINISHED` for the files a stopped run finished.

    Returns
    -------
    pathlib.Path
    """
    out_dir = Path(out_dir)
    known = {Path(p).resolve(): d for p, d in (digests or {}).items()}
    entries, seen = [], set()
    for f in files:
        path = Path(f)  # as the command wrote it: absolute, or relative to the cwd
        rel = path.resolve().relative_to(out_dir.resolve()).as_posix()
        if rel in seen or rel in (MANIFEST, UNFINISHED):
            continue
        seen.add(rel)
        size, digest = path.stat().st_size, known.get(path.resolve())
        sha = digest[1] if digest is not None and digest[0] == size else file_sha256(path)
        entries.append({"path": rel, "bytes": size, "sha256": sha})
    manifest = {
        "manifest_version": MANIFEST_VERSION,
        "leolink_version": version,
        "command": command,
        "config_sha256": config_sha256(config_text),
        "arguments": arguments or {},
        "finished_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "files": entries,
    }
    return write_json_atomic(out_dir / name, manifest)
