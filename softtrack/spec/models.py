"""The spec's top-level model :class:`ExperimentSpec` with its training and cluster sections.

The environment and algorithm sections live in :mod:`softtrack.spec.env_models` and
:mod:`softtrack.spec.algo_models`, the shared field types and :class:`SpecError` in
:mod:`softtrack.spec.fields`; :mod:`softtrack.spec` exports them all."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from softtrack.env.targets import EVAL_TRAJECTORIES, TrajectoryName
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
from softtrack.spec.tune_models import TuneSpec, check_tune

__all__ = ["ClusterSpec", "ExperimentSpec", "TrainingSpec"]

_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"


# ------------------------------------------------------------------------------------------
# training
# ------------------------------------------------------------------------------------------
class TrainingSpec(SpecModel):
    """Budget, parallelism, checkpointing and logging of each training run."""

    total_timesteps: Int = unit_field(
        10_000_000,
        "training budget, summed over all parallel envs (rl-zoo: n_timesteps); per arm for "
        "controller: independent",
        "env steps",
        gt=0,
    )
    n_envs: Int = unit_field(1, "parallel environments", "-", ge=1)
    checkpoint_interval: Int = unit_field(
        100_000,
        "save a checkpoint (model + replay buffer + normalisation state) this often; 0 = only "
        "the final model",
        "env steps",
        ge=0,
    )
    tensorboard: bool = unit_field(
        False,
        "also log training to TensorBoard in <run>/tb/ (SB3's scalars: episode return and "
        "length, losses, fps; view with `tensorboard --logdir runs`); needs the tensorboard "
        "package (pip install 'softtrack[tensorboard]'); does not change the spec hash",
        "-",
    )
    keep_checkpoints: Int = unit_field(
        2,
        "most recent checkpoints kept on disk (a 2e6-transition replay buffer is ~1.5 GB)",
        "checkpoints",
        ge=1,
    )
    save_replay_buffer: bool = unit_field(
        True, "include the replay buffer in checkpoints (off-policy)", "-"
    )
    log_interval: Int = unit_field(
        10_000, "progress line (steps/s, recent returns) this often", "env steps", ge=1
    )
    heartbeat_interval: Float = unit_field(
        30.0, "update run.json's heartbeat and step count this often", "s", gt=0
    )
    torch_threads: Int = unit_field(
        1, "torch.set_num_threads per training process", "threads", ge=1
    )
    eval_trajectories: list[TrajectoryName] = unit_field(
        list(EVAL_TRAJECTORIES),
        "target trajectories of the deterministic evaluation after training (one episode each)",
        "-",
    )
    eval_duration: Float = unit_field(10.0, "length of each evaluation episode", "s", gt=0)
    validation_episodes: Int = unit_field(
        0,
        "held-out random-target episodes (eval_duration each) run on each periodic "
        "checkpoint's model; their metrics go to tables/validation.parquet and the model with "
        "the lowest mean 3-D RMSE so far to best/; 0 = no validation",
        "episodes",
        ge=0,
    )
    validation_trajectories: bool = unit_field(
        False,
        "also run each eval_trajectories episode on every validated checkpoint's model "
        "(rows of tables/validation.parquet with that trajectory): the accuracy on the "
        "evaluation trajectories against env steps and training time; these rows never enter "
        "the validation score, which selects models on held-out random targets only",
        "-",
    )
    final_policy: Literal["last", "best_validated"] = unit_field(
        "last",
        "the run's policy for evaluation, reports and export: 'last' the model at the end of "
        "training, 'best_validated' the checkpoint model with the lowest validation 3-D RMSE "
        "(needs validation_episodes ≥ 1)",
        "-",
    )
    confirm_episodes: Int = unit_field(
        0,
        "with final_policy best_validated: after training, the best-validated and the last "
        "model of each policy each run this many more held-out random-target episodes, and the "
        "one with the lower mean 3-D RMSE becomes the policy (tables/confirmation.parquet); "
        "0 = no confirmation, the best-validated model is the policy",
        "episodes",
        ge=0,
    )
    goal_warmup_steps: Int = unit_field(
        0,
        "curriculum, transport task: the goal's motion away from the sphere's start (the "
        "approach and the path) grows linearly from none to full over the first this many env "
        "steps of training, so the first episodes only hold the sphere where it starts; "
        "validation and evaluation always see the full motion; 0 = full motion from the start",
        "env steps",
        ge=0,
    )
    randomisation_warmup_steps: Int = unit_field(
        0,
        "curriculum: env.realism's random perturbations (per-episode ranges of the model "
        "error and the action delay, observation noise, stuck and dropped values) grow "
        "linearly from none to their full size over the first this many env steps of "
        "training; fixed settings apply throughout, evaluation always sees the full size; "
        "0 = full size from the start",
        "env steps",
        ge=0,
    )
    final_stage_fraction: Float = unit_field(
        0.1,
        "the final-stage return averages episodes in this last fraction of total_timesteps "
        "(independent: of each arm's budget, then over the arms)",
        "-",
        gt=0,
        le=1,
    )

    @field_validator("eval_trajectories")
    @classmethod
    def _unique_trajectories(cls, value: list[str]) -> list[str]:
        if len(set(value)) != len(value):
            raise custom_error(f"duplicate trajectories in {value}; list each at most once")
        return value


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


def check_validated_checkpoints(
    t: TrainingSpec,
    needed_by: str,
    field: str,
    where: str = "",
    or_else: str = "",
    interval_field: str = "training.checkpoint_interval",
) -> None:
    """Raise the spec error of the first setting that leaves ``t`` no validated checkpoint.

    Args:
        t: the training section.
        needed_by: what needs the validation, e.g. ``"final_policy 'best_validated'"``.
        field: the field the missing-episodes error names.
        interval_field: the field the checkpoint-interval error names.
        where: appended to the problem, e.g. ``" when the trial sets ..."``.
        or_else: the alternative fix, e.g. ``" or final_policy: last"``.
    """
    if t.validation_episodes < 1:
        raise custom_error(
            f"{needed_by} picks or scores checkpoints by their validation episodes, but "
            f"training.validation_episodes is 0{where}; set training.validation_episodes to at "
            f"least 1 (e.g. 10){or_else}",
            field,
        )
    if not 0 < t.checkpoint_interval <= t.total_timesteps:
        raise custom_error(
            f"{needed_by} validates each periodic checkpoint, but checkpoint_interval "
            f"{t.checkpoint_interval} gives none within total_timesteps {t.total_timesteps}"
            f"{where}; set training.checkpoint_interval between 1 and total_timesteps",
            interval_field,
        )


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
        if a.n_step_returns > 1 and a.critic != "joint":
            raise custom_error(
                f"n_step_returns {a.n_step_returns} needs SB3's n-step replay buffer, which "
                "critic: per_arm replaces with its own; set algo.critic: joint or "
                "n_step_returns: 1",
                "algo.n_step_returns",
            )
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
        if t.validation_trajectories:
            check_validated_checkpoints(
                t,
                "validation_trajectories",
                "training.validation_trajectories",
                or_else=" or validation_trajectories: false",
            )
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
