"""The settings of a sampling planner (:class:`PlannerConfig`), without the engine, so that the
spec validates them without importing numba."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from softtrack.numbers import out_of_range, setting

__all__ = ["PlannerConfig"]


@dataclass(frozen=True)
class PlannerConfig:
    """Settings of a :class:`SamplingPlanner` (the spec's ``mpc:`` section).

    Attributes:
        method: ``mppi`` or ``cem``.
        samples: K plans rolled out per iteration (≥ 2).
        horizon: H control steps planned ahead (≥ 1; 50 = 100 ms at the study's control step).
        knots: values per control value along the horizon (2 ≤ knots ≤ H, or H = 1 and 1);
            ``None`` = H.
        iterations: sampling iterations per plan (≥ 1).
        noise_std: std of the Gaussian perturbation of each knot value (control units, > 0).
        temperature: MPPI's λ on costs normalised to [0, 1] (> 0; smaller = greedier).
        elite_fraction: CEM's share of samples refitted (0 < f ≤ 1).
        replan_interval: control steps executed from one plan before the next (1 ≤ r ≤ H).
        warm_start: start each plan from the previous one shifted in time (else from zeros).
        arm_weights: wᵢ of the squared tip distances (1/m²).
        action_rate_weight: c_rate on the mean squared change of the control values per step.
        action_weight: c_act on the mean squared control value.
    """

    method: Literal["mppi", "cem"] = setting("mppi", number=False)
    samples: int = setting(64, ge=2, whole=True)
    horizon: int = setting(50, "control steps", ge=1, whole=True)
    knots: int | None = setting(5, ge=1, whole=True, off=True)
    iterations: int = setting(1, ge=1, whole=True)
    noise_std: float = setting(0.3, "control units", gt=0)
    temperature: float = setting(0.05, gt=0)
    elite_fraction: float = setting(0.1, gt=0, le=1)
    replan_interval: int = setting(5, "control steps", ge=1, whole=True)
    warm_start: bool = setting(True, number=False)
    arm_weights: tuple[float, ...] = (1.0, 1.0)
    action_rate_weight: float = setting(0.0, ge=0)
    action_weight: float = setting(0.0, ge=0)

    @property
    def n_knots(self) -> int:
        return self.horizon if self.knots is None else int(self.knots)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid setting and its valid range."""
        if self.method not in ("mppi", "cem"):
            raise ValueError(f"method={self.method!r}: use mppi or cem")
        problem = out_of_range(self)
        if problem is not None:
            raise ValueError(problem)
        if not 1 <= self.n_knots <= self.horizon or (self.n_knots == 1 and self.horizon > 1):
            raise ValueError(
                f"knots={self.knots!r} must be in 2 … horizon ({self.horizon}), "
                "or null for one per control step"
            )
        if self.replan_interval > self.horizon:
            raise ValueError(
                f"replan_interval={self.replan_interval} must be ≤ horizon ({self.horizon})"
            )
