"""What every ``softtrack`` command shares: the Typer app, the options several commands take,
one-line user errors, progress lines and the printing of an evaluated episode."""

from __future__ import annotations

import enum
import math
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, NoReturn

import typer

from softtrack.cli_classes import App, Group
from softtrack.lazy import lazy_module
from softtrack.signals import (
    SignalExit,
    StoppedBySignal,
    forget_stops,
    interrupt_on_sigint,
    note_stop,
    stops_received,
)
from softtrack.store import provenance
from softtrack.store.disk import MachineLimitError, machine_limit, storage_problem
from softtrack.store.location import resolve_runs_dir
from softtrack.trajectories import EVAL_TRAJECTORIES

if TYPE_CHECKING:
    import pandas as pd

    from softtrack import api
    from softtrack.evaluation.episodes import Episode
    from softtrack.executors import dispatch
    from softtrack.executors.dispatch import Outcome
    from softtrack.store.runs import RunRecord
else:
    # loaded at their first use, so `softtrack --help` and `softtrack runs` start at once
    api = lazy_module("softtrack.api")
    dispatch = lazy_module("softtrack.executors.dispatch")


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


def fail(exc: BaseException | str) -> NoReturn:
    typer.echo(f"error: {exc}", err=True)
    raise typer.Exit(2)


def refuse_blocked_output(
    output: str | os.PathLike[str] | None, flag: str, *, directory: bool = False
) -> None:
    """Fail (one line, exit 2) before any work when an output path cannot be written: a parent
    of ``output`` is a file, or ``output`` is of the wrong kind (a directory where a file goes, or
    the other way round with ``directory``)."""
    if output is None:
        return
    path = Path(output)
    if path.exists() and path.is_dir() != directory:
        want = "a directory" if directory else "a file"
        fail(f"{flag} {path}: exists and is not {want}; choose another {flag}")
    blocker = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        fail(f"{flag} {path}: {blocker} is a file, not a directory; choose another {flag}")


#: The library's errors name the argument of a call; the command line names its flag.
ARGUMENT_FLAGS = {
    "trajectories": "--trajectory",
    "random_episodes": "--random",
    "model": "--model",
    "seed": "--seed",
    "episodes": "--episodes",
    "executor": "--executor",
    "detach": "--detach",
    "overrides": "--set",
}


@contextmanager
def user_errors(runs_dir: str | None = None) -> Iterator[None]:
    """Turn the user errors of softtrack, and a full or read-only disk, into one stderr line
    and exit code 2 (``runs_dir``: the command's ``--runs-dir``, named when a library's
    error does not say which file it was writing)."""
    try:
        yield
    except (MemoryError, MachineLimitError) as exc:  # the machine's limit: exit code 1
        limit = machine_limit(exc)
        typer.echo(f"error: {limit}", err=True)
        raise typer.Exit(1) from None
    except api.USER_ERRORS as exc:
        if isinstance(exc, api.SpecError) and exc.file in ARGUMENT_FLAGS:
            exc.file = ARGUMENT_FLAGS[exc.file]  # the library names its argument
        limit = machine_limit(exc)  # a healthy table that could not be opened is not damaged
        if limit is not None:
            typer.echo(f"error: {limit}", err=True)
            raise typer.Exit(1) from None
        fail(exc)
    except Exception as exc:
        if isinstance(exc, StoppedBySignal) or stops_received():
            raise  # a stop: one line from cli_classes.Group
        limit = machine_limit(exc)
        if limit is not None:
            typer.echo(f"error: {limit}", err=True)
            raise typer.Exit(1) from None
        problem = storage_problem(exc, "then run the command again", resolve_runs_dir(runs_dir))
        if problem is None:
            raise
        fail(problem)


def plural(count: int, noun: str) -> str:
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


def exit_on_sigterm(signum: int, _frame: object) -> None:
    note_stop(signum)
    raise SignalExit(signum)


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
        # and the pools install their own clean stop while they run); both are recorded, for
        # an error that a library raised while the signal unwound it (cli_classes.Group)
        forget_stops()
        signal.signal(signal.SIGTERM, exit_on_sigterm)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, interrupt_on_sigint)


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


def exec_options(
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


def print_progress(line: str) -> None:
    typer.echo(line, err=True)


def finish(outcome: Outcome, what: str) -> None:
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


def print_notes(notices: list[str]) -> None:
    """Lines about the catalog, after a command's answer (an error stays one line)."""
    for notice in notices:
        typer.echo(f"note: {notice}", err=True)


def write_stdout(text: str) -> None:
    sys.stdout.write(text)


#: --trajectory: one of the evaluation trajectories (softtrack.env.targets), all or none
TrajectoryChoice = enum.StrEnum(  # type: ignore[misc]
    "TrajectoryChoice", [(name, name) for name in (*EVAL_TRAJECTORIES, "all", "none")]
)
ALL_TRAJECTORIES = TrajectoryChoice("all")


def print_episode(record: RunRecord, episode: Episode, metrics: pd.DataFrame) -> None:
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
