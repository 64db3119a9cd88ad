"""Deterministic evaluation episodes on the closed-form trajectories, and their tables.

An evaluation drives both arms from the straight initial state for ``duration`` seconds while
the target follows a circle, rectangle or figure-eight (SPEC §3), and records every control
step. A centralized controller maps the 81-value observation to 24 actions; an independent
controller is two single-arm policies, each fed its arm's 37 values plus the target's 7.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from softtrack.env.config import TrackingConfig
from softtrack.env.core import TrackingCore
from softtrack.env.observation import arm_view_columns
from softtrack.metrics import AXES, action_statistics, moment_rms, tracking_metrics
from softtrack.sim.actuation import N_CONTROL_POINTS

__all__ = [
    "CONFIRM_SEED",
    "EVAL_TRAJECTORIES",
    "RANDOM_TARGET_SEED",
    "STEADY_START",
    "VALIDATION_SEED",
    "Episode",
    "Policy",
    "element_moments_table",
    "element_peaks_frame",
    "independent_policy",
    "metrics_table",
    "moment_peaks_table",
    "moments_table",
    "run_episode",
    "trajectory_table",
    "validation_score",
]

EVAL_TRAJECTORIES = ("circle", "rectangle", "figure8")
STEADY_START = 1.0  # s: the "steady" metrics leave out the initial approach
# Random-target evaluation episode k draws its target path from seed RANDOM_TARGET_SEED + k.
# Training seeds environment i of a run with seed run_seed + i (small), so these never recur.
RANDOM_TARGET_SEED = 1_000_000
# Validation episode k during training (softtrack.rl.validation) uses VALIDATION_SEED + k.
VALIDATION_SEED = 2_000_000
# Confirmation episode k after training (softtrack.rl.confirmation) uses CONFIRM_SEED + k.
CONFIRM_SEED = 3_000_000

# A policy maps one observation (obs_dim,) to one action (act_dim,).
Policy = Callable[[np.ndarray], np.ndarray]

_ARM_ACTIONS = 2 * N_CONTROL_POINTS  # per arm: 6 normal, then 6 binormal control points


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
    """

    trajectory: str
    t: np.ndarray
    tips: np.ndarray
    target: np.ndarray
    element_torques: np.ndarray
    actions: np.ndarray
    terminated: bool


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


def run_episode(policy: Policy, config: TrackingConfig, trajectory: str,
                duration: float = 10.0, seed: int = 0) -> Episode:
    """Run ``policy`` from the straight initial state while the target follows ``trajectory``.

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
    terminated = False
    done_steps = n_steps
    for k in range(n_steps):
        action = np.asarray(policy(obs), dtype=np.float64).reshape(-1)
        result = core.step(action[None])
        actions[k] = action
        tips[k] = core.engine.tip_position[0]
        target[k] = core.targets.position[0]
        torques[k] = core.engine.torques[0]
        obs = result.observation[0]
        if result.terminated[0]:
            terminated, done_steps = True, k + 1
            break
    t = np.arange(1, done_steps + 1) * eval_config.sim.control_dt
    return Episode(trajectory, t, tips[:done_steps], target[:done_steps], torques[:done_steps],
                   actions[:done_steps], terminated)


def trajectory_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """Rows (run_id, trajectory, step, t, arm, tip_x/y/z, target_x/y/z), one per step and arm;
    positions in m as float32 (0.1 µm resolution: for figures; the metrics are computed in
    float64 before storing)."""
    n, n_arms = episode.tips.shape[:2]
    step = np.repeat(np.arange(1, n + 1, dtype=np.int32), n_arms)
    data = {
        "run_id": run_id,
        "trajectory": episode.trajectory,
        "step": step,
        "t": np.repeat(episode.t, n_arms),
        "arm": np.tile(np.arange(n_arms, dtype=np.int32), n),
    }
    for i, axis in enumerate(AXES):
        data[f"tip_{axis}"] = episode.tips[:, :, i].reshape(-1).astype(np.float32)
    for i, axis in enumerate(AXES):
        data[f"target_{axis}"] = np.repeat(episode.target[:, i], n_arms).astype(np.float32)
    return pd.DataFrame(data)


def metrics_table(run_id: str, episode: Episode, steady_start: float = STEADY_START) -> pd.DataFrame:
    """One row per arm: every SPEC §5 metric over the episode, and ``*_steady`` over t ≥ 1 s
    (NaN when the episode is shorter than that), and the arm's action statistics
    (``action_saturation``, ``action_change``, ``action_rms``, see
    :func:`softtrack.metrics.action_statistics`) over the steps the episode ran."""
    rows = []
    steady = episode.t >= steady_start - 1e-9
    n_arms = episode.tips.shape[1]
    if episode.actions.shape != (len(episode.t), _ARM_ACTIONS * n_arms):
        raise ValueError(
            f"actions have shape {episode.actions.shape}; expected "
            f"{(len(episode.t), _ARM_ACTIONS * n_arms)}"
        )
    for arm in range(n_arms):
        row: dict[str, object] = {"run_id": run_id, "trajectory": episode.trajectory, "arm": arm}
        row.update(tracking_metrics(episode.tips[:, arm], episode.target))
        if steady.any():
            steady_metrics = tracking_metrics(episode.tips[steady, arm], episode.target[steady])
        else:  # an episode shorter than the approach: no steady window
            steady_metrics = dict.fromkeys(tracking_metrics(episode.tips[:, arm], episode.target),
                                           float("nan"))
        row.update({f"{k}_steady": v for k, v in steady_metrics.items()})
        columns = slice(_ARM_ACTIONS * arm, _ARM_ACTIONS * (arm + 1))
        row.update(action_statistics(episode.actions[:, columns]))
        row["terminated"] = episode.terminated
        row["duration"] = float(episode.t[-1]) if len(episode.t) else 0.0
        rows.append(row)
    return pd.DataFrame(rows)


def moments_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """The SPEC §5 moment history: one row per step, arm and direction (0 normal,
    1 binormal) with the spatial RMS of the element torques at that step (``rms_moment``,
    N·m, float32)."""
    torques = episode.element_torques  # (N, A, 2, n_elem)
    n, n_arms, n_dirs, _ = torques.shape
    return pd.DataFrame({
        "run_id": run_id,
        "trajectory": episode.trajectory,
        "step": np.repeat(np.arange(1, n + 1, dtype=np.int32), n_arms * n_dirs),
        "t": np.repeat(episode.t, n_arms * n_dirs),
        "arm": np.tile(np.repeat(np.arange(n_arms, dtype=np.int32), n_dirs), n),
        "direction": np.tile(np.arange(n_dirs, dtype=np.int32), n * n_arms),
        "rms_moment": moment_rms(torques).reshape(-1).astype(np.float32),
    })


def moment_peaks_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """The SPEC §5 peak moments: one row per arm, direction and element with the largest
    absolute torque of that element over the episode (``peak_abs_moment``, N·m)."""
    peaks = np.abs(episode.element_torques.astype(np.float32)).max(axis=0)  # (A, 2, n_elem)
    return element_peaks_frame(run_id, episode.trajectory, peaks)


def element_peaks_frame(run_id: str, trajectory: str, peaks: np.ndarray) -> pd.DataFrame:
    """Rows (run_id, trajectory, arm, direction, element, peak_abs_moment) from peaks of shape
    (A arms, 2 directions, n_elem elements), N·m, stored as float32."""
    n_arms, n_dirs, n_elem = peaks.shape
    return pd.DataFrame({
        "run_id": run_id,
        "trajectory": trajectory,
        "arm": np.repeat(np.arange(n_arms, dtype=np.int32), n_dirs * n_elem),
        "direction": np.tile(np.repeat(np.arange(n_dirs, dtype=np.int32), n_elem), n_arms),
        "element": np.tile(np.arange(n_elem, dtype=np.int32), n_arms * n_dirs),
        "peak_abs_moment": peaks.reshape(-1).astype(np.float32),
    })


def element_moments_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """The full torque history, only on request (``softtrack evaluate --full-moments``): one
    row per step, arm and direction with the list of its ``n_elem`` element torques
    (``element_torques``, N·m, float32)."""
    torques = episode.element_torques  # (N, A, 2, n_elem)
    n, n_arms, n_dirs, n_elem = torques.shape
    frame = moments_table(run_id, episode).drop(columns="rms_moment")
    frame["element_torques"] = list(torques.reshape(n * n_arms * n_dirs, n_elem).astype(np.float32))
    return frame


def validation_score(rows: pd.DataFrame) -> float:
    """The validation score of one checkpoint from its rows of ``tables/validation.parquet``
    (one per episode and arm): the mean ``rmse_3d`` (m), or ∞ if an episode terminated."""
    if len(rows) == 0 or rows["terminated"].astype(bool).any():
        return math.inf
    return float(rows["rmse_3d"].mean())
