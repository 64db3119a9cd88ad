"""Stop a long native call (a DuckDB query) when SIGINT or SIGTERM arrives.

A signal's Python handler runs only when the main thread returns to the interpreter. DuckDB
checks for it between its tasks and then raises "Query interrupted", but a signal that lands
at the wrong moment of a query is lost and the query runs on (seen about one time in five).
:func:`interrupt_on_signals` therefore also has the signal's C handler write the signal's
number to a socket (:func:`signal.set_wakeup_fd`), and a helper thread that reads it calls
the query's ``interrupt``; the query then ends with DuckDB's interrupt error.
"""

from __future__ import annotations

import signal
import socket
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from softtrack.signals import STOP_SIGNALS

__all__ = ["interrupt_on_signals"]


def _relay(reader: socket.socket, interrupt: Callable[[], None], received: list[int]) -> None:
    while data := reader.recv(64):
        stops = [signum for signum in data if signum in STOP_SIGNALS]
        if stops:
            received.extend(stops)
            interrupt()


@contextmanager
def interrupt_on_signals(interrupt: Callable[[], None]) -> Iterator[list[int]]:
    """While the block runs, a SIGINT or SIGTERM also calls ``interrupt`` (from another
    thread). Yields the list the signals that arrived are appended to (numbers).

    Only a signal with a Python handler reaches ``interrupt`` (Ctrl-C's default handler, the
    CLI's SIGTERM handler); outside the main thread the block runs without the relay."""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return
    reader, writer = socket.socketpair()
    writer.setblocking(False)
    try:
        previous = signal.set_wakeup_fd(writer.fileno(), warn_on_full_buffer=False)
    except ValueError:  # not the main interpreter
        reader.close()
        writer.close()
        yield received
        return
    relay = threading.Thread(
        target=_relay, args=(reader, interrupt, received), name="signal-relay", daemon=True
    )
    relay.start()
    try:
        yield received
    finally:
        signal.set_wakeup_fd(previous)
        writer.shutdown(socket.SHUT_WR)
        relay.join(timeout=5.0)
        writer.close()
        reader.close()
