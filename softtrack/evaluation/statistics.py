"""Statistics for comparing controllers across seeds (pure NumPy/SciPy).

:func:`mean_difference` gives the difference of two controllers' seed means with Welch's
t-interval (unequal variances, Welch–Satterthwaite degrees of freedom) and its two-sided
p-value: with a handful of seeds per controller, the interval is the honest statement of what
the seeds show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["Difference", "mean_difference", "wilson_interval"]


@dataclass(frozen=True)
class Difference:
    """mean(a) − mean(b) with its confidence interval.

    Attributes:
        difference: mean(a) − mean(b), in the samples' unit.
        low, high: the interval's bounds (NaN with fewer than two samples on a side).
        p_value: two-sided p-value of "no difference" (NaN where the interval is).
        n_a, n_b: the sample sizes.
        confidence: the interval's level, e.g. 0.95.
    """

    difference: float
    low: float
    high: float
    p_value: float
    n_a: int
    n_b: int
    confidence: float

    def text(self, digits: int = 4, scale: float = 1.0) -> str:
        """``-0.0040 [-0.0071, -0.0009]`` (values × ``scale``); no interval when undefined."""
        value = f"{scale * self.difference:+.{digits}f}"
        if not math.isfinite(self.low):
            return value
        return f"{value} [{scale * self.low:+.{digits}f}, {scale * self.high:+.{digits}f}]"


def mean_difference(a: ArrayLike, b: ArrayLike, confidence: float = 0.95) -> Difference:
    """Welch's interval for mean(a) − mean(b).

    Args:
        a, b: (n_a,), (n_b,) one value per seed (e.g. a trajectory/arm cell's 3-D RMSE, m);
            non-finite values are left out.
        confidence: the interval's level in (0, 1).

    Raises:
        ValueError: a side has no finite value, or ``confidence`` is outside (0, 1).
    """
    from scipy import stats  # here: a second of import for the one function that needs it

    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence={confidence!r} must lie in (0, 1)")
    x = np.asarray(a, dtype=np.float64).reshape(-1)
    y = np.asarray(b, dtype=np.float64).reshape(-1)
    x, y = x[np.isfinite(x)], y[np.isfinite(y)]
    if x.size == 0 or y.size == 0:
        raise ValueError("each side needs at least one finite value")
    difference = float(x.mean() - y.mean())
    nan = float("nan")
    if x.size < 2 or y.size < 2:
        return Difference(difference, nan, nan, nan, x.size, y.size, confidence)
    va, vb = x.var(ddof=1) / x.size, y.var(ddof=1) / y.size
    se = math.sqrt(va + vb)
    if se == 0.0:
        p = 1.0 if difference == 0.0 else 0.0
        return Difference(difference, difference, difference, p, x.size, y.size, confidence)
    dof = (va + vb) ** 2 / (va**2 / (x.size - 1) + vb**2 / (y.size - 1))
    half = float(stats.t.ppf(0.5 + confidence / 2.0, dof)) * se
    p_value = float(2.0 * stats.t.sf(abs(difference) / se, dof))
    return Difference(
        difference, difference - half, difference + half, p_value, x.size, y.size, confidence
    )


def wilson_interval(successes: int, trials: int, z: float = 1.959964) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (95 % by default): e.g. the share
    of fresh seeds that reach a target, or of episodes that carry the sphere through."""
    if trials <= 0:
        raise ValueError("no trials")
    p = successes / trials
    denominator = 1.0 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    return max(0.0, centre - half), min(1.0, centre + half)
