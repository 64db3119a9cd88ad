"""``softtrack sync mlflow``: the runs of a runs directory in an MLflow tracking store.

One MLflow experiment per softtrack experiment name, one MLflow run per softtrack run:

* **params**: the run's resolved spec, flattened (``algo.learning_rate``, ``env.reward.*``);
  lists and mappings as JSON;
* **tags**: ``softtrack.run_id``, ``softtrack.dir``, the seed, algorithm, controller, spec
  hash, git commit (also as ``mlflow.source.git.commit``), host, CPU, and
  ``softtrack.signature``, a digest of the run's files at the sync;
* **metrics**: every numeric column of ``eval_metrics`` per trajectory and arm
  (``eval/circle/arm0/rmse_3d``) and its mean over the cells (``eval/rmse_3d``); the training
  curve (``train/return``, per arm ``train/return/arm0`` for an independent run, step = env
  steps) and the validation curves (``validation/<trajectory>/rmse_3d``, the mean over
  episodes and arms at each validation point) as metric histories;
* **artifacts**: ``spec.yaml``, ``run.json``, ``summary.md`` (the run's report: its row of
  ``softtrack runs`` and its evaluation table) and the policy files (``model.zip``,
  ``vecnormalize.pkl``, ``policy.json``; per arm for an independent run).

The tables are read through the results database (:class:`softtrack.store.query.
ResultsDatabase`: DuckDB over the catalog), one query per table for all the runs. A sync is
idempotent: a run whose signature is unchanged is skipped; a changed run (trained further,
evaluated again) replaces its MLflow run. MLflow is optional: ``pip install
'softtrack[mlflow]'`` (mlflow-skinny).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from softtrack.store.errors import RunStoreError
from softtrack.store.location import resolve_runs_dir
from softtrack.store.query import ResultsDatabase
from softtrack.store.runs import RunStore
from softtrack.store.selection import select_runs

__all__ = ["DEFAULT_TRACKING_URI", "SyncOutcome", "sync_mlflow"]

DEFAULT_TRACKING_URI = "sqlite:///mlflow.db"
"""Where runs go without ``--tracking-uri`` or ``$MLFLOW_TRACKING_URI``: MLflow's SQLite
store in the current directory (``mlflow ui --backend-store-uri sqlite:///mlflow.db``)."""

_STATUS = {
    "completed": "FINISHED",
    "failed": "FAILED",
    "interrupted": "KILLED",
    "running": "RUNNING",
    "queued": "SCHEDULED",
}
_POLICY_FILES = ("model.zip", "vecnormalize.pkl", "policy.json")
_PARAM_VALUE_LIMIT = 6000
_BATCH = 1000  # MLflow's most metrics (and params) per log_batch call
_SUMMARY_METRICS = ("rmse_3d", "rmse_3d_steady", "mean_spatial_error", "max_error")


class MlflowSyncError(RunStoreError):
    """MLflow is missing or refuses the store; the message is one line with the fix."""


@dataclass
class SyncOutcome:
    """What a sync did: MLflow run ids by softtrack run id."""

    tracking_uri: str
    created: dict[str, str] = field(default_factory=dict)
    replaced: dict[str, str] = field(default_factory=dict)
    unchanged: dict[str, str] = field(default_factory=dict)


def _client(tracking_uri: str) -> Any:
    try:
        from mlflow import MlflowClient
    except ImportError:
        raise MlflowSyncError(
            "sync mlflow: MLflow is not installed; install it with "
            "`pip install 'softtrack[mlflow]'` (mlflow-skinny)"
        ) from None
    with _store_refusals(tracking_uri):
        return MlflowClient(tracking_uri=tracking_uri)


@contextmanager
def _store_refusals(tracking_uri: str) -> Iterator[None]:
    """MLflow's refusals of the tracking store (a file where it wants a directory, a retired
    file store, a database it cannot open) as one :class:`MlflowSyncError` line."""
    from mlflow.exceptions import MlflowException

    try:
        yield
    except MlflowException as exc:
        first = " ".join(str(exc.message).split())
        first = first.split(". ")[0].rstrip(".")[:300]
        raise MlflowSyncError(
            f"sync mlflow: the tracking store {tracking_uri} refused the sync ({first}); give "
            f"another with --tracking-uri, e.g. {DEFAULT_TRACKING_URI}"
        ) from None


def flatten_spec(spec: dict[str, Any], prefix: str = "") -> dict[str, str]:
    """A spec as MLflow params: dotted keys, scalars as text, lists and mappings of scalars
    as JSON (values cut to MLflow's 6,000 characters)."""
    params: dict[str, str] = {}
    for key, value in spec.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict) and value:
            params.update(flatten_spec(value, f"{name}."))
            continue
        text = value if isinstance(value, str) else json.dumps(value, sort_keys=True)
        params[name] = text[:_PARAM_VALUE_LIMIT]
    return params


def run_signature(run_path: Path) -> str:
    """A digest of what a sync writes of a run: its ``run.json``, ``spec.yaml`` and every
    table and policy file's size and modification time."""
    digest = hashlib.blake2b(digest_size=16)
    for name in ("run.json", "spec.yaml"):
        try:
            digest.update((run_path / name).read_bytes())
        except OSError:
            digest.update(b"-")
    files = sorted(
        p for p in run_path.rglob("*") if p.suffix in (".parquet", ".zip", ".pkl", ".json")
    )
    for path in files:
        if "checkpoints" in path.parts or "best" in path.parts:
            continue
        st = path.stat()
        digest.update(f"{path.relative_to(run_path)}:{st.st_size}:{st.st_mtime_ns}".encode())
    return digest.hexdigest()


def _finite(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def _eval_metrics(rows: pd.DataFrame) -> dict[str, float]:
    """``eval/<trajectory>/arm<k>/<column>`` and ``eval/<column>`` (mean over the cells)."""
    metrics: dict[str, float] = {}
    numeric = [
        c
        for c in rows.columns
        if c not in ("run_id", "trajectory", "arm")
        and (pd.api.types.is_numeric_dtype(rows[c]) or pd.api.types.is_bool_dtype(rows[c]))
    ]
    for row in rows.itertuples(index=False):
        cell = f"eval/{row.trajectory}/arm{int(row.arm)}"
        for column in numeric:
            value = _finite(getattr(row, column))
            if value is not None:
                metrics[f"{cell}/{column}"] = value
    for column in _SUMMARY_METRICS:
        if column in rows:
            value = _finite(pd.to_numeric(rows[column], errors="coerce").mean())
            if value is not None:
                metrics[f"eval/{column}"] = value
    return metrics


def _histories(train: pd.DataFrame | None, validation: pd.DataFrame | None) -> list[Any]:
    """The training and validation curves as MLflow metric points (step: env steps)."""
    from mlflow.entities import Metric

    points = []
    if train is not None and len(train):
        arms = train["arm"] if "arm" in train else pd.Series([None] * len(train))
        for arm, step, value, clock in zip(
            arms, train["global_step"], train["return"], train["wall_time"], strict=True
        ):
            number = _finite(value)
            if number is None:
                continue
            key = (
                "train/return"
                if arm is None or pd.isna(arm) or arm < 0
                else f"train/return/arm{int(arm)}"
            )
            points.append(Metric(key, number, int(1000 * (_finite(clock) or 0.0)), int(step)))
    if validation is not None and len(validation):
        curves = validation.groupby(["trajectory", "global_step"], sort=True)
        for (trajectory, step), group in curves:
            for column in ("rmse_3d", "rmse_3d_steady"):
                if column in group:
                    value = _finite(pd.to_numeric(group[column], errors="coerce").mean())
                    clock = _finite(group["wall_time"].max()) if "wall_time" in group else 0.0
                    if value is not None:
                        key = f"validation/{trajectory}/{column}"
                        points.append(Metric(key, value, int(1000 * (clock or 0.0)), int(step)))
    return points


def _summary(run: pd.Series, metrics: pd.DataFrame | None) -> str:
    lines = [
        f"# {run['name']} (seed {run['seed']})",
        "",
        f"softtrack run `{run['run_id']}` ({run['dir']}): {run['status']}, "
        f"{run['global_step']}/{run['total_timesteps']} env steps, algorithm {run['algo']}, "
        f"{run['controller']}.",
        "",
    ]
    if metrics is not None and len(metrics):
        lines += ["| trajectory | arm | 3-D RMSE (m) | steady 3-D RMSE (m) |", "|---|---|---|---|"]
        for row in metrics.itertuples(index=False):
            steady = getattr(row, "rmse_3d_steady", float("nan"))
            lines.append(f"| {row.trajectory} | {row.arm} | {row.rmse_3d:.4f} | {steady:.4f} |")
    return "\n".join(lines) + "\n"


def _table(db: ResultsDatabase, name: str, runs: Iterable[str]) -> dict[str, pd.DataFrame]:
    """A table's rows of the given runs, by run id (one query for all of them)."""
    if name not in db.table_names():
        return {}
    ids = ", ".join("'" + r.replace("'", "''") + "'" for r in runs)
    frame = db.query(f"SELECT * FROM {name} WHERE run_id IN ({ids})") if ids else None
    if frame is None or not len(frame):
        return {}
    return {str(k): v.reset_index(drop=True) for k, v in frame.groupby("run_id", sort=False)}


def _ms(moment: Any) -> int | None:
    return (
        None if moment is None or pd.isna(moment) else int(pd.Timestamp(moment).timestamp() * 1000)
    )


def _log_run(
    client: Any,
    experiment_id: str,
    run: pd.Series,
    run_path: Path,
    signature: str,
    tables: dict[str, pd.DataFrame | None],
) -> str:
    from mlflow.entities import Metric, Param

    tags = {
        "softtrack.run_id": str(run["run_id"]),
        "softtrack.dir": str(run["dir"]),
        "softtrack.signature": signature,
        "softtrack.seed": str(run["seed"]),
        "softtrack.algo": str(run["algo"]),
        "softtrack.controller": str(run["controller"]),
        "softtrack.spec_hash": str(run["spec_hash"]),
        "softtrack.host": str(run["host"] or ""),
        "softtrack.cpu": str(run["cpu"] or ""),
    }
    if run["git_commit"]:
        tags["mlflow.source.git.commit"] = str(run["git_commit"])
    created = client.create_run(
        experiment_id, start_time=_ms(run["created"]), tags=tags, run_name=str(run["dir"])
    )
    mlflow_id = created.info.run_id
    raw = RunStore(run_path.parent).read_record(run_path).raw_spec()
    params = [Param(k, v) for k, v in sorted(flatten_spec(raw).items())]
    for start in range(0, len(params), 100):
        client.log_batch(mlflow_id, params=params[start : start + 100])
    metrics = tables.get("eval_metrics")
    points = (
        [Metric(k, v, 0, 0) for k, v in _eval_metrics(metrics).items()]
        if metrics is not None
        else []
    )
    points += _histories(tables.get("train_episodes"), tables.get("validation"))
    for start in range(0, len(points), _BATCH):
        client.log_batch(mlflow_id, metrics=points[start : start + _BATCH])
    with tempfile.TemporaryDirectory() as scratch:
        summary = Path(scratch) / "summary.md"
        summary.write_text(_summary(run, metrics), encoding="utf-8")
        client.log_artifact(mlflow_id, str(summary))
    for name in ("spec.yaml", "run.json"):
        if (run_path / name).is_file():
            client.log_artifact(mlflow_id, str(run_path / name))
    for policy_dir, where in [(run_path, "policy")] + [
        (arm, f"policy/{arm.name}") for arm in sorted((run_path / "models").glob("arm*"))
    ]:
        for name in _POLICY_FILES:
            if (policy_dir / name).is_file():
                client.log_artifact(mlflow_id, str(policy_dir / name), where)
    client.set_tag(mlflow_id, "softtrack.status", str(run["status"]))
    status = _STATUS.get(str(run["status"]), "FINISHED")
    if status in ("RUNNING", "SCHEDULED"):
        client.update_run(mlflow_id, status=status)
    else:
        client.set_terminated(mlflow_id, status, end_time=_ms(run["ended"]))
    return str(mlflow_id)


def sync_mlflow(
    selection: Sequence[str] = (),
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    tracking_uri: str | None = None,
    on_run: Callable[[str, str], None] | None = None,
) -> SyncOutcome:
    """Write the runs of ``runs_dir`` (``selection``: experiment names, run ids or spec
    files; empty: every run) to the MLflow store at ``tracking_uri`` (default
    ``$MLFLOW_TRACKING_URI``, else :data:`DEFAULT_TRACKING_URI`); see the module docstring.
    ``on_run(run id, what)`` is called per run (``created``, ``replaced``, ``unchanged``).

    Raises:
        MlflowSyncError: MLflow is not installed or refuses the store.
        RunStoreError, QueryError, SpecError: a bad selection or runs directory.
    """
    uri = tracking_uri or os.environ.get("MLFLOW_TRACKING_URI") or DEFAULT_TRACKING_URI
    root = resolve_runs_dir(runs_dir)
    client = _client(uri)
    outcome = SyncOutcome(uri)
    with ResultsDatabase(root) as db:
        runs = db.query("SELECT * FROM runs ORDER BY dir")
        if selection:
            chosen = {r.info.run_id for r in select_runs(RunStore(root), selection)}
            runs = runs[runs["run_id"].isin(chosen)]
        ids = list(runs["run_id"])
        tables = {
            name: _table(db, name, ids) for name in ("eval_metrics", "train_episodes", "validation")
        }
    with _store_refusals(uri):
        _sync_rows(client, root, runs, tables, outcome, on_run)
    return outcome


def _sync_rows(
    client: Any,
    root: Path,
    runs: pd.DataFrame,
    tables: dict[str, dict[str, pd.DataFrame]],
    outcome: SyncOutcome,
    on_run: Callable[[str, str], None] | None,
) -> None:
    """Create, replace or skip each run of ``runs`` (rows of the ``runs`` view) in MLflow."""
    experiments: dict[str, str] = {}
    for _, run in runs.iterrows():
        run_id, name = str(run["run_id"]), str(run["name"])
        run_path = root / str(run["dir"])
        if name not in experiments:
            found = client.get_experiment_by_name(name)
            experiments[name] = found.experiment_id if found else client.create_experiment(name)
        signature = run_signature(run_path)
        existing = client.search_runs(
            [experiments[name]], filter_string=f"tags.`softtrack.run_id` = '{run_id}'"
        )
        if existing and existing[0].data.tags.get("softtrack.signature") == signature:
            outcome.unchanged[run_id] = existing[0].info.run_id
            what = "unchanged"
        else:
            for old in existing:
                client.delete_run(old.info.run_id)
            run_tables = {t: rows.get(run_id) for t, rows in tables.items()}
            mlflow_id = _log_run(client, experiments[name], run, run_path, signature, run_tables)
            (outcome.replaced if existing else outcome.created)[run_id] = mlflow_id
            what = "replaced" if existing else "created"
        if on_run is not None:
            on_run(run_id, what)
