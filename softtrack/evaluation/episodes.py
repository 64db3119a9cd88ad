"""Deterministic evaluation episodes: one policy driving both arms while the target moves.

An evaluation drives both arms from the straight initial state for ``duration`` seconds while
the target follows a circle, rectangle or figure-eight (docs/environment.md), or the run's random training
target, and records every control step (:class:`Episode`). A centralized controller maps the
81-value observation to 24 actions; an independent controller is two single-arm policies, each
fed its arm's 37 values plus the target's 7 (:func:`independent_policy`). The tables of an
episode are in :mod:`softtrack.evaluation.episode_tables`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from softtrack.env.core import StepResult, TrackingCore
from softtrack.env.observation import arm_view_columns
from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import EVAL_TRAJECTORIES
from softtrack.evaluation.metrics import arm_clearance

__all__ = [
    "CONFIRM_SEED",
    "EVAL_TRAJECTORIES",
    "RANDOM_TARGET_SEED",
    "VALIDATION_PATH_SEED",
    "VALIDATION_SEED",
    "Episode",
    "Policy",
    "accepts_batches",
    "independent_policy",
    "iter_episodes",
    "run_episode",
    "run_episodes",
]

# Random-target evaluation episode k draws its target path from seed RANDOM_TARGET_SEED + k.
# Training seeds environment i of a run with seed run_seed + i (small), so these never recur.
RANDOM_TARGET_SEED = 1_000_000
# Validation episode k during training (softtrack.rl.validation) uses VALIDATION_SEED + k.
VALIDATION_SEED = 2_000_000
# Confirmation episode k after training (softtrack.rl.confirmation) uses CONFIRM_SEED + k.
CONFIRM_SEED = 3_000_000
# Held-out path k of validation (target mode "paths") draws its path from seed
# VALIDATION_PATH_SEED + k (4_000_000 is the robustness sweep's).
VALIDATION_PATH_SEED = 5_000_000

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
    target block (7 values), the single-arm environment's layout, and returns 12 actions. It
    accepts batches (:func:`accepts_batches`) when every arm's policy does.
    """

    def act(observation: np.ndarray) -> np.ndarray:
        batch = observation.shape[:-1]
        actions = []
        for k, policy in enumerate(arm_policies):
            columns = arm_view_columns(k, len(arm_policies), observation.shape[-1])
            arm_actions = np.asarray(policy(observation[..., columns]), dtype=np.float64)
            actions.append(arm_actions.reshape(*batch, -1))
        return np.concatenate(actions, axis=-1)

    act.accepts_batches = all(accepts_batches(p) for p in arm_policies)  # type: ignore[attr-defined]
    return act


def run_episode(
    policy: Policy,
    config: TrackingConfig,
    trajectory: str,
    duration: float = 10.0,
    seed: int = 0,
    snapshot_steps: Sequence[int] | None = None,
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
        snapshot_steps: the 0-based control steps after which the arms' nodes are kept
            (``Episode.snapshots``; an animation's frames); default the ends of the
            episode's quarters.
    """
    return run_episodes(policy, config, trajectory, duration, [seed], snapshot_steps)[0]


def accepts_batches(policy: Policy) -> bool:
    """Whether ``policy`` maps a batch of observations (n, obs_dim) to (n, act_dim) with the
    same numbers, row by row, as one observation at a time (its ``accepts_batches``
    attribute; :func:`independent_policy` passes it on)."""
    return bool(getattr(policy, "accepts_batches", False))


def run_episodes(
    policy: Policy,
    config: TrackingConfig,
    trajectory: str | Sequence[str],
    duration: float = 10.0,
    seeds: Sequence[int] = (0,),
    snapshot_steps: Sequence[int] | None = None,
) -> list[Episode]:
    """Run one episode per seed of ``seeds`` together, in one batch of environments: the
    episodes of :func:`run_episode` with those seeds, number for number. ``trajectory`` is
    every episode's target, or one per seed (validation's random episodes and trajectories in
    one batch).

    Each environment draws from its own generator and the engine integrates each environment
    alone, so batching changes nothing in an episode. The policy is called with one
    observation at a time (a network's matrix product may round a batch differently from one
    row, and the closed loop would amplify that), or once per control step with every
    episode's observation (n, obs_dim) when it :func:`accepts_batches`. An episode that ends
    early (non-finite state, a dropped object) stops recording; the batch steps on until
    every episode has ended. ``snapshot_steps``: as :func:`run_episode`'s.

    Raises:
        ValueError: ``seeds`` is empty, or several seeds with a controller that plans on the
            episode's state (``start_episode``).
    """
    n = len(seeds)
    start_episode = getattr(policy, "start_episode", None)
    if n == 0:
        raise ValueError("run_episodes needs at least one seed")
    if n > 1 and start_episode is not None:
        raise ValueError(
            "a controller that plans on the episode's state (start_episode) runs one "
            "episode at a time"
        )
    batched = n > 1 and accepts_batches(policy)
    names = [trajectory] * n if isinstance(trajectory, str) else [str(t) for t in trajectory]
    if len(names) != n:
        raise ValueError(f"{len(names)} trajectories for {n} seeds")
    eval_config = dataclasses.replace(
        config,
        target=dataclasses.replace(config.target, name=names[0]),
        episode_duration=float(duration),
    )
    core = TrackingCore(n, eval_config, None if len(set(names)) == 1 else names)
    obs = core.reset(list(range(n)), [np.random.default_rng(seed) for seed in seeds])
    n_steps = eval_config.max_episode_steps
    if snapshot_steps is None:
        snapshot_at = _snapshot_steps(n_steps)
    else:
        snapshot_at = np.unique(np.clip(np.asarray(snapshot_steps, dtype=int), 0, n_steps - 1))
    recording = _Recording(core, n_steps, snapshot_at)
    planning = None
    if start_episode is not None:
        start_episode(core)
        planning = np.full(n_steps, np.nan)
    active = np.ones(n, dtype=bool)
    for k in range(n_steps):
        started = time.thread_time() if planning is not None else 0.0
        if batched:
            action = np.asarray(policy(obs), dtype=np.float64).reshape(n, -1)
        else:  # one observation at a time: each episode's actions as when it runs alone
            action = np.zeros((n, core.action_dim))
            for i in np.flatnonzero(active).tolist():
                action[i] = np.asarray(policy(obs[i]), dtype=np.float64).reshape(-1)
        action[~active] = 0.0  # ended episodes: the batch steps on without them
        if planning is not None:
            planning[k] = time.thread_time() - started
        result = core.step(action)
        live = np.flatnonzero(active)
        recording.record(k, live, action, result)
        obs = result.observation
        ended = live[result.terminated[live]]
        recording.end(ended, k + 1)
        active[ended] = False
        if not active.any():
            break
    return [recording.episode(i, names[i], planning) for i in range(n)]


class _Recording:
    """What :func:`run_episodes` keeps of each of ``core``'s episodes at every control step,
    (n, n_steps, ...) arrays, NaN after an episode's end."""

    def __init__(self, core: TrackingCore, n_steps: int, snapshot_at: np.ndarray) -> None:
        n, n_arms, sim = core.n_envs, core.n_arms, core.config.sim
        self.core = core
        self.snapshot_at = snapshot_at
        self.tips = np.full((n, n_steps, n_arms, 3), np.nan)
        self.target = np.full((n, n_steps, 3), np.nan)
        self.torques = np.full((n, n_steps, n_arms, 2, sim.n_elem), np.nan)
        self.actions = np.full((n, n_steps, core.action_dim), np.nan)
        self.clearance = np.full((n, n_steps), np.nan)  # NaN with one arm: nothing to clear
        self.penetration = np.full((n, n_steps), np.nan)
        self.contact_force = np.zeros((n, n_steps))
        self.snapshots = np.full((n, len(snapshot_at), n_arms, 3, sim.n_nodes), np.nan)
        # each episode's rod radius: the nominal one, times its model-error factor if any
        self.radius = np.array(
            [float(sim.radius) * core.parameters(i)["radius_scale"] for i in range(n)]
        )
        self.carried = None
        if core.transport is not None:  # the sphere's centre, each arm's force and touch
            self.carried = (
                np.full((n, n_steps, 3), np.nan),
                np.zeros((n, n_steps, n_arms)),
                np.zeros((n, n_steps, n_arms), dtype=bool),
            )
        self.dropped = np.zeros(n, dtype=bool)
        self.terminated = np.zeros(n, dtype=bool)
        self.done_steps = np.full(n, n_steps)

    def record(self, k: int, live: np.ndarray, action: np.ndarray, result: StepResult) -> None:
        """Keep control step ``k`` of the ``live`` episodes (after ``core.step``)."""
        engine, transport = self.core.engine, self.core.transport
        self.actions[live, k] = action[live]
        self.tips[live, k] = engine.tip_position[live]
        self.target[live, k] = self.core.targets.position[live]
        self.torques[live, k] = engine.torques[live]
        if transport is not None and self.carried is not None:
            self.target[live, k] = transport.goal_position[live]
            force, _, steps = engine.sphere_contact_state()
            self.carried[0][live, k] = engine.sphere_position[live]
            self.carried[1][live, k] = force[live]
            self.carried[2][live, k] = steps[live] > 0
            if result.dropped is not None:
                self.dropped[live] = result.dropped[live]
        if self.core.n_arms >= 2:
            self.clearance[live, k] = arm_clearance(engine.position[live], self.radius[live])
            if engine.contact_on:
                depth, total_force = engine.contact_state()
                self.penetration[live, k] = depth[live]
                self.contact_force[live, k] = total_force[live]
            else:  # NaN clearance: 0
                self.penetration[live, k] = np.fmax(0.0, -self.clearance[live, k])
        at_snapshot = self.snapshot_at == k
        if at_snapshot.any():
            self.snapshots[live[:, None], at_snapshot] = engine.position[live][:, None]

    def end(self, ended: np.ndarray, steps: int) -> None:
        """The ``ended`` episodes terminated after ``steps`` control steps."""
        self.terminated[ended] = True
        self.done_steps[ended] = steps

    def episode(self, i: int, trajectory: str, planning: np.ndarray | None) -> Episode:
        """Episode ``i`` as recorded, cut at its end."""
        done = int(self.done_steps[i])
        kept = self.snapshot_at < done
        carried = self.carried
        return Episode(
            trajectory,
            np.arange(1, done + 1) * self.core.config.sim.control_dt,
            self.tips[i, :done],
            self.target[i, :done],
            self.torques[i, :done],
            self.actions[i, :done],
            bool(self.terminated[i]),
            self.clearance[i, :done],
            float(self.core.config.reward.collision_margin),
            None if planning is None else planning[:done],
            self.penetration[i, :done],
            self.contact_force[i, :done],
            self.snapshots[i, kept],
            self.snapshot_at[kept],
            self.core.goal_offsets.copy(),
            None if carried is None else carried[0][i, :done],
            None if carried is None else carried[1][i, :done],
            None if carried is None else carried[2][i, :done],
            bool(self.dropped[i]),
        )


#: Episodes run together by :func:`iter_episodes`: the environments' step is shared, the
#: policy still sees one observation at a time.
EPISODE_BATCH = 16


def iter_episodes(
    policy: Policy,
    config: TrackingConfig,
    trajectory: str,
    duration: float,
    seeds: Sequence[int],
    batch: int = EPISODE_BATCH,
) -> Iterator[Episode]:
    """The episodes of :func:`run_episode` for each seed of ``seeds``, in order: ``batch`` at
    a time (:func:`run_episodes`), one by one for a controller that plans on the episode's
    state (``start_episode``)."""
    size = 1 if hasattr(policy, "start_episode") else max(1, int(batch))
    seeds = list(seeds)
    for first in range(0, len(seeds), size):
        yield from run_episodes(policy, config, trajectory, duration, seeds[first : first + size])


SNAPSHOTS = 4  # arm shapes kept per episode, evenly spaced, the last at the episode's end


def _snapshot_steps(n_steps: int) -> np.ndarray:
    """(S,) 0-based control steps at which an episode keeps the arms' shapes: the ends of
    its quarters (2.5, 5, 7.5, 10 s of a 10-s episode)."""
    quarters = np.arange(1, SNAPSHOTS + 1) * n_steps // SNAPSHOTS - 1
    return np.unique(np.clip(quarters, 0, n_steps - 1))
