"""Time to the study's accuracy: validation curves of training runs against environment steps and
against hours of training *on this machine*, with each config's training throughput measured
side by side, so configs trained on different machines compare fairly.

Each argument is a run directory (``models/<run>/`` or ``runs/<run_id>/``: ``run.json``,
``spec.yaml``, ``tables/validation.parquet``). Runs are grouped by experiment name (run.json
``name``), one config per name. Per run it reads the validation curve: per checkpoint the env
steps, the stored training clock (``wall_time``, where the table has it) and the validation
score (:func:`softtrack.evaluation.validation_score`: mean 3-D RMSE of the held-out
random-target episodes). Runs trained with ``training.validation_trajectories`` also have per
checkpoint one episode per evaluation trajectory and arm; their first checkpoint at which all
six trajectory x arm cells are at or below the study's 3-D RMSE
(:data:`softtrack.report.reference.STUDY_RMSE_3D`, centralized TD3 unless ``--study``) is the
run's *steps to the study's accuracy*.

Throughput (unless ``--throughput-steps 0``): each config's stored spec is trained for
``--throughput-steps`` env steps after a warm-up (``time_learning`` of
``benchmarks/bench_training.py``), configs interleaved in ``--repeats`` rounds, and the median
env steps/s kept. Before timing, the replay buffer is shrunk to 200,000 and ``learning_starts``
to 2,000 (memory and warm-up only); everything that sets the cost of a step (networks, batch,
gradient steps, n_envs, train_freq, mirror replay, algorithm) is kept. Hours here = env steps /
the config's measured steps/s.

Independent runs (two single-arm policies, trained one after the other, each arm's rows at its
own step) are read by arm: a pair checkpoint is a per-arm step s that both arms validated, its
env steps are 2 s (the sum over the arms), its score the mean over both arms' random episodes,
its cells each arm's own trajectory rows, and its stored clock the time to train both arms to s
(arm 0's clock at s plus arm 1's time from its start to s). Their throughput is timed on arm 0's
single-arm environment (both arms cost the same, and the pair's rate is an arm's rate).

Usage (run on one core; ``taskset -c 0``)::

    taskset -c 0 .venv/bin/python benchmarks/bench_time_to_accuracy.py \\
        runs/<id1>/ runs/<id2>/ models/td3-sbx-128-mirror-val-4e6-seed*/ \\
        --throughput-steps 4000 --repeats 3 --figure tta.png --csv tta.csv

Prints: the study's six cells; the measured steps/s per config and its ratio to the reference
config (``--reference``, default ``td3-sbx-128-mirror-val``, whose run directories must be among
the arguments); a table per run (config, seed, steps to the study's accuracy or "not reached",
hours here to it, stored hours and minutes to it, the median minutes of training between its
validations, best validation score @ step); a table per config (mean ±
sample std over seeds; steps and hours over the seeds that reached it) with the ratio of its
hours here to the study's accuracy to the reference's full training hours here (its
total_timesteps / its measured steps/s). ``--figure`` draws the validation score against env
steps and against hours (mean over seeds, min-max band) and each run's worst cell relative to
the study against its stored minutes of training; ``--csv`` writes one row per run and
checkpoint.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import pandas as pd

from softtrack.evaluation import validation_score
from softtrack.report.reference import STUDY_RMSE_3D
from softtrack.spec import ExperimentSpec

TRAJECTORIES: Final = ("circle", "rectangle", "figure8")
ARMS: Final = (0, 1)  # table arm indices; the study's "arm 1" is index 0
DEFAULT_REFERENCE: Final = "td3-sbx-128-mirror-val"
THROUGHPUT_BUFFER_SIZE: Final = 200_000
THROUGHPUT_LEARNING_STARTS: Final = 2_000
NOT_REACHED: Final = "not reached"
NO_CELLS: Final = "n/a (no trajectory rows)"
TARGET_MINUTES: Final = 5.0  # the issue's target: the study's accuracy within 5 min of training
WORST_CELL_CLIP: Final = 4.0  # the figure's y range for worst-cell ratios

#: ``timer(spec, steps)`` → seconds of training for ``steps`` env steps after a warm-up.
Timer = Callable[[ExperimentSpec, int], float]


# ---------------------------------------------------------------- the study's accuracy


def cell_name(trajectory: str, arm: int) -> str:
    """The column of one trajectory x arm cell, e.g. ``rmse_3d_circle_arm0`` (``arm``: the
    table's index, 0 or 1)."""
    return f"rmse_3d_{trajectory}_arm{arm}"


def study_cells(controller: str = "centralized") -> dict[str, float]:
    """The study's 3-D RMSE (m) of TD3 with ``controller``, by :func:`cell_name`: six cells."""
    table = STUDY_RMSE_3D[controller]
    return {cell_name(t, arm): table[t][arm] for t in TRAJECTORIES for arm in ARMS}


# ---------------------------------------------------------------- runs and their curves


@dataclass(frozen=True)
class RunInfo:
    """What a run's ``run.json`` says about it.

    Attributes:
        path: the run directory.
        name: the experiment name (the config).
        seed: the run's seed.
        controller: ``centralized`` or ``independent``.
        total_timesteps: the run's budget in env steps (independent: over both arms).
        steps_per_second: the run's recorded training rate on its own machine (env steps/s),
            or None.
    """

    path: Path
    name: str
    seed: int
    controller: str
    total_timesteps: int
    steps_per_second: float | None

    @property
    def independent(self) -> bool:
        """Whether the run trains one policy per arm."""
        return self.controller == "independent"


def run_info(path: Path, meta: Mapping[str, Any]) -> RunInfo:
    """The :class:`RunInfo` of the run at ``path`` from its parsed ``run.json`` ``meta``."""
    controller = str(meta.get("controller") or "centralized")
    total = meta.get("total_timesteps") or meta.get("global_step") or 0
    rate = meta.get("steps_per_second")
    return RunInfo(
        path=Path(path),
        name=str(meta["name"]),
        seed=int(meta.get("seed", 0)),
        controller=controller,
        total_timesteps=int(total),
        steps_per_second=float(rate) if rate else None,
    )


def group_by_config(runs: Iterable[RunInfo]) -> dict[str, list[RunInfo]]:
    """Runs by experiment name, configs in first-seen order, each config's runs by seed."""
    groups: dict[str, list[RunInfo]] = {}
    for run in runs:
        groups.setdefault(run.name, []).append(run)
    return {
        name: sorted(group, key=lambda r: (r.seed, str(r.path))) for name, group in groups.items()
    }


def checkpoint_cells(rows: pd.DataFrame) -> dict[str, float]:
    """The trajectory x arm cells of one checkpoint's rows: the 3-D RMSE (m) of its rows with
    an evaluation trajectory (mean if several), ∞ where that episode terminated. Cells without
    rows are left out; so are the random-target rows."""
    if "trajectory" not in rows:
        return {}
    tracked = rows[rows["trajectory"].isin(TRAJECTORIES)]
    cells: dict[str, float] = {}
    for (trajectory, arm), part in tracked.groupby(["trajectory", "arm"], sort=False):
        failed = bool(part["terminated"].astype(bool).any()) if "terminated" in part else False
        cells[cell_name(str(trajectory), int(arm))] = (
            math.inf if failed else float(part["rmse_3d"].mean())
        )
    return cells


def _clock(rows: pd.DataFrame) -> float:
    """The stored training clock (s) of one checkpoint's rows; NaN without one."""
    if "wall_time" not in rows:
        return math.nan
    value = pd.to_numeric(rows["wall_time"], errors="coerce").max()
    return float(value) if pd.notna(value) else math.nan


def _checkpoints(table: pd.DataFrame, independent: bool) -> list[tuple[int, float, pd.DataFrame]]:
    """(env steps of the run, stored clock in s, rows) per checkpoint, by step. An independent
    run's pair checkpoints: per-arm steps both arms validated (module docstring)."""
    if not independent:
        return [
            (int(step), _clock(rows), rows)
            for step, rows in table.groupby("global_step", sort=True)
        ]
    arms = {arm: part for arm, part in table.groupby("arm")}
    if set(arms) != set(ARMS):
        return []
    first, second = arms[0], arms[1]
    steps = sorted(set(first["global_step"]) & set(second["global_step"]))
    arm0_end = _clock(first[first["global_step"] == first["global_step"].max()])
    out = []
    for step in steps:
        rows0 = first[first["global_step"] == step]
        rows1 = second[second["global_step"] == step]
        clock = _clock(rows0) + _clock(rows1) - arm0_end  # arm 1's clock continues arm 0's
        out.append((2 * int(step), clock, pd.concat([rows0, rows1], ignore_index=True)))
    return out


def validation_curve(table: pd.DataFrame, independent: bool = False) -> pd.DataFrame:
    """One run's validation curve from its ``validation`` table.

    Returns:
        One row per checkpoint, by step: ``global_step`` (env steps of the run; independent:
        the sum over both arms), ``wall_time`` (stored training clock, s; NaN where the table
        has none), ``score`` (validation score, m; ∞ if an episode terminated), and, where the
        table has trajectory rows, the six :func:`cell_name` columns (m; NaN where a checkpoint
        lacks the cell).
    """
    records = []
    for step, clock, rows in _checkpoints(table, independent):
        records.append(
            {
                "global_step": step,
                "wall_time": clock,
                "score": validation_score(rows),
                **checkpoint_cells(rows),
            }
        )
    curve = pd.DataFrame(records, columns=["global_step", "wall_time", "score"])
    if records:
        curve = pd.DataFrame(records)
    tracked = "trajectory" in table and table["trajectory"].isin(TRAJECTORIES).any()
    if tracked:
        for name in study_cells():
            if name not in curve:
                curve[name] = math.nan
    first = ["global_step", "wall_time", "score", *[c for c in study_cells() if c in curve]]
    return curve[first + [c for c in curve.columns if c not in first]].reset_index(drop=True)


def has_cells(curve: pd.DataFrame, study: Mapping[str, float]) -> bool:
    """Whether ``curve`` has all the cell columns of ``study`` (trajectory rows were stored)."""
    return all(name in curve for name in study)


def worst_cell_ratio(curve: pd.DataFrame, study: Mapping[str, float]) -> pd.Series:
    """Per checkpoint of ``curve``, the largest of the six cells' 3-D RMSE divided by the
    study's value for that cell: 1 or below means the study's accuracy in every cell (∞ where a
    cell is missing or failed).

    Raises:
        ValueError: ``curve`` has no cell columns (:func:`has_cells`).
    """
    if not has_cells(curve, study):
        raise ValueError("the curve has no trajectory cells (no validation_trajectories rows)")
    names = list(study)
    ratios = curve[names].astype(float) / pd.Series(study)[names]
    return ratios.fillna(math.inf).max(axis=1)


def validation_cadence_min(curve: pd.DataFrame) -> float:
    """The median training-clock minutes between consecutive validated checkpoints of one
    run (the first from the start of training); NaN without a stored clock."""
    clock = pd.to_numeric(curve["wall_time"], errors="coerce").dropna().sort_values()
    if clock.empty:
        return math.nan
    gaps = np.diff(np.concatenate([[0.0], clock.to_numpy()]))
    return float(np.median(gaps)) / 60.0


def first_at_study(curve: pd.DataFrame, study: Mapping[str, float]) -> pd.Series | None:
    """The first checkpoint (a row of ``curve``) at which every cell of ``study`` is at or
    below the study's value (m); None if none is (a missing or ∞ cell never is).

    Raises:
        ValueError: ``curve`` has no cell columns (:func:`has_cells`).
    """
    if not has_cells(curve, study):
        raise ValueError("the curve has no trajectory cells (no validation_trajectories rows)")
    names = list(study)
    ok = (curve[names] <= pd.Series(study)[names]).all(axis=1)
    ordered = curve[ok].sort_values("global_step", kind="stable")
    return None if ordered.empty else ordered.iloc[0]


def best_checkpoint(curve: pd.DataFrame) -> tuple[int, float]:
    """(env steps, score in m) of the lowest validation score, the earliest on ties."""
    if curve.empty:
        return 0, math.inf
    ordered = curve.sort_values("global_step", kind="stable").reset_index(drop=True)
    row = (
        ordered.loc[ordered["score"].idxmin()]
        if np.isfinite(ordered["score"]).any()
        else ordered.iloc[0]
    )
    return int(row["global_step"]), float(row["score"])


@dataclass(frozen=True)
class RunResult:
    """One run's summary.

    Attributes:
        info: the run.
        curve: its :func:`validation_curve`.
        tracked: whether it stored trajectory rows (else steps to accuracy are n/a).
        reached_step: env steps of the first checkpoint at the study's accuracy, or None.
        reached_wall_time: the stored clock (s) there; NaN if not stored or not reached.
        best_step, best_score: :func:`best_checkpoint` (env steps, m).
    """

    info: RunInfo
    curve: pd.DataFrame
    tracked: bool
    reached_step: int | None
    reached_wall_time: float
    best_step: int
    best_score: float


def summarize_run(info: RunInfo, table: pd.DataFrame, study: Mapping[str, float]) -> RunResult:
    """The :class:`RunResult` of the run ``info`` with validation table ``table``."""
    curve = validation_curve(table, info.independent)
    tracked = has_cells(curve, study)
    row = first_at_study(curve, study) if tracked else None
    best_step, best_score = best_checkpoint(curve)
    return RunResult(
        info=info,
        curve=curve,
        tracked=tracked,
        reached_step=None if row is None else int(row["global_step"]),
        reached_wall_time=math.nan if row is None else float(row["wall_time"]),
        best_step=best_step,
        best_score=best_score,
    )


# ---------------------------------------------------------------- statistics


def mean_std(values: Sequence[float]) -> tuple[float, float]:
    """(mean, sample standard deviation, ddof 1) of ``values``; NaN std for fewer than two,
    (NaN, NaN) for none."""
    if not values:
        return math.nan, math.nan
    mean = float(np.mean(values))
    return mean, float(np.std(values, ddof=1)) if len(values) > 1 else math.nan


def hours(steps: float, steps_per_second: float | None) -> float:
    """Hours for ``steps`` env steps at ``steps_per_second``; NaN without a rate."""
    if not steps_per_second or not math.isfinite(steps):
        return math.nan
    return float(steps) / steps_per_second / 3600.0


def band_on_grid(curves: Sequence[pd.DataFrame], x: str = "global_step") -> pd.DataFrame:
    """Seeds' scores on a common grid of ``x``: the union of the seeds' ``x`` values within the
    range every seed covers, each seed's ``score`` linearly interpolated onto it (∞ scores as
    missing).

    Returns:
        Columns ``x`` (the grid, ascending), ``mean``, ``min``, ``max`` (m), one row per grid
        point; empty if the seeds share no range.
    """
    parts = [c[[x, "score"]].dropna(subset=[x]).sort_values(x) for c in curves]
    parts = [p for p in parts if not p.empty]
    if not parts or len(parts) < len(curves):
        return pd.DataFrame(columns=[x, "mean", "min", "max"])
    low = max(float(p[x].iloc[0]) for p in parts)
    high = min(float(p[x].iloc[-1]) for p in parts)
    grid = np.unique(np.concatenate([p[x].to_numpy(float) for p in parts]))
    grid = grid[(grid >= low) & (grid <= high)]
    if grid.size == 0:
        return pd.DataFrame(columns=[x, "mean", "min", "max"])
    values = np.vstack(
        [
            np.interp(
                grid,
                p[x].to_numpy(float),
                np.where(np.isfinite(p["score"].to_numpy(float)), p["score"], np.nan),
            )
            for p in parts
        ]
    )
    with warnings.catch_warnings():  # all-NaN columns (every seed terminated there)
        warnings.simplefilter("ignore", RuntimeWarning)
        return pd.DataFrame(
            {
                x: grid,
                "mean": np.nanmean(values, axis=0),
                "min": np.nanmin(values, axis=0),
                "max": np.nanmax(values, axis=0),
            }
        )


# ---------------------------------------------------------------- throughput


def throughput_spec(spec: ExperimentSpec) -> ExperimentSpec:
    """``spec`` with a small replay buffer (≤ 200,000) and ``learning_starts`` ≤ 2,000 for
    timing; everything that sets the cost of a step is kept."""
    data = spec.model_dump()
    data["algo"]["buffer_size"] = min(int(data["algo"]["buffer_size"]), THROUGHPUT_BUFFER_SIZE)
    data["algo"]["learning_starts"] = min(
        int(data["algo"]["learning_starts"]), THROUGHPUT_LEARNING_STARTS
    )
    return ExperimentSpec.model_validate(data)


def time_arm_learning(spec: ExperimentSpec, steps: int, arm: int = 0) -> float:
    """``bench_training.time_learning`` on arm ``arm``'s single-arm environment (an independent
    run's policy): seconds for ``steps`` env steps of training after the same warm-up."""
    from softtrack.rl.factory import build_model, make_vec_env

    env = make_vec_env(spec, arm=arm)
    model = build_model(spec, env, seed=0)
    model.learn(spec.algo.learning_starts + 2 * spec.training.n_envs * 100)  # + JIT compile
    start = time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    return time.perf_counter() - start


def default_timer(spec: ExperimentSpec, steps: int) -> float:
    """Seconds for ``steps`` env steps of training ``spec`` on this machine:
    ``time_learning`` of ``bench_training.py`` (same folder), or :func:`time_arm_learning` for
    an independent spec."""
    if spec.controller == "independent":
        return time_arm_learning(spec, steps)
    here = str(Path(__file__).resolve().parent)
    if here not in sys.path:
        sys.path.insert(0, here)
    from bench_training import time_learning

    return float(time_learning(spec, steps))


def measure_throughput(
    specs: Mapping[str, ExperimentSpec],
    steps: int,
    repeats: int,
    timer: Timer = default_timer,
    log: Callable[[str], None] = lambda line: None,
) -> dict[str, float]:
    """Median env steps/s of each config: ``repeats`` rounds, each timing every config once
    (interleaved, so slow drifts of the machine hit all configs alike)."""
    rates: dict[str, list[float]] = {name: [] for name in specs}
    for round_ in range(repeats):
        for name, spec in specs.items():
            rate = steps / timer(spec, steps)
            rates[name].append(rate)
            log(f"  round {round_ + 1}/{repeats} {name}: {rate:,.0f} env steps/s")
    return {name: float(statistics.median(values)) for name, values in rates.items()}


# ---------------------------------------------------------------- tables


def checkpoint_table(results: Sequence[RunResult], rates: Mapping[str, float]) -> pd.DataFrame:
    """One row per run and checkpoint: config, seed, global_step (env steps), wall_time
    (stored clock, s), hours_here (h at the config's measured rate; NaN if not measured),
    score (m) and the six cells (m) where stored."""
    frames = []
    for result in results:
        curve = result.curve.copy()
        rate = rates.get(result.info.name)
        curve.insert(0, "seed", result.info.seed)
        curve.insert(0, "config", result.info.name)
        curve.insert(4, "hours_here", [hours(s, rate) for s in curve["global_step"]])
        frames.append(curve)
    if not frames:
        return pd.DataFrame(
            columns=["config", "seed", "global_step", "wall_time", "hours_here", "score"]
        )
    return pd.concat(frames, ignore_index=True)


def config_summary(
    runs: Sequence[RunResult],
    rate: float | None,
    reference_full_hours: float,
) -> dict[str, Any]:
    """One config's row: seeds, reached (count), steps and hours here to the study's accuracy
    (mean, sample std over the seeds that reached it), the runs' stored training clock to it
    (``minutes_stored``, min, over those seeds with a clock), best score (m) and its step (mean, std
    over all seeds), full training hours here, and ``ratio``: mean hours here to the study's
    accuracy / the reference's full training hours here (NaN where either is unknown)."""
    reached = [r.reached_step for r in runs if r.reached_step is not None]
    steps_mean, steps_std = mean_std([float(s) for s in reached])
    hours_mean, hours_std = (
        mean_std([hours(s, rate) for s in reached]) if rate else (math.nan, math.nan)
    )
    stored = [r.reached_wall_time / 60.0 for r in runs if r.reached_step is not None]
    minutes_mean, minutes_std = mean_std([m for m in stored if math.isfinite(m)])
    best_mean, best_std = mean_std([r.best_score for r in runs])
    best_step_mean, best_step_std = mean_std([float(r.best_step) for r in runs])
    full = hours(float(np.mean([r.info.total_timesteps for r in runs])), rate)
    ratio = hours_mean / reference_full_hours if reference_full_hours > 0 else math.nan
    return {
        "seeds": len(runs),
        "tracked": sum(r.tracked for r in runs),
        "reached": len(reached),
        "steps": (steps_mean, steps_std),
        "hours": (hours_mean, hours_std),
        "minutes_stored": (minutes_mean, minutes_std),
        "best": (best_mean, best_std),
        "best_step": (best_step_mean, best_step_std),
        "full_hours": full,
        "ratio": ratio,
    }


def _pm(pair: tuple[float, float], fmt: str) -> str:
    mean, std = pair
    if not math.isfinite(mean):
        return "-"
    return format(mean, fmt) + ("" if not math.isfinite(std) else " ± " + format(std, fmt))


def _h(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.2f}"


def _m(value: float) -> str:
    return "-" if not math.isfinite(value) else f"{value:.1f}"


# ---------------------------------------------------------------- figure


def _hours_curve(result: RunResult, rate: float | None) -> tuple[pd.DataFrame, bool]:
    """The run's curve with an ``hours`` column: at the config's measured rate (True), else at
    the run's recorded rate on its own machine (False)."""
    curve = result.curve.copy()
    here = bool(rate)
    curve["hours"] = [
        hours(s, rate if here else result.info.steps_per_second) for s in curve["global_step"]
    ]
    return curve, here


def write_figure(
    path: Path,
    groups: Mapping[str, Sequence[RunResult]],
    rates: Mapping[str, float],
    study_mean: float,
    log_x: bool = False,
) -> Path:
    """A PNG of three panels, one colour per config: validation 3-D RMSE (m) against env steps
    and against hours (mean over seeds as a line, min-max band; a dashed line at the study's
    mean over the six cells, m), and each run's worst trajectory x arm cell relative to the
    study (:func:`worst_cell_ratio`; 1 = the study's accuracy in all six cells) against the
    minutes of its stored training clock (one line per seed; runs without trajectory rows or a
    stored clock are left out of this panel), with the five-minute target marked."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from softtrack.report.families import PALETTE as GROUP_COLORS
    from softtrack.report.figures import DPI

    fig = Figure(figsize=(18, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    by_steps, by_hours, by_minutes = fig.subplots(1, 3)
    by_hours.sharey(by_steps)
    study = study_cells()
    all_here = True
    for k, (name, runs) in enumerate(groups.items()):
        color = GROUP_COLORS[k % len(GROUP_COLORS)]
        label = f"{name} ({len(runs)} seed{'s' if len(runs) != 1 else ''})"
        steps_band = band_on_grid([r.curve for r in runs], "global_step")
        curves = [_hours_curve(r, rates.get(name)) for r in runs]
        all_here &= all(here for _, here in curves)
        hours_band = band_on_grid([c for c, _ in curves], "hours")
        for ax, band, x in ((by_steps, steps_band, "global_step"), (by_hours, hours_band, "hours")):
            if band.empty:
                continue
            ax.plot(band[x], band["mean"], color=color, lw=1.6, marker=".", label=label)
            ax.fill_between(band[x], band["min"], band["max"], color=color, alpha=0.2, lw=0)
        for seed_index, run in enumerate(r for r in runs if has_cells(r.curve, study)):
            clocked = run.curve.dropna(subset=["wall_time"]).sort_values("global_step")
            if clocked.empty:
                continue
            by_minutes.plot(
                clocked["wall_time"] / 60.0,
                worst_cell_ratio(clocked, study).clip(upper=WORST_CELL_CLIP),
                color=color,
                lw=1.2,
                marker=".",
                label=label if seed_index == 0 else None,
            )
    for ax in (by_steps, by_hours):
        ax.axhline(
            study_mean,
            color="0.2",
            ls="--",
            lw=1.2,
            label=f"study, mean of six cells ({study_mean:.4f} m)",
        )
        ax.grid(alpha=0.3)
        if log_x:
            ax.set_xscale("log")
    by_steps.set_xlabel("environment steps")
    if not log_x:
        by_steps.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    by_hours.set_xlabel(
        "hours of training on this machine"
        if all_here
        else "hours of training (not measured here: at each run's\n"
        "recorded rate, run.json steps_per_second)"
    )
    by_minutes.axhline(1.0, color="0.2", ls="--", lw=1.2, label="the study's accuracy")
    by_minutes.axvline(TARGET_MINUTES, color="0.5", ls=":", lw=1.2, label="5-min target")
    by_minutes.set_xlabel("minutes of training (each run's stored clock)")
    by_minutes.set_ylabel(f"worst cell / study (clipped at {WORST_CELL_CLIP:g})")
    by_minutes.set_title("worst of the six cells against training time", fontsize=11)
    by_minutes.grid(alpha=0.3)
    by_minutes.legend(loc="best", fontsize=8)
    by_steps.set_ylabel("validation 3-D RMSE (m)")
    by_steps.set_title("against env steps", fontsize=11)
    by_hours.set_title("against training time", fontsize=11)
    by_steps.legend(loc="best", fontsize=8)
    fig.suptitle(
        "Validation score (held-out random targets): mean over seeds, min-max band", fontsize=12
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI, format="png")
    return path


# ---------------------------------------------------------------- main


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories")
    parser.add_argument(
        "--throughput-steps",
        type=int,
        default=4_000,
        help="timed env steps per measurement; 0: no throughput measure",
    )
    parser.add_argument("--repeats", type=int, default=3, help="interleaved rounds (median)")
    parser.add_argument("--reference", default=DEFAULT_REFERENCE, help="reference config name")
    parser.add_argument(
        "--study",
        default="centralized",
        choices=sorted(STUDY_RMSE_3D),
        help="the study's controller whose 3-D RMSE is the target",
    )
    parser.add_argument("--figure", type=Path, help="write the three-panel PNG here")
    parser.add_argument("--csv", type=Path, help="write one row per run and checkpoint here")
    parser.add_argument("--log-x", action="store_true", help="logarithmic x axes in the figure")
    args = parser.parse_args(argv)

    from softtrack.spec import load_spec
    from softtrack.store.provenance import cpu_description
    from softtrack.store.tables import read_table

    study = study_cells(args.study)
    study_mean = float(np.mean(list(study.values())))
    results: list[RunResult] = []
    for path in args.runs:
        meta_file, table_file = path / "run.json", path / "tables" / "validation.parquet"
        if not meta_file.is_file() or not table_file.is_file():
            print(f"note: skipping {path}: no run.json or tables/validation.parquet")
            continue
        info = run_info(path, json.loads(meta_file.read_text(encoding="utf-8")))
        results.append(summarize_run(info, read_table(table_file), study))
    groups = group_by_config(r.info for r in results)
    by_run = {r.info.path: r for r in results}
    grouped = {name: [by_run[i.path] for i in infos] for name, infos in groups.items()}

    cells_text = ", ".join(
        f"{t} {study[cell_name(t, 0)]:.3f}/{study[cell_name(t, 1)]:.3f}" for t in TRAJECTORIES
    )
    print(
        f"Time to the study's accuracy: all six trajectory x arm cells at or below the study's "
        f"{args.study} TD3 3-D RMSE ({cells_text} m, arm 1/arm 2; mean {study_mean:.4f} m)"
    )
    if any(r.info.independent for r in results):
        print(
            "note: independent runs are read by arm: a pair checkpoint is a per-arm step s "
            "both arms validated, counted as 2 s env steps (the sum over both arms)"
        )

    rates: dict[str, float] = {}
    if args.throughput_steps > 0:
        if args.reference not in grouped:
            print(f"note: reference config {args.reference!r} is not among the runs: no ratios")
        specs = {
            name: throughput_spec(load_spec(runs[0].info.path / "spec.yaml"))
            for name, runs in grouped.items()
        }
        print(
            f"\nThroughput here ({cpu_description()}): {args.throughput_steps:,} timed env steps "
            f"after warm-up, buffer ≤ {THROUGHPUT_BUFFER_SIZE:,}, learning_starts ≤ "
            f"{THROUGHPUT_LEARNING_STARTS:,}, {args.repeats} interleaved round(s), median"
        )
        rates = measure_throughput(
            specs,
            args.throughput_steps,
            args.repeats,
            log=lambda line: print(line, file=sys.stderr, flush=True),
        )
        ref_rate = rates.get(args.reference)
        for name, rate in rates.items():
            ratio = f"{rate / ref_rate:5.2f}x reference" if ref_rate else ""
            recorded = [r.info.steps_per_second for r in grouped[name] if r.info.steps_per_second]
            stored = f"   recorded in run.json: {np.mean(recorded):,.0f}" if recorded else ""
            print(f"  {name:<34} {rate:8,.0f} env steps/s  {ratio}{stored}")

    ref_runs = grouped.get(args.reference, [])
    ref_full = (
        hours(float(np.mean([r.info.total_timesteps for r in ref_runs])), rates.get(args.reference))
        if ref_runs
        else math.nan
    )

    print(
        "\nRuns (steps to the study's accuracy: first checkpoint with all six cells at or "
        "below the study; h here: at the config's measured rate; h stored: run's own clock)"
    )
    print(
        f"  {'config':<34} {'seed':>4}  {'steps to study':>24}  {'h here':>7}  "
        f"{'h stored':>8}  {'min stored':>10}  {'val. every':>10}  best validation @ step"
    )
    for name, runs in grouped.items():
        for r in runs:
            if not r.tracked:
                reached = NO_CELLS
            elif r.reached_step is None:
                reached = NOT_REACHED
            else:
                reached = f"{r.reached_step:,}"
            here = (
                hours(r.reached_step, rates.get(name)) if r.reached_step is not None else math.nan
            )
            print(
                f"  {name:<34} {r.info.seed:>4}  {reached:>24}  {_h(here):>7}  "
                f"{_h(r.reached_wall_time / 3600):>8}  {_m(r.reached_wall_time / 60):>10}  "
                f"{_m(validation_cadence_min(r.curve)) + ' min':>10}  "
                f"{r.best_score:.4f} m @ {r.best_step:,}"
            )

    print(
        "\nConfigs (mean ± sample std over seeds; steps and hours over the seeds that reached "
        "the study's accuracy; ratio: h here to it / the reference's full training h here"
        + (f" = {ref_full:.2f} h" if math.isfinite(ref_full) else ", n/a")
        + ")"
    )
    print(
        f"  {'config':<34} {'reached':>9}  {'steps to study':>22}  {'h here':>12}  "
        f"{'full h here':>11}  {'min stored':>12}  {'best validation (m)':>19}  "
        f"{'best step':>21}  ratio"
    )
    for name, runs in grouped.items():
        row = config_summary(runs, rates.get(name), ref_full)
        reached = f"{row['reached']}/{row['seeds']}" if row["tracked"] else "n/a"
        ratio = "-" if not math.isfinite(row["ratio"]) else f"{row['ratio']:.2f}"
        print(
            f"  {name:<34} {reached:>9}  {_pm(row['steps'], ',.0f'):>22}  "
            f"{_pm(row['hours'], '.2f'):>12}  {_h(row['full_hours']):>11}  "
            f"{_pm(row['minutes_stored'], '.1f'):>12}  {_pm(row['best'], '.4f'):>19}  "
            f"{_pm(row['best_step'], ',.0f'):>21}  {ratio}"
        )

    if args.figure:
        write_figure(args.figure, grouped, rates, study_mean, args.log_x)
        print(f"\nfigure: {args.figure}")
    if args.csv:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        checkpoint_table(results, rates).to_csv(args.csv, index=False)
        print(f"csv: {args.csv}")


if __name__ == "__main__":
    main()
