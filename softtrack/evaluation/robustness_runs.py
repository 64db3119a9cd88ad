"""Run robustness evaluations of stored runs, in this process or on the local and SLURM executors.

:func:`run_robustness` evaluates every (run, setting) cell not yet in the runs' tables
(:func:`~softtrack.evaluation.perturbations.done_settings`; ``redo`` evaluates them again):

* ``executor="local"`` with one worker: in this process, each run's policy loaded once; the
  rows of every setting are stored as soon as it is done, so an interrupted evaluation loses at
  most one setting and continues where it stopped when started again;
* ``executor="local"`` with N workers, or ``executor="slurm"``: one worker process (or array
  task) per cell, ``python -m softtrack.workers robustness RUN_DIR --level f=v ...``,
  each writing its rows to a part file of the run; this process merges them into the tables
  once the workers ended (and any later ``softtrack robustness`` merges parts left behind,
  e.g. after ``--detach``). Worker output is appended to ``<run>/robustness.log``.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from softtrack.evaluation.episodes import Policy
from softtrack.evaluation.perturbations import (
    Setting,
    copy_nominal,
    done_settings,
    evaluate_setting,
    merge_parts,
    part_path,
    perturbed_spec,
    store_rows,
)
from softtrack.executors.dispatch import ExecOptions, slurm_options
from softtrack.executors.local import LocalPool
from softtrack.spec import ClusterSpec, ExperimentSpec
from softtrack.store.runs import RunRecord, RunStore

__all__ = ["RobustnessJob", "RobustnessOutcome", "run_robustness"]


@dataclass(frozen=True)
class RobustnessJob:
    """One (run, setting) cell as a worker process (:class:`~softtrack.executors.base.PoolJob`)."""

    run_dir: str
    setting: Setting
    trajectories: tuple[str, ...]
    episodes: int
    keep_realism: bool

    @property
    def key(self) -> str:
        return f"{Path(self.run_dir).name} {self.setting.key}"

    @property
    def command(self) -> list[str]:
        cmd = [
            sys.executable,
            "-m",
            "softtrack.workers",
            "robustness",
            self.run_dir,
            "--trajectories",
            ",".join(self.trajectories),
            "--episodes",
            str(self.episodes),
        ]
        for factor, value in self.setting.levels:
            cmd += ["--level", f"{factor}={value}"]
        return cmd + (["--keep-realism"] if self.keep_realism else [])

    def log_path(self) -> Path:
        """``<run>/robustness.log`` (appended)."""
        return Path(self.run_dir) / "robustness.log"

    def after_exit(self, returncode: int) -> None:
        """Nothing: the parent merges the part files of the workers that finished."""


@dataclass
class RobustnessOutcome:
    """What a robustness evaluation did.

    Attributes:
        rows: the rows evaluated in this process (empty when workers did the work).
        cells: (run id, setting key) of every cell evaluated now.
        skipped: cells already in the tables.
        failed: cells whose worker failed (see ``<run>/robustness.log``).
        detached: the workers were left running (their parts merge on the next call).
        copied: cells whose setting equals the nominal one for that run (e.g.
            ``action_delay=0`` of a run without delay): the nominal rows stored under their
            key, no episode run again.
    """

    rows: pd.DataFrame = field(default_factory=pd.DataFrame)
    cells: list[tuple[str, str]] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)
    detached: bool = False
    copied: list[tuple[str, str]] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        return 1 if self.failed else 0


def run_robustness(
    records: Sequence[RunRecord],
    settings: Sequence[Setting],
    trajectories: Sequence[str],
    episodes: int = 1,
    *,
    keep_realism: bool = False,
    redo: bool = False,
    options: ExecOptions | None = None,
    on_cell: Callable[[RunRecord, Setting, pd.DataFrame], None] | None = None,
    on_progress: Callable[[str], None] | None = None,
    load: Callable[[RunRecord, ExperimentSpec], Policy],
    require: Callable[[RunRecord, ExperimentSpec], object],
) -> RobustnessOutcome:
    """Evaluate ``settings`` for every run (module docstring); every setting is validated
    against every run's spec before any episode runs (a SpecError names the bad one).

    Args:
        on_cell: called with (run, setting, its rows) after each cell evaluated in-process.
        on_progress: called with a progress line while workers run.
        load: the run's deterministic policy (``softtrack.rl.policy.load_policy``).
        require: raises if the run has no model to evaluate (``rl.policy.require_model``).
    """
    options = options or ExecOptions()
    specs = {}
    as_nominal: dict[str, list[Setting]] = {}  # run id → settings equal to its nominal one
    for record in records:
        merge_parts(record)
        specs[record.run_id] = spec = record.load_spec()
        require(record, spec)
        nominal = perturbed_spec(spec, Setting(()), keep_realism)
        for setting in settings:
            if perturbed_spec(spec, setting, keep_realism) == nominal and setting.levels:
                as_nominal.setdefault(record.run_id, []).append(setting)
    outcome = RobustnessOutcome()
    todo: list[tuple[RunRecord, Setting]] = []
    for record in records:
        done = set() if redo else done_settings(record, trajectories, episodes, keep_realism)
        copied = as_nominal.get(record.run_id, [])
        for setting in settings:
            cell = (record.run_id, setting.key)
            if setting.key in done:
                outcome.skipped.append(cell)
            elif setting not in copied:
                todo.append((record, setting))
    try:
        _evaluate(
            todo,
            specs,
            trajectories,
            episodes,
            keep_realism,
            options,
            outcome,
            on_cell,
            on_progress,
            load,
            records,
        )
    finally:
        for record in records:
            for setting in as_nominal.get(record.run_id, []):
                if (record.run_id, setting.key) in outcome.skipped:
                    continue
                if copy_nominal(record, setting, trajectories, keep_realism):
                    outcome.copied.append((record.run_id, setting.key))
    return outcome


def _evaluate(
    todo: list[tuple[RunRecord, Setting]],
    specs: dict[str, ExperimentSpec],
    trajectories: Sequence[str],
    episodes: int,
    keep_realism: bool,
    options: ExecOptions,
    outcome: RobustnessOutcome,
    on_cell: Callable[[RunRecord, Setting, pd.DataFrame], None] | None,
    on_progress: Callable[[str], None] | None,
    load: Callable[[RunRecord, ExperimentSpec], Policy],
    records: Sequence[RunRecord],
) -> None:
    """Evaluate the ``todo`` cells in this process or on workers (:func:`run_robustness`)."""
    in_process = options.executor == "local" and (options.workers or 1) == 1 and not options.detach
    if in_process:
        frames = []
        policies = {}
        for record, setting in todo:
            if record.run_id not in policies:
                policies[record.run_id] = load(record, specs[record.run_id])
            rows = evaluate_setting(
                record.run_id,
                policies[record.run_id],
                specs[record.run_id],
                setting,
                trajectories,
                episodes,
                keep_realism=keep_realism,
            )
            store_rows(record, rows)
            frames.append(rows)
            outcome.cells.append((record.run_id, setting.key))
            if on_cell is not None:
                on_cell(record, setting, rows)
        outcome.rows = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
        return
    jobs = [
        RobustnessJob(str(record.path), setting, tuple(trajectories), episodes, keep_realism)
        for record, setting in todo
    ]
    cluster = specs[records[0].run_id].cluster if records else ClusterSpec()
    parts = [
        part_path(record, setting, trajectories, episodes, keep_realism) for record, setting in todo
    ]
    _run_jobs(jobs, parts, records, options, outcome, on_progress, cluster)
    if outcome.detached:
        return
    for (record, setting), part in zip(todo, parts, strict=True):
        (outcome.cells if part.is_file() else outcome.failed).append((record.run_id, setting.key))
    for record in records:
        merge_parts(record)


def _run_jobs(
    jobs: Sequence[RobustnessJob],
    parts: Sequence[Path],
    records: Sequence[RunRecord],
    options: ExecOptions,
    outcome: RobustnessOutcome,
    on_progress: Callable[[str], None] | None,
    cluster: ClusterSpec,
) -> None:
    """Run the workers on ``options.executor`` (until they end unless detached); SLURM
    resources from the options, else ``cluster`` (the first run's spec)."""
    if not jobs:
        return

    def tick() -> None:
        if on_progress is not None:
            done = sum(part.is_file() for part in parts)
            on_progress(f"robustness: {done} of {len(jobs)} cells done")

    if options.executor == "local":
        LocalPool(options.workers).run(jobs, on_tick=tick, tick_s=10.0)
        return

    store = RunStore(Path(records[0].path).parent)
    slurm = slurm_options(options, cluster, store)
    from softtrack.executors.slurm import submit_commands  # submitit: for --executor slurm

    submitted = submit_commands(
        [(j.command, str(j.log_path())) for j in jobs], slurm, name="softtrack-robustness"
    )
    if options.detach:
        outcome.detached = True
        return
    while not all(j.done() for j in submitted):
        tick()
        time.sleep(10.0)
