"""Run ids: ULIDs, unique without coordination and sortable by creation time.

A ULID is 26 characters of Crockford base32 (``0-9 A-Z`` without ``I L O U``): 10 characters
for a 48-bit Unix time in milliseconds, then 16 for 80 random bits from :mod:`secrets`.
Within one process, ids made in the same millisecond increment the random part (the ULID
"monotonic" rule), so they still sort in creation order. Across processes, uniqueness comes
from the 80 random bits and, for directories, from :func:`create_unique_dir`'s atomic
``os.mkdir`` (which fails instead of reusing an existing directory).
"""

from __future__ import annotations

import os
import re
import secrets
import threading
import time
from datetime import UTC, datetime
from pathlib import Path

__all__ = ["CROCKFORD_ALPHABET", "create_unique_dir", "id_timestamp", "is_valid_id", "new_id"]

CROCKFORD_ALPHABET = "0123456789ABCDEFGHJKMNPQRSTVWXYZ"
_DECODE = {c: i for i, c in enumerate(CROCKFORD_ALPHABET)}
_ID_PATTERN = re.compile(r"^[0-7][0-9A-HJKMNP-TV-Z]{25}$")
_RANDOM_BITS = 80
_lock = threading.Lock()
_last_ms = -1
_last_random = 0


def _encode(value: int, length: int) -> str:
    chars = []
    for _ in range(length):
        value, digit = divmod(value, 32)
        chars.append(CROCKFORD_ALPHABET[digit])
    return "".join(reversed(chars))


def new_id(timestamp_ms: int | None = None) -> str:
    """A new 26-character ULID (upper case), e.g. ``01JDQ7Z8W3K4M5N6P7Q8R9S0TV``.

    Args:
        timestamp_ms: Unix time in ms to encode (default: now).
    """
    global _last_ms, _last_random
    ms = int(time.time() * 1000) if timestamp_ms is None else int(timestamp_ms)
    if not 0 <= ms < 2**48:
        raise ValueError(f"timestamp {ms} ms does not fit in 48 bits")
    with _lock:
        if ms == _last_ms and _last_random + 1 < 2**_RANDOM_BITS:
            rand = _last_random + 1
        else:
            rand = secrets.randbits(_RANDOM_BITS)
        _last_ms, _last_random = ms, rand
    return _encode(ms, 10) + _encode(rand, 16)


def is_valid_id(text: str) -> bool:
    """True if ``text`` is a canonical (upper-case) ULID."""
    return bool(_ID_PATTERN.match(text))


def id_timestamp(run_id: str) -> datetime:
    """The creation time (UTC, ms resolution) encoded in a ULID."""
    if not is_valid_id(run_id.upper()):
        raise ValueError(f"{run_id!r} is not a ULID")
    ms = 0
    for char in run_id.upper()[:10]:
        ms = ms * 32 + _DECODE[char]
    return datetime.fromtimestamp(ms / 1000, tz=UTC)


def create_unique_dir(parent: str | os.PathLike[str], *, attempts: int = 100) -> tuple[str, Path]:
    """Create ``parent/<new id>`` atomically and return ``(id, path)``.

    ``os.mkdir`` either creates the directory or fails, so two processes (or hosts sharing a
    POSIX file system) can never both obtain the same directory; on the (astronomically rare)
    collision a fresh id is drawn. ``parent`` is created if needed.
    """
    parent = Path(parent)
    parent.mkdir(parents=True, exist_ok=True)
    for _ in range(attempts):
        run_id = new_id()
        path = parent / run_id
        try:
            os.mkdir(path)
        except FileExistsError:
            continue
        return run_id, path
    raise RuntimeError(f"could not create a unique directory in {parent} after {attempts} attempts")
