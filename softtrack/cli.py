"""The ``softtrack`` command line (Typer). Thin: it parses, calls :mod:`softtrack.api`, prints.

Every error a user can cause (a bad spec, a bad override, a missing run) is printed as one
line on stderr, ``error: <file>: <field>: <problem>; <fix>``, with exit code 2 and no traceback.
"""

from __future__ import annotations

import enum
import json
import math
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Annotated, Any, NoReturn

import typer

from softtrack.cli_classes import App, Command, Group
from softtrack.lazy import lazy_module
from softtrack.store import provenance
from softtrack.store.disk import storage_problem
from softtrack.store.location import QUICKSTART_PRETRAINED, resolve_runs_dir
from softtrack.trajectories import EVAL_TRAJECTORIES

if TYPE_CHECKING:
    import duckdb
    import pandas as pd

    from softtrack import api
    from softtrack.evaluation.episodes import Episode
    from softtrack.executors import dispatch
    from softtrack.executors.dispatch import Outcome
    from softtrack.store import query as results_db
    from softtrack.store import run_summaries as summaries
    from softtrack.store.runs import RunRecord
else:
    # loaded at their first use, so `softtrack --help` and `softtrack runs` start at once
    api = lazy_module("softtrack.api")
    dispatch = lazy_module("softtrack.executors.dispatch")
    duckdb = lazy_module("duckdb")
    results_db = lazy_module("softtrack.store.query")
    summaries = lazy_module("softtrack.store.run_summaries")

app = App(
    name="softtrack",
    help="Train, evaluate and compare controllers for two soft arms tracking a moving target.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
    rich_markup_mode=None,
    cls=Group,
)

SetOption = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        "-s",
        metavar="PATH=VALUE",
        help="Override a spec field, e.g. --set training.total_timesteps=2000 --set 'seeds=[0,1]' "
        "(values are YAML). Repeatable.",
        show_default=False,
    ),
]
InPlaceOption = Annotated[
    bool,
    typer.Option(
        "--in-place",
        metavar="",
        help="Store the results in a shipped (read-only) run itself, e.g. to update "
        "models/ on purpose [default: in its copy in the runs directory].",
    ),
]
RunsDirOption = Annotated[
    str | None,
    typer.Option(
        "--runs-dir",
        metavar="DIR",
        help="Directory holding the runs [default: $SOFTTRACK_RUNS_DIR, else runs/].",
        show_default=False,
    ),
]


class OutputFormat(enum.StrEnum):
    table = "table"
    json = "json"


def _fail(exc: BaseException | str) -> NoReturn:
    typer.echo(f"error: {exc}", err=True)
    raise typer.Exit(2)


@contextmanager
def _user_errors(runs_dir: str | None = None) -> Iterator[None]:
    """Turn the user errors of softtrack, and a full or read-only disk, into one stderr line
    and exit code 2 (``runs_dir``: the command's ``--runs-dir``, named when a library's
    error does not say which file it was writing)."""
    try:
        yield
    except api.USER_ERRORS as exc:
        _fail(exc)
    except Exception as exc:
        problem = storage_problem(exc, "then run the command again", resolve_runs_dir(runs_dir))
        if problem is None:
            raise
        _fail(problem)


def _plural(count: int, noun: str) -> str:
    """``1 run``, ``2 runs``."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import PackageNotFoundError, version

        try:
            typer.echo(f"softtrack {version('softtrack')}")
        except PackageNotFoundError:
            typer.echo("softtrack (not installed; running from source)")
        raise typer.Exit()


def _exit_on_sigterm(signum: int, _frame: object) -> None:
    raise SystemExit(128 + signum)


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option(
            "--version", metavar="", callback=_version, is_eager=True, help="Print the version."
        ),
    ] = False,
) -> None:
    """Train, evaluate and compare controllers for two soft arms tracking a moving target."""

    provenance.mark_cli()
    if threading.current_thread() is threading.main_thread():
        # SIGTERM unwinds like Ctrl-C, so every command removes its temporary files (training
        # and the pools install their own clean stop while they run)
        signal.signal(signal.SIGTERM, _exit_on_sigterm)


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
    with _user_errors():
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
        _fail(
            "spec: choose exactly one of --schema, --defaults or a SPEC file; "
            "e.g. `softtrack spec --defaults > my.yaml`"
        )
    if overrides and spec is None:
        _fail(
            "spec: --set needs a SPEC file; e.g. "
            "`softtrack spec experiments/study/td3-64-1e7.yaml --set seeds=0`"
        )
    with _user_errors():
        if schema:
            typer.echo(api.spec_schema_json())
        elif defaults:
            typer.echo(api.spec_defaults_yaml(), nl=False)
        else:
            assert spec is not None
            typer.echo(api.resolved_spec_yaml(spec, overrides or []), nl=False)


@app.command(cls=Command)
def train(
    spec: Annotated[
        str | None,
        typer.Argument(
            metavar="SPEC", help="Experiment spec (YAML): one run per seed.", show_default=False
        ),
    ] = None,
    overrides: SetOption = None,
    runs_dir: RunsDirOption = None,
    seed: Annotated[
        int | None,
        typer.Option("--seed", metavar="N", help="Train only this seed.", show_default=False),
    ] = None,
    resume: Annotated[
        str | None,
        typer.Option(
            "--resume",
            metavar="RUN_ID",
            help="Continue this run (id or unique prefix) from its latest checkpoint.",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Train one run per seed of SPEC (printing each run id), or resume a run.

    Ctrl-C (SIGINT) or SIGTERM saves a checkpoint and marks the run interrupted (exit 130 /
    143); `softtrack train --resume RUN_ID` continues it with the same id and step count.
    With controller: independent, a run trains arm 0's single-arm policy, then arm 1's, each
    for training.total_timesteps env steps (models/arm0/, models/arm1/ in the run directory).
    """
    if (spec is None) == (resume is None):
        _fail(
            "train: give either a SPEC file or --resume RUN_ID; e.g. `softtrack train "
            "experiments/quickstart.yaml`"
        )
    if resume is not None and (overrides or seed is not None):
        _fail("train: --set and --seed cannot be combined with --resume (a run keeps its spec)")

    def started(record: RunRecord) -> None:
        typer.echo(record.run_id)

    with _user_errors(runs_dir):
        if resume is not None:
            outcomes = [api.resume(resume, runs_dir=runs_dir, on_start=started)]
        else:
            assert spec is not None
            outcomes = api.train(
                spec, overrides or [], runs_dir=runs_dir, seed=seed, on_start=started
            )
    for outcome in outcomes:
        if outcome.status == "interrupted" and outcome.error:
            typer.echo(
                f"error: run {outcome.run_id} stopped at step {outcome.global_step}: "
                f"{outcome.error}",
                err=True,
            )
        elif outcome.status == "interrupted":
            typer.echo(
                f"interrupted: run {outcome.run_id} at step {outcome.global_step}; continue with "
                f"`softtrack train --resume {outcome.run_id}`",
                err=True,
            )
        elif outcome.status == "failed":
            typer.echo(f"error: run {outcome.run_id} failed: {outcome.error}", err=True)
    code = max((o.exit_code for o in outcomes), default=0)
    if code:
        raise typer.Exit(code)


class ExecutorChoice(enum.StrEnum):
    local = "local"
    slurm = "slurm"


ExecutorOption = Annotated[
    ExecutorChoice,
    typer.Option(
        "--executor",
        "-e",
        case_sensitive=False,
        help="local: a process pool on this machine; slurm: a SLURM job array "
        "(needs `pip install 'softtrack[cluster]'`).",
    ),
]
WorkersOption = Annotated[
    int | None,
    typer.Option(
        "--workers",
        "-w",
        metavar="N",
        min=1,
        show_default=False,
        help="Runs at once (local: worker processes, default the number of cores; "
        "slurm: array parallelism, default no limit).",
    ),
]
DetachOption = Annotated[
    bool,
    typer.Option(
        "--detach",
        metavar="",
        help="Return once the runs are submitted (follow them with `softtrack runs`).",
    ),
]
PartitionOption = Annotated[
    str | None,
    typer.Option(
        "--partition",
        metavar="NAME",
        show_default=False,
        help="slurm: partition [default: spec cluster.partition].",
    ),
]
TimeOption = Annotated[
    int | None,
    typer.Option(
        "--time",
        metavar="MIN",
        min=1,
        show_default=False,
        help="slurm: time limit per job, min; longer runs are requeued "
        "and resume [default: spec cluster.time_min, 240].",
    ),
]
CpusOption = Annotated[
    int | None,
    typer.Option(
        "--cpus",
        metavar="N",
        min=1,
        show_default=False,
        help="slurm: cores per job [default: spec cluster.cpus_per_task, 1].",
    ),
]
MemOption = Annotated[
    float | None,
    typer.Option(
        "--mem",
        metavar="GB",
        min=0.001,
        show_default=False,
        help="slurm: memory per job, GB [default: spec cluster.mem_gb, 4].",
    ),
]


TuneWorkersOption = Annotated[
    int | None,
    typer.Option(
        "--workers",
        "-w",
        metavar="N",
        min=1,
        show_default=False,
        help="Worker processes pulling trials from the study [default: 1, in this "
        "process] (slurm: N jobs).",
    ),
]


def _exec_options(
    executor: ExecutorChoice,
    workers: int | None,
    detach: bool,
    partition: str | None,
    time_min: int | None,
    cpus: int | None,
    mem: float | None,
) -> dispatch.ExecOptions:
    """The executor options of a command (``--executor`` … ``--mem``) as one object."""
    return dispatch.ExecOptions(
        executor=executor.value,
        workers=workers,
        detach=detach,
        partition=partition,
        time_min=time_min,
        cpus_per_task=cpus,
        mem_gb=mem,
    )


def _progress(line: str) -> None:
    typer.echo(line, err=True)


def _finish(outcome: Outcome, what: str) -> None:
    """Print what is complete and what is missing; exit with the outcome's code."""
    o = outcome
    if o.detached:
        typer.echo(
            f"{what} {o.sweep_id}: {len(o.run_ids)} runs submitted; follow them with "
            f"`softtrack runs` (log: {o.log})",
            err=True,
        )
        return
    missing = o.missing
    done = len(o.run_ids) - len(missing)
    typer.echo(f"{what} {o.sweep_id}: {done}/{len(o.run_ids)} runs completed", err=True)
    for run_id, status in missing:
        typer.echo(f"  missing: {run_id} ({status})", err=True)
    if missing:
        typer.echo(
            f"  continue with `softtrack resume {o.sweep_id}`; failures: `softtrack runs --failed`",
            err=True,
        )
    if o.exit_code:
        raise typer.Exit(o.exit_code)


@app.command(cls=Command)
def sweep(
    specs: Annotated[
        list[str],
        typer.Argument(
            metavar="SPEC",
            help="Experiment specs (YAML): one run per seed and grid point.",
            show_default=False,
        ),
    ],
    grid: Annotated[
        list[str] | None,
        typer.Option(
            "--grid",
            "-g",
            metavar="KEY=V1,V2",
            show_default=False,
            help="A grid axis over any spec field, e.g. --grid algo.name=td3,ddpg,ppo "
            "(values are YAML; commas inside [...] are kept). Repeatable: the grid is "
            "the product of the axes.",
        ),
    ] = None,
    seeds: Annotated[
        str | None,
        typer.Option(
            "--seeds",
            metavar="LIST",
            show_default=False,
            help="Seeds of every grid point, e.g. 0,1,2 or 0-4 [default: the spec's].",
        ),
    ] = None,
    overrides: SetOption = None,
    *,
    executor: ExecutorOption = ExecutorChoice.local,
    workers: WorkersOption = None,
    detach: DetachOption = False,
    partition: PartitionOption = None,
    time_min: TimeOption = None,
    cpus: CpusOption = None,
    mem: MemOption = None,
    runs_dir: RunsDirOption = None,
) -> None:
    """Run a grid of experiments: create every run, then train them in parallel.

    Prints each new run id, shows progress on stderr (runs completed/running/failed and the
    total steps/s), and returns when all have ended, with what is missing. Every job runs in
    its own process with one torch thread; a failing job never stops the others (its
    traceback: `softtrack runs --failed`). Ctrl-C/SIGTERM checkpoints the running jobs;
    `softtrack resume SWEEP_ID` finishes the sweep. Exit 0 when every run completed.
    """
    options = _exec_options(executor, workers, detach, partition, time_min, cpus, mem)

    def created(sweep_id: str, records: list[RunRecord]) -> None:
        typer.echo(f"sweep {sweep_id}: {len(records)} runs", err=True)
        for record in records:
            typer.echo(record.run_id)

    with _user_errors(runs_dir):
        outcome = api.sweep(
            specs,
            grid or [],
            overrides or [],
            seeds=seeds,
            runs_dir=runs_dir,
            options=options,
            on_created=created,
            on_progress=_progress,
        )
    _finish(outcome, "sweep")


@app.command("resume", cls=Command)
def resume_command(
    selection: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="EXPERIMENT|SWEEP_ID|RUN_ID",
            show_default=False,
            help="Experiment names, sweep ids or run ids [default: every resumable run].",
        ),
    ] = None,
    *,
    executor: ExecutorOption = ExecutorChoice.local,
    workers: WorkersOption = None,
    detach: DetachOption = False,
    partition: PartitionOption = None,
    time_min: TimeOption = None,
    cpus: CpusOption = None,
    mem: MemOption = None,
    runs_dir: RunsDirOption = None,
) -> None:
    """Resume interrupted, never-started, failed-by-signal and lost runs from their checkpoints.

    Experiment names and sweep ids select their resumable runs; a run id selects that run
    (unless completed or still training). The runs go through the same executors as
    `softtrack sweep`.
    """
    options = _exec_options(executor, workers, detach, partition, time_min, cpus, mem)

    def selected(resume_id: str, records: list[RunRecord]) -> None:
        typer.echo(f"resume {resume_id}: {len(records)} runs", err=True)
        for record in records:
            typer.echo(record.run_id)

    with _user_errors(runs_dir):
        outcome = api.resume_runs(
            selection or [],
            runs_dir=runs_dir,
            options=options,
            on_selected=selected,
            on_progress=_progress,
        )
    if outcome is None:
        typer.echo(
            "nothing to resume: no interrupted, queued, failed-by-signal or lost run matches",
            err=True,
        )
        return
    _finish(outcome, "resume")


@app.command("tune", cls=Command)
def tune_command(
    spec: Annotated[
        str | None,
        typer.Argument(
            metavar="SPEC",
            show_default=False,
            help="Experiment spec (YAML) with a tune: section (the search space).",
        ),
    ] = None,
    overrides: SetOption = None,
    trials: Annotated[
        int | None,
        typer.Option(
            "--trials",
            "-n",
            metavar="N",
            min=1,
            show_default=False,
            help="Finished trials (complete or pruned) the study should have.",
        ),
    ] = None,
    study: Annotated[
        str | None,
        typer.Option(
            "--study",
            metavar="NAME",
            show_default=False,
            help="The study: started, or continued if it exists [default: the spec's name].",
        ),
    ] = None,
    storage: Annotated[
        str | None,
        typer.Option(
            "--storage",
            metavar="URL",
            show_default=False,
            help="Optuna RDB storage URL, e.g. postgresql://user@host/db [default: "
            "sqlite:///RUNS_DIR/optuna.db].",
        ),
    ] = None,
    best: Annotated[
        str | None,
        typer.Option(
            "--best",
            metavar="STUDY",
            show_default=False,
            help="Write the study's best trial as a spec file (see --out) instead.",
        ),
    ] = None,
    out: Annotated[
        str | None,
        typer.Option(
            "--out",
            "-o",
            metavar="FILE",
            show_default=False,
            help="With --best: the spec file to write [default: STUDY-best.yaml].",
        ),
    ] = None,
    status: Annotated[
        str | None,
        typer.Option(
            "--status",
            metavar="STUDY",
            show_default=False,
            help="Print the study's trials (state, score, params, run id) instead.",
        ),
    ] = None,
    *,
    executor: ExecutorOption = ExecutorChoice.local,
    workers: TuneWorkersOption = None,
    detach: DetachOption = False,
    partition: PartitionOption = None,
    time_min: TimeOption = None,
    cpus: CpusOption = None,
    mem: MemOption = None,
    runs_dir: RunsDirOption = None,
) -> None:
    """Search the spec's `tune:` space with Optuna (TPE, pruning on the validation score).

    Each trial is a run of the store (the spec with the sampled values, named NAME-tK) whose
    objective is its best validation score (mean 3-D RMSE, m; minimised); the pruner stops
    unpromising runs at a validated checkpoint (the run is kept, `interrupted`). Running it
    again with the same --study continues until --trials trials are finished: interrupted
    trials and those of dead workers are retried, resuming their runs. `--best STUDY` writes
    the best trial as a spec for `softtrack train`; `--status STUDY` lists the trials.
    Details: docs/tuning.md.
    """
    options = _exec_options(executor, workers, detach, partition, time_min, cpus, mem)
    modes = sum([spec is not None, best is not None, status is not None])
    example = "e.g. `softtrack tune SPEC --trials 30 --study NAME`"
    if modes != 1:
        _fail(f"tune: give a SPEC to tune, or --best STUDY, or --status STUDY; {example}")
    if out is not None and best is None:
        _fail("tune: --out goes with --best STUDY (the spec file to write)")
    with _user_errors(runs_dir):
        if status is not None:
            typer.echo(api.tune_status(status, storage=storage, runs_dir=runs_dir))
            return
        if best is not None:
            path, trial = api.tune_best(best, out, storage=storage, runs_dir=runs_dir)
            typer.echo(str(path))
            typer.echo(
                f"best trial {trial.number} of study {best}: validation score "
                f"{trial.value:.4f} m (run {trial.user_attrs.get('run_id', '?')}); "
                f"train it with `softtrack train {path}`",
                err=True,
            )
            return
        if trials is None:
            _fail(f"tune: --trials N is needed (finished trials the study should have); {example}")
        assert spec is not None
        outcome = api.tune(
            spec,
            overrides or [],
            trials=trials,
            study=study,
            storage=storage,
            runs_dir=runs_dir,
            options=options,
            log=_progress,
            on_progress=_progress,
        )
    if outcome.detached:
        typer.echo(
            f"tune {outcome.study}: workers started; follow them with `softtrack tune "
            f"--status {outcome.study}` (logs: {outcome.log})",
            err=True,
        )
        return
    typer.echo(outcome.summary, err=True)
    for where, code in outcome.crashed:
        typer.echo(
            f"error: a tune worker ended with exit code {code} (log: {where}); "
            f"its trial is retried when the study continues",
            err=True,
        )
    if outcome.missing:
        again = f"softtrack tune {spec} --trials {trials} --study {outcome.study}"
        typer.echo(
            f"  {outcome.missing} trial{'s' if outcome.missing != 1 else ''} missing; "
            f"continue with `{again}` (same --set and --storage); trials: "
            f"`softtrack tune --status {outcome.study}`",
            err=True,
        )
    else:
        typer.echo(
            f"  write the best trial as a spec: `softtrack tune --best {outcome.study}`", err=True
        )
    if outcome.exit_code:
        raise typer.Exit(outcome.exit_code)


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
    with _user_errors(runs_dir):
        listing = summaries.run_listing(
            runs_dir, failed=failed, limit=limit or None, progress=_catalog_progress
        )
    shown = listing.summaries
    _print_notes(listing.notices)
    if output_format is OutputFormat.json:
        typer.echo(json.dumps(shown, indent=2, ensure_ascii=False))
        return
    if not shown:
        root = resolve_runs_dir(runs_dir)
        note = "" if root.is_dir() else " (the directory does not exist)"
        typer.echo(f"no {'failed ' if failed else ''}runs in {root}{note}", err=True)
        return
    if failed:
        typer.echo(summaries.format_failures(shown))
        return
    typer.echo(summaries.format_runs_table(shown))
    if limit and listing.total > len(shown):
        typer.echo(
            f"(the {_plural(limit, 'run')} created last of {listing.total}; --limit 0 lists all)",
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
        _fail('query: give either SQL or --views; e.g. `softtrack query "SELECT * FROM runs"`')

    with _user_errors():
        if sql is not None:  # a refused statement is refused before anything is read
            results_db.check_read_only(sql)
    with _user_errors(), results_db.ResultsDatabase(runs_dir, progress=_catalog_progress) as db:
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
                    results_db.write_cursor(cursor, output_format.value, _write_stdout)
                except duckdb.Error as exc:
                    _fail(db.explain(exc))
        _print_notes(db.notices)


def _print_notes(notices: list[str]) -> None:
    """Lines about the catalog, after a command's answer (an error stays one line)."""
    for notice in notices:
        typer.echo(f"note: {notice}", err=True)


def _write_stdout(text: str) -> None:
    sys.stdout.write(text)


#: --trajectory: one of the evaluation trajectories (softtrack.env.targets), all or none
TrajectoryChoice = enum.StrEnum(  # type: ignore[misc]
    "TrajectoryChoice", [(name, name) for name in (*EVAL_TRAJECTORIES, "all", "none")]
)
ALL_TRAJECTORIES = TrajectoryChoice("all")


class ModelOption(enum.StrEnum):
    policy = "policy"
    last = "last"
    best = "best"


@app.command(cls=Command)
def evaluate(
    references: Annotated[
        list[str],
        typer.Argument(
            metavar="RUN",
            help="Runs: run ids (or unique prefixes), run directories, experiment names or spec files.",
            show_default=False,
        ),
    ],
    trajectory: Annotated[
        TrajectoryChoice,
        typer.Option(
            "--trajectory", "-t", help="Target trajectory to evaluate on.", case_sensitive=False
        ),
    ] = ALL_TRAJECTORIES,
    random: Annotated[
        int,
        typer.Option(
            "--random",
            metavar="N",
            help="Also run N episodes on the run's random training target, from "
            "seeds training never uses (table eval_random).",
        ),
    ] = 0,
    model: Annotated[
        ModelOption,
        typer.Option(
            "--model",
            "-m",
            case_sensitive=False,
            help="Which model of each run: its policy (training.final_policy), the "
            "last model of training, or the best-validated one. Only the "
            "policy's results are stored.",
        ),
    ] = ModelOption.policy,
    in_place: InPlaceOption = False,
    full_moments: Annotated[
        bool,
        typer.Option(
            "--full-moments",
            metavar="",
            help="Also store every element torque at every step (table "
            "eval_element_moments, ~2 MB per trajectory); by default only "
            "the per-step RMS and the per-element peaks are stored.",
        ),
    ] = False,
    runs_dir: RunsDirOption = None,
) -> None:
    """Evaluate runs on the circle, rectangle and figure-eight targets.

    Runs each run's deterministic policy for its training.eval_duration (10 s by default) per
    trajectory from the straight initial state and stores the tables eval_trajectories,
    eval_metrics, eval_moments (spatial RMS of the element torques per step) and
    eval_moment_peaks (each element's peak). Prints the 3-D RMSE of each arm per run and
    trajectory (m); in the transport task the sphere's 3-D RMSE, the time both arms held it
    and any drop. With --random N, also N episodes on the
    random target the run was trained on (seeds 1,000,000 + k, the same for every run), and
    their mean 3-D RMSE per arm (--trajectory none --random N: only those).

    --model last (or best) evaluates another of the run's models, e.g. the last model of a
    run that keeps its best-validated one, and only prints its results: the tables keep the
    evaluation of the run's policy.

    A spec file of controller: mpc (a sampling planner, nothing to train) in place of a run
    creates one run per seed of the spec and evaluates it (docs/mpc.md); its metrics add the
    planning time per control step.
    """
    if trajectory.value == "all":
        chosen: list[str] | None = None
    else:
        chosen = [] if trajectory.value == "none" else [trajectory.value]

    with _user_errors(runs_dir):
        api.evaluate(
            references,
            chosen,
            runs_dir=runs_dir,
            on_episode=_print_episode,
            random_episodes=random,
            on_random=_print_random,
            model=model.value,
            full_moments=full_moments,
            on_created=_print_created,
            in_place=in_place,
            on_copied=_print_copied,
        )


def _print_copied(shipped: RunRecord, copy: RunRecord) -> None:
    typer.echo(
        f"{api.shown_path(shipped.path)} is a shipped run (read-only): its results go to its "
        f"copy {api.shown_path(copy.path)} (--in-place writes into the shipped run)",
        err=True,
    )


def _print_created(record: RunRecord) -> None:
    typer.echo(
        f"{record.run_id}  created: {record.info.name} seed {record.info.seed} "
        f"(controller mpc, {record.info.algo})",
        err=True,
    )


def _print_episode(record: RunRecord, episode: Episode, metrics: pd.DataFrame) -> None:
    rows = metrics.sort_values("arm")
    if "object_rmse_3d" in rows:  # transport: the sphere's error, the drop, the hold
        first = rows.iloc[0]
        dropped = f", dropped at {first['drop_time']:.2f} s" if bool(first["dropped"]) else ""
        typer.echo(
            f"{record.run_id}  {episode.trajectory:9s}  sphere 3-D RMSE "
            f"{first['object_rmse_3d']:.4f} m, held by both arms "
            f"{100 * first['two_arm_contact']:.0f} % of the steps{dropped}"
        )
        return
    rmse = " / ".join(f"{v:.4f}" for v in rows["rmse_3d"])
    steady = " / ".join("n/a" if math.isnan(v) else f"{v:.4f}" for v in rows["rmse_3d_steady"])
    note = "  (diverged: episode ended early)" if bool(rows["terminated"].any()) else ""
    typer.echo(
        f"{record.run_id}  {episode.trajectory:9s}  3-D RMSE arm 1 / arm 2: {rmse} m "
        f"(t ≥ 1 s: {steady} m){note}"
    )


def _print_random(record: RunRecord, rows: pd.DataFrame) -> None:
    if "object_rmse_3d" in rows:  # transport: one sphere per episode
        episodes = rows.drop_duplicates("episode")
        n = len(episodes)
        drops = int(episodes["dropped"].astype(bool).sum())
        typer.echo(
            f"{record.run_id}  random     sphere 3-D RMSE {episodes['object_rmse_3d'].mean():.4f}"
            f" m (mean over {n} episode{'s' if n != 1 else ''}), {drops} dropped"
        )
        return
    per_arm = rows.groupby("arm")["rmse_3d"]
    means, stds = per_arm.mean(), per_arm.std()
    cells = " / ".join(
        f"{means[a]:.4f}" + ("" if math.isnan(stds[a]) else f" ± {stds[a]:.4f}")
        for a in sorted(means.index)
    )
    n = int(rows["episode"].nunique())
    diverged = int(rows.groupby("episode")["terminated"].any().sum())
    note = f"  ({diverged} diverged)" if diverged else ""
    typer.echo(
        f"{record.run_id}  random     3-D RMSE arm 1 / arm 2: {cells} m "
        f"(mean ± std over {n} episode{'s' if n != 1 else ''}){note}"
    )


RobustnessWorkersOption = Annotated[
    int | None,
    typer.Option(
        "--workers",
        "-w",
        metavar="N",
        min=1,
        show_default=False,
        help="Settings evaluated at once (local: worker processes, default 1 = in "
        "this process; slurm: array parallelism, default no limit).",
    ),
]


@app.command(cls=Command)
def robustness(
    references: Annotated[
        list[str],
        typer.Argument(
            metavar="RUN",
            help="Runs: run ids (or unique prefixes), run directories, experiment names or spec files.",
            show_default=False,
        ),
    ],
    grid: Annotated[
        list[str] | None,
        typer.Option(
            "--grid",
            "-g",
            metavar="FACTOR=L1,L2",
            show_default=False,
            help="Levels of one perturbation, e.g. --grid obs_noise=0,0.005 --grid "
            "action_delay=0,2 (a field of env.realism, obs_noise, gravity, contact (on/off or N/m), or a spec "
            "path env.*). Repeatable.",
        ),
    ] = None,
    full_grid: Annotated[
        bool,
        typer.Option(
            "--full-grid",
            metavar="",
            help="Every combination of the axes' levels "
            "[default: one factor at a time, the others nominal].",
        ),
    ] = False,
    trajectory: Annotated[
        TrajectoryChoice,
        typer.Option(
            "--trajectory", "-t", help="Target trajectory to evaluate on.", case_sensitive=False
        ),
    ] = ALL_TRAJECTORIES,
    episodes: Annotated[
        int,
        typer.Option(
            "--episodes",
            metavar="K",
            min=1,
            help="Episodes per setting and trajectory (noise seeds 4,000,000 + k).",
        ),
    ] = 1,
    keep_realism: Annotated[
        bool,
        typer.Option(
            "--keep-realism",
            metavar="",
            help="Perturb each run's own env.realism "
            "[default: the idealised environment, realism off].",
        ),
    ] = False,
    redo: Annotated[
        bool,
        typer.Option("--redo", metavar="", help="Evaluate again settings the tables already hold."),
    ] = False,
    in_place: InPlaceOption = False,
    *,
    executor: ExecutorOption = ExecutorChoice.local,
    workers: RobustnessWorkersOption = None,
    detach: DetachOption = False,
    partition: PartitionOption = None,
    time_min: TimeOption = None,
    cpus: CpusOption = None,
    mem: MemOption = None,
    runs_dir: RunsDirOption = None,
) -> None:
    """Evaluate controllers under perturbed sensing, actuation and physics.

    Each setting (a level of one factor, or with --full-grid a combination) runs each run's
    deterministic policy on the circle, rectangle and figure-eight targets and stores the
    metrics rows in the run's table eval_robustness (perturbation, level, setting,
    trajectory, arm, the tracking, smoothness and safety metrics). Settings already stored are
    skipped, so an interrupted evaluation continues where it stopped. Prints the 3-D RMSE of
    each arm per run, setting and trajectory (m); `softtrack report` plots RMSE against level.

    Example: softtrack robustness models/td3-sbx-128-mirror-val-4e6-seed0 --grid
    obs_noise=0,0.002,0.005,0.01 --grid action_delay=0,1,2,4 --grid
    youngs_modulus_scale=0.7,1,1.3
    """
    options = _exec_options(executor, workers, detach, partition, time_min, cpus, mem)
    if trajectory.value == "none":
        _fail("robustness: --trajectory none leaves nothing to evaluate; name a trajectory or all")
    chosen = None if trajectory.value == "all" else [trajectory.value]

    def cell(record: RunRecord, setting: Any, rows: pd.DataFrame) -> None:
        for name, part in rows.groupby("trajectory", sort=False):
            rmse = " / ".join(f"{v:.4f}" for v in part.groupby("arm")["rmse_3d"].mean())
            note = "  (diverged)" if bool(part["terminated"].any()) else ""
            typer.echo(
                f"{record.run_id}  {setting.key:28s} {name:9s}  3-D RMSE arm 1 / arm 2: "
                f"{rmse} m{note}"
            )

    with _user_errors(runs_dir):
        outcome = api.robustness(
            references,
            grid or [],
            full_grid=full_grid,
            trajectories=chosen,
            episodes=episodes,
            keep_realism=keep_realism,
            redo=redo,
            runs_dir=runs_dir,
            options=options,
            on_cell=cell,
            on_progress=_progress,
            in_place=in_place,
            on_copied=_print_copied,
        )
    if outcome.copied:
        keys = ", ".join(dict.fromkeys(key for _, key in outcome.copied))
        typer.echo(
            f"robustness: {keys} equal the nominal setting of the run(s): its episodes are "
            "stored under them too, not run again",
            err=True,
        )
    if outcome.skipped:
        typer.echo(
            f"robustness: {len(outcome.skipped)} settings already stored (--redo "
            "evaluates them again)",
            err=True,
        )
    if outcome.detached:
        typer.echo(
            "robustness: workers submitted; run the same command again once they "
            "ended to merge their results",
            err=True,
        )
    for run_id, key in outcome.failed:
        typer.echo(f"  failed: {run_id} {key} (see the run's robustness.log)", err=True)
    if outcome.exit_code:
        raise typer.Exit(outcome.exit_code)


@app.command(cls=Command)
def export(
    run: Annotated[
        str,
        typer.Argument(
            metavar="RUN", help="Run id, unique id prefix or run directory.", show_default=False
        ),
    ],
    dest: Annotated[
        str, typer.Argument(metavar="DEST", help="New directory to create.", show_default=False)
    ],
    runs_dir: RunsDirOption = None,
    policy_only: Annotated[
        bool,
        typer.Option(
            "--policy-only",
            help="Leave out the run's other model (the last or best-validated one, what "
            "`evaluate --model` reads): about a third smaller.",
        ),
    ] = False,
) -> None:
    """Copy a finished run to DEST without checkpoints or replay buffers (spec, run.json,
    model, tables, log): small enough to commit or share, e.g. under models/.

    `softtrack evaluate DEST` and `softtrack report NAME --runs-dir PARENT_OF_DEST` use it as
    any run.
    """
    with _user_errors(runs_dir):
        path = api.export(run, dest, runs_dir=runs_dir, policy_only=policy_only)
    size = sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
    typer.echo(f"exported: {path} ({size / 1e6:.1f} MB)")


@app.command(cls=Command)
def upgrade(
    run_dirs: Annotated[
        list[str],
        typer.Argument(metavar="RUN_DIR", show_default=False, help="Run directories to rewrite."),
    ],
    keep_full_moments: Annotated[
        bool,
        typer.Option(
            "--keep-full-moments",
            metavar="",
            help="Keep the per-element torque history as eval_element_moments.",
        ),
    ] = False,
) -> None:
    """Rewrite runs made by earlier softtrack versions in the current format.

    Tables: element-torque histories become the summaries of docs/environment.md (eval_moments:
    per-step RMS; eval_moment_peaks: each element's peak) and positions float32, about 14x
    smaller, computed from the stored tables alone. Exported runs (no checkpoints) also get the
    current model layout: model.zip is the run's policy (policy.json says which), the other
    model goes to other_models/, all inference-only. Runs already current are left as they are.
    Example: softtrack upgrade models/*/
    """
    with _user_errors():
        results = api.upgrade(run_dirs, keep_full_moments=keep_full_moments)
    for path, written in results.items():
        typer.echo(f"{path}: {', '.join(written) if written else 'already current'}")


@app.command(cls=Command)
def report(
    selection: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="SELECTION",
            show_default=False,
            help="Experiment names, run ids (or prefixes), run directories or spec files.",
        ),
    ] = None,
    out: Annotated[
        str, typer.Option("--out", "-o", metavar="DIR", help="Output directory of the report.")
    ] = "reports/latest",
    runs_dir: RunsDirOption = None,
    all_figures: Annotated[
        bool,
        typer.Option(
            "--all-figures",
            metavar="",
            help="Draw the trajectory, error and moment figures of every controller "
            "(one per controller and trajectory), not only of the study "
            "protocol and the best centralized and independent controllers.",
        ),
    ] = False,
    figures_for: Annotated[
        list[str] | None,
        typer.Option(
            "--figures-for",
            metavar="NAME",
            show_default=False,
            help="Draw those figures for this experiment's controller instead of the "
            "automatic choice. Repeatable.",
        ),
    ] = None,
    interactive: Annotated[
        bool,
        typer.Option(
            "--html",
            metavar="",
            help="Also write interactive.html: the answers first, the featured controllers "
            "replayed in a 3-D viewer, training curves a click hides, the runs last (offline).",
        ),
    ] = False,
    studies: Annotated[
        list[str] | None,
        typer.Option(
            "--study",
            metavar="NAME",
            show_default=False,
            help="A tuning study (softtrack tune --study): its trials' runs join the selection; "
            "the report shows its parameter importance and best trials, and --html its trials "
            "in parallel coordinates. Repeatable.",
        ),
    ] = None,
    storage: Annotated[
        str | None,
        typer.Option(
            "--storage",
            metavar="URL",
            show_default=False,
            help="The studies' Optuna storage [default: sqlite:///RUNS_DIR/optuna.db].",
        ),
    ] = None,
) -> None:
    """Build a report (PNG figures, index.md, index.html) from the selected runs.

    Reads only the stored tables; completed runs without an evaluation are evaluated first.
    Every controller is in the tables; with more than three, the per-run figures show the
    study protocol and the best centralized and independent controllers (--all-figures: all).
    """

    with _user_errors(runs_dir):
        # an empty selection is a one-line error (EmptySelectionError), like every command's
        index = api.report(
            selection or [],
            out,
            runs_dir=runs_dir,
            command_line=["softtrack", *sys.argv[1:]],
            on_episode=_print_episode,
            all_figures=all_figures,
            figures_for=figures_for or [],
            interactive=interactive,
            studies=studies or [],
            storage=storage,
        )
    typer.echo(f"report: {index}")
    if interactive:
        typer.echo(f"interactive: {index.parent / 'interactive.html'}")


@app.command(cls=Command)
def compare(
    selection: Annotated[
        list[str],
        typer.Argument(
            metavar="CONTROLLER",
            show_default=False,
            help="Two or more controllers, each an experiment name, run id (or prefix), run "
            "directory or spec file; the first is compared with each other.",
        ),
    ],
    runs_dir: RunsDirOption = None,
    metric: Annotated[
        str,
        typer.Option(
            "--metric",
            metavar="COLUMN",
            help="eval_metrics column to compare (an error, m); transport: object_rmse_3d, or "
            "object_carry_score (the sphere's error with every step after a drop at 1 m).",
        ),
    ] = "rmse_3d",
    random: Annotated[
        bool,
        typer.Option(
            "--random",
            help="Compare on the held-out random-target episodes (eval_random, the same "
            "targets for every run: softtrack evaluate RUN --random 20), one cell per episode.",
        ),
    ] = False,
    figure: Annotated[
        str | None,
        typer.Option(
            "--figure",
            metavar="PNG",
            show_default=False,
            help="Also write the performance profile figure here.",
        ),
    ] = None,
    reps: Annotated[
        int, typer.Option("--reps", metavar="N", min=100, help="Bootstrap resamples.")
    ] = 2000,
) -> None:
    """Compare controllers across their seeds, as a reviewer would want it.

    Per trajectory and arm and over all of them: the interquartile mean of the runs' 3-D RMSE
    with a 95 % stratified bootstrap interval; the probability that the first controller
    improves on each other (0.5: no difference); the seeds and CPU kinds behind each, and the
    cross-CPU noise floor. Reads only stored evaluations (docs/statistics.md).
    Example: softtrack compare td3-sbx-128-mirror-val-confirm independent-td3-sbx-2e6-val-confirm
    --runs-dir models
    """
    with _user_errors(runs_dir):
        if len(selection) < 2:
            raise api.SpecError(
                "compare", "needs at least two controllers", "name two or more, e.g. A B"
            )
        from softtrack.report import compare as comparing  # not api: it loads the simulator

        comparison = comparing.compare_selection(
            selection, runs_dir=runs_dir, metric=metric, reps=reps, random=random
        )
        for line in comparison.lines():
            typer.echo(line)
        if figure:
            typer.echo(f"figure: {comparing.profile_figure([('', comparison)], figure)}")


AnimateTrajectory = enum.StrEnum(  # type: ignore[misc]
    "AnimateTrajectory", [(name, name) for name in (*EVAL_TRAJECTORIES, "all")]
)
CIRCLE = AnimateTrajectory("circle")


@app.command("animate", cls=Command)
def animate(
    references: Annotated[
        list[str],
        typer.Argument(
            metavar="RUN...",
            help="One run, or several drawn side by side on the same target: run ids, run "
            "directories, experiment names or spec files.",
            show_default=False,
        ),
    ],
    trajectory: Annotated[
        AnimateTrajectory,
        typer.Option(
            "--trajectory",
            "-t",
            help="Target trajectory (all: every one, for an .html page).",
            case_sensitive=False,
        ),
    ] = CIRCLE,
    random: Annotated[
        int | None,
        typer.Option(
            "--random",
            metavar="K",
            min=0,
            show_default=False,
            help="Instead, the K-th held-out random-target episode (as evaluate --random).",
        ),
    ] = None,
    out: Annotated[
        str,
        typer.Option(
            "--out",
            "-o",
            metavar="FILE",
            help="The animation: .mp4, .gif, or .html (a page that plays the runs in 3-D).",
        ),
    ] = "animation.mp4",
    strip: Annotated[
        str | None,
        typer.Option(
            "--strip",
            metavar="PNG",
            show_default=False,
            help="Also a film strip of six instants (a PNG for papers).",
        ),
    ] = None,
    fps: Annotated[
        float, typer.Option("--fps", min=1.0, max=120.0, help="Frames per second.")
    ] = 30.0,
    width: Annotated[
        int, typer.Option("--width", min=160, max=1920, help="Panel width, px.")
    ] = 640,
    height: Annotated[
        int, typer.Option("--height", min=120, max=1080, help="Panel height, px.")
    ] = 480,
    runs_dir: RunsDirOption = None,
) -> None:
    """Draw runs tracking a target: replays each run's policy and writes an MP4, a GIF or a
    self-contained HTML page that plays them in 3-D (play, pause, scrub, speed, controller and
    trajectory; offline). Nothing is written into the runs: shipped runs work read-only.

    Each replay's tips are compared with the run's stored evaluation (one line says whether
    they are equal to the last bit). Example:
    softtrack animate models/td3-sbx-128-mirror-val-confirm-4e6-seed0 --out circle.mp4
    """
    from softtrack.report.animation import animate_runs
    from softtrack.rl.policy import load_policy
    from softtrack.store.runs import RunStore
    from softtrack.store.selection import select_runs

    with _user_errors(runs_dir):
        records = select_runs(RunStore(resolve_runs_dir(runs_dir)), references)
        chosen = list(EVAL_TRAJECTORIES) if str(trajectory) == "all" else [str(trajectory)]
        written = animate_runs(
            records,
            chosen,
            out,
            load=load_policy,
            fps=fps,
            size=(width, height),
            strip=strip,
            random=random,
            on_note=lambda line: typer.echo(f"note: {line}", err=True),
        )
        typer.echo(f"animation: {written} ({written.stat().st_size / 1e6:.1f} MB)")
        if strip:
            typer.echo(f"film strip: {strip}")


@app.command("watch", cls=Command)
def watch_command(
    selection: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="[RUN_OR_NAME]...",
            show_default=False,
            help="Run ids, id prefixes or experiment names (default: running and recent runs).",
        ),
    ] = None,
    interval: Annotated[
        float, typer.Option("--interval", metavar="S", min=0.2, help="Seconds between refreshes.")
    ] = 2.0,
    recent: Annotated[
        int, typer.Option("--recent", metavar="N", min=0, help="Ended runs shown, the last N.")
    ] = 8,
    once: Annotated[
        bool, typer.Option("--once", metavar="", help="Print the view once and exit.")
    ] = False,
    runs_dir: RunsDirOption = None,
) -> None:
    """A live view of running and recent runs: status, env steps, steps/s, time left, the
    validation scores as a sparkline with the last and best, the CPU. Reads the store without
    changing it; works over SSH and on a SLURM login node. Ctrl-C stops it.
    Example: softtrack watch --runs-dir runs
    """
    from softtrack.report.watch import watch

    with _user_errors(runs_dir):
        try:
            watch(runs_dir, selection or (), interval=interval, recent=recent, once=once)
        except KeyboardInterrupt:
            return


sync_app = typer.Typer(
    name="sync",
    help="Copy runs to the tools people already use (MLflow).",
    no_args_is_help=True,
    cls=Group,
)
app.add_typer(sync_app)


@sync_app.command("mlflow", cls=Command)
def sync_mlflow(
    selection: Annotated[
        list[str] | None,
        typer.Argument(
            metavar="[RUN_OR_NAME]...",
            show_default=False,
            help="Experiment names, run ids (or prefixes) or spec files [default: every run].",
        ),
    ] = None,
    runs_dir: RunsDirOption = None,
    tracking_uri: Annotated[
        str | None,
        typer.Option(
            "--tracking-uri",
            metavar="URI",
            show_default=False,
            help="The MLflow store [default: $MLFLOW_TRACKING_URI, else sqlite:///mlflow.db "
            "in the current directory].",
        ),
    ] = None,
) -> None:
    """Write runs to an MLflow tracking store: the spec as params, the evaluation metrics,
    the training and validation curves as metric histories, a summary report and the policy
    as artifacts; one MLflow experiment per experiment name.

    Idempotent: a run unchanged since its last sync is skipped, a changed one replaced.
    Needs MLflow: pip install 'softtrack[mlflow]'. Example:
    softtrack sync mlflow td3-sbx-128-mirror-tta --runs-dir models --tracking-uri
    sqlite:///mlflow.db, then mlflow ui --backend-store-uri sqlite:///mlflow.db
    """

    def progress(run_id: str, what: str) -> None:
        typer.echo(f"{run_id}: {what}", err=True)

    with _user_errors(runs_dir):
        outcome = api.sync_mlflow(
            selection or [], runs_dir=runs_dir, tracking_uri=tracking_uri, on_run=progress
        )
    typer.echo(
        f"mlflow {outcome.tracking_uri}: {len(outcome.created)} runs created, "
        f"{len(outcome.replaced)} replaced (changed since the last sync), "
        f"{len(outcome.unchanged)} unchanged"
    )


@app.command(cls=Command)
def quickstart(
    overrides: SetOption = None,
    runs_dir: RunsDirOption = None,
    out: Annotated[
        str, typer.Option("--out", "-o", metavar="DIR", help="Output directory of the report.")
    ] = "reports/quickstart",
    pretrained: Annotated[
        str | None,
        typer.Option(
            "--pretrained",
            metavar="DIR",
            show_default=False,
            help="A trained run directory to show beside the quickstart's own run "
            f"[default: {QUICKSTART_PRETRAINED} of this checkout].",
        ),
    ] = None,
    no_pretrained: Annotated[
        bool, typer.Option("--no-pretrained", metavar="", help="Leave the shipped policy out.")
    ] = False,
) -> None:
    """Train, evaluate and report the quickstart experiment (a few minutes).

    TD3 for 1e5 env steps (experiments/quickstart.yaml), then `softtrack evaluate` on the three
    trajectories, then the shipped study-budget policy (models/td3-sbx-1e7-seed0, 1e7 env
    steps) driving the arms live on the same trajectories, and `softtrack report` of both into
    --out. The shipped run directory is only read: it is copied into the runs directory
    (without its stored evaluation) and evaluated there, so the report shows this machine's
    evaluation.
    """
    with _user_errors(runs_dir):
        index, code = api.quickstart(
            overrides or [],
            out,
            runs_dir=runs_dir,
            pretrained=pretrained,
            no_pretrained=no_pretrained,
            on_line=typer.echo,
            on_episode=_print_episode,
        )
    if index is None:
        raise typer.Exit(code)
    typer.echo(f"report: {index}")


if __name__ == "__main__":  # python -m softtrack.cli
    app()
