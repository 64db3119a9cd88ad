"""Sampling-based model predictive control over softtrack's own batched rod engine.

:class:`SamplingPlanner` plans the 24 control values of the dual-arm scene over a horizon of H
control steps. Each iteration draws K perturbed plans around the current mean, rolls all of
them out in one :class:`~softtrack.sim.engine.RodBatch` of K environments branched from the
current state (:meth:`~softtrack.sim.engine.RodBatch.set_state`), scores each by the tracking
cost along the target's known path, and updates the mean:

* ``mppi``: the exponentially weighted mean of all samples, weights exp(−c̃/λ) with the costs
  c̃ normalised to [0, 1] over the batch (λ: ``temperature``);
* ``cem``: the mean (and, per value, the std) of the ``elite_fraction`` cheapest samples.

A plan is given by ``knots`` values per control value, linearly interpolated over the H steps
(``knots = H``: one value per control step; fewer knots give smooth plans and a smaller search
space). The first sample of every iteration is the current mean itself, so an iteration never
loses the best plan it started from. Between control steps the mean is shifted in time by the
steps executed (warm start) and the tail holds its last value.

Cost of a plan, summed over its H steps after each control step (m² and unitless penalties):
Σᵢ wᵢ·dᵢ² + c_rate·mean((aₜ − aₜ₋₁)²) + c_act·mean(aₜ²), with dᵢ the distance from tip i to
where the target will be, wᵢ the reward's arm weights; a plan whose state becomes non-finite
costs +inf. With a sphere in the model (the transport task) the tracking term is the sphere's,
w̄·d² (d: its centre's distance from its goal, w̄ the mean arm weight), plus the reward's hold
bonus b_hold for each arm not touching the sphere in the step.
"""

from __future__ import annotations

import numpy as np

from softtrack.mpc.planner_config import PlannerConfig
from softtrack.sim.actuation import N_CONTROL_POINTS
from softtrack.sim.engine import RodBatch, RodState
from softtrack.sim.params import SimParams

__all__ = ["PlannerConfig", "SamplingPlanner", "interpolation_matrix"]


def interpolation_matrix(horizon: int, knots: int) -> np.ndarray:
    """(horizon, knots) weights that turn knot values into per-step values: knot j sits at
    step j·(H − 1)/(knots − 1) and step h takes the linear interpolation between its two
    neighbouring knots (``knots = H`` gives the identity)."""
    if knots == 1:
        return np.ones((horizon, 1))
    at = np.linspace(0.0, horizon - 1.0, knots)
    steps = np.arange(horizon, dtype=float)
    weights = np.zeros((horizon, knots))
    right = np.clip(np.searchsorted(at, steps, side="right"), 1, knots - 1)
    left = right - 1
    frac = (steps - at[left]) / (at[right] - at[left])
    weights[np.arange(horizon), left] = 1.0 - frac
    weights[np.arange(horizon), right] += frac
    return weights


class SamplingPlanner:
    """MPPI or CEM over a batch of ``config.samples`` rod systems (module docstring).

    Args:
        config: the planner settings.
        sim: the model's physics (the engine is built from it).
        rng: the generator of the sampling noise (a seeded one makes plans reproducible).
        model_factors: model-error factors of the model (name → factor,
            :meth:`~softtrack.sim.engine.RodBatch.set_parameters`); ``None``: nominal.
        hold_weight: with a sphere in ``sim``, the cost of each arm not touching it in a
            step (the transport task's ``hold_bonus``).
        action_offset: (24,) added to every sampled control before clipping, as the
            environment adds it (the transport task's grip); ``None``: zeros.
    """

    def __init__(
        self,
        config: PlannerConfig,
        sim: SimParams,
        rng: np.random.Generator,
        model_factors: dict[str, float] | None = None,
        hold_weight: float = 0.0,
        action_offset: np.ndarray | None = None,
    ) -> None:
        config.validate()
        self.config = config
        self.rng = rng
        self.model = RodBatch(config.samples, sim)
        if model_factors:
            self.model.set_parameters(None, model_factors)
        self.n_arms = sim.n_arms
        self.action_dim = self.n_arms * 2 * N_CONTROL_POINTS
        h, m = config.horizon, config.n_knots
        self._expand = interpolation_matrix(h, m)
        # warm start: knot j of the next plan = this plan at knot j's (rounded) step + r
        knot_steps = np.rint(np.linspace(0, h - 1, m)).astype(int)
        self._warm_steps = np.minimum(knot_steps + config.replan_interval, h - 1)
        self.mean = np.zeros((m, self.action_dim))
        self.std = np.full((m, self.action_dim), config.noise_std)
        self.weights = np.asarray(config.arm_weights, dtype=float)
        self.hold_weight = float(hold_weight)
        self.action_offset = action_offset

    def reset(self) -> None:
        """Forget the previous plan (a new episode)."""
        self.mean[:] = 0.0
        self.std[:] = self.config.noise_std

    def plan(
        self, state: RodState, target_path: np.ndarray, previous_action: np.ndarray
    ) -> np.ndarray:
        """Plan from ``state`` and return the per-step plan.

        Args:
            state: the system's current state (one environment).
            target_path: (H, A, 3) each arm's point (or (H, 3) one point for all arms; with
                a sphere, its goal) after each of the next H control steps, m.
            previous_action: (24,) the control values applied in the last step.

        Returns:
            (H, 24) control values in [−1, 1] for the next H control steps.
        """
        c = self.config
        k, h = c.samples, c.horizon
        self.mean = (
            (self._expand @ self.mean)[self._warm_steps]
            if c.warm_start
            else np.zeros_like(self.mean)
        )
        self.std[:] = c.noise_std
        for _ in range(c.iterations):
            noise = self.rng.standard_normal((k, *self.mean.shape)) * self.std
            noise[0] = 0.0
            knots = np.clip(self.mean + noise, -1.0, 1.0)
            controls = np.clip(np.einsum("hm,kmd->khd", self._expand, knots), -1.0, 1.0)
            cost = self._rollout_costs(state, controls, target_path, previous_action)
            self._update(knots, cost)
            if not np.isfinite(cost).any():
                break
        return np.clip(self._expand @ self.mean, -1.0, 1.0)[:h]

    def _rollout_costs(
        self,
        state: RodState,
        controls: np.ndarray,
        target_path: np.ndarray,
        previous_action: np.ndarray,
    ) -> np.ndarray:
        c, model = self.config, self.model
        k = c.samples
        model.set_state(state)
        cost = np.zeros(k)
        last = np.broadcast_to(previous_action, (k, self.action_dim))
        for step in range(c.horizon):
            u = controls[:, step]
            commanded = u if self.action_offset is None else np.clip(u + self.action_offset, -1, 1)
            model.set_actions(commanded.reshape(k, self.n_arms, 2, N_CONTROL_POINTS))
            model.advance()
            if model.has_sphere:
                diff = model.sphere_position - target_path[step]
                cost += float(np.mean(self.weights)) * np.einsum("ki,ki->k", diff, diff)
                untouched = model.sphere_contact_state()[2] == 0
                cost += self.hold_weight * untouched.sum(axis=1)
            else:
                diff = model.tip_position - target_path[step]
                cost += np.einsum("kai,kai->ka", diff, diff) @ self.weights
            if c.action_rate_weight:
                cost += c.action_rate_weight * np.mean((u - last) ** 2, axis=1)
            if c.action_weight:
                cost += c.action_weight * np.mean(u * u, axis=1)
            last = u
        cost[~model.finite() | ~np.isfinite(cost)] = np.inf
        return cost

    def _update(self, knots: np.ndarray, cost: np.ndarray) -> None:
        finite = np.isfinite(cost)
        if not finite.any():
            return
        c = self.config
        if c.method == "cem":
            n_elite = max(1, round(c.elite_fraction * c.samples))
            elite = knots[np.argsort(np.where(finite, cost, np.inf))[:n_elite]]
            self.mean = elite.mean(axis=0)
            self.std = np.maximum(elite.std(axis=0), 1e-3 * c.noise_std)
            return
        low, high = cost[finite].min(), cost[finite].max()
        scaled = (cost - low) / (high - low) if high > low else np.zeros_like(cost)
        weights = np.where(finite, np.exp(-scaled / c.temperature), 0.0)
        weights /= weights.sum()
        self.mean = np.einsum("k,kmd->md", weights, knots)
