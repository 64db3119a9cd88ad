"""``softtrack train``: one run per seed of a spec, created and trained one after another;
``train --resume``: a run continued from its checkpoint."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from softtrack.evaluation.workspace_floors import reach_warning
from softtrack.rl.factory import check_supported
from softtrack.spec import SpecError, load_spec, spec_chain
from softtrack.spec.env_config import env_config
from softtrack.store.runs import RunRecord, RunStore, resolve_runs_dir
from softtrack.store.selection import select_one_run

# Imported where used: softtrack.rl.train loads JAX, torch and Stable-Baselines3 (seconds).
if TYPE_CHECKING:
    from softtrack.rl.train import TrainOutcome


def train(
    path: str | os.PathLike[str],
    overrides: Sequence[str] = (),
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    seed: int | None = None,
    on_start: Callable[[RunRecord], None] | None = None,
    show_progress: bool | None = None,
    on_warning: Callable[[str], None] | None = None,
) -> list[TrainOutcome]:
    """Create and train one run per seed of the spec (or only ``seed``), one after another.

    The spec is validated (and checked to be supported) before anything is written.
    Training stops after a run that did not complete (interrupted or failed).

    Args:
        on_start: called with each new run before it trains (the CLI prints its id).
        on_warning: called once, before training, with a transport spec's line about its
            paths' reach (:func:`~softtrack.evaluation.workspace_floors.reach_warning`).

    Returns:
        The outcome of each run started.
    """
    from softtrack.rl.train import train_run  # torch and JAX: when a run trains, not with the API

    spec = load_spec(path, overrides)
    chain = spec_chain(path)
    if spec.controller == "mpc":
        raise SpecError(
            str(path),
            "mpc has nothing to train (a planner plans at every control step)",
            f"evaluate it: `softtrack evaluate {path}` creates one run per seed and evaluates it",
            field="controller",
        )
    check_supported(spec, str(path))
    seeds = list(spec.seeds) if seed is None else [int(seed)]
    if seed is not None and not 0 <= seed < 2**32:
        raise SpecError("seed", f"seed {seed} is out of range", "use 0 ≤ seed < 2**32")
    store = RunStore(resolve_runs_dir(runs_dir))
    warning = reach_warning(env_config(spec), str(path))
    if warning is not None and on_warning is not None:
        on_warning(warning)
    outcomes = []
    for s in seeds:
        record = store.create_run(spec, s, spec_files=chain)
        if on_start is not None:
            on_start(record)
        outcome = train_run(store, record, show_progress=show_progress)
        outcomes.append(outcome)
        if outcome.status != "completed":
            break
    return outcomes


def resume(
    run_id: str,
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    on_start: Callable[[RunRecord], None] | None = None,
    show_progress: bool | None = None,
) -> TrainOutcome:
    """Continue an interrupted (or killed, or failed) run from its latest checkpoint (``run_id``:
    a run id or unique prefix, a run directory, or an experiment of one run)."""
    from softtrack.rl.train import check_resumable, train_run  # torch and JAX, as in train()

    record = select_one_run(run_id, runs_dir)
    store = RunStore(record.path.parent)
    check_resumable(record)
    if on_start is not None:
        on_start(record)
    return train_run(store, record, resume=True, show_progress=show_progress)
