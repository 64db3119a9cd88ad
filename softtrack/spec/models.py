"""The spec's top-level model :class:`ExperimentSpec` with its cluster section.

The environment, algorithm, training, MPC and tune sections live in
:mod:`softtrack.spec.env_models`, :mod:`softtrack.spec.algo_models`,
:mod:`softtrack.spec.training_models`, :mod:`softtrack.spec.mpc_models` and
:mod:`softtrack.spec.tune_models`, the shared field types and :class:`SpecError` in
:mod:`softtrack.spec.fields`; :mod:`softtrack.spec` exports them all."""

from __future__ import annotations

import itertools
import json
import math
from typing import Any, Literal

from pydantic import BaseModel, Field, ValidationError, field_validator, model_validator

from softtrack.spec.algo_models import AlgoSpec
from softtrack.spec.env_models import EnvSpec, check_step_count
from softtrack.spec.fields import (
    Float,
    Int,
    Seed,
    SpecModel,
    custom_error,
    section_field,
    unit_field,
)
from softtrack.spec.mpc_models import MpcSpec
from softtrack.spec.parsing import _convert, _sub_model, _suggest
from softtrack.spec.training_models import (
    TrainingSpec,
    check_validated_checkpoints,
    check_validation_needs,
)
from softtrack.spec.tune_models import MAX_COMBINATIONS, TuneSpec, trial_data

__all__ = ["ClusterSpec", "ExperimentSpec", "TrainingSpec"]

_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"


# ------------------------------------------------------------------------------------------
# cluster
# ------------------------------------------------------------------------------------------
class ClusterSpec(SpecModel):
    """SLURM resources of each run's job (``softtrack sweep --executor slurm``); options of the
    command override them. Not part of the experiment: excluded from :func:`spec_hash`."""

    partition: str | None = unit_field(None, "SLURM partition (None: the cluster's default)", "-")
    time_min: Int = unit_field(
        240,
        "time limit of one job; a run that needs longer is requeued and resumes from its "
        "last checkpoint",
        "min",
        ge=1,
    )
    cpus_per_task: Int = unit_field(1, "CPU cores per job", "cores", ge=1)
    mem_gb: Float = unit_field(4.0, "memory per job", "GB", gt=0)
    max_requeues: Int = unit_field(
        10, "how often a job may be requeued after preemption or time-out", "-", ge=0
    )


# ------------------------------------------------------------------------------------------
# experiment
# ------------------------------------------------------------------------------------------


def _check_per_arm_critic(spec: ExperimentSpec) -> None:
    """Raise the spec error of the first setting ``algo.critic: per_arm`` cannot run with."""
    a = spec.algo
    if a.name != "td3" or a.backend != "sbx":
        raise custom_error(
            f"critic 'per_arm' is implemented for td3 with backend sbx, not {a.name} with "
            f"backend {a.backend}; set algo.name: td3 and algo.backend: sbx, or critic: joint",
            "algo.critic",
        )
    if spec.controller != "centralized":
        raise custom_error(
            "critic 'per_arm' splits the dual-arm reward, so it needs controller: centralized "
            "(an independent run's policies each learn one arm already); use critic: joint",
            "algo.critic",
        )
    if a.normalize_reward:
        raise custom_error(
            "critic 'per_arm' learns the raw per-arm reward shares, which VecNormalize cannot "
            "scale; set algo.normalize_reward: false",
            "algo.critic",
        )


def _check_mirror_replay(spec: ExperimentSpec) -> None:
    """Raise the spec error of the first setting ``algo.mirror_replay`` cannot run with."""
    a, physics = spec.algo, spec.env.physics
    hint = "or set algo.mirror_replay: false"
    if not a.is_off_policy or spec.controller != "centralized" or a.critic != "joint":
        raise custom_error(
            "mirror_replay fills the replay buffer of one centralized dual-arm policy; it needs "
            f"an off-policy algo, controller: centralized and critic: joint, {hint}",
            "algo.mirror_replay",
        )
    if a.normalize:
        raise custom_error(
            f"mirror_replay stores raw observations, which VecNormalize rescales; set "
            f"algo.normalize: false {hint}",
            "algo.mirror_replay",
        )
    (x1, y1, z1), (x2, y2, z2) = physics.base_positions
    if x1 != -x2 or y1 != y2 or z1 != z2:
        raise custom_error(
            f"mirror_replay needs bases that are mirror images in x = 0, e.g. [[-0.1, 0, 0], "
            f"[0.1, 0, 0]], got {physics.base_positions}; move them {hint}",
            "algo.mirror_replay",
        )
    w1, w2 = spec.env.reward.arm_weights
    if w1 != w2:
        raise custom_error(
            f"mirror_replay swaps the arms, which leaves the reward unchanged only with equal "
            f"env.reward.arm_weights, got ({w1:g}, {w2:g}); make them equal {hint}",
            "algo.mirror_replay",
        )


def _check_actor_preactivation_penalty(spec: ExperimentSpec) -> None:
    """Raise the spec error of a setting ``algo.actor_preactivation_penalty`` cannot run with."""
    a = spec.algo
    if a.name != "td3" or a.backend != "sbx" or a.critic != "joint":
        raise custom_error(
            "actor_preactivation_penalty is implemented for td3 with backend sbx and "
            f"critic joint, not {a.name} with backend {a.backend} and critic {a.critic}; "
            "change those or set algo.actor_preactivation_penalty: 0",
            "algo.actor_preactivation_penalty",
        )


def _check_randomisation_warmup(spec: ExperimentSpec) -> None:
    """Raise the spec error of a ``training.randomisation_warmup_steps`` with nothing to ramp
    or longer than the training."""
    t = spec.training
    if not spec.env.realism.random_perturbations:
        raise custom_error(
            f"randomisation_warmup_steps {t.randomisation_warmup_steps} ramps env.realism's "
            "random perturbations, but it has none (no [low, high] range, action_delay_max, "
            "noise, stuck or dropped values); add some or set randomisation_warmup_steps: 0",
            "training.randomisation_warmup_steps",
        )
    if t.randomisation_warmup_steps > t.total_timesteps:
        raise custom_error(
            f"randomisation_warmup_steps {t.randomisation_warmup_steps} > total_timesteps "
            f"{t.total_timesteps}, so training would never see the full perturbations; use "
            "at most total_timesteps",
            "training.randomisation_warmup_steps",
        )


def _check_goal_warmup(spec: ExperimentSpec) -> None:
    """Raise the spec error of a ``training.goal_warmup_steps`` without the transport task or
    longer than the training."""
    t = spec.training
    if spec.env.task.name != "transport":
        raise custom_error(
            f"goal_warmup_steps {t.goal_warmup_steps} ramps the transport goal's motion, but "
            f"env.task.name is {spec.env.task.name!r}; set env.task.name: transport or "
            "goal_warmup_steps: 0",
            "training.goal_warmup_steps",
        )
    if t.goal_warmup_steps > t.total_timesteps:
        raise custom_error(
            f"goal_warmup_steps {t.goal_warmup_steps} > total_timesteps {t.total_timesteps}, "
            "so training would never see the full motion; use at most total_timesteps",
            "training.goal_warmup_steps",
        )


class ExperimentSpec(SpecModel):
    """One experiment: an environment, an algorithm, a budget and a set of seeds.

    It expands to one training run per seed (see :meth:`with_seed`).
    """

    name: str = Field(
        "experiment",
        description="name of the experiment: letters, digits, '_', '-', '.'; at most 64 "
        "characters (defaults to the spec file's name) [-]",
        pattern=_NAME_PATTERN,
    )
    env: EnvSpec = section_field(EnvSpec, "the environment")
    algo: AlgoSpec = section_field(
        AlgoSpec, "the RL algorithm and its hyperparameters (rl-zoo key names)"
    )
    training: TrainingSpec = section_field(
        TrainingSpec, "budget, parallelism, checkpoints, logging"
    )
    cluster: ClusterSpec = section_field(
        ClusterSpec, "SLURM resources per run for `softtrack sweep --executor slurm`"
    )
    seeds: list[Seed] = Field(
        [0, 1, 2],
        description="random seeds, one training run per seed; an int or a list [-]",
        min_length=1,
    )
    controller: Literal["centralized", "independent", "mpc"] = unit_field(
        "centralized",
        "centralized: one policy drives both arms; independent: one single-arm policy per arm "
        "(docs/environment.md), trained one after the other (arm 0, then arm 1) in the single-arm "
        "environment of its arm, each with the algo settings and training.total_timesteps env "
        "steps, so an independent run takes twice the env steps of a centralized one; mpc: "
        "the sampling planner of the mpc section (docs/mpc.md), nothing to train",
        "-",
    )
    mpc: MpcSpec = section_field(
        MpcSpec, "the sampling planner of controller: mpc (docs/mpc.md); unused otherwise"
    )
    tune: TuneSpec | None = Field(
        None,
        description="the search space of `softtrack tune` (docs/tuning.md); null = none. Not "
        "part of the experiment: excluded from spec_hash and from the trials' run specs [-]",
    )

    @field_validator("seeds", mode="before")
    @classmethod
    def _seeds_as_list(cls, value: Any) -> Any:
        if isinstance(value, int) and not isinstance(value, bool):
            return [value]
        return value

    @field_validator("seeds")
    @classmethod
    def _unique_seeds(cls, value: list[int]) -> list[int]:
        if len(set(value)) != len(value):
            raise custom_error(f"duplicate seeds in {value}; list each seed once")
        return value

    @model_validator(mode="after")
    def _check_curricula(self) -> ExperimentSpec:
        if self.training.randomisation_warmup_steps > 0:
            _check_randomisation_warmup(self)
        if self.training.goal_warmup_steps > 0:
            _check_goal_warmup(self)
        return self

    @model_validator(mode="after")
    def _check_budget(self) -> ExperimentSpec:
        a, t = self.algo, self.training
        if a.is_off_policy:
            if a.learning_starts >= t.total_timesteps:
                raise custom_error(
                    f"learning_starts {a.learning_starts} ≥ training.total_timesteps "
                    f"{t.total_timesteps}, so the agent would never learn; use a value below "
                    "total_timesteps",
                    "algo.learning_starts",
                )
            if a.batch_size > a.buffer_size:
                raise custom_error(
                    f"batch_size {a.batch_size} > buffer_size {a.buffer_size}; use a batch "
                    "no larger than the buffer",
                    "algo.batch_size",
                )
        elif a.batch_size > a.n_steps * t.n_envs or a.batch_size < 2:
            raise custom_error(
                f"batch_size {a.batch_size} must lie in [2, n_steps·n_envs = "
                f"{a.n_steps * t.n_envs}] for ppo; lower batch_size or raise n_steps",
                "algo.batch_size",
            )
        if a.critic == "per_arm":
            _check_per_arm_critic(self)
        elif a.per_arm_networks:
            raise custom_error(
                "per_arm_networks splits the networks by the per-arm reward shares, which only "
                "critic 'per_arm' learns; set algo.critic: per_arm or per_arm_networks: false",
                "algo.per_arm_networks",
            )
        if a.actor_observation != "full" and not a.per_arm_networks:
            raise custom_error(
                f"actor_observation '{a.actor_observation}' gives each arm's own actor network "
                "part of the observation; set algo.per_arm_networks: true (with critic: per_arm) "
                "or actor_observation: full",
                "algo.actor_observation",
            )
        if a.mirror_replay:
            _check_mirror_replay(self)
        if a.actor_preactivation_penalty > 0:
            _check_actor_preactivation_penalty(self)
        if self.env.task.name == "transport" and self.controller == "independent":
            raise custom_error(
                "controller: independent trains each arm's policy alone, in a one-arm scene "
                "that cannot hold the sphere; for the transport task's independent baseline "
                "use controller: centralized with algo.critic: per_arm, "
                "per_arm_networks: true and actor_observation: own_arm (each arm's actor "
                "sees its own state, the sphere and the goal)",
                "controller",
            )
        if t.final_policy == "best_validated":
            check_validated_checkpoints(
                t,
                "final_policy 'best_validated'",
                "training.final_policy",
                or_else=" or final_policy: last",
            )
        elif t.confirm_episodes > 0:
            raise custom_error(
                f"confirm_episodes {t.confirm_episodes} confirms the best-validated model, but "
                "final_policy is 'last'; set final_policy: best_validated or confirm_episodes: 0",
                "training.confirm_episodes",
            )
        check_validation_needs(t)
        control_dt = self.env.control_dt
        if t.eval_duration < control_dt:
            raise custom_error(
                f"eval_duration {t.eval_duration:g} s is shorter than one control step "
                f"({control_dt:g} s); use at least {control_dt:g}",
                "training.eval_duration",
            )
        check_step_count(
            t.eval_duration,
            self.env.physics.dt,
            self.env.physics.steps_per_action,
            "env.physics.dt",
        )
        if self.tune is not None:
            check_tune(self)
        return self

    @property
    def n_runs(self) -> int:
        """Training runs this spec expands to (one per seed)."""
        return len(self.seeds)

    def with_seed(self, seed: int) -> ExperimentSpec:
        """A copy with ``seeds = [seed]``: the fully resolved spec of a single run."""
        return self.model_copy(update={"seeds": [int(seed)]}, deep=True)


# ------------------------------------------------------------------------------------------
# the tune section against the whole spec
# ------------------------------------------------------------------------------------------
def _check_tune_paths(tune: TuneSpec) -> None:
    """Raise the spec error of the first ``tune.params`` key that is not a field of the spec
    that takes a value."""
    for path in tune.params:
        field = ("tune", "params", path)
        parts = path.split(".")
        model: type[BaseModel] | None = ExperimentSpec
        for depth, part in enumerate(parts):
            if model is None:
                where = ".".join(parts[:depth])
                raise custom_error(
                    f"{where!r} has no sub-fields; tune {where} itself with categorical choices",
                    field,
                )
            if part not in model.model_fields:
                raise custom_error(
                    f"not a spec field: unknown field {part!r}; "
                    + _suggest(part, model.model_fields),
                    field,
                )
            model = _sub_model(model, part)
        if model is not None:
            example = next(iter(model.model_fields))
            raise custom_error(
                f"{path!r} is a section, not a field; tune one of its fields, e.g. "
                f"{path}.{example}",
                field,
            )


def _check_scored(training: TrainingSpec, where: str) -> None:
    check_validated_checkpoints(
        training, "metric 'validation'", "tune.metric", where, interval_field="tune.metric"
    )


def check_tune(spec: ExperimentSpec) -> None:
    """Raise the spec error of the first key or value of ``spec.tune`` that makes an invalid
    spec (or a spec that cannot be scored); see :mod:`softtrack.spec.tune_models`."""
    tune = spec.tune
    assert tune is not None
    _check_tune_paths(tune)
    base = spec.model_dump(mode="json", exclude={"tune"})
    _check_scored(spec.training, "")
    candidates = {path: param.check_values() for path, param in tune.params.items()}
    # each value alone (with the other fields at the spec's own values), then the combinations
    points = [{path: v} for path, values in candidates.items() for v in values]
    if len(candidates) > 1 and math.prod(len(v) for v in candidates.values()) <= MAX_COMBINATIONS:
        points += [
            dict(zip(candidates, combo, strict=True))
            for combo in itertools.product(*candidates.values())
        ]
    for point in points:
        try:
            trial = ExperimentSpec.model_validate(trial_data(base, point))
        except ValidationError as exc:
            inner = _convert(exc, ExperimentSpec, "", {}, {})
            shown = (
                ", ".join(f"{p} {json.dumps(v)}" for p, v in point.items())
                if len(point) > 1
                else f"{json.dumps(next(iter(point.values())))}"
            )
            subject = (
                f"the combination {shown}"
                if len(point) > 1
                else f"{next(iter(point))}: value {shown}"
            )
            raise custom_error(
                f"{subject} makes an invalid spec ({inner.field}: {inner.problem}); narrow "
                "the range or drop the choice",
                "tune.params",
            ) from None
        where = " when the trial sets " + ", ".join(
            f"{p} {json.dumps(v)}" for p, v in point.items()
        )
        _check_scored(trial.training, where)
