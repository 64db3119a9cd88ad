"""Stop signals: the relay that interrupts a native call, and the command line's one line."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator

import pytest

from softtrack.signals import SignalExit, StoppedBySignal
from softtrack.store.signal_interrupt import interrupt_on_signals


@pytest.fixture
def quiet_sigterm() -> Iterator[list[int]]:
    """A SIGTERM handler that only records (as a handler whose exception a library lost)."""
    handled: list[int] = []
    previous = signal.signal(signal.SIGTERM, lambda signum, _frame: handled.append(signum))
    yield handled
    signal.signal(signal.SIGTERM, previous)


def test_a_signal_calls_interrupt_from_the_relay(quiet_sigterm: list[int]) -> None:
    interrupted = threading.Event()
    with interrupt_on_signals(interrupted.set) as received:
        os.kill(os.getpid(), signal.SIGTERM)
        assert interrupted.wait(10.0)
    assert received == [signal.SIGTERM] and quiet_sigterm == [signal.SIGTERM]


def test_after_the_block_a_signal_interrupts_nothing(quiet_sigterm: list[int]) -> None:
    before = signal.set_wakeup_fd(-1)
    signal.set_wakeup_fd(before)
    calls: list[int] = []
    with interrupt_on_signals(lambda: calls.append(1)) as received:
        pass
    os.kill(os.getpid(), signal.SIGTERM)
    assert received == [] and calls == [] and quiet_sigterm == [signal.SIGTERM]
    assert signal.set_wakeup_fd(before) == before  # the wakeup socket was given back


def test_outside_the_main_thread_the_block_runs_without_a_relay() -> None:
    outcome: list[list[int]] = []

    def body() -> None:
        with interrupt_on_signals(lambda: None) as received:
            outcome.append(received)

    worker = threading.Thread(target=body)
    worker.start()
    worker.join(10.0)
    assert outcome == [[]]


def test_the_stop_errors_name_the_signal_and_the_exit_code() -> None:
    assert str(StoppedBySignal(signal.SIGTERM)) == "stopped by SIGTERM"
    stop = SignalExit(signal.SIGTERM)
    assert stop.code == 143 and str(stop) == "stopped by SIGTERM"
    assert isinstance(stop, SystemExit) and not isinstance(stop, Exception)


def test_the_stop_signal_behind_an_error_is_found_along_its_chain() -> None:
    """A signal that lands in the middle of an import leaves a module half made; the error its
    next use raises still ends the command as stopped by that signal."""
    from softtrack.cli_classes import stop_signal_behind

    def chained(first: BaseException) -> BaseException:
        try:
            try:
                raise first
            except BaseException:
                raise AttributeError("module 'softtrack.api' has no attribute 'X'")  # noqa: B904
        except AttributeError as exc:
            return exc

    assert stop_signal_behind(chained(KeyboardInterrupt())) == signal.SIGINT
    assert stop_signal_behind(chained(SignalExit(signal.SIGTERM))) == signal.SIGTERM
    assert stop_signal_behind(StoppedBySignal(signal.SIGTERM)) == signal.SIGTERM
    assert stop_signal_behind(chained(ValueError("a bug"))) is None


def test_a_command_whose_signal_error_was_lost_still_stops_with_one_line() -> None:
    """A library turned the recorded Ctrl-C into an unrelated error (an import cut in half):
    the command line still says it stopped, with 128 + the signal."""
    from typer.testing import CliRunner

    from softtrack.cli_classes import App, Group
    from softtrack.signals import forget_stops, note_stop

    app = App(cls=Group, add_completion=False)

    @app.command()
    def half_imported() -> None:
        note_stop(signal.SIGINT)
        raise ImportError("cannot import name 'ExecOptions' (partially initialized module)")

    @app.command()
    def plain_bug() -> None:
        raise ImportError("a bug")

    try:
        result = CliRunner().invoke(app, ["half-imported"])
        assert result.exit_code == 130 and result.stderr.strip() == "stopped by SIGINT"
        forget_stops()
        result = CliRunner().invoke(app, ["plain-bug"])
        assert result.exit_code == 1 and isinstance(result.exception, ImportError)
    finally:
        forget_stops()
