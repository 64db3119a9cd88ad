"""The batched tracking dynamics shared by the Gymnasium envs and the vectorised env.

:class:`TrackingCore` steps ``n_envs`` environments with one engine call: actions → spline
torques → 10 integration steps → target motion → observation, reward, termination. The
single environments are a core with ``n_envs = 1``, so a vectorised env and N single envs
compute the same transitions by construction.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from softtrack.env.observation import build_observation, observation_size
from softtrack.env.realism import RealismModel
from softtrack.env.reward import action_penalty, collision_penalty, tracking_reward
from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import BatchedTargets, MixedTargets
from softtrack.env.transport_env import TransportModel
from softtrack.sim.actuation import N_CONTROL_POINTS
from softtrack.sim.engine import RodBatch
from softtrack.sim.params import MODEL_PARAMETERS

__all__ = ["NonFiniteActionError", "StepResult", "TrackingCore"]


class NonFiniteActionError(ValueError):
    """An action contained NaN or inf."""


@dataclass
class StepResult:
    """Outcome of one control step of every environment.

    Attributes:
        observation: (n, obs_dim) float32.
        reward: (n,) float64.
        terminated: (n,) bool, the state became non-finite.
        truncated: (n,) bool, the episode reached its duration (and did not terminate).
        distances: (n, A) distances of each tip from its arm's point (the target centre in
            the shared task, the goal in the transport task), m.
        object_distance: (n,) transport: the sphere's distance from the goal, m; else None.
        touching: (n, A) transport: bool, each arm touched the sphere during the step.
        dropped: (n,) transport: bool, the sphere was dropped (the episode terminated).
    """

    observation: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    distances: np.ndarray
    object_distance: np.ndarray | None = None
    touching: np.ndarray | None = None
    dropped: np.ndarray | None = None


class TrackingCore:
    """``n_envs`` tracking environments stepped together (see module docstring).

    Args:
        n_envs: number of environments.
        config: the validated settings shared by all of them.
        target_names: (n_envs,) each environment's target mode when they differ
            (:class:`~softtrack.env.targets.MixedTargets`); default ``config.target.name``.
    """

    def __init__(
        self, n_envs: int, config: TrackingConfig, target_names: Sequence[str] | None = None
    ) -> None:
        config.validate()
        self.config = config
        self.n_envs = int(n_envs)
        self.n_arms = config.n_arms
        self.engine = RodBatch(self.n_envs, config.sim)
        if target_names is not None and len(target_names) != self.n_envs:
            raise ValueError(f"{len(target_names)} target names for {self.n_envs} environments")
        self.targets: BatchedTargets | MixedTargets = (
            BatchedTargets(config.target, self.n_envs)
            if target_names is None
            else MixedTargets(config.target, target_names)
        )
        self.goal_offsets = config.goal_offsets()  # (A, 3) m, each arm's point − target centre
        self.rngs: list[np.random.Generator | None] = [None] * self.n_envs
        self.step_count = np.zeros(self.n_envs, dtype=np.int64)
        self.max_steps = config.max_episode_steps
        self.action_dim = self.n_arms * 2 * N_CONTROL_POINTS
        grip = config.task.action_offset() if config.task.grip else None
        self._action_offset = grip  # (24,) added to every action before clipping, or None
        # the transport task (softtrack.env.transport_env): goal, observation, reward and drops
        self.transport: TransportModel | None = (
            TransportModel(self.n_envs, config) if config.task.carries_object else None
        )
        self.obs_dim = (
            self.transport.observation_size
            if self.transport is not None
            else observation_size(self.n_arms, config.sim.n_nodes)
        )
        self._obs = np.zeros((self.n_envs, self.obs_dim), dtype=np.float32)
        self._control_dt = config.sim.control_dt
        # the previous clipped action of each environment, for reward.action_rate_penalty
        self._previous_action = np.zeros((self.n_envs, self.action_dim))
        # Sensing/actuation imperfections (softtrack.env.realism); None when all are off, so a
        # default environment takes exactly the path (and the random draws) it always took.
        self.realism: RealismModel | None = (
            RealismModel(
                config.realism, self.n_envs, self.n_arms, config.sim.n_nodes, self._control_dt
            )
            if config.realism.active
            else None
        )
        # Model error (env.realism): fixed factors are set once here, ranges at every reset.
        self.model_error = config.realism.model_error_active
        self._randomised = config.realism.randomised
        if self.model_error and not self._randomised:
            fixed = {name: low for name, (low, _) in config.realism.model_error_ranges.items()}
            self.engine.set_parameters(None, fixed, validate=False)  # checked by validate()

    # ---- state ----------------------------------------------------------------------------
    @property
    def time(self) -> np.ndarray:
        """(n,) simulated seconds since each environment's reset."""
        return self.step_count * self._control_dt

    def observe(self, env_indices: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Current true observations of the listed environments: (k, obs_dim) float32 copy
        (without the realism's delay, noise and drops, which :meth:`reset` and :meth:`step`
        apply)."""
        engine, targets = self.engine, self.targets
        if self.transport is not None:
            self.transport.observation(engine, self._obs)
        else:
            build_observation(
                engine.position,
                engine.tip_velocity,
                targets.position,
                targets.velocity,
                out=self._obs,
            )
        obs = self._obs[env_indices]
        if not np.isfinite(obs).all():
            obs = np.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)
        return obs.copy()

    def reset(
        self, env_indices: Sequence[int] | np.ndarray, rngs: Sequence[np.random.Generator]
    ) -> np.ndarray:
        """Restart the listed environments (straight arms at rest, new target).

        Args:
            env_indices: (k,) environment indices.
            rngs: k generators, kept by those environments for their random draws.

        Returns:
            (k, obs_dim) float32 initial observations (as the policy sees them: with the
            realism's noise and drops when it is on).
        """
        idx = np.atleast_1d(np.asarray(env_indices, dtype=np.intp))
        for i, rng in zip(idx.tolist(), rngs, strict=True):
            self.rngs[i] = rng
        self.engine.reset(idx)
        self.targets.reset(idx, list(rngs))
        self.step_count[idx] = 0
        self._previous_action[idx] = 0.0
        if self.transport is not None:
            self.transport.reset(idx, self.targets)
        obs = self.observe(idx)
        if self.realism is not None:
            obs = self.realism.reset(idx, list(rngs), obs)
            if self._randomised:  # this episode's model error (the initial state is the same)
                factors = self.realism.sample_model_error(idx)
                self.engine.set_parameters(idx, factors, validate=False)  # range checked
        return obs

    def step(self, actions: np.ndarray) -> StepResult:
        """Advance every environment by one control step.

        Args:
            actions: (n, 12·A) control values in [−1, 1]; out-of-range values are clipped
                (then delayed, lagged and rate-limited when the realism says so).

        Raises:
            NonFiniteActionError: if an action is NaN or inf.
        """
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != (self.n_envs, self.action_dim):
            raise ValueError(
                f"actions have shape {actions.shape}; expected {(self.n_envs, self.action_dim)}"
            )
        if not np.isfinite(actions).all():
            row = int(np.argwhere(~np.isfinite(actions))[0, 0])
            raise NonFiniteActionError(f"action of environment {row} contains NaN or inf")
        realism = self.realism
        policy_actions = np.clip(actions, -1.0, 1.0)
        commanded = policy_actions
        if self._action_offset is not None:  # the transport task's grip
            commanded = np.clip(policy_actions + self._action_offset, -1.0, 1.0)
        clipped = commanded if realism is None else realism.filter_actions(commanded)
        engine = self.engine
        engine.set_actions(clipped.reshape(self.n_envs, self.n_arms, 2, N_CONTROL_POINTS))
        if realism is not None:
            realism.saturate_torques(engine.torques)
        engine.advance()
        self.step_count += 1
        transport = self.transport
        if transport is None:
            self.targets.step(self._control_dt)
        else:
            self.targets.step(self._control_dt, transport.target_active(self.step_count))
            transport.update_goal(self.step_count, self.targets)

        finite = engine.finite()
        diff = engine.tip_position - self.goal_positions()
        distances = np.sqrt(np.einsum("nai,nai->na", diff, diff))
        object_distance = touching = dropped = None
        if transport is None:
            reward = tracking_reward(distances, self.config.reward)
        else:
            object_distance = transport.object_distance(engine)
            reward, touching, dropped = transport.step_reward(engine, object_distance)
        if self.config.reward.collision_penalty:
            reward = reward + collision_penalty(engine.position, self.config.reward)
        if self.config.reward.penalises_actions:
            reward = reward + action_penalty(
                policy_actions, self._previous_action, self.config.reward
            )
        self._previous_action[...] = policy_actions
        terminated = ~finite
        if terminated.any():
            reward[terminated] = self.config.reward.nonfinite_reward
        if dropped is not None:
            terminated = terminated | dropped
        truncated = (self.step_count >= self.max_steps) & ~terminated
        observation = self.observe()
        if realism is not None:
            observation = realism.filter_obs(observation)
        return StepResult(
            observation,
            reward,
            terminated,
            truncated,
            distances,
            object_distance,
            touching,
            dropped,
        )

    def goal_positions(self) -> np.ndarray:
        """(n, A, 3) the point each arm tracks (the target centre plus the task's offset; in
        the transport task the goal of the sphere), m."""
        if self.transport is not None:
            return np.repeat(self.transport.goal_position[:, None, :], self.n_arms, axis=1)
        return self.targets.position[:, None, :] + self.goal_offsets[None]

    def info(self, i: int, distances: np.ndarray) -> dict[str, Any]:
        """The info dict (docs/environment.md) of environment ``i`` after a step (copies, SI units)."""
        info: dict[str, Any] = {
            "tip_positions": self.engine.tip_position[i].copy(),
            "target_position": self.targets.position[i].copy(),
            "distances": distances[i].copy(),
            "element_torques": self.engine.torques[i].copy(),
            "time": float(self.step_count[i] * self._control_dt),
        }
        if self.engine.contact_on:
            penetration, force = self.engine.contact_state()
            info["penetration"] = float(penetration[i])
            info["contact_force"] = float(force[i])
        if self.transport is not None:
            object_force, object_overlap, object_steps = self.engine.sphere_contact_state()
            info["object_position"] = self.engine.sphere_position[i].copy()
            info["goal_position"] = self.transport.goal_position[i].copy()
            info["object_force"] = object_force[i]
            info["object_overlap"] = object_overlap[i]
            info["touching"] = object_steps[i] > 0
            info["dropped"] = bool(self.transport.dropped()[i])
        if self.model_error:
            info["parameters"] = self.parameters(i)
        return info

    def parameters(self, i: int) -> dict[str, float]:
        """The model-error factors of environment ``i``'s current episode (name → factor, all
        five of ``softtrack.sim.params.MODEL_PARAMETERS``; 1 = nominal)."""
        return dict(zip(MODEL_PARAMETERS, self.engine.factors[i].tolist(), strict=True))
