"""The reward's settings (``docs/environment.md``, "Reward"): a plain dataclass, apart from the
reward's numba kernels (:mod:`softtrack.env.reward`), so the spec models can take their defaults
from it without loading numba."""

from __future__ import annotations

from dataclasses import dataclass

from softtrack.numbers import is_finite_number

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

    arm_weights: tuple[float, ...] = (1.0, 1.0)
    bonus_thresholds: tuple[float, ...] = (0.10, 0.075)
    bonus_values: tuple[float, ...] = (0.5, 1.0)
    cooperative_threshold: float = 0.05
    cooperative_bonus: float = 1.5
    nonfinite_reward: float = -1000.0
    collision_penalty: float = 0.0
    collision_margin: float = 0.0
    arm_radius: float = 0.05
    action_rate_penalty: float = 0.0
    action_penalty: float = 0.0

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
        for name in (
            "cooperative_threshold",
            "cooperative_bonus",
            "nonfinite_reward",
            "collision_penalty",
            "collision_margin",
            "arm_radius",
            "action_rate_penalty",
            "action_penalty",
        ):
            if not is_finite_number(getattr(self, name)):
                raise ValueError(f"reward {name}={getattr(self, name)!r} must be a finite number")
        if self.cooperative_threshold <= 0:
            raise ValueError(
                f"reward cooperative_threshold={self.cooperative_threshold!r} must be > 0 m"
            )
        if self.collision_penalty < 0:
            raise ValueError(
                f"reward collision_penalty={self.collision_penalty!r} must be ≥ 0 "
                "(it is subtracted; 0 disables it)"
            )
        if self.collision_margin < 0:
            raise ValueError(f"reward collision_margin={self.collision_margin!r} must be ≥ 0 m")
        if self.arm_radius <= 0:
            raise ValueError(f"reward arm_radius={self.arm_radius!r} must be > 0 m")
        for name in ("action_rate_penalty", "action_penalty"):
            if getattr(self, name) < 0:
                raise ValueError(
                    f"reward {name}={getattr(self, name)!r} must be ≥ 0 (it is "
                    "subtracted; 0 disables it)"
                )

    @property
    def penalises_actions(self) -> bool:
        """True when an action penalty is on."""
        return bool(self.action_rate_penalty or self.action_penalty)
