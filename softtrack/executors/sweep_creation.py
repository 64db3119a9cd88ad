"""Creating a sweep's runs: progress on a large grid, and a stop that keeps what was made.

A sweep writes one queued run per grid point and seed before any of them starts; 20,000 seeds
take minutes. :func:`create_sweep_runs` reports how far it got about once a second, and a
Ctrl-C or SIGTERM meanwhile stops it between two runs: every run made so far is queued with the
sweep's id (``softtrack resume SWEEP_ID`` runs them) and :class:`SweepStopped` says how many of
the grid were not made.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from softtrack.signals import StopFlag, stop_on_signals
from softtrack.store.runs import RunRecord, RunStore

__all__ = ["PROGRESS_INTERVAL_S", "SweepStopped", "create_sweep_runs"]

#: Seconds between two progress calls while runs are made.
PROGRESS_INTERVAL_S = 1.0


class SweepStopped(Exception):
    """A stop signal arrived while a sweep's runs were being made.

    Attributes:
        sweep_id: the sweep.
        created: the runs made (queued, with the sweep's id).
        total: the runs of the whole grid.
    """

    def __init__(self, sweep_id: str, created: int, total: int) -> None:
        self.sweep_id, self.created, self.total = sweep_id, created, total
        super().__init__(
            f"sweep {sweep_id}: stopped while making its runs: {created:,} of {total:,} made "
            f"and queued (`softtrack resume {sweep_id}` runs them); the other "
            f"{total - created:,} were not made (run the sweep with the seeds or grid points "
            "left for them)"
        )


def create_sweep_runs(
    store: RunStore,
    points: Sequence[Any],
    sweep_id: str,
    spec_files: Mapping[Any, Any],
    command: Sequence[str],
    on_progress: Callable[[str], None] | None = None,
) -> list[RunRecord]:
    """One queued run per grid point and seed, each noted with the sweep and its grid point.

    Args:
        points: :class:`~softtrack.executors.sweep.GridPoint` items (``spec``, ``path``, ``grid``).
        spec_files: each point's ``path`` → its spec file chain (stored with the run).
        command: the command line recorded in each run.
        on_progress: called with ``sweep ID: making runs: N/TOTAL`` about once a second.

    Raises:
        SweepStopped: SIGINT or SIGTERM arrived; the runs made so far stay queued.
    """
    jobs = [(point, seed) for point in points for seed in point.spec.seeds]
    records: list[RunRecord] = []
    last = time.monotonic()
    with stop_on_signals(StopFlag()) as stopped:
        for point, seed in jobs:
            if stopped():
                raise SweepStopped(sweep_id, len(records), len(jobs))
            notes = {"sweep": sweep_id, "grid": point.grid}
            records.append(
                store.create_run(
                    point.spec, seed, list(command), notes=notes, spec_files=spec_files[point.path]
                )
            )
            if on_progress is not None and time.monotonic() - last >= PROGRESS_INTERVAL_S:
                on_progress(f"sweep {sweep_id}: making runs: {len(records):,}/{len(jobs):,}")
                last = time.monotonic()
    return records
