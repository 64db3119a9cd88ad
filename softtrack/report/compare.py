"""``softtrack compare``: controllers side by side with across-seed statistics.

Each controller is the set of runs one selection item names (an experiment name, a run id or
prefix, a spec file: :func:`softtrack.store.selection.select_runs`). Its scores are the
stored evaluation metric (default the 3-D RMSE, m) as a runs × cells matrix, a cell being a
trajectory and arm. :func:`compare_controllers` gives, with the statistics of
:mod:`softtrack.evaluation.seed_statistics`:

* per controller and cell, and over all cells, the interquartile mean with its 95 % stratified
  bootstrap interval;
* for the first controller against each other, the probability of improvement (a random run of
  the first has the lower error in a random cell) with its interval;
* the seeds and the CPU kinds that computed the scores, and the cross-CPU noise floor.

The report's comparison tables and performance profile use the same functions.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from softtrack.evaluation.scores import CARRY_SCORE, with_carry_score
from softtrack.evaluation.seed_statistics import (
    BOOTSTRAP_REPS,
    Interval,
    interquartile_mean,
    performance_profile,
    probability_of_improvement,
    stratified_bootstrap,
)
from softtrack.evaluation.transport_metrics import TRANSPORT_STATISTICS
from softtrack.report.data import RunData, load_runs
from softtrack.report.reference import TRAJECTORY_TITLES
from softtrack.store.runs import RunStore, RunStoreError, resolve_runs_dir
from softtrack.store.selection import RunIndex, select_runs
from softtrack.trajectories import EVAL_TRAJECTORIES

__all__ = [
    "CROSS_CPU_NOTE",
    "MAX_PRINTED_CELLS",
    "SCENE_METRICS",
    "Comparison",
    "ControllerScores",
    "compare_controllers",
    "compare_selection",
    "profile_figure",
    "scored_rows",
]

#: Metrics of the whole scene, the same in both arms' rows: one cell per trajectory.
SCENE_METRICS = frozenset((*TRANSPORT_STATISTICS, CARRY_SCORE))

#: More cells than this (e.g. one per random-target episode) print only the statistics over
#: all cells.
MAX_PRINTED_CELLS = 12

CROSS_CPU_NOTE = (
    "cross-CPU noise floor: one deterministic evaluation of a shipped policy moved by a median "
    "0.31 %, at most 4.4 % (0.0032 m) between CPU kinds (docs/performance.md, "
    "benchmarks/cross_cpu_spread.py); a difference below that is not a finding"
)


@dataclass(frozen=True)
class ControllerScores:
    """One controller's runs as a score matrix.

    Attributes:
        label: the selection item that named it.
        cells: the (trajectory, arm) of each column.
        scores: (runs, cells) the metric of each run and cell (NaN where not stored).
        seeds: each run's seed, in row order.
        cpus: CPU kind → number of scores it computed (``eval_metrics.cpu``; "unrecorded" for
            tables written before the column existed).
        non_finite: "seed S, cell: value" for each stored score that is not a finite number
            (a diverged episode's ±inf, a NaN): left out of every statistic, and said so.
    """

    label: str
    cells: tuple[tuple[str, int], ...]
    scores: np.ndarray
    seeds: tuple[int, ...]
    cpus: dict[str, int]
    non_finite: tuple[str, ...] = ()


@dataclass(frozen=True)
class Comparison:
    """The statistics of :func:`compare_controllers` (all intervals at ``confidence``)."""

    metric: str
    controllers: tuple[ControllerScores, ...]
    per_cell: dict[str, tuple[Interval | None, ...]]
    overall: dict[str, Interval]
    improvement: dict[str, Interval]
    per_cell_improvement: dict[str, tuple[Interval | None, ...]]
    reps: int
    confidence: float

    def lines(self) -> list[str]:
        """The comparison as text tables (what ``softtrack compare`` prints)."""
        first = self.controllers[0]
        width = max(len(c.label) for c in self.controllers)
        level = f"{100 * self.confidence:g} %"
        out = [
            f"{self.metric} (lower is better): interquartile mean over runs [{level} stratified "
            f"bootstrap interval, {self.reps} resamples]",
            "",
            f"{'controller':{width}}  runs  seeds  {'all cells':>24}  CPU kinds",
        ]
        for c in self.controllers:
            cpus = ", ".join(f"{kind} ({n})" for kind, n in sorted(c.cpus.items()))
            out.append(
                f"{c.label:{width}}  {len(c.seeds):>4}  {_seeds(c.seeds):>5}  "
                f"{self.overall[c.label].text():>24}  {cpus}"
            )
        for c in self.controllers:
            if c.non_finite:
                out.append(
                    f"note: {c.label}: {len(c.non_finite)} stored score"
                    f"{'s are' if len(c.non_finite) > 1 else ' is'} not a finite number, left "
                    f"out of every statistic: {'; '.join(c.non_finite[:4])}"
                    + (f"; and {len(c.non_finite) - 4} more" if len(c.non_finite) > 4 else "")
                )
        per_cell = len(first.cells) <= MAX_PRINTED_CELLS
        scene = not any(arm for _, arm in first.cells)
        columns = {c.label: max(24, len(c.label)) for c in self.controllers}
        if per_cell:
            out += [
                "",
                f"{'cell':20}"
                + "".join(f"  {c.label:>{columns[c.label]}}" for c in self.controllers),
            ]
        for j, (trajectory, arm) in enumerate(first.cells if per_cell else ()):
            row = f"{_cell_name(trajectory, arm, scene, ', '):20}"
            for c in self.controllers:
                interval = self.per_cell[c.label][j]
                row += f"  {interval.text() if interval else 'no data':>{columns[c.label]}}"
            out.append(row)
        if not per_cell:
            out += ["", f"({len(first.cells)} cells: the per-cell intervals are left out)"]
        for other in self.controllers[1:]:
            p = self.improvement[other.label]
            out += [
                "",
                f"P({first.label} improves on {other.label}) = {p.text(2)} over all cells "
                "(0.5: no difference; above 0.5: the first is better)",
            ]
            cells = [
                f"{_cell_name(t, a, scene, ' ')} {i.text(2) if i else 'no data'}"
                for (t, a), i in zip(
                    first.cells, self.per_cell_improvement[other.label], strict=True
                )
            ]
            if per_cell:
                out.append("  per cell: " + "; ".join(cells))
        out += ["", CROSS_CPU_NOTE]
        return out


def _cell_name(trajectory: str, arm: int, scene: bool, separator: str) -> str:
    """``circle, arm 1`` (or, for a metric of the whole scene, ``circle``)."""
    title = TRAJECTORY_TITLES.get(trajectory, trajectory)
    return title if scene else f"{title}{separator}arm {arm + 1}"


def _seeds(seeds: Sequence[int]) -> str:
    values = sorted(set(seeds))
    if values and values == list(range(values[0], values[-1] + 1)) and len(values) > 2:
        return f"{values[0]}-{values[-1]}"
    return ",".join(str(s) for s in values)


def controller_scores(
    label: str,
    metrics: Sequence[tuple[int, pd.DataFrame | None]],
    metric: str,
    trajectories: Sequence[str],
    table_name: str = "eval_metrics",
) -> ControllerScores:
    """The score matrix of one controller from its runs' ``(seed, eval_metrics)`` (or other
    rows with the columns trajectory, arm and ``metric``; ``table_name`` names them in errors).
    A cell is a trajectory and arm; for a metric of the whole scene (the sphere's, the same in
    both arms' rows) a trajectory, as arm 0, so that no value counts twice.

    Raises:
        RunStoreError: no run has ``metric`` stored.
    """
    arms = (0,) if metric in SCENE_METRICS else (0, 1)
    cells = tuple((t, arm) for t in trajectories for arm in arms)
    rows: list[list[float]] = []
    seeds: list[int] = []
    cpus: dict[str, int] = {}
    non_finite: list[str] = []
    for seed, table in metrics:
        if table is None or metric not in table:
            continue
        by_cell = {
            (str(r.trajectory), int(r.arm)): float(getattr(r, metric))
            for r in table.itertuples(index=False)
        }
        scene = not any(arm for _, arm in cells)
        non_finite += [
            f"seed {seed}, {_cell_name(t, a, scene, ' ')}: {value}"
            for (t, a), value in by_cell.items()
            if (t, a) in cells and not np.isfinite(value)
        ]
        rows.append([by_cell.get(cell, np.nan) for cell in cells])
        seeds.append(seed)
        counted = table[table["arm"].isin(arms)] if "arm" in table else table
        kinds = (
            counted["cpu"].fillna("unrecorded")
            if "cpu" in counted
            else ["unrecorded"] * len(counted)
        )
        for kind in kinds:
            cpus[str(kind)] = cpus.get(str(kind), 0) + 1
    if not rows:
        raise RunStoreError(
            f"{label}: no run has {metric} in {table_name}; evaluate it first "
            f"(`softtrack evaluate RUN{' --random 20' if table_name == 'eval_random' else ''}`)"
        )
    scores = np.asarray(rows, dtype=float)
    scores[~np.isfinite(scores)] = np.nan  # named in non_finite; no statistic sees them
    return ControllerScores(label, cells, scores, tuple(seeds), cpus, tuple(non_finite))


def compare_controllers(
    controllers: Sequence[ControllerScores],
    metric: str = "rmse_3d",
    *,
    reps: int = BOOTSTRAP_REPS,
    confidence: float = 0.95,
    seed: int = 0,
    cells: bool = True,
) -> Comparison:
    """The statistics of the module docstring for ``controllers`` (the first against each
    other); every controller must have the first one's cells. ``cells=False``: only the
    statistics over all cells (the per-cell ones are empty)."""
    if len(controllers) < 1:
        raise ValueError("nothing to compare")
    per_cell: dict[str, tuple[Interval | None, ...]] = {}
    overall: dict[str, Interval] = {}
    for c in controllers:
        per_cell[c.label] = tuple(
            stratified_bootstrap(col, reps=reps, confidence=confidence, seed=seed)
            if cells and np.isfinite(col).any()
            else None
            for col in c.scores.T
        )
        overall[c.label] = stratified_bootstrap(
            c.scores, interquartile_mean, reps=reps, confidence=confidence, seed=seed
        )
    first = controllers[0]
    improvement, per_cell_improvement = {}, {}
    for other in controllers[1:]:
        improvement[other.label] = probability_of_improvement(
            first.scores, other.scores, reps=reps, confidence=confidence, seed=seed
        )
        per_cell_improvement[other.label] = tuple(
            probability_of_improvement(a, b, reps=reps, confidence=confidence, seed=seed)
            if cells and np.isfinite(a).any() and np.isfinite(b).any()
            else None
            for a, b in zip(first.scores.T, other.scores.T, strict=True)
        )
    return Comparison(
        metric,
        tuple(controllers),
        per_cell,
        overall,
        improvement,
        per_cell_improvement,
        reps,
        confidence,
    )


def compare_selection(
    selection: Sequence[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    metric: str = "rmse_3d",
    trajectories: Sequence[str] = EVAL_TRAJECTORIES,
    reps: int = BOOTSTRAP_REPS,
    seed: int = 0,
    random: bool = False,
) -> Comparison:
    """Compare the controllers the ``selection`` items name (one controller per item).

    ``random``: the cells are the held-out random-target episodes of ``eval_random`` (the same
    targets for every run, ``softtrack evaluate RUN --random N``), "random k" and arm, instead
    of ``trajectories``. In the transport task ``metric`` may also be
    :data:`~softtrack.evaluation.episode_tables.CARRY_SCORE`, derived from the stored columns.

    Raises:
        EmptySelectionError, RunNotFoundError: an item names no run (one line with the fix).
        RunStoreError: an item's runs have no stored ``metric``; two items select one run.
    """
    store = RunStore(resolve_runs_dir(runs_dir))
    index = RunIndex.of(store)
    tables = []
    named_by: dict[str, str] = {}
    for item in selection:
        records = select_runs(store, [item], index)
        for record in records:
            earlier = named_by.setdefault(record.info.run_id, item)
            if earlier != item or selection.count(item) > 1:
                raise RunStoreError(
                    f"compare: {earlier!r} and {item!r} both select run {record.info.run_id}; "
                    "name each controller once, with runs of its own"
                )
        runs = load_runs(records, ["random" if random else "metrics"])
        problems = [problem for run in runs for problem in run.problems]
        if problems:  # a seed left out silently would change every interval
            raise RunStoreError(f"{item}: {problems[0]}")
        tables.append([(run.seed, scored_rows(run, random)) for run in runs])
    if random:
        episodes = {
            str(t)
            for runs in tables
            for _, rows in runs
            if rows is not None
            for t in rows["trajectory"]
        }
        trajectories = sorted(episodes, key=lambda t: int(t.split()[-1]))
    table_name = "eval_random" if random else "eval_metrics"
    controllers = [
        controller_scores(item, runs, metric, trajectories, table_name)
        for item, runs in zip(selection, tables, strict=True)
    ]
    return compare_controllers(controllers, metric, reps=reps, seed=seed)


def scored_rows(run: RunData, random: bool) -> pd.DataFrame | None:
    """A run's eval_metrics (or, ``random``, its eval_random with each episode named "random
    k" as its trajectory), with the transport task's carry score derived."""
    rows = run.random if random else run.metrics
    if rows is None:
        return None
    if random:
        if "episode" not in rows:
            return None
        rows = rows.assign(trajectory="random " + rows["episode"].astype(int).astype(str))
    return with_carry_score(rows, run.eval_duration)


def profile_figure(
    panels: Sequence[tuple[str, Comparison]],
    path: str | os.PathLike[str],
    colors: Mapping[str, str] | None = None,
    footer: str | None = None,
    names: Mapping[str, str] | None = None,
) -> Path:
    """Performance profiles, one panel per (title, comparison): the fraction of (run, cell)
    scores at or below each threshold, one line per controller (``names``: the legend's name
    of a label, default the label)."""
    from softtrack.report.figures import new_figure, save_figure, suptitle  # matplotlib

    fig = new_figure(7.5 if len(panels) == 1 else 12.0, 4.2 * math.ceil(len(panels) / 2) + 0.8)
    cols = 1 if len(panels) == 1 else 2
    axes = fig.subplots(math.ceil(len(panels) / cols), cols, squeeze=False).ravel()
    for ax, (title, comparison) in zip(axes, panels, strict=False):
        top = max(float(np.nanmax(c.scores)) for c in comparison.controllers)
        bottom = min(float(np.nanmin(c.scores)) for c in comparison.controllers)
        taus = np.linspace(0.9 * bottom, 1.05 * top, 300)
        for i, c in enumerate(comparison.controllers):
            color = (colors or {}).get(c.label, f"C{i}")
            runs = len(c.seeds)
            name = (names or {}).get(c.label, c.label)
            label = f"{name} ({runs} run{'s' if runs != 1 else ''})"
            ax.plot(taus, performance_profile(c.scores, taus), color=color, lw=1.6, label=label)
        ax.set_xlabel(f"threshold τ on {comparison.metric} (m)")
        ax.set_ylabel("fraction of runs × cells with score ≤ τ")
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7.5, loc="lower right")
        if title:
            ax.set_title(title, fontsize=9.5)
    for ax in axes[len(panels) :]:
        ax.set_axis_off()
    suptitle(
        fig,
        "Performance profile",
        12,
        "higher and further left is better; every run's every trajectory and arm counts once",
    )
    return save_figure(fig, path, footer)
