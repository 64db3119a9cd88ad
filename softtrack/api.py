"""The public Python functions behind the ``softtrack`` command line.

The CLI (:mod:`softtrack.cli`) only parses arguments and prints; everything it shows is
computed here, so the same results are available from Python.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from softtrack.sim.params import InvalidParameterError
from softtrack.spec import (
    ExperimentSpec,
    SpecError,
    load_spec,
    spec_json_schema,
    spec_to_yaml,
)
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, parse_time, resolve_runs_dir
from softtrack.store.tables import TableError, read_table

if TYPE_CHECKING:
    from softtrack.rl.train import TrainOutcome

__all__ = [
    "QUICKSTART_PRETRAINED",
    "RUN_TABLE_COLUMNS",
    "USER_ERRORS",
    "effective_status",
    "evaluate",
    "export",
    "final_stage_return",
    "format_failures",
    "format_runs_table",
    "is_lost",
    "list_run_summaries",
    "quickstart_pretrained_path",
    "quickstart_spec_path",
    "report",
    "resolved_spec_yaml",
    "resume",
    "resume_runs",
    "run_summary",
    "spec_defaults_yaml",
    "spec_schema_json",
    "sweep",
    "train",
    "validate_spec",
    "validation_summary",
]

#: Errors a user can cause; the CLI prints their one-line message and exits with code 2.
USER_ERRORS: tuple[type[Exception], ...] = (
    SpecError,
    RunStoreError,
    TableError,
    InvalidParameterError,
)

DEFAULT_FINAL_STAGE_FRACTION = 0.1
DEFAULT_HEARTBEAT_INTERVAL_S = 30.0


# ---- specs --------------------------------------------------------------------------------
def validate_spec(path: str | os.PathLike[str], overrides: Sequence[str] = ()) -> ExperimentSpec:
    """Load and validate a spec file with ``--set`` style overrides (raises ``SpecError``)."""
    return load_spec(path, overrides)


def validation_summary(spec: ExperimentSpec) -> str:
    """``ok: td3, 3 runs (seeds 0, 1, 2): td3/centralized, 10,000,000 env steps each``."""
    seeds = ", ".join(str(s) for s in spec.seeds)
    runs = f"{spec.n_runs} run{'s' if spec.n_runs != 1 else ''}"
    seed_word = "seeds" if spec.n_runs != 1 else "seed"
    return (
        f"ok: {spec.name}, {runs} ({seed_word} {seeds}): {spec.algo.name}/{spec.controller}, "
        f"{spec.training.total_timesteps:,} env steps each"
    )


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
    """A spec file with defaults filled in and overrides applied, as YAML."""
    return spec_to_yaml(load_spec(path, overrides))


# ---- runs ---------------------------------------------------------------------------------
def _training_value(raw: dict[str, Any], key: str, default: float) -> float:
    training = raw.get("training")
    value = training.get(key) if isinstance(training, dict) else None
    return (
        float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else default
    )


def _final_mean(df: pd.DataFrame, threshold: float) -> tuple[float | None, int]:
    """Mean finite ``return`` of the rows with ``global_step > threshold``, and their count."""
    final = pd.to_numeric(df.loc[df["global_step"] > threshold, "return"], errors="coerce")
    final = final[np.isfinite(final)]
    return (float(final.mean()), int(final.size)) if not final.empty else (None, 0)


def final_stage_return(
    record: RunRecord, fraction: float | None = None
) -> tuple[float | None, int, int]:
    """Mean training-episode return over the last ``fraction`` of the run's budget (SPEC §4).

    Episodes count when their ``global_step`` (at the episode's end) exceeds
    ``(1 - fraction) · total_timesteps``. ``fraction`` defaults to the run's
    ``training.final_stage_fraction`` (0.1).

    An independent run's table has an ``arm`` column (0, 1) and counts ``global_step`` per arm:
    each arm's final stage is the last ``fraction`` of its own budget (``arm_total_timesteps``),
    and the result is the mean over the arms of their final-stage means (single-arm returns,
    not comparable with dual-arm ones). Rows without an arm (column absent, null or negative)
    are a centralized policy's.

    Returns:
        ``(mean return or None if no episode qualifies, number of such episodes,
        env steps the table reaches: its largest global_step, summed over the arms, or 0)``.
    """
    if fraction is None:
        fraction = _training_value(
            record.raw_spec(), "final_stage_fraction", DEFAULT_FINAL_STAGE_FRACTION
        )
    df = read_table(record.table_path("train_episodes"), missing_ok=True)
    if df.empty or not {"global_step", "return"} <= set(df.columns):
        return None, 0, 0
    arms = pd.to_numeric(df["arm"], errors="coerce") if "arm" in df.columns else None
    if arms is None or not (arms >= 0).any():
        threshold = (1.0 - fraction) * record.info.total_timesteps
        mean, count = _final_mean(df, threshold)
        return mean, count, int(df["global_step"].max())
    info = record.info
    budget = info.arm_total_timesteps or info.total_timesteps // max(1, int(arms.max()) + 1)
    means, count, last_step = [], 0, 0
    for _, rows in df[arms >= 0].groupby(arms[arms >= 0]):
        mean, n = _final_mean(rows, (1.0 - fraction) * budget)
        last_step += int(rows["global_step"].max())
        count += n
        if mean is not None:
            means.append(mean)
    return (float(np.mean(means)) if means else None), count, last_step


def stale_after_s(heartbeat_interval: float) -> float:
    """A running run's heartbeat older than this is stale: max(120 s, 10 heartbeat intervals)."""
    return max(120.0, 10.0 * heartbeat_interval)


def _is_stale(record: RunRecord, heartbeat_interval: float, now: datetime) -> bool:
    if record.info.status != "running":
        return False
    beat = parse_time(record.info.heartbeat or record.info.started or record.info.created)
    if beat is None:
        return False
    return (now - beat).total_seconds() > stale_after_s(heartbeat_interval)


def _heartbeat_interval(record: RunRecord) -> float:
    return _training_value(record.raw_spec(), "heartbeat_interval", DEFAULT_HEARTBEAT_INTERVAL_S)


def is_lost(record: RunRecord, *, now: datetime | None = None, stale: bool | None = None) -> bool:
    """A ``running`` run whose process is gone: nobody holds its ``run.lock``, and its
    heartbeat is stale or (on this host) its pid is not alive."""
    import socket

    from softtrack.store.runs import lock_held, pid_alive

    info = record.info
    if info.status != "running" or lock_held(record) is True:
        return False
    if stale is None:
        stale = _is_stale(record, _heartbeat_interval(record), now or datetime.now(UTC))
    if stale:
        return True
    return info.host == socket.gethostname() and not pid_alive(info.pid)


def effective_status(record: RunRecord, *, now: datetime | None = None) -> str:
    """run.json's status, or ``lost`` for a running run whose process is gone (:func:`is_lost`);
    run.json itself is never changed by this."""
    return "lost" if is_lost(record, now=now) else record.info.status


def run_summary(record: RunRecord, *, now: datetime | None = None) -> dict[str, Any]:
    """One row of ``softtrack runs`` (JSON-serialisable)."""
    raw = record.raw_spec()
    info = record.info
    try:
        final, n_final, last_step = final_stage_return(
            record, _training_value(raw, "final_stage_fraction", DEFAULT_FINAL_STAGE_FRACTION)
        )
    except TableError:
        final, n_final, last_step = None, 0, 0
    now = now or datetime.now(UTC)
    stale = _is_stale(
        record, _training_value(raw, "heartbeat_interval", DEFAULT_HEARTBEAT_INTERVAL_S), now
    )
    return {
        "run_id": info.run_id,
        "name": info.name,
        "algo": info.algo,
        "controller": info.controller,
        "seed": info.seed,
        "status": "lost" if is_lost(record, now=now, stale=stale) else info.status,
        "stored_status": info.status,
        "stale": stale,
        "sweep": (info.notes or {}).get("sweep"),
        "global_step": max(info.global_step, last_step),
        "total_timesteps": info.total_timesteps,
        "final_return": final,
        "final_return_episodes": n_final,
        "steps_per_second": info.steps_per_second,
        "cpu": info.cpu,
        "created": info.created,
        "started": info.started,
        "ended": info.ended,
        "spec_hash": info.spec_hash,
        "git_commit": info.git_commit,
        "git_dirty": info.git_dirty,
        "error": info.error,
        "traceback": info.traceback,
        "path": str(record.path),
    }


def list_run_summaries(
    runs_dir: str | os.PathLike[str] | None = None, *, failed: bool = False
) -> list[dict[str, Any]]:
    """Summaries of every run under ``runs_dir`` (resolved with ``resolve_runs_dir``), oldest
    first; with ``failed=True`` only the failed runs."""
    store = RunStore(resolve_runs_dir(runs_dir))
    now = datetime.now(UTC)
    rows = [run_summary(record, now=now) for record in store.list_runs()]
    return [r for r in rows if r["status"] == "failed"] if failed else rows


def format_failures(summaries: Sequence[dict[str, Any]]) -> str:
    """Each failed run's id, experiment, seed, error and stored traceback."""
    blocks = []
    for s in summaries:
        head = f"== {s['run_id']}  {s['name']}  seed {s['seed']}: {s.get('error') or '(no error)'}"
        body = (s.get("traceback") or "").rstrip()
        blocks.append(head + ("\n" + "\n".join("   " + line for line in body.splitlines())
                              if body else ""))
    return "\n".join(blocks)


RUN_TABLE_COLUMNS = (
    "ID",
    "NAME",
    "ALGO",
    "CONTROLLER",
    "SEED",
    "STATUS",
    "STEPS",
    "FINAL RETURN",
    "STARTED (UTC)",
    "ENDED (UTC)",
)


def _time_cell(text: str | None) -> str:
    moment = parse_time(text)
    return moment.strftime("%Y-%m-%d %H:%M:%S") if moment else ""


def format_runs_table(summaries: Sequence[dict[str, Any]]) -> str:
    """A plain, aligned text table of run summaries (one line per run, with a header)."""
    rows = [list(RUN_TABLE_COLUMNS)]
    for s in summaries:
        status = s["status"] + (" (stale)" if s.get("stale") and s["status"] != "lost" else "")
        final = s.get("final_return")
        rows.append(
            [
                s["run_id"],
                s["name"],
                s["algo"],
                s["controller"],
                str(s["seed"]),
                status,
                f"{s['global_step']}/{s['total_timesteps']}",
                "" if final is None else f"{final:.2f}",
                _time_cell(s.get("started")),
                _time_cell(s.get("ended")),
            ]
        )
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    right = {4, 6, 7}  # numeric columns
    lines = []
    for row in rows:
        cells = [
            cell.rjust(widths[i]) if i in right else cell.ljust(widths[i])
            for i, cell in enumerate(row)
        ]
        lines.append("  ".join(cells).rstrip())
    return "\n".join(lines)


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
    from softtrack.rl.factory import check_supported
    from softtrack.rl.train import train_run

    spec = load_spec(path, overrides)
    check_supported(spec, str(path))
    seeds = list(spec.seeds) if seed is None else [int(seed)]
    if seed is not None and not 0 <= seed < 2**32:
        raise SpecError("--seed", f"seed {seed} is out of range", "use 0 ≤ seed < 2**32")
    store = RunStore(resolve_runs_dir(runs_dir))
    outcomes = []
    for s in seeds:
        record = store.create_run(spec, s)
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
    """Continue an interrupted (or killed, or failed) run from its latest checkpoint."""
    from softtrack.rl.train import check_resumable, train_run

    store = RunStore(resolve_runs_dir(runs_dir))
    record = store.get_run(run_id)
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
) -> pd.DataFrame:
    """Evaluate runs (ids, id prefixes or run directories) on the closed-form trajectories.

    Every run is resolved and its spec checked before any episode runs, so a bad reference
    fails without writing anything.

    Args:
        trajectories: subset of circle, rectangle, figure8 (default: all three).
        on_episode: called with (record, episode, metrics) after each trajectory.
        write: store the tables in each run (``False``: only return the metrics).

    Returns:
        The metrics rows (one per run, trajectory and arm).
    """
    from softtrack.eval_runs import evaluate_run, resolve_run
    from softtrack.evaluation import EVAL_TRAJECTORIES
    from softtrack.rl.policy import model_paths

    chosen = list(trajectories) if trajectories else list(EVAL_TRAJECTORIES)
    unknown = sorted(set(chosen) - set(EVAL_TRAJECTORIES))
    if unknown:
        raise SpecError("--trajectory", f"unknown trajectory {unknown[0]!r}",
                        f"choose from {', '.join(EVAL_TRAJECTORIES)} or all")
    if not references:
        raise RunStoreError("no run given; name run ids or run directories (see `softtrack runs`)")
    records = [resolve_run(ref, runs_dir) for ref in references]
    for record in records:
        spec = record.load_spec()
        missing = [p for p in model_paths(record, spec) if not p.is_file()]
        if missing:
            raise RunStoreError(
                f"{missing[0]}: run {record.run_id} has no trained model (status "
                f"{record.info.status}); finish it with `softtrack train --resume {record.run_id}`"
            )
    frames = [evaluate_run(record, chosen, on_episode, write=write) for record in records]
    return pd.concat(frames, ignore_index=True)


def export(
    reference: str, dest: str | os.PathLike[str], *, runs_dir: str | os.PathLike[str] | None = None
) -> Path:
    """Copy a finished run (id, id prefix or run directory) to ``dest`` without its checkpoints
    and replay buffers: spec, run.json, final model(s), tables and log (see
    :mod:`softtrack.store.export`). Returns ``dest``."""
    from softtrack.eval_runs import resolve_run
    from softtrack.rl.policy import model_paths
    from softtrack.store.export import export_run

    record = resolve_run(reference, runs_dir)
    return export_run(record, model_paths(record, record.load_spec()), dest)


def report(
    selection: Sequence[str],
    out_dir: str | os.PathLike[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    command_line: Sequence[str] | None = None,
    on_episode: Callable[..., None] | None = None,
    extra_runs: Sequence[str | os.PathLike[str]] = (),
) -> Any:
    """Build the report of the selected runs (experiment names, run ids or spec files).

    Completed runs without evaluation tables are evaluated first; the report itself reads only
    the stored tables. Returns the path of ``index.md``.

    Args:
        extra_runs: run directories from elsewhere (e.g. ``models/td3-sbx-1e7-seed0``) reported
            beside the selection; they must already be evaluated and are only read.
    """
    from softtrack.eval_runs import evaluate_run, has_evaluation, resolve_run
    from softtrack.report import build_report, select_runs
    from softtrack.rl.policy import model_paths

    store = RunStore(resolve_runs_dir(runs_dir))
    records = select_runs(store, selection)
    extra = [resolve_run(str(path)) for path in extra_runs]
    for record in extra:
        if not has_evaluation(record):
            raise RunStoreError(f"{record.path}: no stored evaluation; run `softtrack evaluate "
                                f"{record.path}` first")
    for record in records:
        spec = record.load_spec()
        trained = all(p.is_file() for p in model_paths(record, spec))
        if trained and not has_evaluation(record):
            evaluate_run(record, on_episode=on_episode)
    if command_line is None:
        command_line = ["softtrack", "report", *selection, "--out", str(out_dir)]
    return build_report([*records, *extra], out_dir, command_line)


QUICKSTART_PRETRAINED = "models/td3-sbx-1e7-seed0"
"""The shipped policy the quickstart shows beside its own short training (repo-relative)."""


def quickstart_pretrained_path() -> Path | None:
    """The checkout's :data:`QUICKSTART_PRETRAINED` run directory, or ``None`` if absent."""
    path = Path(__file__).resolve().parents[1] / QUICKSTART_PRETRAINED
    return path if (path / "run.json").is_file() else None


def quickstart_spec_path() -> Path:
    """``experiments/quickstart.yaml`` of this checkout."""
    path = Path(__file__).resolve().parents[1] / "experiments" / "quickstart.yaml"
    if not path.is_file():
        raise SpecError(str(path), "the quickstart spec is missing",
                        "run from a softtrack checkout (the file ships in experiments/)")
    return path


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
        on_progress: called with a progress line whenever it changes.
    """
    import sys

    from softtrack.executors import dispatch
    from softtrack.executors.sweep import expand_grid, parse_grid, parse_seeds

    options = options or dispatch.ExecOptions()
    if options.executor not in dispatch.EXECUTORS:
        raise SpecError("--executor", f"unknown executor {options.executor!r}",
                        "use local or slurm")
    points = expand_grid(paths, parse_grid(grid), seeds=parse_seeds(seeds), overrides=overrides)
    store = RunStore(resolve_runs_dir(runs_dir))
    sweep_id = dispatch.new_sweep_id()
    records = []
    for point in points:
        for s in point.spec.seeds:
            notes = {"sweep": sweep_id, "grid": point.grid}
            records.append(store.create_run(point.spec, s, list(sys.argv), notes=notes))
    if on_created is not None:
        on_created(sweep_id, records)
    ids = [r.run_id for r in records]
    return dispatch.execute(store, ids, options, sweep_id, cluster=points[0].spec.cluster,
                            on_progress=on_progress)


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
    from softtrack.executors import dispatch

    options = options or dispatch.ExecOptions()
    store = RunStore(resolve_runs_dir(runs_dir))
    records = dispatch.select_runs(store, selection)
    if not records:
        return None
    resume_id = dispatch.new_sweep_id()
    if on_selected is not None:
        on_selected(resume_id, records)
    ids = [r.run_id for r in records]
    return dispatch.execute(store, ids, options, resume_id,
                            cluster=dispatch.cluster_of(store, ids), on_progress=on_progress,
                            label=f"resume {resume_id}")
