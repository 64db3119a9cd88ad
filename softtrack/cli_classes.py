"""Typer classes that make the ``softtrack`` command line read like its own errors.

* :class:`Group` prints a usage error (an unknown option, a missing argument, a bad value) as
  one line, ``error: <problem>; see `softtrack <command> --help```, exit code 2, like every
  other user error of the command line, instead of a framed panel;
* :class:`App` builds only the command a command line runs (Typer builds every command's
  options from its signature before parsing: 0.08 s of every start);
* :class:`Command` writes plain usage lines (``softtrack train [OPTIONS] [SPEC]``,
  ``softtrack evaluate [OPTIONS] RUN_ID_OR_DIR...``) without Typer's braces around required
  arguments, and shows ``--help`` without a ``<bool>`` value.
"""

from __future__ import annotations

import re
import signal
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

import typer
from typer.core import TyperCommand, TyperGroup

from softtrack.signals import SignalExit, StoppedBySignal, stops_received

__all__ = ["App", "Command", "Group", "stop_signal_behind"]

#: The click Typer is built on (its exception classes): click itself up to Typer 0.24, the
#: copy Typer vendors from 0.26 on (constraints.txt pins 0.24: it starts 0.3 s sooner).
_click: Any = getattr(typer.core, "click", None) or getattr(typer.core, "_click")  # noqa: B009


def _usage_error(exc: Any) -> NoReturn:
    """One line for a usage error, naming the command's help."""
    sentences = re.split(r"(?<=[.?!])\s+", " ".join(str(exc.format_message()).split()))
    message = " ".join(dict.fromkeys(sentences)).rstrip(".")  # click and Typer both suggest
    ctx = getattr(exc, "ctx", None)
    command = ctx.command_path if ctx is not None else "softtrack"
    typer.echo(f"error: {message}; see `{command} --help`", err=True)
    sys.exit(exc.exit_code)


class Group(TyperGroup):
    """The ``softtrack`` group: one-line usage errors (module docstring)."""

    def main(
        self,
        args: Sequence[str] | None = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        windows_expand_args: bool = True,
        **extra: Any,
    ) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, windows_expand_args, **extra)
        try:
            code = super().main(args, prog_name, complete_var, False, windows_expand_args, **extra)
        except _click.exceptions.NoArgsIsHelpError as exc:
            exc.show()
            sys.exit(exc.exit_code)
        except _click.exceptions.ClickException as exc:
            _usage_error(exc)
        except typer.Abort:
            typer.echo("error: aborted", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)

    def invoke(self, ctx: Any) -> Any:
        """Run the command; a Ctrl-C or SIGTERM that unwinds it ends in one line, ``stopped by
        SIGINT`` (``SIGTERM``), and exit code 128 + the signal."""
        try:
            return super().invoke(ctx)
        except (_click.exceptions.Exit, _click.exceptions.ClickException, _click.exceptions.Abort):
            raise  # the command's own exit and usage errors (already printed where needed)
        except (KeyboardInterrupt, SignalExit, Exception) as exc:
            signum = stop_signal_behind(exc)
            if signum is None and stops_received():  # the signal's error was lost on the way
                signum = stops_received()[-1]
            if signum is None:
                raise
            kept = "; ".join(stop_notes(exc))
            typer.echo(
                f"stopped by {signal.Signals(signum).name}" + (f": {kept}" if kept else ""),
                err=True,
            )
            raise typer.Exit(128 + signum) from None

    def get_help_option(self, ctx: Any) -> Any:
        option = super().get_help_option(ctx)
        if option is not None:
            option.metavar = ""
        return option


def stop_signal_behind(exc: BaseException) -> int | None:
    """The stop signal behind ``exc``: Ctrl-C (``KeyboardInterrupt``), SIGTERM's handler
    (``SignalExit``), a query a signal stopped (``StoppedBySignal``), or any error raised while
    one of those unwound the command (a signal in the middle of an import leaves a module half
    made, and the next use of it fails); ``None`` for any other error."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, KeyboardInterrupt):
            return int(signal.SIGINT)
        if isinstance(current, (SignalExit, StoppedBySignal)):
            return current.signum
        current = current.__cause__ or current.__context__
    return None


def stop_notes(exc: BaseException) -> list[str]:
    """What the code a stop unwound kept (``exc.add_note``), along ``exc``'s chain."""
    notes: list[str] = []
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        notes.extend(getattr(current, "__notes__", ()))
        current = current.__cause__ or current.__context__
    return notes


class Command(TyperCommand):
    """A ``softtrack`` command: plain usage line, ``--help`` without a value type."""

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        return [
            piece[1:-1] if piece.startswith("{") and piece.endswith("}") else piece
            for piece in (p.replace("}...", "...}") for p in super().collect_usage_pieces(ctx))
        ]

    def get_help_option(self, ctx: Any) -> Any:
        option = super().get_help_option(ctx)
        if option is not None:
            option.metavar = ""
        return option


class App(typer.Typer):
    """The ``softtrack`` application: builds only the command that ``sys.argv`` names
    (every command where it names none, or an unknown one: ``--help``, a typo)."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        argv = list(kwargs.get("args") or (args[0] if args else sys.argv[1:]) or [])
        name = next((arg for arg in argv if not arg.startswith("-")), None)
        commands = [c for c in self.registered_commands if _command_name(c) == name]
        groups = [g for g in self.registered_groups if _group_name(g) == name]
        if name is None or not (commands or groups):
            return super().__call__(*args, **kwargs)
        every = self.registered_commands, self.registered_groups
        self.registered_commands, self.registered_groups = commands, groups
        try:
            return super().__call__(*args, **kwargs)
        finally:
            self.registered_commands, self.registered_groups = every


def _command_name(info: Any) -> str | None:
    if info.name:
        return str(info.name)
    return None if info.callback is None else typer.main.get_command_name(info.callback.__name__)


def _group_name(info: Any) -> str | None:
    name = info.name if isinstance(info.name, str) else None
    if name is None and info.typer_instance is not None:
        found = info.typer_instance.info.name
        name = found if isinstance(found, str) else None
    return name
