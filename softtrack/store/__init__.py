"""The run store: run ids, atomic file writes, run directories and Parquet tables.

Layout of one run (``<runs dir>/<run id>/``)::

    spec.yaml             fully resolved spec of this run (seeds: [its seed])
    run.json              status, times, seed, spec hash, git commit, versions, command, progress,
                          CPU
    model.zip             the final model (written atomically by the trainer)
    checkpoints/          step-<global step>/ directories (model, replay buffer, normalisation)
    models/arm<k>/        independent runs: arm k's model.zip, vecnormalize.pkl, state.json
                          and checkpoints/ (instead of the three entries above)
    tables/*.parquet      e.g. train_episodes.parquet, appended as episodes finish; validation
                          and confirmation (softtrack.rl.validation, softtrack.rl.confirmation);
                          eval_*.parquet (softtrack.evaluation.runs)

Every file is written atomically (temporary file in the same directory + fsync + rename), so
a process killed at any point leaves each file either complete or absent.

Reading runs back: :class:`RunInfo` (``run.json``; :attr:`RunInfo.policy_budget` is one
policy's budget), :mod:`softtrack.store.status` (effective status, and the final-stage return,
whose one implementation the report uses too) and :mod:`softtrack.store.query` (SQL over every
run's tables).
"""

from softtrack.store.atomic import (
    atomic_dir,
    atomic_path,
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    is_temp_file,
    remove_temp_files,
)
from softtrack.store.ids import create_unique_dir, id_timestamp, is_valid_id, new_id
from softtrack.store.layout import PolicyDir
from softtrack.store.runs import (
    RUN_STATUSES,
    RunInfo,
    RunNotFoundError,
    RunRecord,
    RunStore,
    RunStoreError,
    resolve_runs_dir,
)
from softtrack.store.tables import (
    TableError,
    TableNotFoundError,
    append_rows,
    list_tables,
    read_table,
    write_table,
)

__all__ = [
    "RUN_STATUSES",
    "PolicyDir",
    "RunInfo",
    "RunNotFoundError",
    "RunRecord",
    "RunStore",
    "RunStoreError",
    "TableError",
    "TableNotFoundError",
    "append_rows",
    "atomic_dir",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "create_unique_dir",
    "id_timestamp",
    "is_temp_file",
    "is_valid_id",
    "list_tables",
    "new_id",
    "read_table",
    "remove_temp_files",
    "resolve_runs_dir",
    "write_table",
]
