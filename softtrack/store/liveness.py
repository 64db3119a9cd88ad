"""Whether a run's training process is alive: its ``run.lock``, its pid, its heartbeat.

Light on purpose (standard library only): ``softtrack runs`` answers from the catalog
(:mod:`softtrack.store.catalog`) and needs these checks without loading the spec models.
"""

from __future__ import annotations

import os
import socket
from datetime import datetime
from pathlib import Path

__all__ = [
    "LOCK_NAME",
    "heartbeat_stale",
    "is_lost_process",
    "lock_file_held",
    "parse_time",
    "pid_alive",
    "stale_after_s",
]

LOCK_NAME = "run.lock"


def parse_time(text: str | None) -> datetime | None:
    """Parse an ISO-8601 time as written in ``run.json`` (``None`` or ``""`` → ``None``)."""
    if not text:
        return None
    return datetime.fromisoformat(text)


def lock_file_held(lock_path: Path) -> bool | None:
    """Whether some process holds the ``flock`` on ``lock_path`` (``None``: no such file)."""
    import fcntl

    try:
        fd = os.open(lock_path, os.O_RDWR)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:
        return None
    finally:
        os.close(fd)  # closing also drops the lock we may just have taken
    return False


def pid_alive(pid: int | None) -> bool:
    """Whether process ``pid`` exists on this host."""
    if not pid:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def is_lost_process(run_path: Path, *, stale: bool, host: str | None, pid: int | None) -> bool:
    """A ``running`` run's process is gone: nobody holds ``<run_path>/run.lock``, and its
    heartbeat is ``stale`` or (on this host) its pid is not alive."""
    if lock_file_held(run_path / LOCK_NAME) is True:
        return False
    if stale:
        return True
    return host == socket.gethostname() and not pid_alive(pid)


def stale_after_s(interval_s: float) -> float:
    """A running run's heartbeat older than this is stale: max(120 s, 10 heartbeat intervals)."""
    return max(120.0, 10.0 * interval_s)


def heartbeat_stale(status: str, last_sign: str | None, interval_s: float, now: datetime) -> bool:
    """A ``running`` run whose last sign of life (its heartbeat, else its start or creation
    time, ISO 8601) is older than :func:`stale_after_s`."""
    if status != "running":
        return False
    beat = parse_time(last_sign)
    if beat is None:
        return False
    return (now - beat).total_seconds() > stale_after_s(interval_s)
