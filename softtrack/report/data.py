"""Load the stored tables of the selected runs and aggregate them across seeds.

Everything here reads only the run directories (``run.json``, ``spec.yaml`` and
``tables/*.parquet``), so a report can be rebuilt at any time. Runs are grouped by
(algorithm, controller, experiment, spec hash); a group's runs differ only in the seed.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from softtrack.evaluation import EVAL_TRAJECTORIES
from softtrack.metrics import ACTION_STATISTICS
from softtrack.store.runs import RunRecord
from softtrack.store.status import DEFAULT_FINAL_STAGE_FRACTION
from softtrack.store.tables import TableError, read_table

__all__ = [
    "AXIS_METRICS",
    "DIRECTIONS",
    "METRIC_COLUMNS",
    "Curve",
    "Group",
    "RunData",
    "Smoothing",
    "final_stage_table",
    "group_runs",
    "load_run",
    "load_runs",
    "metrics_summary",
    "moment_peaks",
    "representative_run",
    "run_final_stage_returns",
    "summary_row",
    "training_curves",
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
    "max_abs_moment",
)
_ALGO_ORDER = {"td3": 0, "ddpg": 1, "ppo": 2, "sac": 3}
_CONTROLLER_ORDER = {"centralized": 0, "independent": 1}


# ---- runs -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunData:
    """One run's identity and stored tables (``None`` where a table is absent or unreadable).

    Attributes:
        record: the run directory and its ``run.json``.
        final_stage_fraction: ``training.final_stage_fraction`` of its spec (default 0.1).
        train: ``train_episodes`` (episode, global_step, return, …, optionally arm).
        trajectories: ``eval_trajectories`` (tip and target positions per step and arm, m).
        metrics: ``eval_metrics`` (one row per trajectory and arm, m; the action statistics
            columns are absent from tables written before they were added).
        moments: ``eval_moments`` without the per-element torques (N·m).
        problems: one line per unreadable table.
    """

    record: RunRecord
    final_stage_fraction: float
    train: pd.DataFrame | None
    trajectories: pd.DataFrame | None
    metrics: pd.DataFrame | None
    moments: pd.DataFrame | None
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
        ``arm_total_timesteps`` of run.json, else the run's budget split over the arms."""
        info = self.record.info
        per_arm = getattr(info, "arm_total_timesteps", None)
        if isinstance(per_arm, int) and per_arm > 0:
            return per_arm
        return (
            info.total_timesteps // 2 if info.controller == "independent" else info.total_timesteps
        )

    @property
    def last_step(self) -> int:
        """Env steps reached: the training table's (summed over arm policies) or run.json's
        ``global_step``, whichever is larger."""
        step = self.record.info.global_step
        if self.train is not None and not self.train.empty:
            parts = _episodes_by_arm(self.train)
            step = max(step, sum(int(p["global_step"].max()) for p in parts.values() if len(p)))
        return int(step)

    def budget_text(self) -> str:
        """``2,000 env steps per run``, or for an independent run ``2,000 env steps per arm``."""
        if self.record.info.controller == "independent":
            return f"{self.arm_budget:,} env steps per arm"
        return f"{self.total_timesteps:,} env steps per run"


def _fraction(raw: dict[str, object]) -> float:
    training = raw.get("training")
    value = training.get("final_stage_fraction") if isinstance(training, dict) else None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and 0 < value <= 1:
        return float(value)
    return DEFAULT_FINAL_STAGE_FRACTION


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


def load_run(record: RunRecord) -> RunData:
    """Read a run's tables (missing ones are ``None``; unreadable ones are noted in problems)."""
    problems: list[str] = []
    return RunData(
        record=record,
        final_stage_fraction=_fraction(record.raw_spec()),
        train=_read(record, "train_episodes", problems),
        trajectories=_read(record, "eval_trajectories", problems),
        metrics=_read(record, "eval_metrics", problems),
        moments=_read(record, "eval_moments", problems, _MOMENT_COLUMNS),
        problems=tuple(problems),
    )


def load_runs(records: Iterable[RunRecord]) -> list[RunData]:
    """:func:`load_run` for each record, in order."""
    return [load_run(r) for r in records]


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
    centralized before independent. Labels are ``TD3`` / ``TD3 (independent)``, with the
    experiment name (and spec hash) added where two groups would otherwise share a label."""
    buckets: dict[tuple[str, str, str, str], list[RunData]] = {}
    for run in runs:
        info = run.record.info
        buckets.setdefault((info.algo, info.controller, info.name, info.spec_hash), []).append(run)
    keys = sorted(
        buckets,
        key=lambda k: (_CONTROLLER_ORDER.get(k[1], 9), _ALGO_ORDER.get(k[0], 9), k[0], k[2], k[3]),
    )

    def base(key: tuple[str, str, str, str]) -> str:
        algo, controller = key[0].upper(), key[1]
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


# ---- training curves ------------------------------------------------------------------------
@dataclass(frozen=True)
class Smoothing:
    """The smoothing applied to every training curve of a report.

    At each of ``n_points`` evenly spaced env steps g in (0, max step], a run's value is the
    mean return of its episodes that ended within the centred window (g − w/2, g + w/2].
    """

    window: float  # env steps
    n_points: int
    window_fraction: float

    def describe(self) -> str:
        return (
            f"each run's episode returns averaged over a centred window of {self.window:,.0f} "
            f"env steps ({self.window_fraction:.0%} of the longest run), at {self.n_points} "
            "points; the same window for every curve"
        )


@dataclass(frozen=True)
class Curve:
    """Smoothed training return of one group (and arm policy), mean and std across seeds.

    Attributes:
        steps: (n_points,) env steps.
        mean: (n_points,) mean over runs of the smoothed return (NaN where no run has data).
        std: (n_points,) sample std across runs (NaN where fewer than 2 runs have data).
        arm: the arm of an independent controller's policy (0/1), or ``None`` for one policy.
    """

    label: str
    group: Group
    arm: int | None
    steps: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    n_runs: int


def _episodes_by_arm(train: pd.DataFrame) -> dict[int | None, pd.DataFrame]:
    if "arm" not in train:
        return {None: train}
    arm = pd.to_numeric(train["arm"], errors="coerce").fillna(-1).astype(int)
    parts: dict[int | None, pd.DataFrame] = {}
    if (arm < 0).any():
        parts[None] = train[arm < 0]
    for a in sorted(set(arm[arm >= 0])):
        parts[int(a)] = train[arm == a]
    return parts


def _window_means(steps: np.ndarray, returns: np.ndarray, grid: np.ndarray, w: float) -> np.ndarray:
    order = np.argsort(steps, kind="stable")
    steps, returns = steps[order], returns[order]
    csum = np.concatenate([[0.0], np.cumsum(returns)])
    lo = np.searchsorted(steps, grid - w / 2, side="right")
    hi = np.searchsorted(steps, grid + w / 2, side="right")
    count = hi - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, (csum[hi] - csum[lo]) / np.maximum(count, 1), np.nan)


def training_curves(
    groups: Sequence[Group], n_points: int = 200, window_fraction: float = 0.05
) -> tuple[list[Curve], Smoothing]:
    """One curve per group (per arm policy for independent controllers), all smoothed alike."""
    max_step = 0
    for group in groups:
        for run in group.runs:
            if run.train is not None:
                max_step = max(max_step, int(run.train["global_step"].max()))
    window = max(1.0, window_fraction * max_step)
    smoothing = Smoothing(window, n_points, window_fraction)
    if max_step <= 0:
        return [], smoothing
    grid = np.linspace(0.0, float(max_step), n_points + 1)[1:]
    curves = []
    for group in groups:
        series: dict[int | None, list[np.ndarray]] = {}
        for run in group.runs:
            if run.train is None:
                continue
            for arm, part in _episodes_by_arm(run.train).items():
                ret = pd.to_numeric(part["return"], errors="coerce").to_numpy(float)
                step = pd.to_numeric(part["global_step"], errors="coerce").to_numpy(float)
                ok = np.isfinite(ret) & np.isfinite(step)
                if ok.any():
                    series.setdefault(arm, []).append(
                        _window_means(step[ok], ret[ok], grid, window)
                    )
        for arm in sorted(series, key=lambda a: -1 if a is None else a):
            stack = np.vstack(series[arm])
            with warnings.catch_warnings():  # all-NaN columns: 'mean of empty slice'
                warnings.simplefilter("ignore", RuntimeWarning)
                mean = np.nanmean(stack, axis=0)
                std = np.nanstd(stack, axis=0, ddof=1)
            std = np.where(np.sum(np.isfinite(stack), axis=0) >= 2, std, np.nan)
            label = group.label if arm is None else f"{group.label}, arm {arm + 1} policy"
            curves.append(Curve(label, group, arm, grid, mean, std, len(stack)))
    return curves, smoothing


# ---- final-stage return ---------------------------------------------------------------------
def run_final_stage_returns(run: RunData) -> dict[int | None, tuple[float | None, int]]:
    """SPEC §4 for one run: mean return of the episodes that ended after
    ``(1 − final_stage_fraction) · budget`` env steps, per arm policy. The budget is the run's
    ``total_timesteps``; for an arm policy of an independent run (``arm`` column ≥ 0, whose
    ``global_step`` counts that arm's own steps) it is the arm's budget (:attr:`RunData.arm_budget`).

    Returns ``{arm or None: (mean return or None if no episode qualifies, episode count)}``.
    """
    if run.train is None:
        return {}
    out: dict[int | None, tuple[float | None, int]] = {}
    for arm, part in _episodes_by_arm(run.train).items():
        budget = run.total_timesteps if arm is None else run.arm_budget
        threshold = (1.0 - run.final_stage_fraction) * budget
        step = pd.to_numeric(part["global_step"], errors="coerce")
        ret = pd.to_numeric(part["return"], errors="coerce")
        final = ret[(step > threshold) & np.isfinite(ret)]
        out[arm] = (float(final.mean()) if len(final) else None, len(final))
    return out


def final_stage_table(groups: Sequence[Group]) -> pd.DataFrame:
    """Final-stage return per group (and arm policy): mean ± sample std across seeds.

    Columns: group, algo, controller, arm (-1 for one policy of both arms), seeds (all runs),
    values ({seed: return} of runs with a final stage), n, mean, std (NaN for n < 2),
    episodes (summed over runs), missing (seeds without a final stage).
    """
    rows = []
    for group in groups:
        per_arm: dict[int | None, dict[str, object]] = {}
        for run in group.runs:
            results = run_final_stage_returns(run) or {None: (None, 0)}
            for arm, (value, count) in results.items():
                row = per_arm.setdefault(arm, {"values": {}, "episodes": 0, "missing": []})
                row["episodes"] = int(row["episodes"]) + count  # type: ignore[call-overload]
                if value is None:
                    row["missing"].append(run.seed)  # type: ignore[attr-defined]
                else:
                    row["values"][run.seed] = value  # type: ignore[index]
        for arm in sorted(per_arm, key=lambda a: -1 if a is None else a):
            row = per_arm[arm]
            arm_value = -1 if arm is None else int(arm)
            values = np.array(list(row["values"].values()), dtype=float)  # type: ignore[attr-defined]
            rows.append(
                {
                    "group": group.label,
                    "algo": group.algo,
                    "controller": group.controller,
                    "arm": arm_value,
                    "seeds": group.seeds,
                    "values": row["values"],
                    "n": int(values.size),
                    "mean": float(values.mean()) if values.size else np.nan,
                    "std": float(values.std(ddof=1)) if values.size >= 2 else np.nan,
                    "episodes": row["episodes"],
                    "missing": row["missing"],
                }
            )
    return pd.DataFrame(rows)


# ---- evaluation metrics ---------------------------------------------------------------------
def metrics_summary(groups: Sequence[Group]) -> pd.DataFrame:
    """Evaluation metrics per group, trajectory and arm: mean and sample std across seeds.

    Columns: group, algo, controller, trajectory, arm, n, seeds, terminated (runs whose episode
    ended early), and ``<metric>_mean`` / ``<metric>_std`` / ``<metric>_n`` (runs with a value)
    for every metric column stored: ``rmse_x`` … ``max_error`` and their ``_steady`` forms, in
    m, and ``action_saturation``, ``action_change``, ``action_rms`` (dimensionless). A metric no
    run of a group stores has no columns (or NaN where another group has it).
    """
    rows = []
    for group in groups:
        frames = []
        for run in group.runs:
            if run.metrics is not None:
                frames.append(run.metrics.assign(seed=run.seed))
        if not frames:
            continue
        df = pd.concat(frames, ignore_index=True)
        metric_cols = [
            c
            for c in df.columns
            if c.removesuffix("_steady") in METRIC_COLUMNS or c in ACTION_STATISTICS
        ]
        for (trajectory, arm), part in df.groupby(["trajectory", "arm"], sort=False):
            row: dict[str, object] = {
                "group": group.label,
                "algo": group.algo,
                "controller": group.controller,
                "trajectory": str(trajectory),
                "arm": int(arm),
                "n": len(part),
                "seeds": sorted(int(s) for s in part["seed"]),
                "terminated": int(part["terminated"].astype(bool).sum())
                if "terminated" in part
                else 0,
            }
            for col in metric_cols:
                values = pd.to_numeric(part[col], errors="coerce").dropna().to_numpy(float)
                row[f"{col}_mean"] = float(values.mean()) if values.size else np.nan
                row[f"{col}_std"] = float(values.std(ddof=1)) if values.size >= 2 else np.nan
                row[f"{col}_n"] = int(values.size)
            rows.append(row)
    return pd.DataFrame(rows)


def summary_row(summary: pd.DataFrame, group: str, trajectory: str, arm: int) -> pd.Series | None:
    """The :func:`metrics_summary` row of ``group`` (its label), ``trajectory`` and ``arm``
    (0-indexed), or None where nothing is stored."""
    if summary.empty:
        return None
    sel = summary[
        (summary["group"] == group) & (summary["trajectory"] == trajectory) & (summary["arm"] == arm)
    ]
    return None if sel.empty else sel.iloc[0]


def moment_peaks(groups: Sequence[Group]) -> pd.DataFrame:
    """Peak absolute element moment (N·m) over an evaluation episode, per group, trajectory,
    direction and arm (``arm`` -1: both arms), as mean and sample std across seeds.

    Columns: group, algo, controller, trajectory, direction (``normal``/``binormal``), arm, n,
    mean, std.
    """
    rows = []
    for group in groups:
        peaks: dict[tuple[str, str, int], list[float]] = {}
        for run in group.runs:
            df = run.moments
            if df is None or "max_abs_moment" not in df:
                continue
            value = pd.to_numeric(df["max_abs_moment"], errors="coerce")
            per = value.groupby([df["trajectory"], df["direction"], df["arm"]]).max()
            both = value.groupby([df["trajectory"], df["direction"]]).max()
            for (trajectory, direction, arm), peak in per.items():
                key = (str(trajectory), _direction(direction), int(arm))
                peaks.setdefault(key, []).append(float(peak))
            for (trajectory, direction), peak in both.items():
                peaks.setdefault((str(trajectory), _direction(direction), -1), []).append(
                    float(peak)
                )
        for (trajectory, direction, arm), values in peaks.items():
            arr = np.array(values)
            rows.append(
                {
                    "group": group.label,
                    "algo": group.algo,
                    "controller": group.controller,
                    "trajectory": trajectory,
                    "direction": direction,
                    "arm": arm,
                    "n": int(arr.size),
                    "mean": float(arr.mean()),
                    "std": float(arr.std(ddof=1)) if arr.size >= 2 else np.nan,
                }
            )
    return pd.DataFrame(rows)


def _direction(value: object) -> str:
    try:
        return DIRECTIONS[int(value)]  # type: ignore[call-overload]
    except (ValueError, TypeError, IndexError):
        return str(value)


def representative_run(group: Group, trajectory: str) -> RunData | None:
    """The run whose ``trajectory`` episode has the median 3-D RMSE (mean over arms; the lower
    median for an even count) among the group's runs with stored trajectories; without
    metrics, the lowest seed. ``None`` if no run has this trajectory."""
    candidates = [
        r
        for r in group.runs
        if r.trajectories is not None and (r.trajectories["trajectory"] == trajectory).any()
    ]
    if not candidates:
        return None
    scored = []
    for run in candidates:
        if run.metrics is None or "rmse_3d" not in run.metrics:
            continue
        rows = run.metrics[run.metrics["trajectory"] == trajectory]
        value = pd.to_numeric(rows["rmse_3d"], errors="coerce").mean()
        if np.isfinite(value):
            scored.append((float(value), run.seed, run))
    if not scored:
        return candidates[0]
    scored.sort(key=lambda s: (s[0], s[1]))
    return scored[(len(scored) - 1) // 2][2]
