"""``softtrack runs`` and ``softtrack query``: the runs of a runs directory and SQL over their tables."""

from __future__ import annotations

import enum
import json
import math
import sys
from typing import TYPE_CHECKING, Annotated, Any

import typer

from softtrack.cli_classes import Command
from softtrack.commands.common import (
    OutputFormat,
    RunsDirOption,
    app,
    fail,
    plural,
    print_notes,
    user_errors,
    write_stdout,
)
from softtrack.lazy import lazy_module
from softtrack.store.location import resolve_runs_dir

if TYPE_CHECKING:
    import duckdb

    from softtrack.store import query as results_db
    from softtrack.store import run_summaries as summaries
else:
    # loaded at their first use, so `softtrack --help` and `softtrack runs` start at once
    duckdb = lazy_module("duckdb")
    results_db = lazy_module("softtrack.store.query")
    summaries = lazy_module("softtrack.store.run_summaries")


@app.command(cls=Command)
def runs(
    runs_dir: RunsDirOption = None,
    output_format: Annotated[
        OutputFormat, typer.Option("--format", "-f", help="Output format.", case_sensitive=False)
    ] = OutputFormat.table,
    failed: Annotated[
        bool,
        typer.Option(
            "--failed", metavar="", help="Only failed runs, each with its stored traceback."
        ),
    ] = False,
    limit: Annotated[
        int,
        typer.Option(
            "--limit",
            "-n",
            min=0,
            metavar="N",
            help="Only the N runs created last (0: all).",
        ),
    ] = 0,
) -> None:
    """List the runs with their status, progress and final-stage return.

    Columns: id, name, algorithm, controller, seed, status, env steps done / budget, final-stage
    return (mean training-episode return over the last 10 % of the budget; blank until such
    episodes exist), start and end times (UTC). A running run whose process is gone (its
    heartbeat is stale, or its pid is dead on this host) shows as `lost`; `softtrack resume`
    continues it. Answered from the runs directory's catalog (`.softtrack-catalog/`, rebuilt
    from the run directories whenever it is missing or out of date).
    """
    with user_errors(runs_dir):
        listing = summaries.run_listing(
            runs_dir, failed=failed, limit=limit or None, progress=_catalog_progress
        )
    shown = listing.summaries
    print_notes(listing.notices)
    if output_format is OutputFormat.json:
        typer.echo(json.dumps(_json_numbers(shown), indent=2, ensure_ascii=False))
        return
    if not shown:
        root = resolve_runs_dir(runs_dir)
        note = "" if root.is_dir() else " (the directory does not exist)"
        if (root / "run.json").is_file():
            note = f" ({root} is a run itself; its runs directory is {root.parent})"
        typer.echo(f"no {'failed ' if failed else ''}runs in {root}{note}", err=True)
        return
    if failed:
        typer.echo(summaries.format_failures(shown))
        return
    typer.echo(summaries.format_runs_table(shown))
    if limit and listing.total > len(shown):
        typer.echo(
            f"(the {plural(limit, 'run')} created last of {listing.total}; --limit 0 lists all)",
            err=True,
        )


def _catalog_progress(done: int, total: int) -> None:
    """A progress line while the catalog reads runs from their directories (many: a new or
    rebuilt catalog)."""
    if total < 50 or not sys.stderr.isatty():
        return
    end = "\n" if done == total else ""
    if done == total or done % 25 == 0:
        sys.stderr.write(f"\rcatalog: reading run directories {done}/{total}{end}")
        sys.stderr.flush()


class QueryFormat(enum.StrEnum):
    table = "table"
    csv = "csv"
    json = "json"


@app.command("query", cls=Command)
def query_command(
    sql: Annotated[
        str | None,
        typer.Argument(
            metavar="SQL",
            show_default=False,
            help='A DuckDB SQL query (quote it), e.g. "SELECT * FROM runs".',
        ),
    ] = None,
    runs_dir: RunsDirOption = None,
    output_format: Annotated[
        QueryFormat,
        typer.Option(
            "--format",
            "-f",
            case_sensitive=False,
            help="table: aligned text; csv: with a header; json: an array of records.",
        ),
    ] = QueryFormat.table,
    views: Annotated[
        bool, typer.Option("--views", metavar="", help="List the views and their columns instead.")
    ] = False,
) -> None:
    """Run SQL (DuckDB) over the runs' run.json and tables and print the result.

    Views: `runs` (one row per run: run_id, name (the experiment), algo, controller, seed,
    status, global_step, steps_per_second, train_seconds, ...), `experiments` (one row per
    name) and one per table that some run has (eval_metrics, train_episodes, validation, ...),
    whose `run_id` is the run's id. `--views` lists them with their columns; docs/query.md
    has more examples. Example, the seed-mean 3-D RMSE per experiment, trajectory and arm:

    `softtrack query "SELECT name, trajectory, arm, avg(rmse_3d) AS rmse_3d FROM eval_metrics
    JOIN runs USING (run_id) GROUP BY ALL ORDER BY ALL" --runs-dir models`
    """
    if views == (sql is not None):
        fail('query: give either SQL or --views; e.g. `softtrack query "SELECT * FROM runs"`')

    with user_errors():
        if sql is not None:  # a refused statement is refused before anything is read
            results_db.check_read_only(sql)
    with user_errors(), results_db.ResultsDatabase(runs_dir, progress=_catalog_progress) as db:
        for path, reason in db.unreadable:
            fix = summaries.unreadable_fix(path)
            typer.echo(f"warning: run {path.name} left out: {reason}; {fix}", err=True)
        if views:
            typer.echo(results_db.format_views(db.views()))
        else:
            assert sql is not None
            cursor = db.execute(sql)
            if cursor.description is not None:
                try:
                    results_db.write_cursor(cursor, output_format.value, write_stdout)
                except duckdb.Error as exc:
                    fail(db.explain(exc))
        print_notes(db.notices)


def _json_numbers(value: Any) -> Any:
    """``value`` with every infinite or NaN float as the string ``"inf"``, ``"-inf"`` or
    ``"nan"``: JSON has no such numbers, and null would read as "no data"."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _json_numbers(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_numbers(v) for v in value]
    return value
