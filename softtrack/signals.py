"""Stop requests by signal: SIGINT and SIGTERM set a flag that a long loop polls.

Training (:mod:`softtrack.rl.train`) and the local worker pool (:mod:`softtrack.executors.local`)
both stop cleanly when asked: they install :func:`stop_on_signals` around their loop and check
the :class:`StopFlag` between steps (training saves a checkpoint, the pool passes SIGTERM on to
its workers). Outside the main thread no handler can be installed and the flag stays unset.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = [
    "STOP_SIGNALS",
    "SignalExit",
    "StopFlag",
    "StoppedBySignal",
    "forget_stops",
    "interrupt_on_sigint",
    "note_stop",
    "stop_on_signals",
    "stops_received",
]

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _stopped_by(signum: int) -> str:
    return f"stopped by {signal.Signals(signum).name}"


#: The stop signals a command received through :func:`note_stop` (numbers, in order).
_received: list[int] = []


def note_stop(signum: int) -> None:
    """Record that stop signal ``signum`` arrived (the command line's handlers call it)."""
    _received.append(signum)


def stops_received() -> list[int]:
    """The stop signals recorded since :func:`forget_stops` (numbers, in order)."""
    return list(_received)


def forget_stops() -> None:
    """Start a command with no stop signal recorded."""
    _received.clear()


def interrupt_on_sigint(signum: int, _frame: object) -> None:
    """Ctrl-C as Python's default (``KeyboardInterrupt``), recorded first: a library that
    turns the interrupt into its own error (an import cut in half) cannot hide it."""
    note_stop(signum)
    raise KeyboardInterrupt


class StoppedBySignal(Exception):
    """A signal stopped the work (``signum``: its number); the CLI exits with 128 + it."""

    def __init__(self, signum: int) -> None:
        super().__init__(_stopped_by(signum))
        self.signum = signum


class SignalExit(SystemExit):
    """Raised by a signal handler to unwind the command (``finally`` blocks run, ``except
    Exception`` does not catch it); exit code 128 + ``signum``."""

    def __init__(self, signum: int) -> None:
        super().__init__(128 + signum)
        self.signum = signum

    def __str__(self) -> str:
        return _stopped_by(self.signum)


class StopFlag:
    """Callable that is true once a stop signal arrived (``signum`` is the latest one) or a stop
    was :meth:`request`-ed.

    Args:
        second_sigint_raises: a SIGINT arriving when the flag is already set raises
            ``KeyboardInterrupt`` (a second Ctrl-C: stop now, without the clean stop).
    """

    def __init__(self, *, second_sigint_raises: bool = False) -> None:
        self.signum: int | None = None
        self.requested = False
        self.second_sigint_raises = second_sigint_raises

    def __call__(self) -> bool:
        return self.signum is not None or self.requested

    def request(self) -> None:
        """Ask for the same clean stop without a signal (``signum`` stays ``None``), e.g. when
        ``softtrack tune`` prunes a trial."""
        self.requested = True

    def handle(self, signum: int, _frame: Any = None) -> None:
        """The signal handler: set the flag (module docstring)."""
        if self.signum is not None and signum == signal.SIGINT and self.second_sigint_raises:
            raise KeyboardInterrupt
        self.signum = signum


@contextmanager
def stop_on_signals(flag: StopFlag) -> Iterator[StopFlag]:
    """While inside, SIGINT and SIGTERM set ``flag`` (:meth:`StopFlag.handle`); the previous
    handlers come back on exit. Nothing is installed outside the main thread."""
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    previous = {s: signal.signal(s, flag.handle) for s in STOP_SIGNALS}
    try:
        yield flag
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
