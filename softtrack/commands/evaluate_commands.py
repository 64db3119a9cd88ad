"""``softtrack evaluate``, ``robustness``, ``export`` and ``upgrade``: a run's policy measured, perturbed,
shipped and brought up to date."""

from __future__ import annotations

import enum
import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any

import typer

from softtrack.cli_classes import Command
from softtrack.commands.common import (
    ALL_TRAJECTORIES,
    CpusOption,
    DetachOption,
    ExecutorChoice,
    ExecutorOption,
    InPlaceOption,
    MemOption,
    PartitionOption,
    RunsDirOption,
    SetOption,
    TimeOption,
    TrajectoryChoice,
    app,
    exec_options,
    fail,
    print_episode,
    print_progress,
    user_errors,
)
from softtrack.lazy import lazy_module

if TYPE_CHECKING:
    import pandas as pd

    from softtrack import api
    from softtrack.store.runs import RunRecord
else:
    # loaded at their first use, so `softtrack --help` and `softtrack runs` start at once
    api = lazy_module("softtrack.api")


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
    overrides: SetOption = None,
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
    planning time per control step. --set changes such a spec, e.g. --set
    env.task.grip=0.1 (a run keeps the spec it was trained with).
    """
    if trajectory.value == "all":
        chosen: list[str] | None = None
    else:
        chosen = [] if trajectory.value == "none" else [trajectory.value]
    if chosen == [] and not random:
        fail("--trajectory none: nothing to evaluate; name a trajectory, or add --random N")

    with user_errors(runs_dir):
        api.evaluate(
            references,
            chosen,
            runs_dir=runs_dir,
            on_episode=print_episode,
            random_episodes=random,
            on_random=_print_random,
            on_random_progress=_RandomProgress(),
            model=model.value,
            full_moments=full_moments,
            on_created=_print_created,
            in_place=in_place,
            on_copied=_print_copied,
            on_warning=lambda record, line: typer.echo(f"{record.run_id}  {line}", err=True),
            overrides=overrides or [],
        )


class _RandomProgress:
    """A stderr line per 5 % of a run's random-target episodes (and at least every 30 s):
    done, asked, the rate and the time left; with Ctrl-C the finished ones are kept.

    Episodes run in batches that finish together (one by one for a planner), and the first
    batch carries the compilation. So the rate counts whole batches after the first: a batch
    has closed when the next episode comes more than :data:`SAME_BATCH_S` later. Until one
    has, a line shows the count alone.
    """

    #: Episodes finishing within this many seconds of each other belong to one batch.
    SAME_BATCH_S = 1.0

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self.first = (0.0, 0)  # (time, episodes done) at the end of the first batch
        self.previous = (0.0, 0)  # (time, episodes done) at the previous episode
        self.closed = (0.0, 0)  # (time, episodes done) at the end of the last closed batch
        self.shown = (0.0, -1)  # (time, percent step) of the last line
        self.in_first_batch = True

    def __call__(self, record: RunRecord, done: int, total: int) -> None:
        now = self.clock()
        if done == 1:  # a new run: its clock starts with its first episode
            self.first = self.previous = self.closed = (now, 1)
            self.shown, self.in_first_batch = (now, 0), True
        elif now - self.previous[0] > self.SAME_BATCH_S:  # the previous episode closed a batch
            self.closed, self.in_first_batch = self.previous, False
        elif self.in_first_batch:
            self.first = self.closed = (now, done)
        self.previous = (now, done)
        step = 20 * done // total
        if done == 1 or (done < total and step == self.shown[1] and now - self.shown[0] < 30.0):
            return
        self.shown = (now, step)
        line = (
            f"{record.run_id[-8:]} random targets: {done:,}/{total:,} episodes "
            f"({100 * done / total:.0f}%)"
        )
        (started, in_first), (closed_at, closed_done) = self.first, self.closed
        if closed_done > in_first:
            rate = (closed_done - in_first) / max(closed_at - started, 1e-9)
            if rate >= 1.0:
                line += f", {rate:,.{1 if rate < 10 else 0}f} episodes/s"
            else:  # one episode at a time (a planner): seconds per episode read better
                line += f", {1.0 / rate:,.0f} s per episode"
            line += f", {(total - done) / rate / 60:.1f} min left" if done < total else ""
        if done < total:
            line += "; Ctrl-C keeps the finished episodes"
        typer.echo(line, err=True)


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


def _print_random(record: RunRecord, rows: pd.DataFrame) -> None:
    if "object_rmse_3d" in rows:  # transport: one sphere per episode
        typer.echo(f"{record.run_id}  random     {api.carried_summary(rows)}")
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


RobustnessRunsArgument = Annotated[
    list[str],
    typer.Argument(
        metavar="RUN",
        help="Runs: run ids (or unique prefixes), run directories, experiment names or spec files.",
        show_default=False,
    ),
]

GridOption = Annotated[
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
]

FullGridOption = Annotated[
    bool,
    typer.Option(
        "--full-grid",
        metavar="",
        help="Every combination of the axes' levels "
        "[default: one factor at a time, the others nominal].",
    ),
]

RobustnessTrajectoryOption = Annotated[
    TrajectoryChoice,
    typer.Option(
        "--trajectory", "-t", help="Target trajectory to evaluate on.", case_sensitive=False
    ),
]

RobustnessEpisodesOption = Annotated[
    int,
    typer.Option(
        "--episodes",
        metavar="K",
        min=1,
        help="Episodes per setting and trajectory (noise seeds 4,000,000 + k).",
    ),
]

KeepRealismOption = Annotated[
    bool,
    typer.Option(
        "--keep-realism",
        metavar="",
        help="Perturb each run's own env.realism "
        "[default: the idealised environment, realism off].",
    ),
]

RedoOption = Annotated[
    bool,
    typer.Option("--redo", metavar="", help="Evaluate again settings the tables already hold."),
]


@app.command(cls=Command)
def robustness(
    references: RobustnessRunsArgument,
    grid: GridOption = None,
    full_grid: FullGridOption = False,
    trajectory: RobustnessTrajectoryOption = ALL_TRAJECTORIES,
    episodes: RobustnessEpisodesOption = 1,
    keep_realism: KeepRealismOption = False,
    redo: RedoOption = False,
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
    options = exec_options(executor, workers, detach, partition, time_min, cpus, mem)
    if trajectory.value == "none":
        fail("robustness: --trajectory none leaves nothing to evaluate; name a trajectory or all")
    chosen = None if trajectory.value == "all" else [trajectory.value]

    def cell(record: RunRecord, setting: Any, rows: pd.DataFrame) -> None:
        for name, part in rows.groupby("trajectory", sort=False):
            rmse = " / ".join(f"{v:.4f}" for v in part.groupby("arm")["rmse_3d"].mean())
            note = "  (diverged)" if bool(part["terminated"].any()) else ""
            typer.echo(
                f"{record.run_id}  {setting.key:28s} {name:9s}  3-D RMSE arm 1 / arm 2: "
                f"{rmse} m{note}"
            )

    with user_errors(runs_dir):
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
            on_progress=print_progress,
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
    with user_errors(runs_dir):
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
    with user_errors():
        results = api.upgrade(run_dirs, keep_full_moments=keep_full_moments)
    for path, written in results.items():
        typer.echo(f"{path}: {', '.join(written) if written else 'already current'}")
