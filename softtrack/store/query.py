"""SQL over a runs directory with DuckDB (``softtrack query``).

:func:`connect` opens an in-memory DuckDB database over a runs directory (see
:func:`~softtrack.store.runs.resolve_runs_dir`); nothing is copied and nothing is written to
the runs. The database is **read-only** (:meth:`ResultsDatabase.query`): it runs only read
statements (SELECT, WITH, VALUES, EXPLAIN, DESCRIBE, SHOW, SUMMARIZE), and once the views exist
DuckDB's file system access is switched off except for reading the store's Parquet files,
extensions can be neither installed nor loaded, and the configuration is locked; so ``COPY``,
``ATTACH``, ``EXPORT``, ``INSTALL``, ``read_csv('/etc/passwd')`` and the like are refused with
one line and nothing is read or written outside the views. It holds:

``runs``
    One row per run (a sub-directory with a readable ``run.json``, as ``softtrack runs``
    lists them): the scalar fields of ``run.json`` (:data:`RUNS_COLUMNS`), the directory name
    ``dir``, the training wall time ``train_seconds`` and the spec's ``final_stage_fraction``.
    ``name`` is the experiment name: the seeds of one experiment share it, so join a table to
    ``runs`` with ``USING (run_id)`` and ``GROUP BY name``.
``experiments``
    One row per experiment name: its number of runs (and completed ones), seeds, algorithm,
    controller and number of distinct specs.
one view per table
    Every ``tables/<name>.parquet`` that at least one run has (temporary files of interrupted
    writers skipped) becomes a view ``<name>`` over that file of every run that has one,
    read with ``union_by_name``: a column missing from some runs' files is NULL for their
    rows, so tables whose columns changed between versions still read as one view. Its
    ``run_id`` column is the run's id from its ``run.json`` (the first column; the value
    stored in the file is replaced: copied or directory-evaluated runs store another id
    there). A table no run has has no view. See :data:`TABLE_DESCRIPTIONS`.

Use :func:`query` for a DataFrame, :func:`available_views` for the views and their columns,
and :class:`ResultsDatabase` to run several queries on one connection. Problems a user can
fix (no runs directory, no runs, bad SQL, an unknown table or column, an unreadable Parquet
file) raise :class:`QueryError` with a one-line message that says what to do.
"""

from __future__ import annotations

import json
import math
import os
import re
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta
from decimal import Decimal
from pathlib import Path
from types import TracebackType
from typing import Any, Literal, Self

import duckdb
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from softtrack.store.runs import RunRecord, RunStore, RunStoreError, parse_time, resolve_runs_dir
from softtrack.store.status import (
    DEFAULT_FINAL_STAGE_FRACTION,
    final_stage_fraction,
    training_seconds,
)
from softtrack.store.tables import list_tables

__all__ = [
    "DEFAULT_FINAL_STAGE_FRACTION",
    "OUTPUT_FORMATS",
    "RUNS_COLUMNS",
    "TABLE_DESCRIPTIONS",
    "QueryError",
    "ResultsDatabase",
    "ViewInfo",
    "available_views",
    "connect",
    "format_result",
    "format_views",
    "query",
]

OutputFormat = Literal["table", "csv", "json"]
OUTPUT_FORMATS: tuple[OutputFormat, ...] = ("table", "csv", "json")

#: Columns of the ``runs`` view: name, Arrow type and meaning. Times are UTC (TIMESTAMP
#: without time zone).
RUNS_COLUMNS: tuple[tuple[str, pa.DataType, str], ...] = (
    ("run_id", pa.string(), "ULID of the run (run.json run_id); every table view's run_id"),
    ("dir", pa.string(), "the run's directory name inside the runs directory"),
    ("name", pa.string(), "experiment name (spec name): group the seeds of an experiment by it"),
    ("algo", pa.string(), "algorithm (spec algo.name)"),
    ("controller", pa.string(), "centralized or independent"),
    ("seed", pa.int64(), "random seed of the run"),
    (
        "status",
        pa.string(),
        (
            "run.json status: queued, running, completed, failed, interrupted "
            "(`softtrack runs` also shows a running run whose process is gone "
            "as lost)"
        ),
    ),
    ("total_timesteps", pa.int64(), "training budget, env steps (independent: both arms)"),
    ("arm_total_timesteps", pa.int64(), "independent runs: budget per arm, env steps"),
    ("global_step", pa.int64(), "env steps done (independent: over both arms)"),
    (
        "steps_per_second",
        pa.float64(),
        (
            "training throughput, env steps/s: global_step / "
            "train_seconds, as in the report's runs table"
        ),
    ),
    (
        "train_seconds",
        pa.float64(),
        (
            "training wall time, s: the run's training clock at its "
            "last logged episode (train_episodes.wall_time), as in the "
            "report; NULL before the first episode"
        ),
    ),
    (
        "final_stage_fraction",
        pa.float64(),
        (
            "spec training.final_stage_fraction (default 0.1): "
            "the final-stage return averages the episodes after "
            "(1 - it) x the budget"
        ),
    ),
    ("spec_hash", pa.string(), "spec hash without the seed: the runs of an experiment share it"),
    ("git_commit", pa.string(), "commit of the code when the run was created"),
    ("git_dirty", pa.bool_(), "the checkout had uncommitted changes"),
    ("created", pa.timestamp("us"), "creation time (UTC)"),
    ("started", pa.timestamp("us"), "time training first started (UTC)"),
    ("ended", pa.timestamp("us"), "time the run ended (UTC)"),
    ("host", pa.string(), "host of the (last) training process"),
    ("cpu", pa.string(), "CPU of the (last) training process"),
    ("sweep", pa.string(), "id of the sweep that created the run, if any"),
    ("error", pa.string(), "one-line error of a failed run"),
)

#: What the tables written by softtrack hold (one row per ...). Other tables get a generic
#: description.
TABLE_DESCRIPTIONS: dict[str, str] = {
    "train_episodes": "one row per finished training episode: episode, global_step at its "
    "end, return, length, wall_time (s since training started); independent runs add arm and "
    "count episode and global_step per arm; truncated is true for an episode a stop cut "
    "short at the checkpoint training resumed from (partial return), NULL otherwise",
    "validation": "validation during training: one row per validation point (global_step, "
    "wall_time: training seconds), episode and arm, with the tracking metrics (rmse_3d, ..., "
    "*_steady for t >= 1 s) and the columns of eval_metrics; trajectory 'random' for the "
    "held-out episodes, and with training.validation_trajectories one row per evaluation "
    "trajectory and arm",
    "confirmation": "after training: one row per candidate model (best, last), held-out "
    "episode and arm, with the tracking metrics and the columns of eval_metrics",
    "eval_metrics": "`softtrack evaluate`: one row per trajectory (circle, rectangle, figure8) "
    "and arm (0, 1): rmse_3d, rmse_x/y/z, mae_*, max_error, *_steady (t >= 1 s), action "
    "statistics, terminated, duration, the arm's torque_rate_rms (N*m/s) and peak_moment "
    "(N*m), the episode's min_arm_distance (m, surface clearance between the arms; NaN with "
    "one arm) and collision_steps (steps with clearance < reward.collision_margin); these "
    "four are NULL in tables written before they existed; with two arms also "
    "max_penetration (m, deepest overlap of the arms' surfaces), contact_steps, "
    "mean_contact_force and max_contact_force (N; 0 without contact), NULL before contact "
    "existed",
    "eval_random": "`softtrack evaluate --random N`: one row per random-target episode and arm, "
    "with the tracking metrics and the columns of eval_metrics",
    "eval_trajectories": "`softtrack evaluate`: tip and target position per trajectory, step "
    "and arm, and the scene's clearance, penetration (m) and contact_force (N) at that step "
    "(NULL in tables written before contact existed)",
    "eval_snapshots": "`softtrack evaluate`: both arms' centreline nodes (x, y, z, m) at four "
    "instants of each trajectory, per step, arm and node",
    "eval_moments": "`softtrack evaluate`: internal moments per trajectory, step, arm and "
    "direction (rms_moment: spatial RMS; runs stored by older versions also have "
    "max_abs_moment and element_torques, NULL for newer runs)",
    "eval_moment_peaks": "`softtrack evaluate`: largest absolute moment of each element over "
    "the episode, per trajectory, arm and direction",
    "eval_robustness": "`softtrack robustness`: one row per perturbation setting (perturbation, "
    "level, setting, baseline), trajectory, episode and arm, with the columns of eval_metrics",
}

_RESERVED = ("runs", "experiments")

_EXPERIMENTS_SQL = """
CREATE VIEW experiments AS
SELECT name,
       count(*) AS runs,
       count(*) FILTER (WHERE status = 'completed') AS completed,
       list(DISTINCT seed ORDER BY seed) AS seeds,
       string_agg(DISTINCT algo, ',' ORDER BY algo) AS algo,
       string_agg(DISTINCT controller, ',' ORDER BY controller) AS controller,
       count(DISTINCT spec_hash) AS specs,
       min(created) AS first_created,
       max(ended) AS last_ended
FROM runs
GROUP BY name
ORDER BY name
"""


class QueryError(RunStoreError):
    """A query cannot run; the message is one line saying what is wrong and what to do."""


@dataclass(frozen=True)
class ViewInfo:
    """A view of the results database (or a table view that is unavailable)."""

    name: str
    description: str
    #: (column name, DuckDB type), in order; empty when unavailable.
    columns: tuple[tuple[str, str], ...]
    #: runs that contribute rows (for ``runs``/``experiments``: all runs).
    runs: int
    #: why the view is unavailable (an unreadable file), else ``None``.
    error: str | None = None


@dataclass(frozen=True)
class _TableFile:
    run_id: str
    path: Path
    has_run_id: bool


def _lit(text: str) -> str:
    """A SQL string literal."""
    return "'" + text.replace("'", "''") + "'"


def _ident(name: str) -> str:
    """A SQL identifier (quoted)."""
    return '"' + name.replace('"', '""') + '"'


def _utc(text: str | None) -> datetime | None:
    try:
        moment = parse_time(text)
    except (TypeError, ValueError):
        return None
    if moment is None:
        return None
    if moment.tzinfo is not None:
        moment = moment.astimezone(UTC).replace(tzinfo=None)
    return moment


def _train_seconds(record: RunRecord) -> float | None:
    """The run's training clock (:func:`softtrack.store.status.training_seconds`), as the
    report's runs table gives it."""
    path = record.table_path("train_episodes")
    try:
        train = pq.read_table(path, columns=["wall_time"]).to_pandas() if path.is_file() else None
    except (pa.ArrowInvalid, OSError, KeyError):
        return None
    return training_seconds(train)


def _raw_spec(record: RunRecord) -> dict[str, Any]:
    """``spec.yaml`` as plain data (``{}`` if missing or unreadable), parsed with libyaml when
    available (the pure-Python parser costs ~10 ms a run)."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        data = yaml.load(record.spec_path.read_text(encoding="utf-8"), Loader=loader)
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        return {}
    return data if isinstance(data, dict) else {}


def _final_stage_fraction(record: RunRecord) -> float:
    return final_stage_fraction(_raw_spec(record))


def _per_second(steps: int, seconds: float | None) -> float | None:
    return steps / seconds if seconds and steps else None


def _runs_row(record: RunRecord) -> dict[str, Any]:
    info = record.info
    seconds = _train_seconds(record)
    sweep = (info.notes or {}).get("sweep")
    return {
        "run_id": info.run_id,
        "dir": record.path.name,
        "name": info.name,
        "algo": info.algo,
        "controller": info.controller,
        "seed": info.seed,
        "status": info.status,
        "total_timesteps": info.total_timesteps,
        "arm_total_timesteps": info.arm_total_timesteps,
        "global_step": info.global_step,
        "steps_per_second": _per_second(info.global_step, seconds) or info.steps_per_second,
        "train_seconds": seconds,
        "final_stage_fraction": _final_stage_fraction(record),
        "spec_hash": info.spec_hash,
        "git_commit": info.git_commit,
        "git_dirty": info.git_dirty,
        "created": _utc(info.created),
        "started": _utc(info.started),
        "ended": _utc(info.ended),
        "host": info.host,
        "cpu": info.cpu,
        "sweep": None if sweep is None else str(sweep),
        "error": info.error,
    }


def _runs_table(records: Sequence[RunRecord]) -> pa.Table:
    rows = [_runs_row(r) for r in records]
    return pa.table(
        {name: pa.array([row[name] for row in rows], type=kind) for name, kind, _ in RUNS_COLUMNS}
    )


def _table_files(record: RunRecord) -> dict[str, list[Path]]:
    """``{table name: [parquet files]}`` of a run (a directory table: its part files)."""
    found: dict[str, list[Path]] = {}
    for name, path in list_tables(record.tables_dir).items():
        if path.is_dir():
            parts = sorted(
                p
                for p in path.rglob("*.parquet")
                if p.is_file()
                and not any(part.startswith((".", "_")) for part in p.relative_to(path).parts)
            )
            if parts:
                found[name] = parts
        elif path.is_file():
            found[name] = [path]
    return found


def _view_sql(files: Sequence[_TableFile]) -> str:
    """A SELECT over ``files`` (union by name) whose ``run_id`` is each file's run's id."""
    paths = ", ".join(_lit(str(f.path)) for f in files)
    mapping = ", ".join(f"({_lit(str(f.path))}, {_lit(f.run_id)})" for f in files)
    drop = "run_id, __softtrack_file" if any(f.has_run_id for f in files) else "__softtrack_file"
    return (
        f"SELECT __softtrack_runs.run_id, __softtrack_t.* EXCLUDE ({drop}) "
        f"FROM read_parquet([{paths}], union_by_name = true, filename = '__softtrack_file') "
        f"AS __softtrack_t JOIN (VALUES {mapping}) AS __softtrack_runs(file, run_id) "
        f"ON __softtrack_t.__softtrack_file = __softtrack_runs.file"
    )


def _first_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split("\n")[0].split())
    return text or type(exc).__name__


#: Statement types :meth:`ResultsDatabase.query` runs (DESCRIBE, SHOW, SUMMARIZE and VALUES
#: parse as SELECT).
_READ_STATEMENTS = frozenset({"SELECT", "EXPLAIN"})


def _check_read_only(sql: str) -> None:
    """Raise :class:`QueryError` for a statement that is not a read (COPY, ATTACH, SET, ...);
    a syntax error is left to the query itself."""
    try:
        statements = duckdb.extract_statements(sql)
    except duckdb.Error:
        return
    for statement in statements:
        if str(statement.type).rsplit(".", 1)[-1] not in _READ_STATEMENTS:
            words = statement.query.split()
            kind = words[0].upper() if words else str(statement.type)
            raise QueryError(
                f"query: {kind} statements are not allowed: a results database is read-only "
                "(SELECT, WITH, EXPLAIN, DESCRIBE, SUMMARIZE); to save a result use "
                "--format csv or json and redirect it, e.g. `softtrack query SQL --format csv "
                "> result.csv`"
            )


class ResultsDatabase:
    """An in-memory DuckDB database over the runs of ``runs_dir`` (see the module docstring).

    Args:
        runs_dir: the runs directory (``None``: ``$SOFTTRACK_RUNS_DIR``, else ``runs/``).

    Raises:
        QueryError: the directory does not exist or holds no runs.
    """

    def __init__(self, runs_dir: str | os.PathLike[str] | None = None) -> None:
        root = resolve_runs_dir(runs_dir)
        self.root = root
        if not root.is_dir():
            what = "is not a directory" if root.exists() else "does not exist"
            raise QueryError(
                f"query: runs directory {root} {what}; pass --runs-dir DIR or set "
                "SOFTTRACK_RUNS_DIR (the shipped runs: --runs-dir models)"
            )
        store = RunStore(root)
        self.records = store.list_runs()
        #: runs left out because their run.json is missing or unreadable
        self.unreadable = store.list_unreadable()
        if not self.records:
            raise QueryError(
                f"query: {root} holds no runs (no sub-directory with a readable run.json); "
                "pass the directory your runs are in with --runs-dir (the shipped runs: "
                "--runs-dir models)"
            )
        self.connection = duckdb.connect(":memory:")
        try:
            self.connection.execute("SET enable_progress_bar = false")
            self._views: dict[str, ViewInfo] = {}
            self._create_runs_views()
            self._create_table_views()
            self._sandbox()
        except BaseException:
            self.connection.close()
            raise

    # ---- setup -------------------------------------------------------------------------
    def _create_runs_views(self) -> None:
        con = self.connection
        con.register("__softtrack_runs_arrow", _runs_table(self.records))
        con.execute("CREATE TABLE runs AS SELECT * FROM __softtrack_runs_arrow")
        con.unregister("__softtrack_runs_arrow")
        con.execute(_EXPERIMENTS_SQL)
        n = len(self.records)
        self._add_view(
            "runs", "one row per run: run.json fields, dir, train_seconds, final_stage_fraction", n
        )
        self._add_view(
            "experiments",
            "one row per experiment name (runs.name): runs, "
            "completed, seeds, algo, controller, specs",
            n,
        )

    def _create_table_views(self) -> None:
        by_table: dict[str, list[_TableFile]] = {}
        broken: dict[str, str] = {}
        self._files: set[str] = set()
        for record in self.records:
            for name, paths in _table_files(record).items():
                for path in paths:
                    try:
                        names = pq.read_schema(path).names
                    except (pa.ArrowException, OSError) as exc:
                        broken.setdefault(
                            name,
                            f"{path} (run {record.info.run_id}) is not readable Parquet "
                            f"({_first_line(exc)})",
                        )
                        continue
                    by_table.setdefault(name, []).append(
                        _TableFile(record.info.run_id, path.resolve(), "run_id" in names)
                    )
        for name in sorted(set(by_table) | set(broken)):
            view = f"{name}_table" if name in _RESERVED else name
            description = TABLE_DESCRIPTIONS.get(name, f"the runs' tables/{name}.parquet")
            files = by_table.get(name, [])
            runs = len({f.run_id for f in files})
            if name in broken:
                self._views[view] = ViewInfo(view, description, (), runs, broken[name])
                continue
            self._files.update(str(f.path) for f in files)
            try:
                self.connection.execute(f"CREATE VIEW {_ident(view)} AS {_view_sql(files)}")
            except duckdb.Error as exc:
                self._views[view] = ViewInfo(
                    view,
                    description,
                    (),
                    runs,
                    f"tables/{name}.parquet of {runs} runs cannot be read as one table "
                    f"({_first_line(exc)})",
                )
                continue
            self._add_view(view, description, runs)

    def _sandbox(self) -> None:
        """No file access but reading the views' Parquet files, no extensions, locked settings."""
        con = self.connection
        files = sorted(self._files)
        if files:
            con.execute("SET allowed_paths = ?", [files])
        for setting in (
            "enable_external_access",
            "autoinstall_known_extensions",
            "autoload_known_extensions",
            "allow_community_extensions",
        ):
            con.execute(f"SET {setting} = false")
        con.execute("SET lock_configuration = true")

    def _add_view(self, name: str, description: str, runs: int) -> None:
        rows = self.connection.execute(
            "SELECT column_name, data_type FROM duckdb_columns() "
            "WHERE table_name = ? AND schema_name = 'main' ORDER BY column_index",
            [name],
        ).fetchall()
        columns = tuple((str(c), str(t)) for c, t in rows)
        self._views[name] = ViewInfo(name, description, columns, runs)

    # ---- use ---------------------------------------------------------------------------
    def views(self) -> list[ViewInfo]:
        """``runs``, ``experiments``, then the table views by name (unavailable ones with
        their ``error``)."""
        return list(self._views.values())

    def query(self, sql: str) -> pd.DataFrame:
        """Run ``sql`` (DuckDB's dialect; several statements: the last one's result) and
        return the result (an empty DataFrame for a statement without one).

        Raises:
            QueryError: bad SQL, an unknown view or column, an unreadable file.
        """
        if not sql.strip():
            raise QueryError('query: no SQL given; e.g. `softtrack query "SELECT * FROM runs"`')
        try:
            _check_read_only(sql)
            cursor = self.connection.execute(sql)
            if cursor.description is None:
                return pd.DataFrame()
            return cursor.df()
        except duckdb.Error as exc:
            raise QueryError(self._explain(exc)) from None

    def _explain(self, exc: duckdb.Error) -> str:
        """A one-line message for a DuckDB error, with what to do."""
        lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
        first = lines[0] if lines else type(exc).__name__
        available = ", ".join(v.name for v in self._views.values() if v.error is None)
        listing = "`softtrack query --views` lists the views and their columns"
        missing = re.search(r"Table with name (.+?) does not exist", first)
        if isinstance(exc, duckdb.CatalogException) and missing:
            name = missing.group(1).strip('"')
            view = self._views.get(name)
            if view is not None and view.error is not None:
                return (
                    f"query: view {name} is unavailable: {view.error}; move the file away "
                    "or rewrite it (e.g. `softtrack evaluate RUN` for eval_* tables)"
                )
            return (
                f"query: no view {name} in {self.root} (no run has tables/{name}.parquet); "
                f"available views: {available} ({listing})"
            )
        context = [ln for ln in lines[1:] if not ln.startswith("LINE ") and set(ln) != {"^"}]
        where = next((ln for ln in lines[1:] if ln.startswith("LINE ")), None)
        detail = first + "".join(f"; {ln}" for ln in context)
        if isinstance(exc, duckdb.PermissionException) or "configuration has been locked" in first:
            return f"query: refused, a query reads only the store's views ({first}); {listing}"
        if isinstance(exc, duckdb.ParserException):
            at = f" ({where})" if where else ""
            return f"query: {detail}{at}; fix the SQL (DuckDB's dialect: duckdb.org/docs/sql)"
        if isinstance(exc, (duckdb.BinderException, duckdb.CatalogException)):
            return f"query: {detail}; {listing}"
        unreadable = isinstance(exc, (duckdb.IOException, duckdb.InvalidInputException))
        if unreadable and ".parquet" in first:
            return (
                f"query: {detail}; a table file is unreadable: move it away or rewrite it "
                "(e.g. `softtrack evaluate RUN` for eval_* tables)"
            )
        return f"query: {detail}"

    def close(self) -> None:
        self.connection.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def connect(runs_dir: str | os.PathLike[str] | None = None) -> duckdb.DuckDBPyConnection:
    """An in-memory DuckDB connection with the views over ``runs_dir`` (module docstring).

    Its file access is limited to reading (and, a raw connection being unfiltered, writing)
    the store's Parquet files; use :func:`query` or :class:`ResultsDatabase` for SQL you do not
    control: they refuse every statement but a read.

    Raises:
        QueryError: the directory does not exist or holds no runs.
    """
    return ResultsDatabase(runs_dir).connection


def query(sql: str, runs_dir: str | os.PathLike[str] | None = None) -> pd.DataFrame:
    """Run ``sql`` over the runs of ``runs_dir`` and return the result as a DataFrame.

    Example::

        query("SELECT name, avg(rmse_3d) FROM eval_metrics JOIN runs USING (run_id) "
              "GROUP BY name", "models")

    Raises:
        QueryError: no runs directory or runs, bad SQL, an unknown view or column, an
            unreadable file (a one-line message).
    """
    with ResultsDatabase(runs_dir) as db:
        return db.query(sql)


def available_views(runs_dir: str | os.PathLike[str] | None = None) -> list[ViewInfo]:
    """The views over ``runs_dir`` with their columns (see :meth:`ResultsDatabase.views`)."""
    with ResultsDatabase(runs_dir) as db:
        return db.views()


# ---- output ---------------------------------------------------------------------------------
def _is_null(value: Any) -> bool:
    if value is None or value is pd.NaT or value is pd.NA:
        return True
    return isinstance(value, (float, np.floating)) and math.isnan(value)


def _json_value(value: Any) -> Any:
    """A JSON-serialisable version of a result cell (NULL, NaN and infinities → null)."""
    if isinstance(value, np.ndarray):
        return [_json_value(v) for v in value.tolist()]
    if isinstance(value, (list, tuple)):
        return [_json_value(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _json_value(v) for k, v in value.items()}
    if _is_null(value):
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating, Decimal)):
        number = float(value)
        return number if math.isfinite(number) else None
    if isinstance(value, (pd.Timestamp, datetime, date)):
        return value.isoformat()
    if isinstance(value, (pd.Timedelta, timedelta)):
        return pd.Timedelta(value).total_seconds()
    if isinstance(value, np.generic):
        return _json_value(value.item())
    if isinstance(value, bytes):
        return value.hex()
    return value if isinstance(value, str) else str(value)


def _text_value(value: Any) -> str:
    """A result cell as table text: NULL/NaN blank, floats to 6 significant digits."""
    if isinstance(value, (np.ndarray, list, tuple, dict)):
        return json.dumps(_json_value(value))
    if _is_null(value):
        return ""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(value):
            return str(float(value))
        return np.format_float_positional(
            float(value), precision=6, unique=True, fractional=False, trim="-"
        )
    if isinstance(value, (pd.Timestamp, datetime)):
        spec = (
            "seconds"
            if value.microsecond == 0
            else ("milliseconds" if value.microsecond % 1000 == 0 else "microseconds")
        )
        return value.isoformat(sep=" ", timespec=spec)
    return str(value)


def _float_cells(values: Sequence[Any]) -> list[str]:
    """A float column as text: 6 significant digits, padded to the same number of decimals
    (at most 6) so the points line up; a value that would show as 0 keeps its own digits."""
    texts = [_text_value(v) for v in values]
    decimals = [len(t.partition(".")[2]) for t in texts if t and t[-1].isdigit()]
    if not decimals:
        return texts
    places = min(max(decimals), 6)
    cells = []
    for value, text in zip(values, texts, strict=True):
        fixed = f"{float(value):.{places}f}" if text and text[-1].isdigit() else text
        cells.append(text if float(fixed or 0) == 0 and float(value or 0) != 0 else fixed)
    return cells


def _text_table(df: pd.DataFrame) -> str:
    columns = [str(c) for c in df.columns]
    cells = [
        _float_cells(df.iloc[:, i].tolist())
        if pd.api.types.is_float_dtype(df.dtypes.iloc[i])
        else [_text_value(v) for v in df.iloc[:, i].tolist()]
        for i in range(len(columns))
    ]
    numeric = [
        pd.api.types.is_numeric_dtype(df.dtypes.iloc[i])
        and not pd.api.types.is_bool_dtype(df.dtypes.iloc[i])
        for i in range(len(columns))
    ]
    widths = [max([len(columns[i]), *(len(c) for c in cells[i])]) for i in range(len(columns))]

    def line(values: Sequence[str]) -> str:
        return "  ".join(
            v.rjust(widths[i]) if numeric[i] else v.ljust(widths[i]) for i, v in enumerate(values)
        ).rstrip()

    rows = [line(columns)]
    rows.extend(line([cells[i][r] for i in range(len(columns))]) for r in range(len(df)))
    return "\n".join(rows)


def format_result(df: pd.DataFrame, output_format: OutputFormat = "table") -> str:
    """A query result as text: ``table`` (aligned columns with a header, no index; NULL is
    blank), ``csv`` (with a header) or ``json`` (an array of records; NULL/NaN → null).

    Lists and structs are written as JSON in ``table`` and ``csv``.
    """
    if output_format == "json":
        records = [
            {str(c): _json_value(v) for c, v in zip(df.columns, row, strict=True)}
            for row in df.itertuples(index=False, name=None)
        ]
        return json.dumps(records, indent=2, ensure_ascii=False)
    if output_format == "csv":
        plain = df.copy()
        for column in plain.columns:
            if plain[column].dtype == object:
                plain[column] = plain[column].map(
                    lambda v: (
                        json.dumps(_json_value(v))
                        if isinstance(v, (np.ndarray, list, tuple, dict))
                        else v
                    )
                )
        return plain.to_csv(index=False).rstrip("\n")
    if output_format == "table":
        return _text_table(df)
    raise ValueError(f"unknown output format {output_format!r}; one of {OUTPUT_FORMATS}")


def format_views(views: Sequence[ViewInfo], width: int = 100) -> str:
    """The views, each with its description and columns (``name TYPE``), as text."""
    blocks = []
    for view in views:
        runs = f"{view.runs} run" + ("" if view.runs == 1 else "s")
        head = f"{view.name} ({runs}): {view.description}"
        lines = textwrap.wrap(head, width, subsequent_indent="    ")
        if view.error is not None:
            lines += textwrap.wrap(
                f"UNAVAILABLE: {view.error}", width, initial_indent="  ", subsequent_indent="    "
            )
        else:
            # break lines only between columns (\xa0: a space textwrap does not break at)
            columns = ", ".join(f"{c} {t}".replace(" ", "\xa0") for c, t in view.columns)
            lines += [
                line.replace("\xa0", " ")
                for line in textwrap.wrap(
                    columns,
                    width,
                    initial_indent="  ",
                    subsequent_indent="  ",
                    break_on_hyphens=False,
                )
            ]
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)
