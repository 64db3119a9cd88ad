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
from softtrack.spec.fields import Float, Int, SpecModel, custom_error, unit_field

__all__ = ["MpcSpec"]


class MpcSpec(SpecModel):
    """Sampling model predictive control over the batched engine (``controller: mpc``)."""

    method: Literal["mppi", "cem"] = unit_field(
        "mppi", "mppi: exponentially weighted mean of the samples; cem: mean of the elite", "-"
    )
    samples: Int = unit_field(64, "plans rolled out per iteration (K)", "-", ge=2)
    horizon: Int = unit_field(
        50, "control steps planned ahead (H; 50 = 100 ms)", "control steps", ge=1
    )
    knots: Int | None = unit_field(
        5,
        "values per control value along the horizon, linearly interpolated (2 … horizon); "
        "null = one per control step",
        "-",
        ge=1,
    )
    iterations: Int = unit_field(1, "sampling iterations per plan", "-", ge=1)
    noise_std: Float = unit_field(
        0.3, "std of the Gaussian perturbation of each knot value", "control units", gt=0
    )
    temperature: Float = unit_field(
        0.05, "MPPI's lambda on plan costs normalised to [0, 1] (smaller = greedier)", "-", gt=0
    )
    elite_fraction: Float = unit_field(0.1, "CEM: share of the samples refitted", "-", gt=0, le=1)
    replan_interval: Int = unit_field(
        5,
        "control steps executed from one plan before the next (≤ horizon)",
        "control steps",
        ge=1,
    )
    warm_start: bool = unit_field(
        True, "start each plan from the previous one shifted by the steps executed", "-"
    )
    action_rate_weight: Float = unit_field(
        0.0, "cost weight of the mean squared change of the control values per step", "-", ge=0
    )
    action_weight: Float = unit_field(
        0.0, "cost weight of the mean squared control value", "-", ge=0
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
        try:
            PlannerConfig(**self.planner_kwargs()).validate()
        except ValueError as exc:
            field = str(exc).split("=", 1)[0]
            raise custom_error(
                str(exc), field if field in type(self).model_fields else ""
            ) from None
        return self

    def planner_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :class:`~softtrack.mpc.planner.PlannerConfig` (without the
        arm weights, which come from ``env.reward``)."""
        return self.model_dump(exclude={"model", "model_scales"})
