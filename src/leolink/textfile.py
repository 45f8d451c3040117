"""The text files users give (configs, TLEs, tracks): read in one place, one error line.

Every reader of a user's file goes through :func:`read_text`, so a missing file, a file
that is not UTF-8 text and a file that cannot be read give the same one-line messages,
naming the file, whatever the reader.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["read_text"]


def read_text(path, what, error):
    """The UTF-8 text of ``path``, without a leading byte-order mark (Windows editors
    write one; it is no part of the first key or column name).

    Parameters
    ----------
    path : str or os.PathLike
    what : str
        What the file is, for the message (e.g. ``"config file"``).
    error : type of Exception
        Raised, with one line: ``{what} '{path}' does not exist``, ``... is not UTF-8 text
        (byte N)`` or ``... cannot be read: {reason}``.
    """
    try:
        return Path(path).read_text(encoding="utf-8-sig")  # a byte-order mark is dropped
    except FileNotFoundError:
        raise error(f"{what} {str(path)!r} does not exist") from None
    except UnicodeDecodeError as exc:
        raise error(f"{what} {str(path)!r} is not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise error(f"{what} {str(path)!r} cannot be read: {exc.strerror}") from None
