"""``softtrack train``, ``sweep``, ``resume`` and ``tune``: runs trained here, on a pool or on SLURM."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from softtrack.cli_classes import Command
from softtrack.commands.common import (
    CpusOption,
    DetachOption,
    ExecutorChoice,
    ExecutorOption,
    MemOption,
    PartitionOption,
    RunsDirOption,
    SetOption,
    TimeOption,
    TuneWorkersOption,
    WorkersOption,
    app,
    exec_options,
    fail,
    finish,
    print_progress,
    user_errors,
)
from softtrack.lazy import lazy_module

if TYPE_CHECKING:
    from softtrack import api
    from softtrack.store.runs import RunRecord
else:
    # loaded at their first use, so `softtrack --help` and `softtrack runs` start at once
    api = lazy_module("softtrack.api")


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
        fail(
            "train: give either a SPEC file or --resume RUN_ID; e.g. `softtrack train "
            "experiments/quickstart.yaml`"
        )
    if resume is not None and (overrides or seed is not None):
        fail("train: --set and --seed cannot be combined with --resume (a run keeps its spec)")

    def started(record: RunRecord) -> None:
        typer.echo(record.run_id)

    with user_errors(runs_dir):
        if resume is not None:
            outcomes = [api.resume(resume, runs_dir=runs_dir, on_start=started)]
        else:
            assert spec is not None
            outcomes = api.train(
                spec,
                overrides or [],
                runs_dir=runs_dir,
                seed=seed,
                on_start=started,
                on_warning=lambda line: typer.echo(line, err=True),
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
    options = exec_options(executor, workers, detach, partition, time_min, cpus, mem)

    def created(sweep_id: str, records: list[RunRecord]) -> None:
        typer.echo(f"sweep {sweep_id}: {len(records)} runs", err=True)
        for record in records:
            typer.echo(record.run_id)

    with user_errors(runs_dir):
        try:
            outcome = api.sweep(
                specs,
                grid or [],
                overrides or [],
                seeds=seeds,
                runs_dir=runs_dir,
                options=options,
                on_created=created,
                on_progress=print_progress,
            )
        except api.SweepStopped as stopped:
            typer.echo(str(stopped), err=True)
            raise typer.Exit(130) from None
    finish(outcome, "sweep")


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
    options = exec_options(executor, workers, detach, partition, time_min, cpus, mem)

    def selected(resume_id: str, records: list[RunRecord]) -> None:
        typer.echo(f"resume {resume_id}: {len(records)} runs", err=True)
        for record in records:
            typer.echo(record.run_id)

    with user_errors(runs_dir):
        outcome = api.resume_runs(
            selection or [],
            runs_dir=runs_dir,
            options=options,
            on_selected=selected,
            on_progress=print_progress,
        )
    if outcome is None:
        typer.echo(
            "nothing to resume: no interrupted, queued, failed-by-signal or lost run matches",
            err=True,
        )
        return
    finish(outcome, "resume")


TuneSpecArgument = Annotated[
    str | None,
    typer.Argument(
        metavar="SPEC",
        show_default=False,
        help="Experiment spec (YAML) with a tune: section (the search space).",
    ),
]

TrialsOption = Annotated[
    int | None,
    typer.Option(
        "--trials",
        "-n",
        metavar="N",
        min=1,
        show_default=False,
        help="Finished trials (complete or pruned) the study should have.",
    ),
]

StudyOption = Annotated[
    str | None,
    typer.Option(
        "--study",
        metavar="NAME",
        show_default=False,
        help="The study: started, or continued if it exists [default: the spec's name].",
    ),
]

StorageOption = Annotated[
    str | None,
    typer.Option(
        "--storage",
        metavar="URL",
        show_default=False,
        help="Optuna RDB storage URL, e.g. postgresql://user@host/db [default: "
        "sqlite:///RUNS_DIR/optuna.db].",
    ),
]

BestOption = Annotated[
    str | None,
    typer.Option(
        "--best",
        metavar="STUDY",
        show_default=False,
        help="Write the study's best trial as a spec file (see --out) instead.",
    ),
]

BestOutOption = Annotated[
    str | None,
    typer.Option(
        "--out",
        "-o",
        metavar="FILE",
        show_default=False,
        help="With --best: the spec file to write [default: STUDY-best.yaml].",
    ),
]

StatusOption = Annotated[
    str | None,
    typer.Option(
        "--status",
        metavar="STUDY",
        show_default=False,
        help="Print the study's trials (state, score, params, run id) instead.",
    ),
]


@app.command("tune", cls=Command)
def tune_command(
    spec: TuneSpecArgument = None,
    overrides: SetOption = None,
    trials: TrialsOption = None,
    study: StudyOption = None,
    storage: StorageOption = None,
    best: BestOption = None,
    out: BestOutOption = None,
    status: StatusOption = None,
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
    options = exec_options(executor, workers, detach, partition, time_min, cpus, mem)
    modes = sum([spec is not None, best is not None, status is not None])
    example = "e.g. `softtrack tune SPEC --trials 30 --study NAME`"
    if modes != 1:
        fail(f"tune: give a SPEC to tune, or --best STUDY, or --status STUDY; {example}")
    if out is not None and best is None:
        fail("tune: --out goes with --best STUDY (the spec file to write)")
    with user_errors(runs_dir):
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
            fail(f"tune: --trials N is needed (finished trials the study should have); {example}")
        assert spec is not None
        outcome = api.tune(
            spec,
            overrides or [],
            trials=trials,
            study=study,
            storage=storage,
            runs_dir=runs_dir,
            options=options,
            log=print_progress,
            on_progress=print_progress,
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
