"""``softtrack robustness``: runs evaluated under a grid of perturbations, every reference and
setting checked before any episode runs."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

from softtrack.evaluation.perturbations import expand_settings
from softtrack.evaluation.robustness_runs import run_robustness
from softtrack.executors import dispatch
from softtrack.executors.sweep import parse_grid
from softtrack.rl.policy import (
    load_policy,
    require_model,
)
from softtrack.spec import (
    SpecError,
)
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir
from softtrack.store.selection import select_runs
from softtrack.trajectories import EVAL_TRAJECTORIES
from softtrack.workflows.shipped_runs import writable_run


def robustness(
    references: Sequence[str],
    grid: Sequence[str],
    *,
    full_grid: bool = False,
    trajectories: Sequence[str] | None = None,
    episodes: int = 1,
    keep_realism: bool = False,
    redo: bool = False,
    runs_dir: str | os.PathLike[str] | None = None,
    options: Any = None,
    on_cell: Callable[..., None] | None = None,
    on_progress: Callable[[str], None] | None = None,
    in_place: bool = False,
    on_copied: Callable[[RunRecord, RunRecord], None] | None = None,
) -> Any:
    """Evaluate runs under perturbations and store their ``eval_robustness`` tables (a
    shipped run's in its copy unless ``in_place``: :func:`writable_run`).

    Every reference, grid axis and setting is checked before any episode runs.

    Args:
        references: run ids (or prefixes) or run directories.
        grid: ``factor=level1,level2`` axes (:mod:`softtrack.evaluation.perturbations`).
        full_grid: every combination of the axes' levels (default: one factor at a time).
        trajectories: subset of circle, rectangle, figure8 (default all three).
        episodes: episodes per setting and trajectory (≥ 1; more for noisy settings).
        keep_realism: keep each run's own ``env.realism`` as the baseline (default: off).
        redo: evaluate settings again that the tables already hold.
        options: :class:`~softtrack.executors.dispatch.ExecOptions`; the default (local, one
            worker) evaluates in this process.
        on_cell: called with (record, setting, rows) after each cell evaluated in-process.
        on_progress: called with a progress line while worker processes run.

    Returns:
        A :class:`~softtrack.evaluation.robustness_runs.RobustnessOutcome`.
    """

    options = options or dispatch.ExecOptions(workers=1)
    if options.executor not in dispatch.EXECUTORS:
        raise SpecError("executor", f"unknown executor {options.executor!r}", "use local or slurm")
    if options.detach and options.executor == "local":
        raise SpecError(
            "detach",
            "local robustness workers cannot be detached",
            "run attached (an interrupted evaluation continues where it stopped), or on the "
            "slurm executor",
        )
    chosen = list(EVAL_TRAJECTORIES) if trajectories is None else list(trajectories)
    unknown = sorted(set(chosen) - set(EVAL_TRAJECTORIES))
    if unknown or not chosen:
        raise SpecError(
            "trajectories",
            f"unknown trajectory {unknown[0]!r}" if unknown else "no trajectory",
            f"choose from {', '.join(EVAL_TRAJECTORIES)}",
        )
    if episodes < 1:
        raise SpecError("episodes", f"{episodes} episodes", "give 1 or more")
    if not references:
        raise RunStoreError("no run given; name run ids or run directories (see `softtrack runs`)")
    settings = expand_settings(parse_grid(grid), full_grid)
    records = select_runs(RunStore(resolve_runs_dir(runs_dir)), references)
    for record in records:
        record.load_spec()  # every run checked before anything is copied or written
    records = [writable_run(r, runs_dir, in_place=in_place, on_copied=on_copied) for r in records]
    return run_robustness(
        records,
        settings,
        chosen,
        episodes,
        keep_realism=keep_realism,
        redo=redo,
        options=options,
        on_cell=on_cell,
        on_progress=on_progress,
        load=load_policy,
        require=require_model,
    )
