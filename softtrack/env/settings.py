"""One settings object for a tracking environment, built from flat keyword arguments."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softtrack.env.realism import RealismConfig
from softtrack.env.reward_config import RewardConfig
from softtrack.env.targets import TargetConfig
from softtrack.env.tasks import TaskConfig
from softtrack.numbers import out_of_range, setting
from softtrack.sim.params import InvalidParameterError, SimParams

__all__ = ["TrackingConfig", "make_config"]


@dataclass(frozen=True)
class TrackingConfig:
    """Everything that defines a tracking environment.

    Attributes:
        sim: physics and actuation (docs/physics.md).
        target: target motion (docs/environment.md).
        reward: reward terms (docs/environment.md).
        episode_duration: simulated seconds before truncation, s.
        realism: sensing and actuation imperfections (docs/environment.md); off by default.
        task: which point each arm tracks (:mod:`softtrack.env.tasks`); the study's shared
            target by default.
        arm: the dual-arm index (0 or 1) of a single-arm scene's arm, ``None`` for the dual
            scene.
    """

    sim: SimParams
    target: TargetConfig
    reward: RewardConfig
    episode_duration: float = setting(10.0, "s", gt=0)
    realism: RealismConfig = field(default_factory=RealismConfig)
    task: TaskConfig = field(default_factory=TaskConfig)
    arm: int | None = None

    @property
    def n_arms(self) -> int:
        return self.sim.n_arms

    def goal_offsets(self) -> np.ndarray:
        """(A, 3) offset of each arm's point from the target centre, m (:mod:`softtrack.env.tasks`)."""
        arms = (0, 1) if self.arm is None else (self.arm,)
        return self.task.goal_offsets(arms[: self.n_arms])

    @property
    def max_episode_steps(self) -> int:
        """Control steps in one episode (5000 at the defaults)."""
        return round(self.episode_duration / self.sim.control_dt)

    def validate(self) -> None:
        """Raise :class:`InvalidParameterError` naming the first invalid setting."""
        self.sim.validate()
        for part in (self.target, self.reward, self.realism, self.task):
            try:
                part.validate()
            except ValueError as err:
                raise InvalidParameterError(str(err)) from None
        try:
            self.realism.check_stability(self.sim)
        except ValueError as err:
            raise InvalidParameterError(str(err)) from None
        if self.reward.n_arms != self.sim.n_arms:
            raise InvalidParameterError(
                f"arm_weights has {self.reward.n_arms} entries but the scene has "
                f"{self.sim.n_arms} arms; give one weight per arm"
            )
        problem = out_of_range(self)
        if problem is not None:
            raise InvalidParameterError(problem)
        if self.max_episode_steps < 1:
            raise InvalidParameterError("episode_duration is shorter than one control step")
        self._validate_object()

    def _validate_object(self) -> None:
        """The transport task and the sphere go together, in the two-arm scene."""
        if self.task.carries_object and self.sim.sphere is None:
            raise InvalidParameterError(
                "task transport needs a sphere to carry: set sphere (e.g. sphere: {} for the "
                "default 0.05-m ball between the tips)"
            )
        if self.sim.sphere is not None and not self.task.carries_object:
            raise InvalidParameterError(
                f"a sphere belongs to the transport task, but the task is {self.task.name!r}; "
                "set task: transport or remove the sphere"
            )


_SIM_FIELDS = {f.name for f in dataclasses.fields(SimParams)}
_TARGET_FIELDS = {f.name for f in dataclasses.fields(TargetConfig)} - {"name"}
_REWARD_FIELDS = {f.name for f in dataclasses.fields(RewardConfig)}
_TASK_FIELDS = {f.name for f in dataclasses.fields(TaskConfig)} - {"name"}


def make_config(n_arms: int = 2, arm: int | None = None, **kwargs: Any) -> TrackingConfig:
    """Build and validate a :class:`TrackingConfig` from flat keyword arguments.

    Any field of :class:`SimParams`, :class:`TargetConfig` or :class:`RewardConfig` may be
    given by name, plus ``target`` (a mode name or a ``TargetConfig``), ``reward`` (a
    ``RewardConfig``), ``episode_duration``, ``realism`` (a ``RealismConfig`` or a mapping
    of its fields; default all off), ``task`` (a task name or a ``TaskConfig``) and any
    field of :class:`TaskConfig` (``standoff``, m, the viewpoints task's distance of each
    arm's point from the target; the transport task's ``approach``, ``drop_grace``,
    ``hold_bonus``, ``squeeze_band``, ``squeeze_penalty``, ``drop_penalty``, ``reach_penalty``,
    ``bonus_needs_grip``, ``grip``). In the
    transport task ``episode_duration`` defaults to the approach plus 10 s (one lap).

    Args:
        n_arms: 2 for the dual-arm scene, 1 for a single arm.
        arm: for ``n_arms=1``, which of the default dual-arm bases the arm sits at (0 or 1).

    Raises:
        InvalidParameterError: an unknown keyword (with the valid names) or an invalid value.
    """
    kwargs = dict(kwargs)
    target = kwargs.pop("target", "random")
    reward = kwargs.pop("reward", None)
    duration = kwargs.pop("episode_duration", None)
    task = kwargs.pop("task", "shared")
    task_config = task if isinstance(task, TaskConfig) else TaskConfig(name=str(task))
    task_kw = {k: kwargs.pop(k) for k in list(kwargs) if k in _TASK_FIELDS}
    if task_kw:
        task_config = dataclasses.replace(task_config, **_tuples(task_kw))
    if duration is None:
        duration = TrackingConfig.episode_duration + (
            task_config.approach if task_config.carries_object else 0.0
        )
    episode_duration = float(duration)
    try:
        realism = RealismConfig.from_value(kwargs.pop("realism", None))
    except ValueError as err:
        raise InvalidParameterError(str(err)) from None
    sim_kw = {k: kwargs.pop(k) for k in list(kwargs) if k in _SIM_FIELDS}
    target_kw = {k: kwargs.pop(k) for k in list(kwargs) if k in _TARGET_FIELDS}
    reward_kw = {k: kwargs.pop(k) for k in list(kwargs) if k in _REWARD_FIELDS}
    if kwargs:
        valid = sorted(
            _SIM_FIELDS
            | _TARGET_FIELDS
            | _REWARD_FIELDS
            | _TASK_FIELDS
            | {"target", "reward", "episode_duration", "realism", "task"}
        )
        raise InvalidParameterError(
            f"unknown environment parameter {min(kwargs)!r}; valid names: {', '.join(valid)}"
        )
    if n_arms == 1:
        if "base_positions" not in sim_kw:
            bases = SimParams().base_positions
            if arm not in (0, 1):
                raise InvalidParameterError(
                    f"arm={arm!r} must be 0 (base x = −0.1) or 1 (x = +0.1)"
                )
            sim_kw["base_positions"] = (bases[arm],)
    elif n_arms != 2:
        raise InvalidParameterError(f"n_arms={n_arms!r} must be 1 or 2")
    elif arm is not None:
        raise InvalidParameterError(
            "arm= selects the base of a single-arm scene; the dual-arm "
            "scene has both arms (set base_positions to move them)"
        )
    sim = SimParams.from_overrides(**sim_kw)
    if isinstance(target, TargetConfig):
        target_config = dataclasses.replace(target, **target_kw)
    else:
        target_config = TargetConfig(name=str(target), **_tuples(target_kw))
    if reward is None:
        reward = RewardConfig() if n_arms == 2 else RewardConfig.single_arm()
    reward_config = dataclasses.replace(reward, **_tuples(reward_kw))
    config = TrackingConfig(
        sim,
        target_config,
        reward_config,
        episode_duration,
        realism,
        task_config,
        arm if n_arms == 1 else None,
    )
    config.validate()
    return config


def _tuples(values: dict[str, Any]) -> dict[str, Any]:
    """Lists (e.g. from YAML) become tuples so the frozen configs stay hashable."""
    return {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
