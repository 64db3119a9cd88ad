"""``softtrack report``: the selected runs (and tuning studies' trials) evaluated where needed,
then reported from their stored tables."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

from softtrack.evaluation.run_evaluation import (
    evaluate_run,
    has_evaluation,
)
from softtrack.rl.policy import (
    load_policy,
    model_paths,
)
from softtrack.store.provenance import portable_command
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir
from softtrack.store.selection import select_one_run, select_runs
from softtrack.store.tables import TableError


def report(
    selection: Sequence[str],
    out_dir: str | os.PathLike[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    command_line: Sequence[str] | None = None,
    on_episode: Callable[..., None] | None = None,
    extra_runs: Sequence[str | os.PathLike[str]] = (),
    all_figures: bool = False,
    figures_for: Sequence[str] = (),
    interactive: bool = False,
    studies: Sequence[str] = (),
    storage: str | None = None,
    on_problem: Callable[[str], None] | None = None,
) -> Any:
    """Build the report of the selected runs (experiment names, run ids or spec files).

    Completed runs without evaluation tables are evaluated first; the report itself reads only
    the stored tables. Returns the path of ``index.md``.

    Args:
        extra_runs: run directories from elsewhere (e.g. ``models/td3-sbx-1e7-seed0``) reported
            beside the selection; they must already be evaluated and are only read.
        all_figures: draw the trajectory, error and moment figures of every controller, not
            only of the chosen few (:func:`softtrack.report.featured.featured_groups`).
        figures_for: experiment names whose controllers get those figures, instead of the
            automatic choice (study protocol, best centralized, best independent).
        interactive: also write ``interactive.html`` (the featured controllers replayed for
            its 3-D viewer: :mod:`softtrack.report.interactive`).
        studies: tuning studies (``softtrack tune --study``) whose trials' runs join the
            selection and whose trials, parameter importance and best trials the report shows.
        storage: the studies' Optuna storage URL (default ``sqlite:///<runs dir>/optuna.db``).
        on_problem: told each table that could not be read (left out of the report).
    """
    # matplotlib and Optuna: loaded when a report is built, not with the API
    from softtrack.report import build_report
    from softtrack.tune.view import load_view

    root = resolve_runs_dir(runs_dir)
    store = RunStore(root)
    views = [load_view(name, storage=storage, runs_dir=root) for name in studies]
    trial_runs = [t.run_id for view in views for t in view.trials if t.run_id]
    trial_runs = [run_id for run_id in trial_runs if (root / run_id / "run.json").is_file()]
    records = select_runs(store, [*selection, *trial_runs])
    extra = [select_one_run(str(path)) for path in extra_runs]
    for record in extra:
        if not has_evaluation(record):
            raise RunStoreError(
                f"{record.path}: no stored evaluation; run `softtrack evaluate {record.path}` first"
            )
    for record in records:
        record.check_tables_dir()
        spec = record.load_spec()
        trained = all(p.is_file() for p in model_paths(record, spec))
        if trained and not _evaluated_or_damaged(record):
            evaluate_run(record, on_episode=on_episode, load=load_policy)
    if command_line is None:
        command_line = ["softtrack", "report", *selection, "--out", str(out_dir)]
    return build_report(
        [*records, *extra],
        out_dir,
        portable_command(list(command_line)),
        all_figures=all_figures,
        figures_for=figures_for,
        load=load_policy if interactive else None,
        tune_views=views,
        on_problem=on_problem,
    )


def _evaluated_or_damaged(record: RunRecord) -> bool:
    """Whether the report reads the run's evaluation as it is: evaluated, or with a damaged
    metrics table, which the report names and leaves out rather than overwriting it."""
    try:
        return has_evaluation(record)
    except TableError:
        return True
