"""``softtrack report``, ``compare``, ``animate``, ``watch``, ``sync`` and ``quickstart``: what the runs
show, to read, to compare and to watch."""

from __future__ import annotations

import enum
import sys
from typing import TYPE_CHECKING, Annotated

import typer

from softtrack.cli_classes import Command, Group
from softtrack.commands.common import (
    RunsDirOption,
    SetOption,
    app,
    print_episode,
    refuse_blocked_output,
    user_errors,
)
from softtrack.lazy import lazy_module
from softtrack.store.location import QUICKSTART_PRETRAINED
from softtrack.trajectories import EVAL_TRAJECTORIES

if TYPE_CHECKING:
    from softtrack import api
else:
    # loaded at their first use, so `softtrack --help` and `softtrack runs` start at once
    api = lazy_module("softtrack.api")


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

    with user_errors(runs_dir):
        # an empty selection is a one-line error (EmptySelectionError), like every command's
        index = api.report(
            selection or [],
            out,
            runs_dir=runs_dir,
            command_line=["softtrack", *sys.argv[1:]],
            on_episode=print_episode,
            all_figures=all_figures,
            figures_for=figures_for or [],
            interactive=interactive,
            studies=studies or [],
            storage=storage,
            on_problem=lambda line: typer.echo(f"warning: {line}; left out", err=True),
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
    refuse_blocked_output(figure, "--figure")
    with user_errors(runs_dir):
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
    refuse_blocked_output(out, "--out")  # before the replays
    refuse_blocked_output(strip, "--strip")
    with user_errors(runs_dir):
        chosen = list(EVAL_TRAJECTORIES) if str(trajectory) == "all" else [str(trajectory)]
        written = api.animate(
            references,
            chosen,
            out,
            runs_dir=runs_dir,
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
    from softtrack.report.watch import watch  # not api: a light view, at once on a login node

    with user_errors(runs_dir):
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

    with user_errors(runs_dir):
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
    with user_errors(runs_dir):
        index, code = api.quickstart(
            overrides or [],
            out,
            runs_dir=runs_dir,
            pretrained=pretrained,
            no_pretrained=no_pretrained,
            on_line=typer.echo,
            on_episode=print_episode,
        )
    if index is None:
        raise typer.Exit(code)
    typer.echo(f"report: {index}")
