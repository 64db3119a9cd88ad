"""The public Python functions behind the ``softtrack`` command line.

The CLI (:mod:`softtrack.cli`) only parses arguments and prints; everything it shows is
computed here, so the same results are available from Python. The run summaries behind
``softtrack runs`` (status, progress, final-stage return) live in :mod:`softtrack.store.status`
and are re-exported here.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from softtrack.evaluation.transport_summary import carried_summary
from softtrack.evaluation.workspace_floors import floors_dir, record_floors
from softtrack.executors import dispatch
from softtrack.executors.sweep import expand_grid, parse_grid, parse_seeds
from softtrack.executors.sweep_creation import SweepStopped, create_sweep_runs
from softtrack.report.video import VideoError
from softtrack.rl.factory import check_supported
from softtrack.rl.policy import load_policy
from softtrack.rl.policy_export import export_policy_run, relayout_exported_run
from softtrack.sim.params import InvalidParameterError
from softtrack.spec import (
    ExperimentSpec,
    SpecError,
    load_spec,
    spec_chain,
)
from softtrack.spec.env_config import env_config
from softtrack.spec.spec_text import (
    resolved_spec_yaml,
    spec_defaults_yaml,
    spec_schema_json,
    validation_summary,
)
from softtrack.store.location import QUICKSTART_PRETRAINED
from softtrack.store.model_zip import deflate_model_zip
from softtrack.store.run_summaries import (
    RUN_TABLE_COLUMNS,
    format_failures,
    format_runs_table,
    list_run_summaries,
    summary_from_row,
)
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir, run_lock
from softtrack.store.selection import select_one_run, select_runs
from softtrack.store.status import (
    effective_status,
    final_stage_fraction,
    final_stage_return,
    heartbeat_interval,
    is_lost,
)
from softtrack.store.tables import TableError
from softtrack.store.upgrade import upgrade_run_tables
from softtrack.tune import TuneError
from softtrack.tune.command import TuneOutcome
from softtrack.tune.command import tune as run_tune
from softtrack.tune.command import tune_best as best_trial_spec
from softtrack.tune.command import tune_status as study_status
from softtrack.workflows.evaluate_runs import evaluate
from softtrack.workflows.perturbed_evaluation import robustness
from softtrack.workflows.quickstart import (
    quickstart,
    quickstart_pretrained_path,
    quickstart_spec_path,
    shown_path,
)
from softtrack.workflows.report_runs import report
from softtrack.workflows.shipped_runs import copy_run
from softtrack.workflows.training_runs import resume, train
from softtrack.workflows.workspace_files import write_workspace_files

# Imported where used, because importing them costs seconds at every command's start:
# softtrack.rl.train (JAX, torch, Stable-Baselines3) and softtrack.report (matplotlib).
if TYPE_CHECKING:
    from softtrack.env.settings import TrackingConfig
    from softtrack.evaluation.workspace import WorkspaceResult
    from softtrack.evaluation.workspace_settings import SearchSettings

__all__ = [
    "QUICKSTART_PRETRAINED",
    "RUN_TABLE_COLUMNS",
    "USER_ERRORS",
    "SweepStopped",
    "animate",
    "carried_summary",
    "compare",
    "compare_figure",
    "copy_run",
    "effective_status",
    "env_config",
    "evaluate",
    "export",
    "final_stage_return",
    "floors_dir",
    "format_failures",
    "format_runs_table",
    "is_lost",
    "list_run_summaries",
    "measure_workspace",
    "quickstart",
    "quickstart_pretrained_path",
    "quickstart_spec_path",
    "record_floors",
    "report",
    "resolved_spec_yaml",
    "resume",
    "resume_runs",
    "robustness",
    "run_summary",
    "shown_path",
    "spec_chain",
    "spec_defaults_yaml",
    "spec_schema_json",
    "sweep",
    "sync_mlflow",
    "train",
    "tune",
    "tune_best",
    "tune_status",
    "upgrade",
    "validate_spec",
    "validation_summary",
    "write_workspace_files",
]

#: Errors a user can cause; the CLI prints their one-line message and exits with code 2.
USER_ERRORS: tuple[type[Exception], ...] = (
    SpecError,
    RunStoreError,
    TableError,
    InvalidParameterError,
    TuneError,
    VideoError,
)


# ---- specs --------------------------------------------------------------------------------
def validate_spec(path: str | os.PathLike[str], overrides: Sequence[str] = ()) -> ExperimentSpec:
    """Load and validate a spec file with ``--set`` style overrides (raises ``SpecError``)."""
    return load_spec(path, overrides)


# ---- training -----------------------------------------------------------------------------


def export(
    reference: str,
    dest: str | os.PathLike[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    policy_only: bool = False,
) -> Path:
    """Copy a finished run (id, id prefix or run directory) to ``dest`` without its checkpoints
    and replay buffers: spec, run.json, tables, log, and its policy as ``model.zip`` beside
    ``policy.json`` (other models under ``other_models/`` unless ``policy_only``),
    inference-only (see :mod:`softtrack.rl.policy_export`). Returns ``dest``."""

    record = select_one_run(reference, runs_dir)
    # a shipped run is never trained in place: no lock file is written into it
    with contextlib.nullcontext() if record.read_only else run_lock(record, "exported"):
        return export_policy_run(record, dest, policy_only)


def upgrade(
    run_dirs: Sequence[str | os.PathLike[str]], *, keep_full_moments: bool = False
) -> dict[Path, list[str]]:
    """Rewrite run directories made by earlier versions in the current format: evaluation
    tables (:mod:`softtrack.store.upgrade`) and, for exported runs, the model layout
    (:func:`softtrack.rl.policy_export.relayout_exported_run`) and model files stored
    uncompressed (deflated: :mod:`softtrack.store.model_zip`; the same bytes once read). Every
    directory is checked before any is changed.

    Returns:
        ``{run directory: what was rewritten}`` (table names, ``models``, ``model.zip``;
        empty: already current).

    Raises:
        RunStoreError: a path is not a run directory (no ``tables/`` or no ``run.json``).
    """

    paths = [Path(d) for d in run_dirs]
    for path in paths:
        if not (path / "tables").is_dir() or not (path / "run.json").is_file():
            raise RunStoreError(
                f"{path}: not a run directory with tables (no run.json or "
                "tables/ inside); give run directories such as models/<name>"
            )
        RunStore(path.parent).get_run(path.name).load_spec()
    done = {}
    for path in paths:
        done[path] = upgrade_run_tables(path, keep_full_moments)
        if relayout_exported_run(path):
            done[path].append("models")
        models = [m for m in sorted(path.rglob("model.zip")) if "checkpoints" not in m.parts]
        if sum(deflate_model_zip(m) for m in models):
            done[path].append("model.zip")
    return done


def compare(
    selection: Sequence[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    metric: str = "rmse_3d",
    reps: int = 2000,
    random: bool = False,
) -> Any:
    """:func:`softtrack.report.compare.compare_selection`: the controllers the ``selection``
    items name, the first against each other, across their seeds (returns a ``Comparison``;
    ``.lines()`` is what ``softtrack compare`` prints); ``random``: over the held-out
    random-target episodes instead of the trajectories."""
    from softtrack.report.compare import compare_selection  # the comparison's statistics

    return compare_selection(selection, runs_dir=runs_dir, metric=metric, reps=reps, random=random)


def sync_mlflow(
    selection: Sequence[str] = (),
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    tracking_uri: str | None = None,
    on_run: Callable[[str, str], None] | None = None,
) -> Any:
    """:func:`softtrack.report.to_mlflow.sync_mlflow`: write the runs (params, metrics,
    curves, report and policy) to an MLflow tracking store; returns a ``SyncOutcome``."""
    # DuckDB and the results database: loaded when syncing, not with the API
    from softtrack.report.to_mlflow import sync_mlflow as sync_runs_to_mlflow

    return sync_runs_to_mlflow(
        selection, runs_dir=runs_dir, tracking_uri=tracking_uri, on_run=on_run
    )


def compare_figure(comparison: Any, path: str | os.PathLike[str]) -> Path:
    """The performance profile of a :func:`compare` result, written to ``path`` (PNG)."""
    from softtrack.report.compare import profile_figure  # as in compare()

    return profile_figure([("", comparison)], path)


def animate(
    references: Sequence[str],
    trajectories: Sequence[str],
    out: str | os.PathLike[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    fps: float = 30.0,
    size: tuple[int, int] = (640, 480),
    strip: str | os.PathLike[str] | None = None,
    random: int | None = None,
    on_note: Callable[[str], None] | None = None,
) -> Path:
    """:func:`softtrack.report.animation.animate_runs` of the runs ``references`` select
    (run ids, directories, experiment names or spec files), each replaying its own policy;
    returns the file written."""
    from softtrack.report.animation import animate_runs  # the renderer and its fonts

    records = select_runs(RunStore(resolve_runs_dir(runs_dir)), references)
    return animate_runs(
        records,
        trajectories,
        out,
        load=load_policy,
        fps=fps,
        size=size,
        strip=strip,
        random=random,
        on_note=on_note,
    )


def run_summary(record: RunRecord, *, now: datetime | None = None) -> dict[str, Any]:
    """One row of ``softtrack runs`` (JSON-serialisable), read from the run's files rather
    than the catalog."""
    raw = record.raw_spec()
    try:
        final, n_final, last_step = final_stage_return(record, final_stage_fraction(raw))
    except TableError:
        final, n_final, last_step = None, 0, 0
    sweep = (record.info.notes or {}).get("sweep")
    row = {
        **record.info.model_dump(),
        "sweep": None if sweep is None else str(sweep),
        "heartbeat_interval": heartbeat_interval(raw),
        "final_return": final,
        "final_return_episodes": n_final,
        "last_step": last_step,
    }
    return summary_from_row(row, record.path, now or datetime.now(UTC))


def measure_workspace(
    config: TrackingConfig,
    settings: SearchSettings,
    per_path: int,
    torque_scales: Sequence[float] = (),
    on_progress: Callable[[float, int, int, int], None] | None = None,
) -> list[WorkspaceResult]:
    """:func:`softtrack.evaluation.workspace.measure_workspace`: where the arms of ``config``
    hold the sphere at rest, and each path's floor, at its own and each extra torque scale."""
    from softtrack.evaluation.workspace import measure_workspace as measure  # with the API: +0.5 s

    return measure(config, settings, per_path, torque_scales, on_progress=on_progress)


# ---- sweeps -------------------------------------------------------------------------------
def sweep(
    paths: Sequence[str],
    grid: Sequence[str] = (),
    overrides: Sequence[str] = (),
    *,
    seeds: str | None = None,
    runs_dir: str | os.PathLike[str] | None = None,
    options: Any = None,
    on_created: Callable[[str, list[RunRecord]], None] | None = None,
    on_progress: Callable[[str], None] | None = None,
) -> Any:
    """Expand the grid over the spec files, create every run, and run them on an executor.

    Every grid point is validated before any run is written. Returns an
    :class:`~softtrack.executors.dispatch.Outcome` (statuses, what is missing, exit code).

    Args:
        grid: ``key=v1,v2`` axes (any spec field).
        seeds: ``"0,1,2"`` or ``"0-4"``: replaces each spec's seeds.
        options: :class:`~softtrack.executors.dispatch.ExecOptions` (default: local pool).
        on_created: called with the sweep id and the new runs before they start.
        on_progress: called with a progress line whenever it changes (while the runs are
            made too).

    Raises:
        SweepStopped: a stop signal while the runs were made (those made stay queued).
    """
    import sys

    options = options or dispatch.ExecOptions()
    if options.executor not in dispatch.EXECUTORS:
        raise SpecError("executor", f"unknown executor {options.executor!r}", "use local or slurm")

    points = expand_grid(
        paths,
        parse_grid(grid),
        seeds=parse_seeds(seeds),
        overrides=overrides,
        check=check_supported,
    )
    store = RunStore(resolve_runs_dir(runs_dir))
    sweep_id = dispatch.new_sweep_id()
    chains = {point.path: spec_chain(point.path) for point in points}
    records = create_sweep_runs(store, points, sweep_id, chains, sys.argv, on_progress)
    if on_created is not None:
        on_created(sweep_id, records)
    ids = [r.run_id for r in records]
    return dispatch.execute(
        store, ids, options, sweep_id, cluster=points[0].spec.cluster, on_progress=on_progress
    )


def resume_runs(
    selection: Sequence[str] = (),
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    options: Any = None,
    on_selected: Callable[[str, list[RunRecord]], None] | None = None,
    on_progress: Callable[[str], None] | None = None,
) -> Any:
    """Resubmit interrupted, queued, failed-by-signal and lost runs (experiment names, sweep
    ids or run ids; none: all of them) from their checkpoints through an executor.

    Returns an :class:`~softtrack.executors.dispatch.Outcome`, or ``None`` if nothing matched
    is resumable.
    """

    options = options or dispatch.ExecOptions()
    store = RunStore(resolve_runs_dir(runs_dir))
    if on_progress is not None:
        for line in dispatch.unresumable_runs(store):
            on_progress(f"warning: {line}")
    records = dispatch.select_resumable_runs(store, selection)
    if not records:
        return None
    resume_id = dispatch.new_sweep_id()
    if on_selected is not None:
        on_selected(resume_id, records)
    ids = [r.run_id for r in records]
    return dispatch.execute(
        store,
        ids,
        options,
        resume_id,
        cluster=dispatch.cluster_of(store, ids),
        on_progress=on_progress,
        label=f"resume {resume_id}",
    )


# ---- robustness ---------------------------------------------------------------------------


# ---- tuning -------------------------------------------------------------------------------
def tune(
    path: str | os.PathLike[str],
    overrides: Sequence[str] = (),
    *,
    trials: int,
    study: str | None = None,
    storage: str | None = None,
    runs_dir: str | os.PathLike[str] | None = None,
    options: Any = None,
    log: Callable[[str], None] | None = None,
    on_progress: Callable[[str], None] | None = None,
    show_progress: bool | None = None,
) -> TuneOutcome:
    """Search the spec's ``tune:`` space with Optuna until ``trials`` trials are finished
    (complete or pruned), each a run of the store; running it again with the same ``study``
    continues the study (:mod:`softtrack.tune.command`, docs/tuning.md).

    Args:
        study: the study name (default: the spec's name).
        storage: an Optuna RDB URL (default ``sqlite:///<runs dir>/optuna.db``).
        options: :class:`~softtrack.executors.dispatch.ExecOptions`: ``workers`` processes
            (default 1: in this process), local or SLURM, detached or not.
        log: called with a line per trial event (in-process worker) and the start summary.
        on_progress: called with the study's summary line whenever it changes (workers in
            other processes).

    Returns:
        A :class:`~softtrack.tune.command.TuneOutcome` (counts, summary, exit code).
    """

    return run_tune(
        path,
        overrides,
        trials=trials,
        study=study,
        storage=storage,
        runs_dir=runs_dir,
        options=options,
        log=log,
        on_progress=on_progress,
        show_progress=show_progress,
    )


def tune_status(
    study: str, *, storage: str | None = None, runs_dir: str | os.PathLike[str] | None = None
) -> str:
    """A study's summary line and its trials (number, state, score, step, run id, params)."""

    return study_status(study, storage=storage, runs_dir=runs_dir)


def tune_best(
    study: str,
    out: str | os.PathLike[str] | None = None,
    *,
    storage: str | None = None,
    runs_dir: str | os.PathLike[str] | None = None,
) -> tuple[Path, Any]:
    """Write a study's best complete trial as a spec file (``base:`` the tuned spec, the best
    values set; default ``<study>-best.yaml``) that ``softtrack train`` loads; returns the
    file and the trial."""

    return best_trial_spec(study, out, storage=storage, runs_dir=runs_dir)
