"""Where two arms can hold the transport task's sphere at rest, and how close a path can come.

The transport task asks the held sphere to follow a path. Whether a path is possible at all is
a question of statics: at each point of the path the arms must be able to hold the sphere
still. :func:`search_workspace` measures the held region with the engine, in the spec's own
physics (its torque per control unit, grip, gravity, sphere and contact):

* a *sample* is one constant action, brought in with a smoothstep over ``ramp`` seconds and
  kept for ``hold`` seconds more (the task's grip is added by the environment as in training).
  Per arm and direction (normal, binormal) the action on control point k = 0…5 is
  offset + slope·(k/5 − ½); both arms share a common part and differ by a differential part
  (arm 1 common + differential, arm 2 common − differential): 8 parameters
  (:func:`actions_from_parameters`);
* the sample *holds the sphere at rest* when it was not dropped, both arms touched it on at
  least half of the last :data:`JUDGE_WINDOW` seconds' control steps, and its mean speed over
  them is below :data:`STILL_SPEED`; its rest position is the mean over those steps;
* a cross-entropy search per goal point (the spec's paths, a few points each, and the sphere's
  start) moves the samples' distribution towards holding the sphere at the goal: every sample
  that held the sphere is kept, so the held region is the union of what all searches found.
  Each iteration runs each goal's mean itself among its samples; the first iteration's mean is
  the grip alone, so a sphere that the grip cannot hold where it starts holds nowhere.

The **floor** of a path (:func:`path_floors`) is the RMSE over the path of each point's
distance to the nearest held position: no controller that must hold the sphere can track the
path with a smaller error (up to the search's coverage: more samples can only lower it).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from softtrack.env.core import TrackingCore
from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import EVAL_TRAJECTORIES, trajectory_position
from softtrack.evaluation.workspace_settings import GOALS_PER_PATH, JUDGE_WINDOW, SearchSettings
from softtrack.sim.actuation import N_CONTROL_POINTS

__all__ = [
    "JUDGE_WINDOW",
    "N_PARAMETERS",
    "STILL_SPEED",
    "SearchSettings",
    "WorkspaceResult",
    "actions_from_parameters",
    "at_torque_scale",
    "boundary_by_height",
    "goal_points",
    "hold_positions",
    "measure_workspace",
    "nearest_distances",
    "path_floors",
    "path_points",
    "search_workspace",
]

#: Action parameters per sample: (common, differential) × (normal, binormal) × (offset, slope).
N_PARAMETERS = 8
#: Mean speed below which a held sphere is at rest, m/s.
STILL_SPEED = 0.05


def actions_from_parameters(parameters: np.ndarray) -> np.ndarray:
    """(n, 24) control values from (n, 8) parameters, clipped to [−1, 1].

    Columns 0–3 are the common part (normal offset, normal slope, binormal offset, binormal
    slope), 4–7 the differential part of the same; arm 1 gets common + differential, arm 2
    common − differential, along the six control points as offset + slope·(k/5 − 1/2).
    """
    ramp = np.linspace(-0.5, 0.5, N_CONTROL_POINTS)  # (6,)
    common, differential = parameters[:, :4], parameters[:, 4:]
    per_arm = np.stack([common + differential, common - differential], axis=1)  # (n, 2, 4)
    offsets, slopes = per_arm[:, :, 0::2], per_arm[:, :, 1::2]  # (n, 2, 2): arm, direction
    values = offsets[..., None] + slopes[..., None] * ramp  # (n, 2, 2, 6)
    return np.clip(values.reshape(len(parameters), -1), -1.0, 1.0)


def hold_positions(
    config: TrackingConfig, parameters: np.ndarray, ramp: float, hold: float
) -> tuple[np.ndarray, np.ndarray]:
    """Run one transport environment per parameter row (module docstring).

    Args:
        config: a transport configuration (``task.carries_object``).
        parameters: (n, 8) action parameters.
        ramp: seconds over which the action is brought in, s.
        hold: seconds the action is kept after the ramp, s.

    Returns:
        (n,) bool, held at rest; (n, 3) the sphere's mean position over the last
        :data:`JUDGE_WINDOW` seconds, m.
    """
    n = len(parameters)
    config = dataclasses.replace(config, episode_duration=ramp + hold)
    core = TrackingCore(n, config)
    core.reset(np.arange(n), [np.random.default_rng(i) for i in range(n)])
    final_actions = actions_from_parameters(parameters)
    dt = config.sim.control_dt
    n_steps = round((ramp + hold) / dt)
    window = max(1, round(JUDGE_WINDOW / dt))
    alive = np.ones(n, dtype=bool)
    both_touching = np.zeros(n)
    speed = np.zeros(n)
    position = np.zeros((n, 3))
    for step in range(n_steps):
        tau = min(1.0, (step + 1) * dt / ramp) if ramp > 0 else 1.0
        result = core.step(final_actions * (3.0 * tau**2 - 2.0 * tau**3))
        alive &= ~result.terminated
        if step >= n_steps - window:
            assert result.touching is not None
            both_touching += result.touching.all(axis=1)
            speed += np.linalg.norm(core.engine.sphere_velocity, axis=1)
            position += core.engine.sphere_position
    held = alive & (both_touching >= 0.5 * window) & (speed / window < STILL_SPEED)
    return held, position / window


def path_points(config: TrackingConfig, name: str, n_points: int = 1000) -> np.ndarray:
    """(n_points, 3) one lap of a closed-form path with the config's target settings, m."""
    target = dataclasses.replace(config.target, name=name)
    t = np.linspace(0.0, target.period, n_points, endpoint=False)
    return trajectory_position(target, t)


def goal_points(
    config: TrackingConfig, paths: Sequence[str] = EVAL_TRAJECTORIES, per_path: int = GOALS_PER_PATH
) -> np.ndarray:
    """(G, 3) the search's goals: ``per_path`` points evenly along each path, then the
    sphere's start, m."""
    assert config.sim.sphere is not None
    goals = [path_points(config, name, per_path) for name in paths]
    return np.concatenate([*goals, np.asarray(config.sim.sphere.center, dtype=float)[None]])


def nearest_distances(points: np.ndarray, reached: np.ndarray) -> np.ndarray:
    """(p,) distance from each of ``points`` (p, 3) to the nearest of ``reached`` (r, 3), m
    (inf when nothing was reached)."""
    if len(reached) == 0:
        return np.full(len(points), np.inf)
    diff = points[:, None, :] - reached[None, :, :]
    return np.sqrt(np.einsum("prk,prk->pr", diff, diff)).min(axis=1)


def search_workspace(
    config: TrackingConfig,
    goals: np.ndarray,
    settings: SearchSettings = SearchSettings(),
    on_progress: Callable[[int, int, int], None] | None = None,
) -> np.ndarray:
    """The sphere's rest positions that constant actions reach, searched towards ``goals``.

    Args:
        config: a transport configuration (``task.carries_object``).
        goals: (G, 3) points the cross-entropy searches aim the sphere at, m.
        settings: the search's sizes and timing.
        on_progress: called with (samples done, samples in all, held so far) after each batch.

    Returns:
        (r, 3) every rest position of a sample that held the sphere, m.

    Raises:
        ValueError: the config carries no object, or a setting is out of range.
    """
    if not config.task.carries_object or config.sim.sphere is None:
        raise ValueError("the workspace is the transport task's: env.task.name must be transport")
    settings.validate()
    rng = np.random.default_rng(settings.seed)
    n_goals = len(goals)
    mean = np.zeros((n_goals, N_PARAMETERS))
    std = np.full((n_goals, N_PARAMETERS), float(settings.initial_std))
    held_positions: list[np.ndarray] = []
    total = n_goals * settings.population * settings.iterations
    done = held_count = 0
    for iteration in range(settings.iterations):
        spread = std[:, None]
        if iteration == 0:  # each sample its own scale, from a nudge to the full range
            low, high = math.log(settings.initial_std), math.log(1.0)
            spread = np.exp(rng.uniform(low, high, (n_goals, settings.population, 1)))
        draws = mean[:, None] + spread * rng.standard_normal(
            (n_goals, settings.population, N_PARAMETERS)
        )
        draws[:, 0] = mean  # each goal's mean itself (at first the grip alone): never lost
        flat = draws.reshape(-1, N_PARAMETERS)
        held = np.zeros(len(flat), dtype=bool)
        position = np.zeros((len(flat), 3))
        for first in range(0, len(flat), settings.batch):
            part = slice(first, first + settings.batch)
            held[part], position[part] = hold_positions(
                config, flat[part], settings.ramp, settings.hold
            )
            done += len(flat[part])
            held_count += int(held[part].sum())
            if on_progress is not None:
                on_progress(done, total, held_count)
        held_positions.append(position[held])
        cost = np.linalg.norm(
            position.reshape(n_goals, settings.population, 3) - goals[:, None], axis=2
        )
        cost[~held.reshape(n_goals, settings.population)] = np.inf
        for g in range(n_goals):
            order = np.argsort(cost[g])[: settings.elite]
            order = order[np.isfinite(cost[g][order])]
            if len(order) >= 2:  # too few held samples: keep searching where it was
                mean[g] = draws[g, order].mean(axis=0)
                std[g] = np.maximum(draws[g, order].std(axis=0), settings.min_std)
    return np.concatenate(held_positions) if held_positions else np.zeros((0, 3))


def path_floors(
    config: TrackingConfig,
    held: np.ndarray,
    paths: Sequence[str] = EVAL_TRAJECTORIES,
    tolerance: float = 0.025,
) -> pd.DataFrame:
    """Per path: ``floor`` (the RMSE of each path point's distance to the nearest held
    position, m), ``median`` and ``max`` of those distances, m, and ``within`` (the share of
    the path within ``tolerance`` m of a held position); inf where nothing was held."""
    rows = []
    for name in paths:
        gap = nearest_distances(path_points(config, name), held)
        rows.append(
            {
                "path": name,
                "floor": float(np.sqrt(np.mean(gap**2))),
                "median": float(np.median(gap)),
                "max": float(gap.max()),
                "within": float(np.mean(gap <= tolerance)),
            }
        )
    return pd.DataFrame(rows)


def boundary_by_height(held: np.ndarray, step: float = 0.05) -> pd.DataFrame:
    """The held region per height: held positions in bins of ``step`` m along y (the arms'
    axis), each with ``count``, the x and z extents (m) and ``reach``, the largest horizontal
    distance from the arms' axis (x = z = 0), m."""
    if len(held) == 0:
        return pd.DataFrame(
            columns=["y_low", "y_high", "count", "x_min", "x_max", "z_min", "z_max", "reach"]
        )
    bins = np.floor(held[:, 1] / step).astype(int)
    rows = []
    for b in np.unique(bins):
        part = held[bins == b]
        rows.append(
            {
                "y_low": b * step,
                "y_high": (b + 1) * step,
                "count": len(part),
                "x_min": float(part[:, 0].min()),
                "x_max": float(part[:, 0].max()),
                "z_min": float(part[:, 2].min()),
                "z_max": float(part[:, 2].max()),
                "reach": float(np.hypot(part[:, 0], part[:, 2]).max()),
            }
        )
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class WorkspaceResult:
    """One :func:`measure_workspace` at one actuation scale.

    Attributes:
        torque_scale: element torque at a control value of 1, N·m.
        held: (r, 3) rest positions of the samples that held the sphere, m.
        samples: samples run.
        floors: :func:`path_floors`'s table.
        boundary: :func:`boundary_by_height`'s table.
        seconds: wall time of the search, s.
    """

    torque_scale: float
    held: np.ndarray
    samples: int
    floors: pd.DataFrame
    boundary: pd.DataFrame
    seconds: float


def at_torque_scale(config: TrackingConfig, torque_scale: float) -> TrackingConfig:
    """``config`` with ``torque_scale`` N·m per control unit and the same squeeze: the grip
    (in control units) scaled by the inverse ratio, so it presses with the same torque."""
    ratio = float(config.sim.torque_scale) / float(torque_scale)
    return dataclasses.replace(
        config,
        sim=dataclasses.replace(config.sim, torque_scale=float(torque_scale)),
        task=dataclasses.replace(config.task, grip=config.task.grip * ratio),
    )


def measure_workspace(
    config: TrackingConfig,
    settings: SearchSettings = SearchSettings(),
    per_path: int = GOALS_PER_PATH,
    torque_scales: Sequence[float] = (),
    paths: Sequence[str] = EVAL_TRAJECTORIES,
    on_progress: Callable[[float, int, int, int], None] | None = None,
) -> list[WorkspaceResult]:
    """The held region and the paths' floors at the config's actuation and at each of
    ``torque_scales`` (N·m per control unit) besides, in that order. At another scale the
    grip presses with the same torque (:func:`at_torque_scale`) and the search's spreads are
    scaled so that it explores the same torques.

    Args:
        config: a transport configuration.
        settings: the search (:class:`SearchSettings`).
        per_path: goal points per path (:func:`goal_points`).
        torque_scales: further actuation scales to measure, N·m per control unit.
        paths: the paths whose floors are computed.
        on_progress: called with (torque scale, samples done, samples in all, held so far).

    Raises:
        ValueError: not a transport config, or a setting out of range.
    """
    own = float(config.sim.torque_scale)
    results = []
    for scale in dict.fromkeys([own, *(float(s) for s in torque_scales)]):
        scaled = at_torque_scale(config, scale)
        ratio = own / scale  # the search explores the same torques (N·m) at every scale
        searched = dataclasses.replace(
            settings,
            initial_std=settings.initial_std * ratio,
            min_std=settings.min_std * ratio,
        )
        started = time.monotonic()
        progress = None
        if on_progress is not None:
            progress = functools.partial(on_progress, scale)
        goals = goal_points(scaled, paths, per_path)
        held = search_workspace(scaled, goals, searched, progress)
        results.append(
            WorkspaceResult(
                scale,
                held,
                len(goals) * searched.population * searched.iterations,
                path_floors(scaled, held, paths),
                boundary_by_height(held),
                time.monotonic() - started,
            )
        )
    return results
