"""The tables of an evaluation episode (:class:`~softtrack.evaluation.episodes.Episode`).

One function per table a run stores (:mod:`softtrack.evaluation.run_evaluation`): tip and target
positions per step (``eval_trajectories``), the metrics of docs/environment.md per arm (``eval_metrics``, also
the rows of ``validation``, ``confirmation`` and ``eval_random``), the spatial RMS of the
element torques per step (``eval_moments``), each element's peak torque (``eval_moment_peaks``)
and, on request, every element torque (``eval_element_moments``); and the validation score
of a checkpoint's metrics rows.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from softtrack.evaluation.episodes import Episode
from softtrack.evaluation.metrics import (
    AXES,
    action_statistics,
    contact_statistics,
    moment_rms,
    safety_statistics,
    torque_statistics,
    tracking_metrics,
)
from softtrack.evaluation.scores import (
    CARRY_SCORE,
    LOST_OBJECT_ERROR,
    VALIDATION_SCORED_COLUMNS,
    carry_errors,
    validation_score,
    with_carry_score,
)
from softtrack.evaluation.transport_metrics import transport_statistics
from softtrack.sim.actuation import N_CONTROL_POINTS
from softtrack.store.tables import element_peaks_frame

__all__ = [
    "CARRY_SCORE",
    "LOST_OBJECT_ERROR",
    "STEADY_START",
    "VALIDATION_SCORED_COLUMNS",
    "carry_errors",
    "element_moments_table",
    "element_peaks_frame",
    "metrics_table",
    "moment_peaks_table",
    "moments_table",
    "snapshot_table",
    "trajectory_table",
    "validation_score",
    "with_carry_score",
]

STEADY_START = 1.0  # s: the "steady" metrics leave out the initial approach

_ARM_ACTIONS = 2 * N_CONTROL_POINTS  # per arm: 6 normal, then 6 binormal control points


def trajectory_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """Rows (run_id, trajectory, step, t, arm, tip_x/y/z, target_x/y/z, clearance,
    penetration, contact_force), one per step and arm (``target_*``: the arm's own point,
    the target centre in the shared task); positions in m as float32 (0.1 µm
    resolution: for figures; the metrics are computed in float64 before storing). The last
    three are the scene's, repeated in both arms' rows (:class:`Episode`): surface clearance
    and overlap (m) and the contact force between the arms (N), float32; NaN where not
    recorded."""
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
    goals = np.stack([episode.goals(arm) for arm in range(n_arms)], axis=1)  # (N, A, 3)
    for i, axis in enumerate(AXES):
        data[f"target_{axis}"] = goals[:, :, i].reshape(-1).astype(np.float32)
    for name in ("clearance", "penetration", "contact_force"):
        values = getattr(episode, name)
        values = np.full(n, np.nan) if values is None else values
        data[name] = np.repeat(values, n_arms).astype(np.float32)
    if episode.object_position is not None:  # transport: the sphere's centre (target: its goal)
        for i, axis in enumerate(AXES):
            data[f"object_{axis}"] = np.repeat(episode.object_position[:, i], n_arms).astype(
                np.float32
            )
    return pd.DataFrame(data)


def snapshot_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """The arms' shapes at a few instants (:attr:`Episode.snapshots`): rows (run_id,
    trajectory, step, t, arm, node, x, y, z), positions in m as float32; no rows when the
    episode kept none."""
    if episode.snapshots is None or episode.snapshot_steps is None:
        nodes = np.zeros((0, episode.tips.shape[1], 3, 0))
        steps = np.zeros(0, dtype=np.int64)
    else:
        nodes, steps = episode.snapshots, episode.snapshot_steps
    n_snap, n_arms, _, n_nodes = nodes.shape
    per_snap = n_arms * n_nodes
    data = {
        "run_id": run_id,
        "trajectory": episode.trajectory,
        "step": np.repeat(steps.astype(np.int32) + 1, per_snap),
        "t": np.repeat(episode.t[steps] if n_snap else np.zeros(0), per_snap),
        "arm": np.tile(np.repeat(np.arange(n_arms, dtype=np.int32), n_nodes), n_snap),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), n_snap * n_arms),
    }
    for i, axis in enumerate(AXES):
        data[axis] = nodes[:, :, i, :].reshape(-1).astype(np.float32)
    return pd.DataFrame(data)


def metrics_table(
    run_id: str, episode: Episode, steady_start: float = STEADY_START
) -> pd.DataFrame:
    """One row per arm: every docs/environment.md metric over the episode (errors from the
    arm's own point, :meth:`Episode.goals`), and ``*_steady`` over t ≥ 1 s
    (NaN when the episode is shorter than that), and the arm's action statistics
    (``action_saturation``, ``action_change``, ``action_rms``, see
    :func:`softtrack.evaluation.metrics.action_statistics`) over the steps the episode ran;
    after ``terminated`` and ``duration``, the arm's torque statistics (``torque_rate_rms``
    N·m/s, ``peak_moment`` N·m: :func:`~softtrack.evaluation.metrics.torque_statistics`) and
    the episode's inter-arm safety, the same in both arms' rows (``min_arm_distance`` m,
    ``collision_steps``: :func:`~softtrack.evaluation.metrics.safety_statistics`; NaN and 0
    in a single-arm scene) and contact (``max_penetration`` m, ``contact_steps``,
    ``mean_contact_force`` and ``max_contact_force`` N:
    :func:`~softtrack.evaluation.metrics.contact_statistics`; absent in a single-arm scene
    and in episodes recorded without them); for a planning controller (``episode.planning_time``), the mean
    and largest CPU time of its call per control step (``planning_time``,
    ``planning_time_max``, s)."""
    rows = []
    steady = episode.t >= steady_start - 1e-9
    n_arms = episode.tips.shape[1]
    if episode.actions.shape != (len(episode.t), _ARM_ACTIONS * n_arms):
        raise ValueError(
            f"actions have shape {episode.actions.shape}; expected "
            f"{(len(episode.t), _ARM_ACTIONS * n_arms)}"
        )
    clearance = (
        episode.clearance if episode.clearance is not None else np.full(len(episode.t), np.nan)
    )
    safety: dict[str, object] = dict(safety_statistics(clearance, episode.collision_margin))
    if n_arms >= 2 and episode.penetration is not None and episode.contact_force is not None:
        safety.update(contact_statistics(episode.penetration, episode.contact_force))
    per_arm: list[dict[str, float]] = [{} for _ in range(n_arms)]
    if (
        episode.object_position is not None
        and episode.object_force is not None
        and episode.object_touching is not None
    ):
        scene, per_arm = transport_statistics(
            episode.object_position,
            episode.target,
            episode.object_force,
            episode.object_touching,
            episode.dropped,
            episode.t,
        )
        safety.update(scene)
    for arm in range(n_arms):
        row: dict[str, object] = {"run_id": run_id, "trajectory": episode.trajectory, "arm": arm}
        goals = episode.goals(arm)
        row.update(tracking_metrics(episode.tips[:, arm], goals))
        if steady.any():
            steady_metrics = tracking_metrics(episode.tips[steady, arm], goals[steady])
        else:  # an episode shorter than the approach: no steady window
            steady_metrics = dict.fromkeys(
                tracking_metrics(episode.tips[:, arm], goals), float("nan")
            )
        row.update({f"{k}_steady": v for k, v in steady_metrics.items()})
        columns = slice(_ARM_ACTIONS * arm, _ARM_ACTIONS * (arm + 1))
        row.update(action_statistics(episode.actions[:, columns]))
        row["terminated"] = episode.terminated
        row["duration"] = float(episode.t[-1]) if len(episode.t) else 0.0
        row.update(torque_statistics(episode.element_torques[:, arm], episode.t))
        row.update(safety)
        row.update(per_arm[arm])
        if episode.planning_time is not None and len(episode.planning_time):
            row["planning_time"] = float(np.mean(episode.planning_time))
            row["planning_time_max"] = float(np.max(episode.planning_time))
        rows.append(row)
    return pd.DataFrame(rows)


def moments_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """The docs/environment.md moment history: one row per step, arm and direction (0 normal,
    1 binormal) with the spatial RMS of the element torques at that step (``rms_moment``,
    N·m, float32)."""
    torques = episode.element_torques  # (N, A, 2, n_elem)
    n, n_arms, n_dirs, _ = torques.shape
    return pd.DataFrame(
        {
            "run_id": run_id,
            "trajectory": episode.trajectory,
            "step": np.repeat(np.arange(1, n + 1, dtype=np.int32), n_arms * n_dirs),
            "t": np.repeat(episode.t, n_arms * n_dirs),
            "arm": np.tile(np.repeat(np.arange(n_arms, dtype=np.int32), n_dirs), n),
            "direction": np.tile(np.arange(n_dirs, dtype=np.int32), n * n_arms),
            "rms_moment": moment_rms(torques).reshape(-1).astype(np.float32),
        }
    )


def moment_peaks_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """The docs/environment.md peak moments: one row per arm, direction and element with the largest
    absolute torque of that element over the episode (``peak_abs_moment``, N·m)."""
    peaks = np.abs(episode.element_torques.astype(np.float32)).max(axis=0)  # (A, 2, n_elem)
    return element_peaks_frame(run_id, episode.trajectory, peaks)


def element_moments_table(run_id: str, episode: Episode) -> pd.DataFrame:
    """The full torque history, only on request (``softtrack evaluate --full-moments``): one
    row per step, arm and direction with the list of its ``n_elem`` element torques
    (``element_torques``, N·m, float32)."""
    torques = episode.element_torques  # (N, A, 2, n_elem)
    n, n_arms, n_dirs, n_elem = torques.shape
    frame = moments_table(run_id, episode).drop(columns="rms_moment")
    frame["element_torques"] = list(torques.reshape(n * n_arms * n_dirs, n_elem).astype(np.float32))
    return frame
