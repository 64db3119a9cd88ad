"""Across-seed statistics in the manner of rliable (Agarwal et al., 2021), on NumPy/SciPy.

Scores are errors (lower is better, e.g. the 3-D RMSE in m) arranged as a matrix of runs ×
cells (a cell is a trajectory and arm); a run may lack a cell (NaN). The statistics:

* :func:`interquartile_mean`: the mean of the middle 50 % of the values (25 % trimmed from
  each end; fewer than 4 values: nothing is trimmed), robust to one bad seed and less noisy
  than the median;
* :func:`stratified_bootstrap`: a percentile confidence interval of any statistic of the
  matrix, resampling runs with replacement within each cell (stratified by cell), so every
  cell keeps its number of runs;
* :func:`probability_of_improvement`: P(X < Y) for a random run X of controller A and Y of B
  in the same cell (ties count half), averaged over cells: 0.5 means no difference, above 0.5
  A is better; its interval resamples the runs of both;
* :func:`performance_profile`: the fraction of (run, cell) scores at or below each threshold.

All resampling uses ``numpy.random.default_rng(seed)``, so a result is reproducible.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "BOOTSTRAP_REPS",
    "Interval",
    "interquartile_mean",
    "performance_profile",
    "probability_of_improvement",
    "stratified_bootstrap",
]

BOOTSTRAP_REPS = 2000
"""Bootstrap resamples of an interval (rliable's default is 2000 too)."""


@dataclass(frozen=True)
class Interval:
    """A point estimate with its percentile bootstrap interval."""

    value: float
    low: float
    high: float
    confidence: float = 0.95

    def text(self, digits: int = 4, scale: float = 1.0) -> str:
        """``0.0412 [0.0398, 0.0430]`` (values × ``scale``)."""
        return (
            f"{scale * self.value:.{digits}f} "
            f"[{scale * self.low:.{digits}f}, {scale * self.high:.{digits}f}]"
        )


def interquartile_mean(values: ArrayLike) -> float:
    """The mean of the middle 50 % of the finite ``values`` (any shape, flattened);
    NaN without a finite value. The very operations of ``scipy.stats.trim_mean(values,
    0.25)`` (so the same bits), without its per-call overhead, which made a bootstrap of
    2,000 replicates cost seconds."""
    array = np.asarray(values, dtype=float).ravel()
    array = array[np.isfinite(array)]
    if not array.size:
        return math.nan
    lowercut = int(0.25 * array.size)
    uppercut = array.size - lowercut
    return float(np.mean(np.partition(array, (lowercut, uppercut - 1))[lowercut:uppercut]))


def _interquartile_means(samples: np.ndarray) -> np.ndarray:
    """:func:`interquartile_mean` of each of ``samples`` (reps, runs, cells) at once, the same
    bits: every sample has its NaN padding in the same places (a stratified resample keeps
    each cell's size), so its finite values, in order, are one row of a (reps, m) matrix."""
    flat = samples.reshape(len(samples), -1)
    finite = np.isfinite(flat[0])
    rows = np.ascontiguousarray(flat[:, finite])
    if not rows.shape[1]:
        return np.full(len(samples), math.nan)
    lowercut = int(0.25 * rows.shape[1])
    uppercut = rows.shape[1] - lowercut
    middle = np.partition(rows, (lowercut, uppercut - 1), axis=1)[:, lowercut:uppercut]
    return np.mean(np.ascontiguousarray(middle), axis=1)


def _columns(scores: ArrayLike) -> list[np.ndarray]:
    """Each cell's finite scores of a runs × cells matrix (a 1-D input is one cell)."""
    matrix = np.asarray(scores, dtype=float)
    if matrix.ndim == 1:
        matrix = matrix[:, None]
    if matrix.ndim != 2:
        raise ValueError(f"scores must be runs × cells, got shape {matrix.shape}")
    return [col[np.isfinite(col)] for col in matrix.T]


def _check(confidence: float, reps: int) -> None:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence {confidence} is outside (0, 1)")
    if reps < 1:
        raise ValueError(f"reps {reps} must be at least 1")


def _resamples(columns: Sequence[np.ndarray], rng: np.random.Generator, reps: int) -> np.ndarray:
    """``reps`` stratified resamples, (reps, runs, cells), NaN-padded to the longest cell;
    drawn one replicate after another, cell by cell."""
    rows = max(len(c) for c in columns)
    out = np.full((reps, rows, len(columns)), np.nan)
    for rep in range(reps):
        for j, col in enumerate(columns):
            if len(col):
                out[rep, : len(col), j] = col[rng.integers(0, len(col), len(col))]
    return out


def _padded(columns: Sequence[np.ndarray]) -> np.ndarray:
    rows = max(len(c) for c in columns)
    out = np.full((rows, len(columns)), np.nan)
    for j, col in enumerate(columns):
        out[: len(col), j] = col
    return out


def stratified_bootstrap(
    scores: ArrayLike,
    statistic: Callable[[np.ndarray], float] = interquartile_mean,
    *,
    reps: int = BOOTSTRAP_REPS,
    confidence: float = 0.95,
    seed: int = 0,
) -> Interval:
    """``statistic`` of a runs × cells score matrix with its percentile bootstrap interval,
    runs resampled with replacement within each cell.

    Args:
        scores: (runs, cells) scores (NaN: no score), or (runs,) for one cell.
        statistic: maps a (runs, cells) matrix (NaN-padded) to a number; default the IQM of
            all scores.

    Raises:
        ValueError: no finite score, a bad shape, ``confidence`` outside (0, 1), ``reps`` < 1.
    """
    _check(confidence, reps)
    columns = _columns(scores)
    if not any(len(c) for c in columns):
        raise ValueError("no finite score to bootstrap")
    rng = np.random.default_rng(seed)
    value = statistic(_padded(columns))
    resamples = _resamples(columns, rng, reps)
    if statistic is interquartile_mean:
        draws = _interquartile_means(resamples)
    else:
        draws = np.array([statistic(sample) for sample in resamples])
    tail = 50.0 * (1.0 - confidence)
    low, high = np.nanpercentile(draws, [tail, 100.0 - tail])
    return Interval(float(value), float(low), float(high), confidence)


def _improvement(a: Sequence[np.ndarray], b: Sequence[np.ndarray]) -> float:
    """Mean over cells with scores on both sides of P(a < b) + ½ P(a = b)."""
    per_cell = []
    for x, y in zip(a, b, strict=True):
        if len(x) and len(y):
            less = (x[:, None] < y[None, :]).mean()
            ties = (x[:, None] == y[None, :]).mean()
            per_cell.append(less + 0.5 * ties)
    return float(np.mean(per_cell)) if per_cell else math.nan


def _improvements(picks_a: list[list[np.ndarray]], picks_b: list[list[np.ndarray]]) -> np.ndarray:
    """:func:`_improvement` of every replicate at once, the same bits (counts of 0/1 are
    exact; the per-cell values are averaged along a contiguous axis, as one replicate's
    are). ``picks_*[cell]``: that cell's resampled scores, one array per replicate."""
    per_cell = []
    for xs, ys in zip(picks_a, picks_b, strict=True):
        if xs and ys:
            x, y = np.stack(xs)[:, :, None], np.stack(ys)[:, None, :]
            size = x.shape[1] * y.shape[2]
            less = (x < y).sum(axis=(1, 2)) / size
            ties = (x == y).sum(axis=(1, 2)) / size
            per_cell.append(less + 0.5 * ties)
    return np.mean(np.ascontiguousarray(np.stack(per_cell, axis=1)), axis=1)


def probability_of_improvement(
    scores_a: ArrayLike,
    scores_b: ArrayLike,
    *,
    reps: int = BOOTSTRAP_REPS,
    confidence: float = 0.95,
    seed: int = 0,
) -> Interval:
    """P(A improves on B): the probability that a random run of A has a lower score than a
    random run of B in the same cell (ties half), averaged over the cells both have, with a
    stratified bootstrap interval (runs of A and of B resampled within each cell).

    Args:
        scores_a, scores_b: (runs_a, cells), (runs_b, cells) errors, the same cells in the
            same order (NaN: no score).

    Raises:
        ValueError: the matrices have different numbers of cells, or no cell has scores on
            both sides.
    """
    _check(confidence, reps)
    a, b = _columns(scores_a), _columns(scores_b)
    if len(a) != len(b):
        raise ValueError(f"A has {len(a)} cells and B {len(b)}: compare the same cells")
    value = _improvement(a, b)
    if not math.isfinite(value):
        raise ValueError("no cell has scores of both controllers")
    rng = np.random.default_rng(seed)
    picks_a: list[list[np.ndarray]] = [[] for _ in a]
    picks_b: list[list[np.ndarray]] = [[] for _ in b]
    for _ in range(reps):  # the draws of one replicate after another, as they always were
        for picks, cells in ((picks_a, a), (picks_b, b)):
            for j, c in enumerate(cells):
                if len(c):
                    picks[j].append(c[rng.integers(0, len(c), len(c))])
    draws = _improvements(picks_a, picks_b)
    tail = 50.0 * (1.0 - confidence)
    low, high = np.percentile(draws, [tail, 100.0 - tail])
    return Interval(value, float(low), float(high), confidence)


def performance_profile(scores: ArrayLike, thresholds: ArrayLike) -> np.ndarray:
    """(len(thresholds),) the fraction of the finite (run, cell) scores ≤ each threshold."""
    values = np.asarray(scores, dtype=float).ravel()
    values = np.sort(values[np.isfinite(values)])
    if not values.size:
        raise ValueError("no finite score for a performance profile")
    taus = np.asarray(thresholds, dtype=float)
    return np.searchsorted(values, taus, side="right") / values.size
