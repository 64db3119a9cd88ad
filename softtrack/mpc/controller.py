"""An MPC controller that plans on the evaluation episode's own engine state.

:class:`MpcController` is a :data:`~softtrack.evaluation.episodes.Policy` with
``start_episode(core)``: :func:`~softtrack.evaluation.episodes.run_episode` hands it the
episode's :class:`~softtrack.env.core.TrackingCore`, and at every replanning step it reads the
true state of the arms (full-state feedback: the realism's sensing noise and delays do not
reach it) and the target's path over the horizon (the closed form of a circle, rectangle,
figure-eight or fixed target; a random target extrapolated at its current velocity; in the
transport task the sphere's goal, :meth:`~softtrack.env.transport_env.TransportModel.goal_ahead`), plans
with a :class:`~softtrack.mpc.planner.SamplingPlanner` and returns the plan's control values
one step after the other (:func:`~softtrack.evaluation.episodes.run_episode` times each call).

The planner's model is the plant's own engine parameters by default (``model="true"``: any
model error of ``env.realism`` included), or the nominal ``env.physics`` (``model="nominal"``);
``model_scales`` multiplies further factors in, so model error can be measured either way.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Literal

import numpy as np

from softtrack.env.targets import CLOSED_FORM_MODES, trajectory_position
from softtrack.mpc.planner import SamplingPlanner
from softtrack.mpc.planner_config import PlannerConfig
from softtrack.sim.params import MODEL_PARAMETERS

if TYPE_CHECKING:
    from softtrack.env.core import TrackingCore

__all__ = ["MpcController"]


class MpcController:
    """Sampling MPC as an evaluation policy (module docstring).

    Args:
        config: the planner settings.
        seed: seed of the sampling noise; every episode starts from it, so an episode is
            reproducible on its own.
        model: ``true`` (the plant's parameters) or ``nominal``.
        model_scales: extra model-error factors of the planner's model (name → factor).
    """

    def __init__(
        self,
        config: PlannerConfig,
        seed: int = 0,
        model: Literal["true", "nominal"] = "true",
        model_scales: Mapping[str, float] | None = None,
    ) -> None:
        config.validate()
        unknown = sorted(set(model_scales or {}) - set(MODEL_PARAMETERS))
        if unknown:
            raise ValueError(
                f"unknown model scale {unknown[0]!r}; use " + ", ".join(MODEL_PARAMETERS)
            )
        self.config = config
        self.seed = int(seed)
        self.model = model
        self.model_scales = dict(model_scales or {})
        self._core: TrackingCore | None = None
        self._planner: SamplingPlanner | None = None
        self._plan = np.zeros((0, 0))
        self._next = 0
        self._previous = np.zeros(0)

    def start_episode(self, core: TrackingCore) -> None:
        """Plan for ``core``'s environment 0 from now on (after its reset)."""
        factors = (
            core.parameters(0) if self.model == "true" else dict.fromkeys(MODEL_PARAMETERS, 1.0)
        )
        for name, scale in self.model_scales.items():
            factors[name] *= float(scale)
        model_factors = {n: f for n, f in factors.items() if f != 1.0}
        self._core = core
        self._planner = SamplingPlanner(
            self.config,
            core.config.sim,
            np.random.default_rng(self.seed),
            model_factors,
            hold_weight=core.config.task.hold_bonus,
            action_offset=core.config.task.action_offset() if core.config.task.grip else None,
        )
        self._plan = np.zeros((0, core.action_dim))
        self._next = 0
        self._previous = np.zeros(core.action_dim)

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        """The next control values (24,), planning first when the plan's executed part is
        used up (every ``replan_interval`` steps)."""
        core, planner = self._core, self._planner
        if core is None or planner is None:
            raise RuntimeError("MpcController needs start_episode(core) before its first call")
        if self._next >= min(self.config.replan_interval, len(self._plan)):
            self._plan = planner.plan(
                core.engine.get_state([0]), self._target_path(core), self._previous
            )
            self._next = 0
        action = self._plan[self._next].copy()
        self._next += 1
        self._previous = action
        return action

    def _target_path(self, core: TrackingCore) -> np.ndarray:
        """(H, A, 3) each arm's point (target centre plus the task's offset) after each of
        the next H control steps, m; in the transport task (H, 3) the sphere's goal."""
        targets = core.targets
        if core.transport is not None:
            steps = np.arange(1, self.config.horizon + 1)
            return core.transport.goal_ahead(int(core.step_count[0]), targets, 0, steps)
        ahead = np.arange(1, self.config.horizon + 1) * core.config.sim.control_dt
        if targets.config.name in CLOSED_FORM_MODES:
            centre = trajectory_position(targets.config, targets.time[0] + ahead)
        else:
            low, high = targets.shrunk_box
            centre = np.clip(targets.position[0] + ahead[:, None] * targets.velocity[0], low, high)
        return centre[:, None, :] + core.goal_offsets[None]
