"""``softtrack evaluate``: runs (or MPC specs) resolved and checked, then each evaluated on the
closed-form trajectories and held-out random targets under its run lock."""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from softtrack.evaluation.run_evaluation import (
    evaluate_random_targets,
    evaluate_run,
)
from softtrack.evaluation.workspace_floors import reach_warning
from softtrack.rl.policy import (
    MODEL_CHOICES,
    ModelChoice,
    load_policy,
    model_paths,
    require_model,
)
from softtrack.spec import (
    ExperimentSpec,
    SpecError,
    load_spec,
    spec_chain,
)
from softtrack.spec.env_config import env_config
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir, run_lock
from softtrack.store.selection import select_runs
from softtrack.trajectories import EVAL_TRAJECTORIES
from softtrack.workflows.shipped_runs import writable_run


def evaluate(
    references: Sequence[str],
    trajectories: Sequence[str] | None = None,
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    on_episode: Callable[..., None] | None = None,
    write: bool = True,
    random_episodes: int = 0,
    on_random: Callable[..., None] | None = None,
    on_random_progress: Callable[[RunRecord, int, int], None] | None = None,
    model: ModelChoice = "policy",
    full_moments: bool = False,
    on_created: Callable[[RunRecord], None] | None = None,
    in_place: bool = False,
    on_copied: Callable[[RunRecord, RunRecord], None] | None = None,
    on_warning: Callable[[RunRecord, str], None] | None = None,
    overrides: Sequence[str] = (),
) -> pd.DataFrame:
    """Evaluate runs (ids, id prefixes or run directories) on the closed-form trajectories,
    and optionally on held-out episodes of their random training target.

    A shipped run (``notes.read_only``) is never written unless ``in_place``: its results go
    to its copy in the runs directory (:func:`writable_run`; ``on_copied`` is told).

    A reference that is a spec file of ``controller: mpc`` (nothing to train) first creates
    one completed run per seed of the spec in the runs directory, which is then evaluated.

    Every run is resolved and its spec checked before any episode runs, so a bad reference
    fails without writing anything.

    Args:
        trajectories: subset of circle, rectangle, figure8 (default None: all three; empty:
            none, only the random-target episodes).
        on_episode: called with (record, episode, metrics) after each trajectory.
        write: store the tables in each run (``False``: only return the metrics).
        random_episodes: random-target episodes per run after the trajectories (0: none;
            :func:`softtrack.evaluation.run_evaluation.evaluate_random_targets`, table ``eval_random``).
        on_random: called with (record, rows of its random-target episodes) per run.
        on_random_progress: called with (record, episodes done, episodes asked) after each
            random-target episode (Ctrl-C keeps the finished ones: ``eval_random`` holds them).
        model: which model of each run (:data:`softtrack.rl.policy.ModelChoice`): ``policy``
            (default), ``last`` or ``best``. The tables hold the evaluation of the run's policy,
            so another model's results are only returned, never stored.
        full_moments: also store every element torque at every step (table
            ``eval_element_moments``, about 2 MB per trajectory); by default only the
            summaries (``eval_moments``, ``eval_moment_peaks``) are stored.
        on_created: called with each run created for an MPC spec.
        on_warning: called with a transport run whose paths' recorded floors are out of the
            held sphere's reach, and that line
            (:func:`~softtrack.evaluation.workspace_floors.reach_warning`).
        overrides: ``path=value`` changes (``--set``) of the MPC spec files among
            ``references``; refused with any other reference (a run keeps its spec).

    Returns:
        The metrics rows of the trajectories (one per run, trajectory and arm).
    """

    chosen = list(EVAL_TRAJECTORIES) if trajectories is None else list(trajectories)
    _check_request(chosen, random_episodes, model)
    if not references:
        raise RunStoreError("no run given; name run ids or run directories (see `softtrack runs`)")
    mpc_specs = _mpc_specs(references, overrides)
    selected = [ref for ref in references if ref not in mpc_specs]
    if overrides and selected:
        raise SpecError(
            "overrides",
            f"{selected[0]} is a run or a trained experiment: it keeps the spec it was trained "
            "with, and overrides change only a planner's spec (controller: mpc)",
            "give only MPC spec files with overrides, or train the changed spec with "
            "`softtrack train SPEC --set ...`",
        )
    records = select_runs(RunStore(resolve_runs_dir(runs_dir)), selected) if selected else []
    # every run checked before anything is copied or written; results are stored for the
    # runs whose evaluated model is their policy, a shipped run's in its copy
    stores = [
        write and require_model(r, spec, model) == model_paths(r, spec)
        for r, spec in ((r, r.load_spec()) for r in records)
    ]
    for record, store in zip(records, stores, strict=True):
        if store:
            record.check_tables_dir()
    records = [
        writable_run(r, runs_dir, in_place=in_place, on_copied=on_copied) if store else r
        for r, store in zip(records, stores, strict=True)
    ]
    store_for_new = RunStore(resolve_runs_dir(runs_dir))
    for ref, spec in mpc_specs.items():
        for seed in spec.seeds:
            record = store_for_new.create_run(spec, seed, spec_files=spec_chain(ref))
            record = store_for_new.mark_finished(record.run_id, "completed")
            records.append(record)
            stores.append(write)
            if on_created is not None:
                on_created(record)
    if on_warning is not None:
        _warn_out_of_reach(records, chosen, on_warning)
    frames = []
    for record, store in zip(records, stores, strict=True):
        with run_lock(record, "evaluated") if store else contextlib.nullcontext():
            frames.extend(
                _evaluate_one(
                    record,
                    store,
                    chosen,
                    random_episodes,
                    model,
                    full_moments,
                    on_episode,
                    on_random,
                    on_random_progress,
                )
            )
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def _check_request(chosen: Sequence[str], random_episodes: int, model: str) -> None:
    """Raise :class:`SpecError` for an unknown trajectory or model, a negative episode count,
    or nothing to evaluate."""
    unknown = sorted(set(chosen) - set(EVAL_TRAJECTORIES))
    if unknown:
        raise SpecError(
            "trajectories",
            f"unknown trajectory {unknown[0]!r}",
            f"choose from {', '.join(EVAL_TRAJECTORIES)} or all",
        )
    if random_episodes < 0:
        raise SpecError(
            "random_episodes",
            f"{random_episodes} random-target episodes",
            "give 0 (none) or more",
        )
    if model not in MODEL_CHOICES:
        raise SpecError(
            "model", f"unknown model {model!r}", f"choose from {', '.join(MODEL_CHOICES)}"
        )
    if not chosen and not random_episodes:
        raise SpecError(
            "trajectories",
            "nothing to evaluate",
            "name a trajectory, or ask for random-target episodes without trajectories",
        )


def _warn_out_of_reach(
    records: Sequence[RunRecord],
    paths: Sequence[str],
    on_warning: Callable[[RunRecord, str], None],
) -> None:
    """Tell ``on_warning`` of each transport run whose paths have recorded floors out of the
    held sphere's reach (:func:`~softtrack.evaluation.workspace_floors.reach_warning`)."""
    for record in records:
        config = env_config(record.load_spec())
        warning = reach_warning(config, str(record.spec_path), paths, unmeasured_note=False)
        if warning is not None:
            on_warning(record, warning)


def _evaluate_one(
    record: RunRecord,
    store: bool,
    chosen: Sequence[str],
    random_episodes: int,
    model: ModelChoice,
    full_moments: bool,
    on_episode: Callable[..., None] | None,
    on_random: Callable[..., None] | None,
    on_random_progress: Callable[[RunRecord, int, int], None] | None,
) -> list[pd.DataFrame]:
    """:func:`evaluate` of one resolved run: its trajectories' metrics (one frame, or none)."""
    frames = []
    if chosen:
        frames.append(
            evaluate_run(
                record,
                chosen,
                on_episode,
                load=load_policy,
                write=store,
                model=model,
                full_moments=full_moments,
            )
        )
    if random_episodes:
        progress = None
        if on_random_progress is not None:
            progress = functools.partial(on_random_progress, record)
        rows = evaluate_random_targets(
            record,
            random_episodes,
            load=load_policy,
            write=store,
            model=model,
            on_progress=progress,
        )
        if on_random is not None:
            on_random(record, rows)
    return frames


def _is_spec_file(reference: str) -> bool:
    return Path(reference).suffix in (".yaml", ".yml") and Path(reference).is_file()


def _mpc_specs(references: Sequence[str], overrides: Sequence[str]) -> dict[str, ExperimentSpec]:
    """The references that are spec files of an MPC controller (evaluated without training),
    with their specs (``overrides`` applied); any other spec file selects the runs trained
    from it.

    Raises:
        SpecError: a spec file or an override is invalid.
    """
    specs = {ref: load_spec(ref, overrides) for ref in references if _is_spec_file(ref)}
    return {ref: spec for ref, spec in specs.items() if spec.controller == "mpc"}
