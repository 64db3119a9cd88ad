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

import dataclasses
import json
import os
import re
import signal
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any, Self

import duckdb

from softtrack.signals import StoppedBySignal
from softtrack.store.catalog import read_catalog
from softtrack.store.catalog_format import file_stamp
from softtrack.store.errors import RunStoreError
from softtrack.store.location import resolve_runs_dir
from softtrack.store.query_output import (
    OUTPUT_FORMATS,
    ViewInfo,
    format_result,
    format_views,
    write_cursor,
)
from softtrack.store.query_snapshot import QuerySnapshot
from softtrack.store.signal_interrupt import interrupt_on_signals
from softtrack.store.table_cache import (
    FILE_COLUMN,
    MAP_FILE,
    MAP_RUN_ID,
    MAP_STAMP,
    CachedTable,
    TableFile,
    create_file_map,
)
from softtrack.store.table_index import table_item

if TYPE_CHECKING:
    import pandas as pd

    from softtrack.store.catalog import CatalogSnapshot

__all__ = [
    "OUTPUT_FORMATS",
    "RUNS_COLUMNS",
    "TABLE_DESCRIPTIONS",
    "QueryError",
    "ResultsDatabase",
    "ViewInfo",
    "available_views",
    "check_read_only",
    "connect",
    "format_result",
    "format_views",
    "query",
    "write_cursor",
]

#: Columns of the ``runs`` view: name, DuckDB type and meaning. Times are UTC (TIMESTAMP
#: without time zone).
RUNS_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("run_id", "VARCHAR", "ULID of the run (run.json run_id); every table view's run_id"),
    ("dir", "VARCHAR", "the run's directory name inside the runs directory"),
    ("name", "VARCHAR", "experiment name (spec name): group the seeds of an experiment by it"),
    ("algo", "VARCHAR", "algorithm (spec algo.name)"),
    ("controller", "VARCHAR", "centralized or independent"),
    ("seed", "BIGINT", "random seed of the run"),
    (
        "status",
        "VARCHAR",
        (
            "run.json status: queued, running, completed, failed, interrupted "
            "(`softtrack runs` also shows a running run whose process is gone "
            "as lost)"
        ),
    ),
    ("total_timesteps", "BIGINT", "training budget, env steps (independent: both arms)"),
    ("arm_total_timesteps", "BIGINT", "independent runs: budget per arm, env steps"),
    ("global_step", "BIGINT", "env steps done (independent: over both arms)"),
    (
        "steps_per_second",
        "DOUBLE",
        (
            "training throughput, env steps/s: global_step / "
            "train_seconds, as in the report's runs table"
        ),
    ),
    (
        "train_seconds",
        "DOUBLE",
        (
            "training wall time, s: the run's training clock at its "
            "last logged episode (train_episodes.wall_time), as in the "
            "report; NULL before the first episode"
        ),
    ),
    (
        "final_stage_fraction",
        "DOUBLE",
        (
            "spec training.final_stage_fraction (default 0.1): "
            "the final-stage return averages the episodes after "
            "(1 - it) x the budget"
        ),
    ),
    ("spec_hash", "VARCHAR", "spec hash without the seed: the runs of an experiment share it"),
    ("git_commit", "VARCHAR", "commit of the code when the run was created"),
    ("git_dirty", "BOOLEAN", "the checkout had uncommitted changes"),
    ("created", "TIMESTAMP", "creation time (UTC)"),
    ("started", "TIMESTAMP", "time training first started (UTC)"),
    ("ended", "TIMESTAMP", "time the run ended (UTC)"),
    ("host", "VARCHAR", "host of the (last) training process"),
    ("cpu", "VARCHAR", "CPU of the (last) training process"),
    ("sweep", "VARCHAR", "id of the sweep that created the run, if any"),
    ("error", "VARCHAR", "one-line error of a failed run"),
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
class _TableFile:
    path: str
    run_id: str
    schema: str
    stamp: str


@dataclass
class _TableFiles:
    """Every file of one table across the runs, as the catalog lists them; checked against
    the files (:meth:`resolve`) only when a query names the table."""

    name: str
    #: (run directory, run id, catalog item: [table, path, schema id, error, file stamp])
    items: list[tuple[str, str, list[Any]]] = field(default_factory=list)
    #: every readable file of the table (after :meth:`resolve`)
    files: list[_TableFile] = field(default_factory=list)
    #: why a file is not readable Parquet (the first such file), else ``None``
    error: str | None = None
    resolved: bool = False

    @property
    def view(self) -> str:
        return f"{self.name}_table" if self.name in _RESERVED else self.name

    @property
    def runs(self) -> int:
        return len({f.run_id for f in self.files})

    def resolve(self, schemas: dict[str, str]) -> None:
        """The files and their schemas, each file stat-ed: one changed since the catalog
        read it (rewritten in place) has its schema read again."""
        if self.resolved:
            return
        for run_path, run_id, item in self.items:
            name, rel, schema, error, stamp = (*item, None)[:5]
            path = f"{run_path}{os.sep}{rel}"
            if stamp is None or file_stamp(path) != stamp:
                name, rel, schema, error, stamp = table_item(
                    name, Path(path), Path(run_path), schemas
                )
            if error is not None or schema is None:
                self.error = self.error or (
                    f"{path} (run {run_id}) is not readable Parquet ({error})"
                )
                continue
            self.files.append(_TableFile(path, run_id, schema, stamp))
        self.resolved = True


def _lit(text: str) -> str:
    """A SQL string literal."""
    return "'" + text.replace("'", "''") + "'"


def _ident(name: str) -> str:
    """A SQL identifier (quoted)."""
    return '"' + name.replace('"', '""') + '"'


def _utc_sql(column: str) -> str:
    """An ISO-8601 text column as a UTC TIMESTAMP (its offset applied; NULL if unparsable)."""
    offset = (
        f"CASE WHEN regexp_matches({column}, '[+-][0-9][0-9]:[0-9][0-9]$') THEN "
        f"(CASE WHEN substr({column}, -6, 1) = '+' THEN 1 ELSE -1 END) * "
        f"(TRY_CAST(substr({column}, -5, 2) AS INTEGER) * 60 "
        f"+ TRY_CAST(substr({column}, -2, 2) AS INTEGER)) ELSE 0 END"
    )
    return f"TRY_CAST({column} AS TIMESTAMP) - to_minutes(CAST({offset} AS BIGINT))"


#: The ``runs`` view from the catalog's columns (softtrack.store.catalog_format.ROW_COLUMNS).
_RUNS_SQL = f"""
CREATE VIEW runs AS
SELECT run_id, dir, name, algo, controller, seed, status, total_timesteps,
       arm_total_timesteps, global_step,
       CASE WHEN global_step > 0 AND train_seconds > 0 THEN global_step / train_seconds
            ELSE steps_per_second END AS steps_per_second,
       train_seconds, final_stage_fraction, spec_hash, git_commit, git_dirty,
       {_utc_sql("created")} AS created, {_utc_sql("started")} AS started,
       {_utc_sql("ended")} AS ended, host, cpu, sweep, error
FROM __softtrack_catalog
WHERE unreadable IS NULL
ORDER BY dir
"""


def _first_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split("\n")[0].split())
    return text or type(exc).__name__


#: Statement types :meth:`ResultsDatabase.query` runs (DESCRIBE, SHOW, SUMMARIZE and VALUES
#: parse as SELECT).
_READ_STATEMENTS = frozenset({"SELECT", "EXPLAIN"})


def _interrupted(exc: BaseException) -> bool:
    """DuckDB's error for a query stopped by ``interrupt()`` or by a signal's handler (which
    loses the handler's ``SystemExit`` or ``KeyboardInterrupt``)."""
    return isinstance(exc, duckdb.InterruptException) or str(exc) == "Query interrupted"


def check_read_only(sql: str) -> None:
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

    The runs come from the runs directory's catalog (:mod:`softtrack.store.catalog`), so
    opening it reads no run directory that has not changed; a table's view is created when a
    query first names it, and DuckDB reads that table's files itself.

    Args:
        runs_dir: the runs directory (``None``: ``$SOFTTRACK_RUNS_DIR``, else ``runs/``).
        progress: called as ``progress(done, total)`` while the catalog reads runs from their
            directories (a new or out-of-date catalog).

    Raises:
        QueryError: the directory does not exist or holds no runs.
    """

    def __init__(
        self,
        runs_dir: str | os.PathLike[str] | None = None,
        *,
        progress: Callable[[int, int], None] | None = None,
        pin_files: bool = True,
    ) -> None:
        root = resolve_runs_dir(runs_dir)
        self.root = root
        if not root.is_dir():
            what = "is not a directory" if root.exists() else "does not exist"
            raise QueryError(
                f"query: runs directory {root} {what}; pass --runs-dir DIR or set "
                "SOFTTRACK_RUNS_DIR (the shipped runs: --runs-dir models)"
            )
        snapshot = read_catalog(root, progress=progress)
        #: lines about the catalog itself (built, rebuilt, not writable)
        self.notices = snapshot.notices
        #: runs left out because their run.json is missing or unreadable: (directory, reason)
        self.unreadable = [(root / d, reason) for d, reason in snapshot.unreadable()]
        self.n_runs = snapshot.n_rows - len(self.unreadable)
        if not self.n_runs:
            raise QueryError(
                f"query: {root} holds no runs (no sub-directory with a readable run.json); "
                "pass the directory your runs are in with --runs-dir (the shipped runs: "
                "--runs-dir models)"
            )
        self._schemas = snapshot.schemas
        self._table_names = snapshot.table_names
        self._root_resolved = root.resolve()
        self._parsed: dict[str, _TableFiles] | None = None
        self._catalog = snapshot
        self._views: dict[str, ViewInfo] = {}
        self._locked = False
        self._snapshot = QuerySnapshot(root) if pin_files else None
        try:
            self.connection = self._open()
        except BaseException:
            self._close_snapshot()
            raise

    # ---- setup -------------------------------------------------------------------------
    def _open(self) -> duckdb.DuckDBPyConnection:
        """A new connection with the ``runs`` and ``experiments`` views, not yet locked."""
        self._views = {}
        self._allowed: set[str] = set()
        self._locked = False
        self.connection = duckdb.connect(":memory:")
        try:
            self.connection.execute("SET enable_progress_bar = false")
            self._create_runs_views(self._catalog)
        except BaseException:
            self.connection.close()
            raise
        return self.connection

    def _prepare(self, tables: list[_TableFiles]) -> None:
        """The views of ``tables`` exist and the connection is sandboxed to their files. The
        sandbox is set once a connection's views are known (DuckDB locks it then): a later
        query that names another table gets a new connection with every view so far."""
        wanted = [t for t in tables if t.view not in self._views]
        if self._locked and not wanted:
            return
        if self._locked:
            earlier = [t for t in (self._parsed or {}).values() if t.view in self._views]
            self.connection.close()
            self._open()
            wanted = earlier + wanted
        for table in wanted:
            self._create_table_view(table)
        self._sandbox(sorted(self._allowed))

    def _create_runs_views(self, catalog: CatalogSnapshot) -> None:
        con = self.connection
        if catalog.file is not None:  # the rows are still in the catalog file: DuckDB reads it
            path = self._pin(str(catalog.file.resolve()))
            con.execute(f"CREATE VIEW __softtrack_catalog AS FROM read_parquet({_lit(path)})")
            self._allowed.add(path)
        else:
            con.register("__softtrack_catalog", catalog.table)
        con.execute(_RUNS_SQL)  # a view over the catalog kept registered: computed when read
        con.execute(_EXPERIMENTS_SQL)
        self._add_view(
            "runs",
            "one row per run: run.json fields, dir, train_seconds, final_stage_fraction",
            self.n_runs,
        )
        self._add_view(
            "experiments",
            "one row per experiment name (runs.name): runs, "
            "completed, seeds, algo, controller, specs",
            self.n_runs,
        )

    def _create_table_view(self, table: _TableFiles) -> None:
        """The view of one table (or, where a file is unreadable, its reason)."""
        if table.view in self._views:
            return
        table.resolve(self._schemas)
        description = TABLE_DESCRIPTIONS.get(table.name, f"the runs' tables/{table.name}.parquet")
        if table.error is not None:
            self._views[table.view] = ViewInfo(table.view, description, (), table.runs, table.error)
            return
        files_table = f"__softtrack_files_{len(self._views)}"
        files = [TableFile(f.path, f.stamp, f.schema, f.run_id) for f in table.files]
        cache = CachedTable(self._root_resolved, table.name, files)
        cache.read_path = Path(self._pin(str(cache.path)))
        fresh, stale = cache.split(self.connection)
        if stale and cache.refresh(fresh, stale):
            cache.read_path = Path(self._pin(str(cache.path), again=True))
            fresh, stale = cache.split(self.connection)
        stale = [dataclasses.replace(f, path=self._pin(f.path)) for f in stale]
        create_file_map(self.connection, _ident(files_table), [*fresh, *stale])
        self._allowed.update(f.path for f in stale)
        if fresh:
            self._allowed.add(str(cache.read_path))
        source = cache.source_sql(fresh, stale, _ident(files_table))
        try:
            self.connection.execute(
                f"CREATE VIEW {_ident(table.view)} AS {_view_sql(source, _ident(files_table))}"
            )
        except duckdb.Error as exc:
            self._views[table.view] = ViewInfo(
                table.view,
                description,
                (),
                table.runs,
                f"tables/{table.name}.parquet of {table.runs} runs cannot be read as one table "
                f"({self._original(_first_line(exc))})",
            )
            return
        self._add_view(table.view, description, table.runs)

    @property
    def _tables(self) -> dict[str, _TableFiles]:
        """Every table's files, parsed from the catalog's cells at the first need (a query
        over ``runs`` alone parses none)."""
        if self._parsed is None:
            cells = self._catalog.columns(["dir", "run_id", "tables", "unreadable"])
            self._parsed = _table_files(self._root_resolved, cells)
        return self._parsed

    def _named_in(self, sql: str) -> list[_TableFiles]:
        """The tables that ``sql`` names (any word equal to a view's name)."""
        words = {word.lower() for word in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", sql)}
        views = {(f"{n}_table" if n in _RESERVED else n).lower() for n in self._table_names}
        if not words & views:
            return []
        return [t for t in self._tables.values() if t.view.lower() in words]

    def _sandbox(self, files: list[str]) -> None:
        """No file access but reading the views' Parquet files, no extensions, locked
        settings."""
        con = self.connection
        if files:
            con.execute("SET allowed_paths = ?", [sorted(files)])
        for setting in (
            "enable_external_access",
            "autoinstall_known_extensions",
            "autoload_known_extensions",
            "allow_community_extensions",
        ):
            con.execute(f"SET {setting} = false")
        con.execute("SET lock_configuration = true")
        self._locked = True

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
        self._prepare(sorted(self._tables.values(), key=lambda t: t.name))
        fixed = [self._views[name] for name in _RESERVED]
        tables = sorted((v for k, v in self._views.items() if k not in _RESERVED), key=_by_name)
        return fixed + tables

    def table_names(self) -> list[str]:
        """The names of the table views some run has files for (readable or not)."""
        return sorted(f"{n}_table" if n in _RESERVED else n for n in self._table_names)

    def execute(self, sql: str) -> duckdb.DuckDBPyConnection:
        """Run ``sql`` (DuckDB's dialect; several statements: the last one's result) and
        return the cursor to fetch the result from (``description`` None: no result).

        Raises:
            QueryError: bad SQL, an unknown view or column, an unreadable file.
        """
        if not sql.strip():
            raise QueryError('query: no SQL given; e.g. `softtrack query "SELECT * FROM runs"`')
        try:
            check_read_only(sql)
            self._prepare(self._named_in(sql))
            stopped = False
            with interrupt_on_signals(self.connection.interrupt) as signals:
                try:
                    return self.connection.execute(sql)
                except (duckdb.Error, RuntimeError) as exc:
                    stopped = _interrupted(exc)
                    if not (stopped or signals):
                        raise
            # the relay has now read every signal that arrived
            raise StoppedBySignal(signals[0] if signals else signal.SIGINT) from None
        except duckdb.Error as exc:
            raise QueryError(self._explain(exc)) from None

    def query(self, sql: str) -> pd.DataFrame:
        """Run ``sql`` (:meth:`execute`) and return the result as a DataFrame (an empty one
        for a statement without a result).

        Raises:
            QueryError: bad SQL, an unknown view or column, an unreadable file.
        """
        import pandas as pd  # only here: `softtrack query` prints without it

        cursor = self.execute(sql)
        try:
            return pd.DataFrame() if cursor.description is None else cursor.df()
        except duckdb.Error as exc:
            raise QueryError(self._explain(exc)) from None

    def explain(self, exc: duckdb.Error) -> str:
        """A one-line message for a DuckDB error raised while fetching a result."""
        return self._explain(exc)

    def _explain(self, exc: duckdb.Error) -> str:
        """A one-line message for a DuckDB error, with what to do."""
        lines = [line.strip() for line in self._original(str(exc)).splitlines() if line.strip()]
        first = lines[0] if lines else type(exc).__name__
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
            available = ", ".join(
                [*_RESERVED, *sorted(t.view for t in self._tables.values() if t.error is None)]
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

    def _pin(self, path: str, *, again: bool = False) -> str:
        """The path to read ``path`` from in this query (:mod:`~softtrack.store.query_snapshot`)."""
        return path if self._snapshot is None else self._snapshot.pin(path, again=again)

    def _original(self, message: str) -> str:
        return message if self._snapshot is None else self._snapshot.original(message)

    def _close_snapshot(self) -> None:
        if self._snapshot is not None:
            self._snapshot.close()

    def close(self) -> None:
        self.connection.close()
        self._close_snapshot()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _by_name(view: ViewInfo) -> str:
    return view.name


def _table_files(root: Path, columns: dict[str, list[Any]]) -> dict[str, _TableFiles]:
    """Every table's files from the catalog's ``tables`` cells, unchecked."""
    tables: dict[str, _TableFiles] = {}
    for directory, run_id, cell, bad in zip(
        columns["dir"], columns["run_id"], columns["tables"], columns["unreadable"], strict=True
    ):
        if bad is not None or not cell:
            continue
        run_path = f"{root}{os.sep}{directory}"
        for item in json.loads(cell):
            tables.setdefault(item[0], _TableFiles(item[0])).items.append((run_path, run_id, item))
    return tables


def _view_sql(source: str, files_table: str) -> str:
    """The view of a table's rows (``source``, with the file of each row) whose ``run_id`` is
    each file's run's id (``files_table``: a :func:`~softtrack.store.table_cache.create_file_map` table),
    first, then the table's own columns."""
    hidden = ", ".join(_lit(c) for c in ("run_id", FILE_COLUMN, MAP_FILE, MAP_STAMP, MAP_RUN_ID))
    return (
        f"SELECT m.{MAP_RUN_ID} AS run_id, COLUMNS(lambda c: c NOT IN ({hidden})) "
        f"FROM ({source}) AS t JOIN {files_table} AS m ON t.{FILE_COLUMN} = m.{MAP_FILE}"
    )


def connect(runs_dir: str | os.PathLike[str] | None = None) -> duckdb.DuckDBPyConnection:
    """An in-memory DuckDB connection with every view over ``runs_dir`` (module docstring).

    Its file access is limited to reading (and, a raw connection being unfiltered, writing)
    inside the runs directory; use :func:`query` or :class:`ResultsDatabase` for SQL you do
    not control: they refuse every statement but a read.

    Raises:
        QueryError: the directory does not exist or holds no runs.
    """
    db = ResultsDatabase(runs_dir, pin_files=False)  # nothing would remove the pins
    db.views()
    return db.connection


def query(sql: str, runs_dir: str | os.PathLike[str] | None = None) -> pd.DataFrame:
    """Run ``sql`` over the runs of ``runs_dir`` and return the result as a DataFrame.

    Example::

        query("SELECT name, avg(rmse_3d) FROM eval_metrics JOIN runs USING (run_id) "
              "GROUP BY name", "models")

    Raises:
        QueryError: no runs directory or runs, bad SQL, an unknown view or column, an
            unreadable file (a one-line message).
    """
    check_read_only(sql)  # before the catalog is even read: a refused query touches nothing
    with ResultsDatabase(runs_dir) as db:
        return db.query(sql)


def available_views(runs_dir: str | os.PathLike[str] | None = None) -> list[ViewInfo]:
    """The views over ``runs_dir`` with their columns (see :meth:`ResultsDatabase.views`)."""
    with ResultsDatabase(runs_dir) as db:
        return db.views()
