"""The reward's settings (``docs/environment.md``, "Reward"): a plain dataclass, apart from the
reward's numba kernels (:mod:`softtrack.env.reward`), so the spec models can take their defaults
from it without loading numba."""

from __future__ import annotations

from dataclasses import dataclass

from softtrack.numbers import is_finite_number, out_of_range, setting

__all__ = ["RewardConfig"]


@dataclass(frozen=True)
class RewardConfig:
    """Reward settings (defaults: the dual-arm reward of the study).

    Attributes:
        arm_weights: wᵢ, one per arm, weights of −dᵢ² (1/m²).
        bonus_thresholds: θ_k, distance thresholds of the individual bonuses, m.
        bonus_values: b_k, bonus paid per arm within θ_k (same length as the thresholds).
        cooperative_threshold: θ_coop, m; the cooperative bonus needs every arm within it.
        cooperative_bonus: b_coop (0 disables the term).
        nonfinite_reward: reward of a step whose state is not finite (the episode ends).
        collision_penalty: c_col ≥ 0 subtracted when the arms come too close (0 disables).
        collision_margin: extra clearance added to 2·arm_radius, m.
        arm_radius: radius of each arm for the collision test, m.
        action_rate_penalty: c_rate ≥ 0, weight of the mean squared change of the clipped
            action values since the previous control step (0 at a reset); 0 disables it.
        action_penalty: c_act ≥ 0, weight of the mean squared clipped action value (drives
            actions away from saturation); 0 disables it.
    """

    arm_weights: tuple[float, ...] = setting((1.0, 1.0), "1/m²", number=False)
    bonus_thresholds: tuple[float, ...] = setting((0.10, 0.075), "m", number=False)
    bonus_values: tuple[float, ...] = setting((0.5, 1.0), "reward units", number=False)
    cooperative_threshold: float = setting(0.05, "m", gt=0)
    cooperative_bonus: float = setting(1.5, "reward units")
    nonfinite_reward: float = setting(-1000.0, "reward units")
    collision_penalty: float = setting(0.0, "reward units", ge=0)
    collision_margin: float = setting(0.0, "m", ge=0)
    arm_radius: float = setting(0.05, "m", gt=0)
    action_rate_penalty: float = setting(0.0, "reward units", ge=0)
    action_penalty: float = setting(0.0, "reward units", ge=0)

    @classmethod
    def single_arm(cls) -> RewardConfig:
        """The original single-arm reward: −d² + 0.5·1(d ≤ 0.10) + 1.5·1(d ≤ 0.05)."""
        return cls(
            arm_weights=(1.0,),
            bonus_thresholds=(0.10, 0.05),
            bonus_values=(0.5, 1.5),
            cooperative_bonus=0.0,
        )

    @property
    def n_arms(self) -> int:
        return len(self.arm_weights)

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field and how to fix it."""
        if len(self.arm_weights) < 1:
            raise ValueError("reward arm_weights must hold one weight per arm (e.g. (1.0, 1.0))")
        for name in ("arm_weights", "bonus_thresholds", "bonus_values"):
            values = getattr(self, name)
            if not all(is_finite_number(v) for v in values):
                raise ValueError(f"reward {name}={values!r} must be finite numbers")
        if any(w < 0 for w in self.arm_weights):
            raise ValueError(f"reward arm_weights={self.arm_weights!r} must be ≥ 0")
        if len(self.bonus_thresholds) != len(self.bonus_values):
            raise ValueError(
                f"reward bonus_thresholds ({len(self.bonus_thresholds)} values) and bonus_values "
                f"({len(self.bonus_values)} values) must have the same length"
            )
        if any(t <= 0 for t in self.bonus_thresholds):
            raise ValueError(f"reward bonus_thresholds={self.bonus_thresholds!r} must be > 0 m")
        problem = out_of_range(self, "reward ")
        if problem is not None:
            raise ValueError(problem)

    @property
    def penalises_actions(self) -> bool:
        """True when an action penalty is on."""
        return bool(self.action_rate_penalty or self.action_penalty)
