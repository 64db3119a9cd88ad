"""``softtrack workspace``: where two arms can hold the transport task's sphere, and each
path's floor (:mod:`softtrack.evaluation.workspace`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from softtrack.cli_classes import Command
from softtrack.commands.common import (
    SetOption,
    app,
    fail,
    print_progress,
    refuse_blocked_output,
    user_errors,
)
from softtrack.evaluation.workspace_settings import GOALS_PER_PATH, SearchSettings
from softtrack.lazy import lazy_module

if TYPE_CHECKING:
    from softtrack import api
    from softtrack.env.settings import TrackingConfig
    from softtrack.evaluation.workspace import WorkspaceResult
else:
    # loaded at its first use, so `softtrack --help` starts at once
    api = lazy_module("softtrack.api")


@app.command("workspace", cls=Command)
def workspace_command(
    spec: Annotated[
        str,
        typer.Argument(metavar="SPEC", help="A transport spec (YAML).", show_default=False),
    ],
    overrides: SetOption = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            metavar="DIR",
            help="Also write held.parquet, floors.csv, boundary.csv and workspace.png here.",
            show_default=False,
        ),
    ] = None,
    torque_scales: Annotated[
        list[float] | None,
        typer.Option(
            "--torque-scale",
            metavar="N·m",
            help="Also measure at this torque per control unit (repeatable): what actuation "
            "would reach the paths.",
            show_default=False,
        ),
    ] = None,
    per_path: Annotated[
        int, typer.Option("--per-path", metavar="N", help="Goal points per path.")
    ] = GOALS_PER_PATH,
    population: Annotated[
        int, typer.Option("--population", metavar="N", help="Samples per goal and iteration.")
    ] = SearchSettings.population,
    iterations: Annotated[
        int, typer.Option("--iterations", metavar="N", help="Search iterations per goal.")
    ] = SearchSettings.iterations,
    seed: Annotated[
        int, typer.Option("--seed", metavar="N", help="Of the samples.")
    ] = SearchSettings.seed,
) -> None:
    """Measure where two arms can hold the sphere at rest, and each path's floor.

    Constant actions, searched towards points of the spec's circle, rectangle and
    figure-eight, run in the engine with the spec's physics (actuation, grip, gravity,
    sphere); every sample that holds the sphere still is a point of the held region. A
    path's floor is the RMSE of each path point's distance to the nearest held point: no
    controller that holds the sphere tracks the path better. Minutes on one core.
    """
    refuse_blocked_output(out, "--out", directory=True)  # before minutes of search
    with user_errors():
        resolved = api.validate_spec(spec, overrides or [])
        config = api.env_config(resolved)
        if not config.task.carries_object:
            fail(
                f"{spec}: env.task.name is {config.task.name}; the workspace is the transport "
                "task's: give a spec with env.task.name: transport"
            )
        settings = SearchSettings(
            population=population,
            iterations=iterations,
            elite=min(population, max(2, population // 5)),
            seed=seed,
        )
        try:
            settings.validate()
        except ValueError as exc:
            fail(f"--{str(exc).split('=', 1)[0]}: {exc}")
        if per_path < 1:
            fail(f"--per-path {per_path}: give at least 1 goal point per path")
        bad = [s for s in torque_scales or [] if not s > 0]
        if bad:
            fail(f"--torque-scale {bad[0]:g}: give a torque per control unit > 0 (N·m)")
        last = [0.0]

        def progress(scale: float, done: int, total: int, held: int) -> None:
            if time.monotonic() - last[0] >= 10 or done == total:
                last[0] = time.monotonic()
                print_progress(
                    f"{scale:g} N·m per unit: {done:,}/{total:,} samples, {held:,} held the "
                    "sphere at rest"
                )

        results = api.measure_workspace(
            config, settings, per_path, torque_scales or [], on_progress=progress
        )
    if not len(results[0].held):
        _record(config, results[0], spec)
        fail(
            f"{spec}: no sample held the sphere at rest (grip {config.task.grip:g}, "
            f"{results[0].torque_scale:g} N·m per control unit): the sphere cannot be gripped "
            "where it starts; raise env.task.grip or check env.physics.sphere"
        )
    typer.echo(_summary(resolved.name, config, results))
    _record(config, results[0], spec)
    if out is not None:
        with user_errors():
            api.write_workspace_files(out, resolved.name, config, results, seed)
        typer.echo(f"wrote {out}/workspace.png, held.parquet, floors.csv, boundary.csv")


def _record(config: TrackingConfig, own: WorkspaceResult, spec: str) -> None:
    """Record the floors at the spec's own actuation (inf where nothing held), for the
    warnings of `train` and `evaluate`, and say where; a cache that cannot be written loses
    only the record (one warning line)."""
    floors = dict(zip(own.floors["path"], own.floors["floor"], strict=True))
    try:
        recorded = api.record_floors(config, floors, own.samples, spec)
    except OSError as exc:  # the measurement printed stands; only the record is lost
        typer.echo(
            f"warning: the floors could not be recorded in {api.floors_dir()} ({exc.strerror or exc}); "
            "set SOFTTRACK_CACHE_DIR to a writable directory to keep them",
            err=True,
        )
    else:
        if len(own.held):
            typer.echo(
                f"recorded the floors at {own.torque_scale:g} N·m per unit in {recorded}: "
                "`train` and `evaluate` of this physics and these paths warn when a path is out "
                "of reach"
            )


def _summary(name: str, config: TrackingConfig, results: list[WorkspaceResult]) -> str:
    """The held region per height at the spec's actuation, and every scale's floors."""
    first = results[0]
    lines = [
        f"held region of {name} at {first.torque_scale:g} N·m per control unit: "
        f"{len(first.held):,} of {first.samples:,} samples held the sphere at rest "
        f"({first.seconds / 60:.1f} min)",
        f"{'height y (m)':<14}{'held':>6}  {'x (m)':<17}{'z (m)':<17}{'reach (m)':>9}",
    ]
    for row in first.boundary.itertuples():
        lines.append(
            f"{row.y_low:.2f}–{row.y_high:.2f}     {row.count:>6}  "
            f"{row.x_min:+.3f} … {row.x_max:+.3f}  {row.z_min:+.3f} … {row.z_max:+.3f}"
            f"{row.reach:>9.3f}"
        )
    paths = list(first.floors["path"])
    lines.append("")
    lines.append(
        "floor: RMSE of each path point's distance to the nearest held point (m), by torque "
        "per control unit"
    )
    lines.append(f"{'N·m per unit':<14}" + "".join(f"{p:>12}" for p in paths))
    for result in results:
        floors = dict(zip(result.floors["path"], result.floors["floor"], strict=True))
        lines.append(f"{result.torque_scale:<14g}" + "".join(f"{floors[p]:>12.3f}" for p in paths))
    return "\n".join(lines)
