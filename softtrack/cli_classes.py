"""Typer classes that make the ``softtrack`` command line read like its own errors.

* :class:`Group` prints a usage error (an unknown option, a missing argument, a bad value) as
  one line, ``error: <problem>; see `softtrack <command> --help```, exit code 2, like every
  other user error of the command line, instead of a framed panel;
* :class:`Command` writes plain usage lines (``softtrack train [OPTIONS] [SPEC]``,
  ``softtrack evaluate [OPTIONS] RUN_ID_OR_DIR...``) without Typer's braces around required
  arguments, and shows ``--help`` without a ``<bool>`` value.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any, NoReturn

import typer
from typer.core import TyperCommand, TyperGroup

__all__ = ["Command", "Group"]

_click = typer.core._click  # the click Typer vendors (its exception classes)


def _usage_error(exc: Any) -> NoReturn:
    """One line for a usage error, naming the command's help."""
    message = " ".join(str(exc.format_message()).split()).rstrip(".")
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

    def get_help_option(self, ctx: Any) -> Any:
        option = super().get_help_option(ctx)
        if option is not None:
            option.metavar = ""
        return option


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
