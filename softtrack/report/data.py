"""Load the stored tables of the selected runs and group them.

Everything here reads only the run directories (``run.json``, ``spec.yaml`` and
``tables/*.parquet``), so a report can be rebuilt at any time. Runs are grouped by
(algorithm, controller, experiment, spec hash); a group's runs differ only in the seed.
:mod:`softtrack.report.curves` and :mod:`softtrack.report.group_summaries` aggregate the groups
across seeds.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from softtrack.evaluation.scores import VALIDATION_SCORED_COLUMNS, scored_targets
from softtrack.store.runs import RunRecord
from softtrack.store.status import (
    episodes_by_arm,
    eval_duration,
    final_stage_fraction,
    validation_score_setting,
)
from softtrack.store.tables import TableError, read_table
from softtrack.trajectories import EVAL_TRAJECTORIES

__all__ = [
    "AXIS_METRICS",
    "DIRECTIONS",
    "METRIC_COLUMNS",
    "RUN_TABLES",
    "Group",
    "RunData",
    "episode_peaks",
    "episode_rmse",
    "episodes_by_arm",
    "group_runs",
    "load_run",
    "load_runs",
    "representative_run",
    "trajectories_in",
]

AXIS_METRICS = ("rmse_x", "rmse_y", "rmse_z", "mae_x", "mae_y", "mae_z")
METRIC_COLUMNS = (*AXIS_METRICS, "mean_spatial_error", "rmse_3d", "max_error")
DIRECTIONS = ("normal", "binormal")  # eval_moments.direction 0, 1
_MOMENT_COLUMNS = (
    "run_id",
    "trajectory",
    "step",
    "t",
    "arm",
    "direction",
    "rms_moment",
    "max_abs_moment",  # only in tables written before eval_moment_peaks existed
)
_PEAK_COLUMNS = ("trajectory", "arm", "direction", "peak_abs_moment")
_RANDOM_COLUMNS = (
    "episode",
    "seed",
    "arm",
    "rmse_3d",
    "terminated",
    "cpu",
    "object_rmse_3d",
    "dropped",
    "drop_time",
)
_ROBUSTNESS_COLUMNS = (
    "perturbation",
    "level",
    "setting",
    "baseline",
    "episode",
    "trajectory",
    "arm",
    "rmse_3d",
    "terminated",
    "peak_moment",
    "action_saturation",
    "min_arm_distance",
    "collision_steps",
    "max_penetration",
    "contact_steps",
    "mean_contact_force",
)
_ALGO_ORDER = {"td3": 0, "ddpg": 1, "ppo": 2, "sac": 3, "tqc": 4, "crossq": 5}
_ALGO_LABELS = {"crossq": "CrossQ"}  # display names that are not the upper-cased algo name
_CONTROLLER_ORDER = {"centralized": 0, "independent": 1, "mpc": 2}


# ---- runs -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunData:
    """One run's identity and stored tables (``None`` where a table is absent or unreadable).

    Attributes:
        record: the run directory and its ``run.json``.
        final_stage_fraction: ``training.final_stage_fraction`` of its spec (default 0.1).
        eval_duration: ``training.eval_duration`` of its spec (s; ``None`` where absent), the
            validation episodes' planned length.
        scored_targets: the validation rows' ``trajectory`` values its score averages
            (``training.validation_score``).
        train: ``train_episodes`` (episode, global_step, return, …, optionally arm).
        trajectories: ``eval_trajectories`` (tip and target positions per step and arm, m).
        metrics: ``eval_metrics`` (one row per trajectory and arm, m; the action statistics
            columns are absent from tables written before they were added).
        moments: ``eval_moments`` without the per-element torques (N·m): per step, arm and
            direction the spatial RMS ``rms_moment`` (older tables also ``max_abs_moment``).
        peaks: the episode's peak absolute element torque per trajectory, arm and direction
            (columns trajectory, arm, direction, peak_abs_moment; N·m): from
            ``eval_moment_peaks`` where it has the trajectory, else the maximum over the steps
            of an older ``eval_moments``' ``max_abs_moment`` (see :func:`episode_peaks`).
        random: ``eval_random`` (one row per random-target episode and arm, m).
        validation: ``validation`` (one row per validated checkpoint, episode and arm, m).
        robustness: ``eval_robustness`` (one row per perturbation setting, trajectory,
            episode and arm; :mod:`softtrack.evaluation.perturbations`).
        snapshots: ``eval_snapshots`` (both arms' centreline nodes at a few instants, m).
        problems: one line per unreadable table.
    """

    record: RunRecord
    final_stage_fraction: float
    eval_duration: float | None
    scored_targets: tuple[str, ...]
    train: pd.DataFrame | None
    trajectories: pd.DataFrame | None
    metrics: pd.DataFrame | None
    moments: pd.DataFrame | None
    random: pd.DataFrame | None = None
    validation: pd.DataFrame | None = None
    peaks: pd.DataFrame | None = None
    robustness: pd.DataFrame | None = None
    snapshots: pd.DataFrame | None = None
    problems: tuple[str, ...] = ()

    @property
    def run_id(self) -> str:
        return self.record.run_id

    @property
    def seed(self) -> int:
        return self.record.info.seed

    @property
    def total_timesteps(self) -> int:
        return self.record.info.total_timesteps

    @property
    def arm_budget(self) -> int:
        """Training budget of one arm's policy in an independent run (env steps):
        :attr:`~softtrack.store.run_records.RunInfo.policy_budget`."""
        return self.record.info.policy_budget

    @property
    def last_step(self) -> int:
        """Env steps reached: the training table's (summed over arm policies) or run.json's
        ``global_step``, whichever is larger."""
        step = self.record.info.global_step
        if self.train is not None and not self.train.empty:
            parts = episodes_by_arm(self.train)
            step = max(step, sum(int(p["global_step"].max()) for p in parts.values() if len(p)))
        return int(step)

    def budget_text(self) -> str:
        """``2,000 env steps per run``, for an independent run ``2,000 env steps per arm``, for
        an MPC run ``no training (planner)``."""
        if self.record.info.controller == "mpc":
            return "no training (planner)"
        if self.record.info.controller == "independent":
            return f"{self.arm_budget:,} env steps per arm"
        return f"{self.total_timesteps:,} env steps per run"


def _read(
    record: RunRecord, name: str, problems: list[str], columns: Sequence[str] | None = None
) -> pd.DataFrame | None:
    path = record.table_path(name)
    if not path.exists():
        return None
    try:
        if columns is not None:  # read only the wanted columns that exist
            import pyarrow.parquet as pq

            present = set(pq.read_schema(path).names)
            columns = [c for c in columns if c in present]
        df = read_table(path, columns)
    except (TableError, OSError, ValueError) as exc:
        problems.append(f"run {record.run_id}: {name} unreadable ({str(exc).splitlines()[0]})")
        return None
    return df if not df.empty else None


def episode_peaks(
    moments: pd.DataFrame | None, element_peaks: pd.DataFrame | None
) -> pd.DataFrame | None:
    """Peak absolute element torque per trajectory, arm and direction over an episode (N·m).

    Reads both table formats: ``element_peaks`` (``eval_moment_peaks``: one row per
    trajectory, arm, direction and element) where it has the trajectory, else the per-step
    ``max_abs_moment`` of an older ``eval_moments``. Returns columns trajectory, arm,
    direction, peak_abs_moment, or ``None`` when neither table gives a peak.
    """
    parts = []
    covered: set[str] = set()
    if element_peaks is not None and set(_PEAK_COLUMNS) <= set(element_peaks.columns):
        value = pd.to_numeric(element_peaks["peak_abs_moment"], errors="coerce")
        keys = [
            element_peaks["trajectory"].astype(str),
            element_peaks["arm"],
            element_peaks["direction"],
        ]
        parts.append(value.groupby(keys).max())
        covered = set(element_peaks["trajectory"].astype(str))
    if moments is not None and "max_abs_moment" in moments:
        old = moments[~moments["trajectory"].astype(str).isin(covered)]
        if len(old):
            value = pd.to_numeric(old["max_abs_moment"], errors="coerce")
            parts.append(
                value.groupby([old["trajectory"].astype(str), old["arm"], old["direction"]]).max()
            )
    if not parts:
        return None
    peaks = pd.concat(parts).rename("peak_abs_moment").dropna()
    peaks.index.names = ["trajectory", "arm", "direction"]
    out = peaks.reset_index()
    out["arm"] = out["arm"].astype(int)
    out["direction"] = out["direction"].astype(int)
    return out if len(out) else None


#: :class:`RunData` fields read from tables, and the tables they are read from.
RUN_TABLES: dict[str, tuple[str, tuple[str, ...] | None]] = {
    "moments": ("eval_moments", _MOMENT_COLUMNS),
    "train": ("train_episodes", None),
    "trajectories": ("eval_trajectories", None),
    "metrics": ("eval_metrics", None),
    "random": ("eval_random", _RANDOM_COLUMNS),
    "validation": ("validation", VALIDATION_SCORED_COLUMNS),
    "robustness": ("eval_robustness", _ROBUSTNESS_COLUMNS),
    "snapshots": ("eval_snapshots", None),
}


def load_run(record: RunRecord, fields: Collection[str] | None = None) -> RunData:
    """Read a run's tables (missing ones are ``None``; unreadable ones are noted in problems);
    with ``fields`` (names of :data:`RUN_TABLES` and ``"peaks"``) only those, the others
    ``None`` (``softtrack compare`` reads one table of each run, not every table)."""
    wanted = set(RUN_TABLES) | {"peaks"} if fields is None else set(fields)
    problems: list[str] = []
    raw_spec = record.raw_spec()
    tables: dict[str, pd.DataFrame | None] = {}
    peaks = None
    for name, (table, columns) in RUN_TABLES.items():
        needed = name in wanted or (name == "moments" and "peaks" in wanted)
        tables[name] = _read(record, table, problems, columns) if needed else None
        if name == "moments" and "peaks" in wanted:
            element_peaks = _read(record, "eval_moment_peaks", problems, _PEAK_COLUMNS)
            peaks = episode_peaks(tables["moments"], element_peaks)
    if "moments" not in wanted:
        tables["moments"] = None
    return RunData(
        record=record,
        final_stage_fraction=final_stage_fraction(raw_spec),
        eval_duration=eval_duration(raw_spec),
        scored_targets=scored_targets(validation_score_setting(raw_spec)),
        peaks=peaks,
        problems=tuple(problems),
        **tables,
    )


def load_runs(records: Iterable[RunRecord], fields: Collection[str] | None = None) -> list[RunData]:
    """:func:`load_run` for each record, in order."""
    return [load_run(r, fields) for r in records]


# ---- groups ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Group:
    """Runs of one experiment configuration that differ only in the seed.

    Attributes:
        label: display name, e.g. ``TD3`` or ``TD3 (independent)`` (made unique in a report).
        slug: file-name-safe form of ``label``.
        runs: the runs, by seed.
    """

    algo: str
    controller: str
    name: str
    spec_hash: str
    label: str
    slug: str
    runs: tuple[RunData, ...] = field(default_factory=tuple)

    @property
    def seeds(self) -> list[int]:
        return [r.seed for r in self.runs]

    @property
    def budgets(self) -> list[str]:
        """The distinct training budgets of the runs, e.g. ``["2,000 env steps per run"]``."""
        return sorted({r.budget_text() for r in self.runs})


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "group"


def group_runs(runs: Sequence[RunData]) -> list[Group]:
    """Group runs by (algo, controller, experiment name, spec hash), ordered TD3, DDPG, PPO, SAC,
    TQC, CrossQ, centralized before independent. Labels are ``TD3`` / ``TD3 (independent)``
    (``CrossQ`` for crossq), with the experiment name (and spec hash) added where two groups
    would otherwise share a label."""
    buckets: dict[tuple[str, str, str, str], list[RunData]] = {}
    for run in runs:
        info = run.record.info
        buckets.setdefault((info.algo, info.controller, info.name, info.spec_hash), []).append(run)
    keys = sorted(
        buckets,
        key=lambda k: (_CONTROLLER_ORDER.get(k[1], 9), _ALGO_ORDER.get(k[0], 9), k[0], k[2], k[3]),
    )

    def base(key: tuple[str, str, str, str]) -> str:
        algo, controller = _ALGO_LABELS.get(key[0], key[0].upper()), key[1]
        if controller == "mpc":
            return f"MPC ({algo})"
        return algo if controller == "centralized" else f"{algo} ({controller})"

    labels = {k: base(k) for k in keys}
    for k in keys:
        if sum(base(o) == base(k) for o in keys) > 1:
            labels[k] = f"{base(k)} [{k[2]}]"
    for k in keys:
        if sum(labels[o] == labels[k] for o in keys) > 1:
            labels[k] = f"{base(k)} [{k[2]} {k[3][:8]}]"
    groups = []
    used: set[str] = set()
    for k in keys:
        slug = _slug(labels[k])
        while slug in used:
            slug += "-x"
        used.add(slug)
        members = tuple(sorted(buckets[k], key=lambda r: (r.seed, r.run_id)))
        groups.append(Group(k[0], k[1], k[2], k[3], labels[k], slug, members))
    return groups


def trajectories_in(groups: Sequence[Group]) -> list[str]:
    """The three evaluation trajectories, then any other trajectory found in the tables."""
    found: set[str] = set()
    for group in groups:
        for run in group.runs:
            for df in (run.trajectories, run.metrics, run.moments):
                if df is not None and "trajectory" in df:
                    found.update(str(t) for t in df["trajectory"].unique())
    return list(EVAL_TRAJECTORIES) + sorted(found - set(EVAL_TRAJECTORIES))


def representative_run(group: Group, trajectory: str) -> RunData | None:
    """The run whose ``trajectory`` episode has the median 3-D RMSE (mean over arms; the lower
    median for an even count) among all the group's runs with metrics for it, so that the
    choice does not depend on which runs keep their per-step tables (shipped runs keep them
    only where the report draws them). If that run has no stored trajectory, the run with one
    nearest to it in RMSE; without metrics, the first run with the trajectory. ``None`` if no
    run has this trajectory stored."""
    drawable = [
        r
        for r in group.runs
        if r.trajectories is not None and (r.trajectories["trajectory"] == trajectory).any()
    ]
    if not drawable:
        return None
    scored = sorted(
        (value, run.seed, id(run), run)
        for run in group.runs
        if np.isfinite(value := episode_rmse(run, trajectory))
    )
    if not scored:
        return drawable[0]
    median = scored[(len(scored) - 1) // 2]
    if any(run is median[3] for run in drawable):
        return median[3]
    return min(
        (r for r in drawable if np.isfinite(episode_rmse(r, trajectory))),
        key=lambda r: (abs(episode_rmse(r, trajectory) - median[0]), r.seed),
        default=drawable[0],
    )


def episode_rmse(run: RunData, trajectory: str) -> float:
    """The run's 3-D RMSE on ``trajectory``, the mean over its arms (m); NaN if not stored."""
    if run.metrics is None or "rmse_3d" not in run.metrics:
        return math.nan
    rows = run.metrics[run.metrics["trajectory"] == trajectory]
    return float(pd.to_numeric(rows["rmse_3d"], errors="coerce").mean())
