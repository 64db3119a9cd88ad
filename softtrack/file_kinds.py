"""What a path is, in words, and a path as it can be printed: for the messages that refuse a
path of the wrong kind or name a hostile one."""

from __future__ import annotations

import os
import stat

__all__ = [
    "FileKindError",
    "FileTooLargeError",
    "describe_mode",
    "describe_path",
    "printable",
    "read_regular_file",
]


class FileKindError(ValueError):
    """A path softtrack reads is not a regular file; the message is ``is a FIFO`` etc."""


class FileTooLargeError(ValueError):
    """A file is larger than what softtrack reads of its kind."""


def describe_mode(mode: int) -> str:
    """``"a directory"``, ``"a FIFO"``, ``"a device"``, ``"a socket"``, ``"a regular file"``
    or ``"not a regular file"`` for an ``st_mode``."""
    if stat.S_ISREG(mode):
        return "a regular file"
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def describe_path(path: str | os.PathLike[str]) -> str:
    """:func:`describe_mode` of what ``path`` names (following links); ``"missing"`` when
    nothing is there, ``"a broken link"`` for a link to nothing, ``"unreadable"`` when it cannot
    be examined."""
    try:
        return describe_mode(os.stat(path).st_mode)
    except FileNotFoundError:
        return "a broken link" if os.path.islink(path) else "missing"
    except OSError:
        return "unreadable"


def printable(text: str) -> str:
    """``text`` with its control characters (newline, escape sequences …) written as Python
    escapes (``\\n``, ``\\x1b``), so a hostile file name cannot break a table or drive the
    terminal; printable text is unchanged."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def read_regular_file(path: str | os.PathLike[str], max_bytes: int) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``. A FIFO, a device or a socket is
    refused before anything is read from it (opened non-blocking, so a FIFO without a writer
    cannot hang the command), and a larger file after ``max_bytes + 1`` bytes (memory stays
    bounded).

    Raises:
        FileKindError: not a regular file (message: ``is a FIFO`` …).
        FileTooLargeError: larger than ``max_bytes``.
        OSError: it cannot be opened or read.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise FileKindError(f"is {describe_mode(mode)}")
        chunks, size = [], 0
        while size <= max_bytes:
            chunk = os.read(fd, min(1 << 20, max_bytes + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    finally:
        os.close(fd)
    if size > max_bytes:
        raise FileTooLargeError(f"is larger than {max_bytes:,} bytes")
    return b"".join(chunks)
