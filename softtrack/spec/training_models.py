"""The spec's training section (:class:`TrainingSpec`: budget, parallelism, checkpoints,
validation and logging of each run) and the check that a setting has validated checkpoints
to pick or score, shared by the training section's users (the final policy, trajectory
validation, tuning)."""

from __future__ import annotations

from typing import Literal

from pydantic import field_validator

from softtrack.env.targets import EVAL_TRAJECTORIES, TrajectoryName
from softtrack.spec.fields import (
    Float,
    Int,
    SpecModel,
    custom_error,
    unit_field,
)

__all__ = ["TrainingSpec", "check_validated_checkpoints", "check_validation_needs"]


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
        "the lowest mean 3-D RMSE so far to best/; 0 = none (no validation unless "
        "validation_paths >= 1)",
        "episodes",
        ge=0,
    )
    validation_paths: Int = unit_field(
        0,
        "held-out path episodes (eval_duration each) run on each periodic checkpoint's "
        "model beside the random-target ones (or alone, with validation_episodes 0): per "
        "episode one of the trajectories' shapes, scaled by 0.8-1.2, its centre moved by up "
        "to 0.15 circle radii along each axis, started at a random phase, run either way "
        "round (target mode 'paths'); they enter the validation score with the random-target "
        "episodes, so models are selected on "
        "paths like the evaluation's that are not the evaluation's; 0 = none",
        "episodes",
        ge=0,
    )
    validation_score: Literal["random_and_paths", "paths"] = unit_field(
        "random_and_paths",
        "the episodes a checkpoint's validation score averages (the kept model has the "
        "lowest, stop_score compares it): 'random_and_paths' the random targets and the "
        "held-out paths, 'paths' the held-out paths only (needs validation_paths >= 1)",
        "-",
    )
    stop_score: Float | None = unit_field(
        None,
        "early stopping: training ends at the first validation whose score (the mean 3-D RMSE "
        "over the random-target and held-out path episodes) is at or below this, with the "
        "budget cut short; the run completes there and its policy is chosen as without it "
        "(with final_policy best_validated: the best-validated model so far); total_timesteps "
        "stays the cap; null = train the whole budget",
        "m",
        gt=0,
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

    @property
    def validates(self) -> bool:
        """Whether each periodic checkpoint is validated: some random-target or held-out path
        episodes (``validation_episodes`` + ``validation_paths`` ≥ 1)."""
        return self.validation_episodes + self.validation_paths >= 1

    @field_validator("eval_trajectories")
    @classmethod
    def _unique_trajectories(cls, value: list[str]) -> list[str]:
        if len(set(value)) != len(value):
            raise custom_error(f"duplicate trajectories in {value}; list each at most once")
        return value


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
    if not t.validates:
        raise custom_error(
            f"{needed_by} picks or scores checkpoints by their validation episodes, but "
            f"training.validation_episodes is 0{where}; set training.validation_episodes to at "
            f"least 1 (e.g. 10) or training.validation_paths (e.g. 16){or_else}",
            field,
        )
    if not 0 < t.checkpoint_interval <= t.total_timesteps:
        raise custom_error(
            f"{needed_by} validates each periodic checkpoint, but checkpoint_interval "
            f"{t.checkpoint_interval} gives none within total_timesteps {t.total_timesteps}"
            f"{where}; set training.checkpoint_interval between 1 and total_timesteps",
            interval_field,
        )


def check_validation_needs(t: TrainingSpec) -> None:
    """Raise the spec error of the first setting of ``t`` that adds to, or acts on, each
    checkpoint's validation (held-out paths, trajectories, early stopping) while ``t``
    validates no checkpoint."""
    for needed_by, off in (
        ("validation_paths", "0"),
        ("validation_trajectories", "false"),
        ("stop_score", "null"),
    ):
        if getattr(t, needed_by) not in (0, False, None):
            check_validated_checkpoints(
                t, needed_by, f"training.{needed_by}", or_else=f" or {needed_by}: {off}"
            )
    if t.validation_score == "paths" and t.validation_paths < 1:
        raise custom_error(
            "validation_score 'paths' scores checkpoints on their held-out paths, but "
            "training.validation_paths is 0; set validation_paths to at least 1 (e.g. 16) or "
            "validation_score: random_and_paths",
            "training.validation_score",
        )
