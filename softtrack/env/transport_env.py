"""Cooperative transport: two arms carry a rigid sphere along the target's path
(docs/environment.md, "Transport").

**Start and goal.** Every episode starts with both arms straight and at rest and the sphere at
its ``SimParams.sphere.center`` (by default between the tips, touching both). The goal g(t)
moves from that centre c₀ to the path's start p(0) over the task's ``approach`` T_a seconds
with a smoothstep, g = c₀ + (3τ² − 2τ³)·(p(0) − c₀), τ = t/T_a, and then follows the path,
g(t) = p(t − T_a): the target (random, circle, rectangle, figure-eight) rests during the
approach and starts at T_a. Every controller gets the same goal. A training curriculum
(``training.goal_warmup_steps``) scales the goal's motion by m ∈ [0, 1] (:attr:`TransportModel.
goal_motion`): g_m = c₀ + m·(g − c₀), its velocity m·ġ; m = 0 keeps the goal where the sphere
starts. Evaluation and validation always see m = 1.

**Observation** (88 values for 21 nodes): the study's 81 with the target block replaced by the
sphere, then the goal:

=========  ==========================================================
0–73       the two arms (as docs/environment.md)
74–76      sphere centre, m
77         sphere speed, m/s
78–80      sphere velocity direction (zeros when still)
81–83      goal, m
84         goal speed, m/s
85–87      goal velocity direction (zeros when still)
=========  ==========================================================

**Reward** per control step, with d the distance of the sphere's centre from the goal (m),
hᵢ = 1 when arm i touched the sphere during the step, Fᵢ arm i's contact force on it (N, mean
over the step) and eᵢ its distance from the squeeze band [F_lo, F_hi]:

    r = −w̄·d² + G·[Σ_k b_k·1(d ≤ θ_k) + b_coop·1(d ≤ θ_coop)] + b_hold·(h₁ + h₂)
        − c_reach·(g₁ + g₂) − c_f·Σᵢ(eᵢ/F_hi)² − c_drop·1(dropped)

w̄ the mean arm weight, θ_k, b_k, θ_coop, b_coop the study's bonus settings (env.reward);
G = h₁h₂ with ``bonus_needs_grip`` (the default), else 1 for the individual bonuses and h₁h₂ for
the cooperative one; gᵢ = 0 when arm i touched the sphere during the step, else
max(0, min_n ‖xᵢₙ − c‖ − R − r), the gap between its nearest node's surface and the sphere's
(c its centre, R its radius, r the arm radius); b_hold, c_reach, c_f,
[F_lo, F_hi] and c_drop the task's; the action penalties of env.reward apply as in the other
tasks. Without the grip condition and the reach term a policy that lets go at once earns more
than one that tries to hold (docs/results.md, "Cooperative transport").

**Drop**: when neither arm has touched the sphere for ``drop_grace`` seconds the episode
terminates (the reward of that step includes −c_drop).

**Grip**: with ``grip`` g the environment adds −g to arm 1's six normal control values and +g
to arm 2's before clipping (both curl onto the sphere), so a zero action holds it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from softtrack.env.observation import build_observation, observation_size
from softtrack.env.targets import CLOSED_FORM_MODES, trajectory_position

if TYPE_CHECKING:
    from softtrack.env.settings import TrackingConfig
    from softtrack.env.targets import BatchedTargets, MixedTargets
    from softtrack.sim.engine import RodBatch

__all__ = ["GOAL_SIZE", "TransportModel"]

#: Values the goal block adds to the observation: centre (3), speed, direction (3).
GOAL_SIZE = 7


def _speed_direction(velocity: np.ndarray) -> np.ndarray:
    """(n, 4) ‖v‖ and v/‖v‖ (zeros when ‖v‖ = 0) of velocities (n, 3)."""
    speed = np.sqrt(np.einsum("ni,ni->n", velocity, velocity))
    direction = np.divide(
        velocity, speed[:, None], out=np.zeros_like(velocity), where=speed[:, None] > 0.0
    )
    return np.concatenate([speed[:, None], direction], axis=1)


class TransportModel:
    """The transport task's goal, observation, reward and drop for ``n_envs`` environments.

    Args:
        n_envs: environments.
        config: the validated settings (task ``transport``, a sphere in ``config.sim``).
    """

    def __init__(self, n_envs: int, config: TrackingConfig) -> None:
        sphere = config.sim.sphere
        if sphere is None or not config.task.carries_object:
            raise ValueError("the transport model needs task: transport and a sphere")
        self.task = config.task
        self.reward_config = config.reward
        self.control_dt = config.sim.control_dt
        self.start = np.asarray(sphere.center, dtype=float)
        self.contact_distance = sphere.radius + config.sim.radius  # m, centre to node at touch
        self.approach_steps = max(round(self.task.approach / self.control_dt), 0)
        self.untouched = np.zeros(n_envs)  # s since either arm last touched the sphere
        self.reach_cost = np.zeros((n_envs, 2))  # each arm's reach term of the last step
        self.goal_position = np.zeros((n_envs, 3))
        self.goal_velocity = np.zeros((n_envs, 3))
        #: m, the fraction of the goal's motion away from the sphere's start (module docstring)
        self.goal_motion = 1.0
        study_size = observation_size(2, config.sim.n_nodes)  # 81: arms, then the sphere
        self.observation_size = study_size + GOAL_SIZE
        self._study = np.zeros((n_envs, study_size), dtype=np.float32)

    def reset(self, idx: np.ndarray, targets: BatchedTargets | MixedTargets) -> None:
        """Environments ``idx`` restart: the goal at the sphere's start."""
        self.untouched[idx] = 0.0
        self.update_goal(np.zeros(len(self.untouched), dtype=np.int64), targets, idx)

    def target_active(self, step_count: np.ndarray) -> np.ndarray:
        """(n,) bool: the environments whose target moves on the step that brings their
        control step count to ``step_count`` (the approach is over)."""
        return step_count > self.approach_steps

    def update_goal(
        self,
        step_count: np.ndarray,
        targets: BatchedTargets | MixedTargets,
        idx: np.ndarray | slice = slice(None),
    ) -> None:
        """Set the goal of environments ``idx`` after ``step_count`` (n,) control steps."""
        count = step_count[idx].astype(float)
        position = targets.position[idx]
        velocity = targets.velocity[idx]
        if self.approach_steps > 0:
            tau = np.minimum(count / self.approach_steps, 1.0)[:, None]
            leg = position - self.start
            approaching = tau < 1.0
            blend = tau * tau * (3.0 - 2.0 * tau)
            rate = 6.0 * tau * (1.0 - tau) / self.task.approach
            position = np.where(approaching, self.start + blend * leg, position)
            velocity = np.where(approaching, rate * leg, velocity)
        m = self.goal_motion
        self.goal_position[idx] = position if m == 1.0 else self.start + m * (position - self.start)
        self.goal_velocity[idx] = velocity if m == 1.0 else m * velocity

    def goal_ahead(
        self, step_count: int, targets: BatchedTargets | MixedTargets, env: int, steps: np.ndarray
    ) -> np.ndarray:
        """(H, 3) environment ``env``'s goal after each of the next ``steps`` (H,) control
        steps (1, 2, …) from ``step_count``, m: the approach, then the path (closed forms
        exactly; a random target or held-out path extrapolated at its velocity inside the random
        target's box), scaled by
        :attr:`goal_motion` as :meth:`update_goal` does."""
        count = step_count + np.asarray(steps, dtype=float)
        path_time = np.maximum(count - self.approach_steps, 0.0) * self.control_dt
        config = targets.config
        if config.name in CLOSED_FORM_MODES:
            path = trajectory_position(config, path_time)
            path_start = trajectory_position(config, np.zeros(1))[0]
        else:
            low, high = targets.shrunk_box
            moved = (path_time - targets.time[env])[:, None] * targets.velocity[env]
            path = np.clip(targets.position[env] + moved, low, high)
            path_start = targets.position[env] if targets.time[env] == 0.0 else path[0]
        if self.approach_steps > 0:
            tau = np.minimum(count / self.approach_steps, 1.0)[:, None]
            blend = tau * tau * (3.0 - 2.0 * tau)
            path = np.where(tau < 1.0, self.start + blend * (path_start - self.start), path)
        m = self.goal_motion
        return path if m == 1.0 else self.start + m * (path - self.start)

    def observation(self, engine: RodBatch, out: np.ndarray) -> np.ndarray:
        """(n, 88) float32 observations (module docstring) written into ``out``."""
        study = self._study
        build_observation(
            engine.position,
            engine.tip_velocity,
            np.ascontiguousarray(engine.sphere_position),
            np.ascontiguousarray(engine.sphere_velocity),
            out=study,
        )
        n_study = study.shape[1]
        out[:, :n_study] = study
        out[:, n_study : n_study + 3] = self.goal_position
        out[:, n_study + 3 :] = _speed_direction(self.goal_velocity)
        return out

    def object_distance(self, engine: RodBatch) -> np.ndarray:
        """(n,) distance of the sphere's centre from the goal, m."""
        diff = engine.sphere_position - self.goal_position
        return np.sqrt(np.einsum("ni,ni->n", diff, diff))

    def step_reward(
        self, engine: RodBatch, distance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The reward of the control step just integrated (module docstring) and the drops.

        Args:
            engine: the engine after the step (its sphere contact state).
            distance: (n,) the sphere's distance from the goal, m.

        Returns:
            reward (n,), touching (n, 2) bool, dropped (n,) bool.
        """
        force, _, steps = engine.sphere_contact_state()
        touching = steps > 0
        task, reward = self.task, self.reward_config
        weight = float(np.mean(reward.arm_weights))
        both = touching.all(axis=1)
        with np.errstate(invalid="ignore"):
            r = -weight * distance * distance
            bonus = np.zeros_like(r)
            for threshold, value in zip(reward.bonus_thresholds, reward.bonus_values, strict=True):
                bonus += value * (distance <= threshold)
            r += np.where(both, bonus, 0.0) if task.bonus_needs_grip else bonus
            r += reward.cooperative_bonus * ((distance <= reward.cooperative_threshold) & both)
        r += task.hold_bonus * touching.sum(axis=1)
        self.reach_cost = task.reach_penalty * np.where(touching, 0.0, self.arm_gaps(engine))
        r -= self.reach_cost.sum(axis=1)
        low, high = task.squeeze_band
        if task.squeeze_penalty and high > 0:
            excess = np.maximum(force - high, 0.0) + np.maximum(low - force, 0.0)
            r -= task.squeeze_penalty * np.sum((excess / high) ** 2, axis=1)
        self.untouched = np.where(touching.any(axis=1), 0.0, self.untouched + self.control_dt)
        dropped = self.dropped()
        r = np.where(dropped, r - task.drop_penalty, r)
        return r, touching, dropped

    def arm_gaps(self, engine: RodBatch) -> np.ndarray:
        """(n, 2) gap between the surface around each arm's nearest node and the sphere's
        surface, m (0 when they overlap; a few mm while an element's side touches it)."""
        offset = engine.position - engine.sphere_position[:, None, :, None]  # (n, 2, 3, N+1)
        nearest = np.sqrt(np.einsum("najk,najk->nak", offset, offset).min(axis=2))
        return np.maximum(nearest - self.contact_distance, 0.0)

    def reward_shares(self, reward: np.ndarray, touching: np.ndarray) -> np.ndarray:
        """(n, 2) each arm's share of the step's reward, for per-arm critics: its own hold
        bonus and reach term plus half of the rest (the sphere's terms, which both arms make
        together), so the shares sum to the reward.

        Args:
            reward: (n,) the rewards of the step.
            touching: (n, 2) bool, each arm touched the sphere in the step.
        """
        own = self.task.hold_bonus * np.asarray(touching, dtype=float) - self.reach_cost
        rest = np.asarray(reward, dtype=float) - own.sum(axis=1)
        return own + 0.5 * rest[:, None]

    def dropped(self) -> np.ndarray:
        """(n,) bool: no arm has touched the sphere for ``drop_grace`` seconds (a control
        step's rounding below it counts)."""
        return self.untouched >= self.task.drop_grace - 1e-9
