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
                          eval_*.parquet (softtrack.evaluation.run_evaluation)

Every file is written atomically (temporary file in the same directory + fsync + rename), so
a process killed at any point leaves each file either complete or absent.

Reading runs back: :class:`RunInfo` (``run.json``; :attr:`RunInfo.policy_budget` is one
policy's budget), :mod:`softtrack.store.status` (effective status, and the final-stage return,
whose one implementation the report uses too) and :mod:`softtrack.store.query` (SQL over every
run's tables), answered from the runs directory's catalog (:mod:`softtrack.store.catalog`).

The names below are imported on first use, so a light module of the store (the catalog,
:mod:`softtrack.store.liveness`) loads without the spec models.
"""

from __future__ import annotations

from softtrack.lazy import lazy_exports

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

_HOME = {
    "atomic_dir": "softtrack.store.atomic",
    "atomic_path": "softtrack.store.atomic",
    "atomic_write_bytes": "softtrack.store.atomic",
    "atomic_write_json": "softtrack.store.atomic",
    "atomic_write_text": "softtrack.store.atomic",
    "is_temp_file": "softtrack.store.atomic",
    "remove_temp_files": "softtrack.store.atomic",
    "create_unique_dir": "softtrack.store.ids",
    "id_timestamp": "softtrack.store.ids",
    "is_valid_id": "softtrack.store.ids",
    "new_id": "softtrack.store.ids",
    "PolicyDir": "softtrack.store.layout",
    "RUN_STATUSES": "softtrack.store.runs",
    "RunInfo": "softtrack.store.runs",
    "RunNotFoundError": "softtrack.store.runs",
    "RunRecord": "softtrack.store.runs",
    "RunStore": "softtrack.store.runs",
    "RunStoreError": "softtrack.store.runs",
    "resolve_runs_dir": "softtrack.store.runs",
    "TableError": "softtrack.store.tables",
    "TableNotFoundError": "softtrack.store.tables",
    "append_rows": "softtrack.store.tables",
    "list_tables": "softtrack.store.tables",
    "read_table": "softtrack.store.tables",
    "write_table": "softtrack.store.tables",
}

__getattr__, __dir__ = lazy_exports(__name__, _HOME, __all__)
