"""The ``mpc:`` section of a spec: the sampling planner of ``controller: mpc`` (docs/mpc.md).

Field names equal those of :class:`softtrack.mpc.planner.PlannerConfig`, plus the planner's
model (``model``, ``model_scales``). The section is used only with ``controller: mpc``; it is
left out of :func:`~softtrack.spec.spec_hash` while at its defaults, so specs written before it
existed keep their hashes.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from softtrack.mpc.planner_config import PlannerConfig
from softtrack.sim.params import MODEL_PARAMETERS
from softtrack.spec.fields import (
    Float,
    Int,
    SpecModel,
    check_with_dataclass,
    custom_error,
    setting_field,
    unit_field,
)

__all__ = ["MpcSpec"]


class MpcSpec(SpecModel):
    """Sampling model predictive control over the batched engine (``controller: mpc``)."""

    method: Literal["mppi", "cem"] = setting_field(
        PlannerConfig,
        "method",
        "mppi: exponentially weighted mean of the samples; cem: mean of the elite",
    )
    samples: Int = setting_field(PlannerConfig, "samples", "plans rolled out per iteration (K)")
    horizon: Int = setting_field(
        PlannerConfig, "horizon", "control steps planned ahead (H; 50 = 100 ms)"
    )
    knots: Int | None = setting_field(
        PlannerConfig,
        "knots",
        "values per control value along the horizon, linearly interpolated (2 … horizon); "
        "null = one per control step",
    )
    iterations: Int = setting_field(PlannerConfig, "iterations", "sampling iterations per plan")
    noise_std: Float = setting_field(
        PlannerConfig, "noise_std", "std of the Gaussian perturbation of each knot value"
    )
    temperature: Float = setting_field(
        PlannerConfig,
        "temperature",
        "MPPI's lambda on plan costs normalised to [0, 1] (smaller = greedier)",
    )
    elite_fraction: Float = setting_field(
        PlannerConfig, "elite_fraction", "CEM: share of the samples refitted"
    )
    replan_interval: Int = setting_field(
        PlannerConfig,
        "replan_interval",
        "control steps executed from one plan before the next (≤ horizon)",
    )
    warm_start: bool = setting_field(
        PlannerConfig,
        "warm_start",
        "start each plan from the previous one shifted by the steps executed",
    )
    action_rate_weight: Float = setting_field(
        PlannerConfig,
        "action_rate_weight",
        "cost weight of the mean squared change of the control values per step",
    )
    action_weight: Float = setting_field(
        PlannerConfig, "action_weight", "cost weight of the mean squared control value"
    )
    model: Literal["true", "nominal"] = unit_field(
        "true",
        "the planner's model: the plant's parameters (env.realism's model error "
        "included) or the nominal env.physics",
        "-",
    )
    model_scales: dict[str, Float] = Field(
        default_factory=dict,
        description="extra model-error factors of the planner's model, e.g. "
        "{youngs_modulus_scale: 0.7}: a model that is wrong by this much [-]",
    )

    @field_validator("model_scales")
    @classmethod
    def _known_scales(cls, value: dict[str, float]) -> dict[str, float]:
        unknown = sorted(set(value) - set(MODEL_PARAMETERS))
        if unknown:
            raise custom_error(f"unknown factor {unknown[0]!r}; use " + ", ".join(MODEL_PARAMETERS))
        if any(not v > 0 for v in value.values()):
            raise custom_error("factors must be > 0")
        return value

    @model_validator(mode="after")
    def _check_plan(self) -> MpcSpec:
        check_with_dataclass(self, PlannerConfig(**self.planner_kwargs()).validate)
        return self

    def planner_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :class:`~softtrack.mpc.planner.PlannerConfig` (without the
        arm weights, which come from ``env.reward``)."""
        return self.model_dump(exclude={"model", "model_scales"})
