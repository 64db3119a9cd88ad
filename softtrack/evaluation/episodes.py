"""Deterministic evaluation episodes: one policy driving both arms while the target moves.

An evaluation drives both arms from the straight initial state for ``duration`` seconds while
the target follows a circle, rectangle or figure-eight (docs/environment.md), or the run's random training
target, and records every control step (:class:`Episode`). A centralized controller maps the
81-value observation to 24 actions; an independent controller is two single-arm policies, each
fed its arm's 37 values plus the target's 7 (:func:`independent_policy`). The tables of an
episode are in :mod:`softtrack.evaluation.tables`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from softtrack.env.config import TrackingConfig
from softtrack.env.core import TrackingCore
from softtrack.env.observation import arm_view_columns
from softtrack.env.targets import EVAL_TRAJECTORIES
from softtrack.evaluation.metrics import arm_clearance

__all__ = [
    "CONFIRM_SEED",
    "EVAL_TRAJECTORIES",
    "RANDOM_TARGET_SEED",
    "VALIDATION_SEED",
    "Episode",
    "Policy",
    "independent_policy",
    "run_episode",
]

# Random-target evaluation episode k draws its target path from seed RANDOM_TARGET_SEED + k.
# Training seeds environment i of a run with seed run_seed + i (small), so these never recur.
RANDOM_TARGET_SEED = 1_000_000
# Validation episode k during training (softtrack.rl.validation) uses VALIDATION_SEED + k.
VALIDATION_SEED = 2_000_000
# Confirmation episode k after training (softtrack.rl.confirmation) uses CONFIRM_SEED + k.
CONFIRM_SEED = 3_000_000

# A policy maps one observation (obs_dim,) to one action (act_dim,).
Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Episode:
    """The record of one evaluation episode (N control steps after the reset).

    Attributes:
        trajectory: target trajectory name.
        t: (N,) time after each control step, s.
        tips: (N, A, 3) tip positions, m.
        target: (N, 3) target centre, m.
        element_torques: (N, A, 2, n_elem) applied torques, N·m.
        actions: (N, 12·A) the policy's actions (before clipping); arm k's are columns
            12k … 12k + 11 (6 normal, then 6 binormal control points).
        terminated: True if the state became non-finite (the episode then stops early).
        clearance: (N,) surface clearance between the arms after each control step, m: the
            smallest node-to-node distance of their centrelines minus both radii (the
            episode's radius: ``physics.radius`` times a model-error ``radius_scale``)
            (:func:`softtrack.evaluation.metrics.arm_clearance`); NaN in a single-arm scene
            and at a non-finite state; ``None`` when not recorded (then treated as all NaN).
        collision_margin: the run's ``reward.collision_margin``, m: steps with a clearance
            below it count as ``collision_steps``.
        penetration: (N,) how deep the arms' surfaces overlap during each control step, m:
            with contact on (``physics.contact_k`` > 0) the engine's deepest overlap of two
            element segments over the step's integration steps; without contact, where the
            arms pass through each other, max(0, −clearance); NaN in a single-arm scene;
            ``None`` when not recorded.
        contact_force: (N,) the magnitude of the total contact force between the arms, mean
            over the control step's integration steps, N (0 without contact).
        snapshots: (S, A, 3, n_nodes) the arms' centreline nodes at the control steps
            ``snapshot_steps`` (S,) (0-based), m; for figures that draw the arms.
        snapshot_steps: (S,) int, see ``snapshots``.
        goal_offsets: (A, 3) offset of each arm's point from the target centre, m (the
            task's, :mod:`softtrack.env.tasks`; zeros in the shared task); ``None``: zeros.
        planning_time: (N,) CPU time of the controller's call at each control step, s (its
            thread's CPU time: the cost on one core, unaffected by other processes sharing
            the machine), for a controller that plans on the episode's state
            (``start_episode``, e.g. MPC); ``None`` for a policy.
        object_position: transport task: (N, 3) the sphere's centre after each step, m
            (``target`` then holds its goal); ``None`` in the other tasks.
        object_force: transport: (N, A) each arm's contact force on the sphere, mean over
            the control step, N.
        object_touching: transport: (N, A) bool, each arm touched the sphere in the step.
        dropped: transport: the episode ended because the sphere was dropped.
    """

    trajectory: str
    t: np.ndarray
    tips: np.ndarray
    target: np.ndarray
    element_torques: np.ndarray
    actions: np.ndarray
    terminated: bool
    clearance: np.ndarray | None = None
    collision_margin: float = 0.0
    planning_time: np.ndarray | None = None
    penetration: np.ndarray | None = None
    contact_force: np.ndarray | None = None
    snapshots: np.ndarray | None = None
    snapshot_steps: np.ndarray | None = None
    goal_offsets: np.ndarray | None = None
    object_position: np.ndarray | None = None
    object_force: np.ndarray | None = None
    object_touching: np.ndarray | None = None
    dropped: bool = False

    def goals(self, arm: int) -> np.ndarray:
        """(N, 3) the point arm ``arm`` tracked at each step: the target centre plus its
        task offset, m."""
        if self.goal_offsets is None:
            return self.target
        return self.target + self.goal_offsets[arm]


def independent_policy(arm_policies: Sequence[Policy]) -> Policy:
    """One dual-arm policy from one single-arm policy per arm.

    Arm k's policy sees the dual-arm observation's arm-k block (37 values) followed by the
    target block (7 values), the single-arm environment's layout, and returns 12 actions.
    """

    def act(observation: np.ndarray) -> np.ndarray:
        actions = []
        for k, policy in enumerate(arm_policies):
            arm_obs = observation[arm_view_columns(k, len(arm_policies), len(observation))]
            actions.append(np.asarray(policy(arm_obs), dtype=np.float64).reshape(-1))
        return np.concatenate(actions)

    return act


def run_episode(
    policy: Policy, config: TrackingConfig, trajectory: str, duration: float = 10.0, seed: int = 0
) -> Episode:
    """Run ``policy`` from the straight initial state while the target follows ``trajectory``.

    A controller with a ``start_episode(core)`` method (an MPC planner) is given the
    episode's :class:`~softtrack.env.core.TrackingCore` after the reset, and the CPU time of
    each of its calls (the calling thread's) is recorded (``Episode.planning_time``).

    Args:
        policy: observation (obs_dim,) → action (act_dim,), deterministic.
        config: the environment settings of the run (physics, reward, target parameters).
        trajectory: ``circle``, ``rectangle``, ``figure8``, ``fixed`` or ``random`` (the
            training target of ``config``: random start and redirections).
        duration: episode length, s.
        seed: seed of the episode's random numbers (only the ``random`` target uses them).
    """
    eval_config = dataclasses.replace(
        config,
        target=dataclasses.replace(config.target, name=trajectory),
        episode_duration=float(duration),
    )
    core = TrackingCore(1, eval_config)
    obs = core.reset([0], [np.random.default_rng(seed)])[0]
    n_steps = eval_config.max_episode_steps
    tips = np.full((n_steps, core.n_arms, 3), np.nan)
    target = np.full((n_steps, 3), np.nan)
    torques = np.full((n_steps, core.n_arms, 2, eval_config.sim.n_elem), np.nan)
    actions = np.full((n_steps, core.action_dim), np.nan)
    clearance = np.full(n_steps, np.nan)  # stays NaN with one arm: no other arm to clear
    two_arms = core.n_arms >= 2
    # the rods' radius in this episode: the nominal one, times its model-error factor if any
    radius = float(eval_config.sim.radius) * core.parameters(0)["radius_scale"]
    penetration = np.full(n_steps, np.nan)
    contact_force = np.zeros(n_steps)
    snapshot_at = _snapshot_steps(n_steps)
    snapshots = np.full((len(snapshot_at), core.n_arms, 3, eval_config.sim.n_nodes), np.nan)
    contact_on = core.engine.contact_on
    start_episode = getattr(policy, "start_episode", None)
    planning = None
    if start_episode is not None:
        start_episode(core)
        planning = np.full(n_steps, np.nan)
    transport = core.transport
    carried = None
    if transport is not None:
        carried = (
            np.full((n_steps, 3), np.nan),
            np.zeros((n_steps, core.n_arms)),
            np.zeros((n_steps, core.n_arms), dtype=bool),
        )
    dropped = False
    terminated = False
    done_steps = n_steps
    for k in range(n_steps):
        started = time.thread_time()
        action = np.asarray(policy(obs), dtype=np.float64).reshape(-1)
        if planning is not None:
            planning[k] = time.thread_time() - started
        result = core.step(action[None])
        actions[k] = action
        tips[k] = core.engine.tip_position[0]
        target[k] = core.targets.position[0]
        torques[k] = core.engine.torques[0]
        if transport is not None and carried is not None:
            target[k] = transport.goal_position[0]
            force, _, steps = core.engine.sphere_contact_state()
            carried[0][k] = core.engine.sphere_position[0]
            carried[1][k] = force[0]
            carried[2][k] = steps[0] > 0
            dropped = bool(result.dropped is not None and result.dropped[0])
        if two_arms:
            clearance[k] = arm_clearance(core.engine.position[0], radius)
            if contact_on:
                depth, force = core.engine.contact_state()
                penetration[k], contact_force[k] = depth[0], force[0]
            else:
                penetration[k] = max(0.0, -clearance[k])
        snapshots[snapshot_at == k] = core.engine.position[0]
        obs = result.observation[0]
        if result.terminated[0]:
            terminated, done_steps = True, k + 1
            break
    t = np.arange(1, done_steps + 1) * eval_config.sim.control_dt
    kept = snapshot_at < done_steps
    return Episode(
        trajectory,
        t,
        tips[:done_steps],
        target[:done_steps],
        torques[:done_steps],
        actions[:done_steps],
        terminated,
        clearance[:done_steps],
        float(eval_config.reward.collision_margin),
        None if planning is None else planning[:done_steps],
        penetration[:done_steps],
        contact_force[:done_steps],
        snapshots[kept],
        snapshot_at[kept],
        core.goal_offsets.copy(),
        None if carried is None else carried[0][:done_steps],
        None if carried is None else carried[1][:done_steps],
        None if carried is None else carried[2][:done_steps],
        dropped,
    )


SNAPSHOTS = 4  # arm shapes kept per episode, evenly spaced, the last at the episode's end


def _snapshot_steps(n_steps: int) -> np.ndarray:
    """(S,) 0-based control steps at which an episode keeps the arms' shapes: the ends of
    its quarters (2.5, 5, 7.5, 10 s of a 10-s episode)."""
    quarters = np.arange(1, SNAPSHOTS + 1) * n_steps // SNAPSHOTS - 1
    return np.unique(np.clip(quarters, 0, n_steps - 1))
