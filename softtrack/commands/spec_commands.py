"""``softtrack validate`` and ``softtrack spec``: check a spec, print it resolved or its fields."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from softtrack.cli_classes import Command
from softtrack.commands.common import (
    SetOption,
    app,
    fail,
    user_errors,
)
from softtrack.lazy import lazy_module

if TYPE_CHECKING:
    from softtrack import api
else:
    # loaded at their first use, so `softtrack --help` and `softtrack runs` start at once
    api = lazy_module("softtrack.api")


@app.command(cls=Command)
def validate(
    spec: Annotated[
        str, typer.Argument(metavar="SPEC", help="Experiment spec (YAML).", show_default=False)
    ],
    overrides: SetOption = None,
) -> None:
    """Check a spec file (and overrides) without running anything.

    A spec with `base:` is checked with its whole chain of bases, which a second line names.
    """
    with user_errors():
        resolved = api.validate_spec(spec, overrides or [])
        chain = api.spec_chain(spec)
    typer.echo(api.validation_summary(resolved, chain))


@app.command("spec", cls=Command)
def spec_command(
    spec: Annotated[
        str | None,
        typer.Argument(metavar="SPEC", help="Print this spec fully resolved.", show_default=False),
    ] = None,
    overrides: SetOption = None,
    schema: Annotated[
        bool, typer.Option("--schema", metavar="", help="Print the JSON Schema of specs.")
    ] = False,
    defaults: Annotated[
        bool,
        typer.Option("--defaults", metavar="", help="Print the default spec as commented YAML."),
    ] = False,
) -> None:
    """Show the spec format: the JSON Schema, the defaults, or a file fully resolved.

    A file with `base:` is printed with its chain of bases merged; comments at the top name
    the file and its bases.
    """
    chosen = sum([schema, defaults, spec is not None])
    if chosen != 1:
        fail(
            "spec: choose exactly one of --schema, --defaults or a SPEC file; "
            "e.g. `softtrack spec --defaults > my.yaml`"
        )
    if overrides and spec is None:
        fail(
            "spec: --set needs a SPEC file; e.g. "
            "`softtrack spec experiments/study/td3-64-1e7.yaml --set seeds=0`"
        )
    with user_errors():
        if schema:
            typer.echo(api.spec_schema_json())
        elif defaults:
            typer.echo(api.spec_defaults_yaml(), nl=False)
        else:
            assert spec is not None
            typer.echo(api.resolved_spec_yaml(spec, overrides or []), nl=False)
