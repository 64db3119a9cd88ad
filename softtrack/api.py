"""The public Python functions behind the ``softtrack`` command line.

The CLI (:mod:`softtrack.cli`) only parses arguments and prints; everything it shows is
computed here, so the same results are available from Python. The run summaries behind
``softtrack runs`` (status, progress, final-stage return) live in :mod:`softtrack.store.status`
and are re-exported here.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from softtrack.evaluation.perturbations import expand_settings
from softtrack.evaluation.robustness_runs import run_robustness
from softtrack.evaluation.run_evaluation import (
    evaluate_random_targets,
    evaluate_run,
    has_evaluation,
)
from softtrack.executors import dispatch
from softtrack.executors.sweep import expand_grid, parse_grid, parse_seeds
from softtrack.executors.sweep_creation import SweepStopped, create_sweep_runs
from softtrack.report.video import VideoError
from softtrack.rl.factory import check_supported
from softtrack.rl.policy import (
    MODEL_CHOICES,
    ModelChoice,
    load_policy,
    model_paths,
    require_model,
)
from softtrack.rl.policy_export import export_policy_run, relayout_exported_run
from softtrack.sim.params import InvalidParameterError
from softtrack.spec import (
    ExperimentSpec,
    SpecError,
    chain_comment,
    load_spec,
    spec_chain,
    spec_json_schema,
    spec_to_yaml,
)
from softtrack.store import run_copies
from softtrack.store.location import QUICKSTART_PRETRAINED
from softtrack.store.model_zip import deflate_model_zip
from softtrack.store.provenance import portable_command
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir, run_lock
from softtrack.store.selection import select_one_run, select_runs
from softtrack.store.status import (
    RUN_TABLE_COLUMNS,
    effective_status,
    final_stage_return,
    format_failures,
    format_runs_table,
    is_lost,
    list_run_summaries,
    run_summary,
)
from softtrack.store.tables import TableError
from softtrack.store.upgrade import upgrade_run_tables
from softtrack.trajectories import EVAL_TRAJECTORIES
from softtrack.tune import TuneError
from softtrack.tune.command import TuneOutcome
from softtrack.tune.command import tune as run_tune
from softtrack.tune.command import tune_best as best_trial_spec
from softtrack.tune.command import tune_status as study_status

# Imported where used, because importing them costs seconds at every command's start:
# softtrack.rl.train (JAX, torch, Stable-Baselines3) and softtrack.report (matplotlib).
if TYPE_CHECKING:
    from softtrack.rl.train import TrainOutcome

__all__ = [
    "QUICKSTART_PRETRAINED",
    "RUN_TABLE_COLUMNS",
    "USER_ERRORS",
    "SweepStopped",
    "compare",
    "compare_figure",
    "copy_run",
    "effective_status",
    "evaluate",
    "export",
    "final_stage_return",
    "format_failures",
    "format_runs_table",
    "is_lost",
    "list_run_summaries",
    "quickstart",
    "quickstart_pretrained_path",
    "quickstart_spec_path",
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


def validation_summary(spec: ExperimentSpec, chain: Sequence[str] = ()) -> str:
    """``ok: td3, 3 runs (seeds 0, 1, 2): td3/centralized, 10,000,000 env steps each``, and
    for a spec with a ``base:`` a second line naming the chain (``chain``: :func:`spec_chain`),
    e.g. ``   base: experiments/study/td3-sbx-64-4e6.yaml → experiments/study/td3-64-1e7.yaml``.
    """
    seeds = ", ".join(str(s) for s in spec.seeds)
    runs = f"{spec.n_runs} run{'s' if spec.n_runs != 1 else ''}"
    seed_word = "seeds" if spec.n_runs != 1 else "seed"
    if spec.controller == "mpc":
        m = spec.mpc
        what = (
            f"{m.method}/mpc, {m.samples} samples × {m.horizon} steps, replanning every "
            f"{m.replan_interval} steps (nothing to train: `softtrack evaluate SPEC`)"
        )
    else:
        what = (
            f"{spec.algo.name}/{spec.controller}, {spec.training.total_timesteps:,} env steps each"
        )
    text = f"ok: {spec.name}, {runs} ({seed_word} {seeds}): {what}"
    if len(chain) > 1:
        text += "\n   base: " + " → ".join(chain[1:])
    if spec.tune is not None:
        text += (
            f"\n   tune: {len(spec.tune.params)} params ({', '.join(spec.tune.params)}), "
            f"metric {spec.tune.metric}, pruner {spec.tune.pruner.type}"
        )
    return text


def spec_defaults_yaml() -> str:
    """The default spec as commented YAML (a template to copy)."""
    header = (
        "# softtrack experiment spec: every field with its default (the study's setting).\n"
        "# Units are in brackets. Validate a copy with `softtrack validate FILE`.\n\n"
    )
    return header + spec_to_yaml(ExperimentSpec(), comments=True)


def spec_schema_json() -> str:
    """The JSON Schema of the spec, indented."""
    return json.dumps(spec_json_schema(), indent=2, ensure_ascii=False)


def resolved_spec_yaml(path: str | os.PathLike[str], overrides: Sequence[str] = ()) -> str:
    """A spec file with its ``base:`` chain merged, defaults filled in and overrides applied, as
    YAML; a spec with a base starts with comments naming the file and its bases
    (:func:`softtrack.spec.chain_comment`), which leave it loadable on its own."""
    spec = load_spec(path, overrides)
    chain = spec_chain(path)
    return (chain_comment(chain) if len(chain) > 1 else "") + spec_to_yaml(spec)


# ---- training -----------------------------------------------------------------------------
def train(
    path: str | os.PathLike[str],
    overrides: Sequence[str] = (),
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    seed: int | None = None,
    on_start: Callable[[RunRecord], None] | None = None,
    show_progress: bool | None = None,
) -> list[TrainOutcome]:
    """Create and train one run per seed of the spec (or only ``seed``), one after another.

    The spec is validated (and checked to be supported) before anything is written.
    Training stops after a run that did not complete (interrupted or failed).

    Args:
        on_start: called with each new run before it trains (the CLI prints its id).

    Returns:
        The outcome of each run started.
    """
    from softtrack.rl.train import train_run

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
    from softtrack.rl.train import check_resumable, train_run

    record = select_one_run(run_id, runs_dir)
    store = RunStore(record.path.parent)
    check_resumable(record)
    if on_start is not None:
        on_start(record)
    return train_run(store, record, resume=True, show_progress=show_progress)


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

    Returns:
        The metrics rows of the trajectories (one per run, trajectory and arm).
    """

    chosen = list(EVAL_TRAJECTORIES) if trajectories is None else list(trajectories)
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
    if not references:
        raise RunStoreError("no run given; name run ids or run directories (see `softtrack runs`)")
    mpc_specs = _mpc_specs(references)
    selected = [ref for ref in references if ref not in mpc_specs]
    records = select_runs(RunStore(resolve_runs_dir(runs_dir)), selected) if selected else []
    # every run checked before anything is copied or written; results are stored for the
    # runs whose evaluated model is their policy, a shipped run's in its copy
    stores = [
        write and require_model(r, spec, model) == model_paths(r, spec)
        for r, spec in ((r, r.load_spec()) for r in records)
    ]
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


def _mpc_specs(references: Sequence[str]) -> dict[str, ExperimentSpec]:
    """The references that are spec files of an MPC controller (evaluated without training),
    with their specs; any other spec file selects the runs trained from it.

    Raises:
        SpecError: a spec file is invalid.
    """
    specs = {ref: load_spec(ref) for ref in references if _is_spec_file(ref)}
    return {ref: spec for ref, spec in specs.items() if spec.controller == "mpc"}


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


def _policy_files(record: RunRecord) -> list[Path]:
    return model_paths(record, record.load_spec())


def copy_run(
    source: str | os.PathLike[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    keep_evaluation: bool = False,
) -> Path:
    """Copy a finished run directory into the runs directory without its evaluation tables
    (:func:`softtrack.store.run_copies.copy_run`); returns the copy's directory."""
    record = select_one_run(str(source))
    return run_copies.copy_run(
        record, _policy_files(record), runs_dir=runs_dir, keep_evaluation=keep_evaluation
    )


def writable_run(
    record: RunRecord,
    runs_dir: str | os.PathLike[str] | None = None,
    *,
    in_place: bool = False,
    on_copied: Callable[[RunRecord, RunRecord], None] | None = None,
) -> RunRecord:
    """``record``, or its copy for results when it is shipped
    (:func:`softtrack.store.run_copies.writable_run`)."""
    return run_copies.writable_run(
        record, _policy_files, runs_dir, in_place=in_place, on_copied=on_copied
    )


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
    from softtrack.report.compare import compare_selection

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
    from softtrack.report.to_mlflow import sync_mlflow as sync

    return sync(selection, runs_dir=runs_dir, tracking_uri=tracking_uri, on_run=on_run)


def compare_figure(comparison: Any, path: str | os.PathLike[str]) -> Path:
    """The performance profile of a :func:`compare` result, written to ``path`` (PNG)."""
    from softtrack.report.compare import profile_figure

    return profile_figure([("", comparison)], path)


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


def _checkout_or_cwd(relative: str) -> list[Path]:
    """``relative`` in this source checkout (an editable install) and in the current
    directory (a checkout the user works in with an installed wheel), in that order."""
    return [Path(__file__).resolve().parents[1] / relative, Path.cwd() / relative]


def quickstart_pretrained_path() -> Path | None:
    """The :data:`QUICKSTART_PRETRAINED` run directory of this checkout or of the current
    directory, or ``None`` if neither has it (an installed wheel used elsewhere)."""
    for path in _checkout_or_cwd(QUICKSTART_PRETRAINED):
        if (path / "run.json").is_file():
            return path
    return None


def quickstart_spec_path() -> Path:
    """``experiments/quickstart.yaml`` of this checkout or the current directory, else the
    copy that ships inside the package (``softtrack/data/quickstart.yaml``)."""
    from importlib.resources import files

    for path in _checkout_or_cwd("experiments/quickstart.yaml"):
        if path.is_file():
            return path
    packaged = Path(str(files("softtrack") / "data" / "quickstart.yaml"))
    if not packaged.is_file():
        raise SpecError(
            str(packaged),
            "the quickstart spec is missing from this installation",
            "reinstall softtrack (pip install softtrack) or run from a checkout",
        )
    return packaged


def quickstart(
    overrides: Sequence[str] = (),
    out: str | os.PathLike[str] = "reports/quickstart",
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    pretrained: str | os.PathLike[str] | None = None,
    no_pretrained: bool = False,
    on_line: Callable[[str], None] = print,
    on_episode: Callable[..., None] | None = None,
) -> tuple[Path | None, int]:
    """Train, evaluate and report the quickstart experiment (``softtrack quickstart``).

    Trains :func:`quickstart_spec_path` (with ``overrides``), evaluates it on the three
    trajectories, evaluates the shipped policy (``pretrained``, default
    :func:`quickstart_pretrained_path`; none with ``no_pretrained``) in a copy in the runs
    directory (the shipped directory is only read), and reports both into ``out``.

    Args:
        on_line: called with each step's line ("1/4 training …").
        on_episode: called after each evaluation episode (as :func:`evaluate`).

    Returns:
        (the report's ``index.md``, 0), or (None, the training's exit code) when the training
        did not complete.

    Raises:
        SpecError: ``pretrained`` is not a run directory, or the quickstart spec is missing.
    """
    shipped = None
    if not no_pretrained:
        shipped = Path(pretrained) if pretrained is not None else quickstart_pretrained_path()
    if shipped is not None and not (shipped / "run.json").is_file():
        raise SpecError(
            "quickstart",
            f"--pretrained {shipped} is not a run directory (no run.json)",
            "give a directory made by `softtrack export`, or --no-pretrained",
        )
    spec_path = quickstart_spec_path()
    copy = None if shipped is None else copy_run(shipped, runs_dir=runs_dir)
    on_line(f"1/4 training {shown_path(spec_path)} (progress on stderr)")
    outcomes = train(
        spec_path,
        overrides,
        runs_dir=runs_dir,
        on_start=lambda record: on_line(f"    run {record.run_id}"),
    )
    if not outcomes or outcomes[-1].status != "completed":
        return None, max((o.exit_code for o in outcomes), default=1)
    run_ids = [o.run_id for o in outcomes]
    on_line("2/4 evaluating on circle, rectangle, figure8")
    evaluate(run_ids, runs_dir=runs_dir, on_episode=on_episode)
    extra: list[Path] = []
    if shipped is None or copy is None:
        on_line(
            "3/4 no shipped policy to show (skipped: --no-pretrained)"
            if no_pretrained
            else f"3/4 no shipped policy to show: {QUICKSTART_PRETRAINED} is neither in a "
            "checkout nor in the current directory (an installed softtrack used elsewhere); "
            "give --pretrained DIR, that directory of a clone, to compare with it"
        )
    else:
        on_line(
            f"3/4 the shipped policy {shown_path(shipped)} on the same trajectories "
            f"(evaluated in its copy {shown_path(copy)})"
        )
        evaluate([str(copy)], on_episode=on_episode)
        extra = [copy]
    on_line("4/4 building the report")
    index = report(
        run_ids,
        out,
        runs_dir=runs_dir,
        extra_runs=extra,
        command_line=["softtrack", "quickstart", "--out", str(out)],
    )
    return Path(index), 0


def shown_path(path: str | os.PathLike[str]) -> str:
    """``path`` relative to the current directory when it lies inside it, else absolute."""
    full = Path(path).resolve()
    return str(full.relative_to(Path.cwd())) if full.is_relative_to(Path.cwd()) else str(full)


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
