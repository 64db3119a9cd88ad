"""The spec's Pydantic models (every field with its default, description and unit) and
:class:`SpecError`. See :mod:`softtrack.spec`."""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from softtrack.sim.params import STANDARD_GRAVITY, InvalidParameterError, SimParams

OFF_POLICY_ALGOS = frozenset({"td3", "ddpg", "sac"})
_ERROR_TYPE = "softtrack"  # type of the PydanticCustomErrors raised by our own validators


# ------------------------------------------------------------------------------------------
# The error type
# ------------------------------------------------------------------------------------------
class SpecError(Exception):
    """A user error in a spec file or a ``--set`` override.

    ``str(error)`` is one line: ``<file>[:<line>]: <field.path>: <problem>; <fix>`` (the field
    path is left out for errors about the file as a whole).

    Attributes:
        file: the spec file (or ``--set path=value`` for an override), as given.
        field: dotted field path such as ``env.physics.dt``; ``""`` for file-level errors.
        problem: what is wrong.
        fix: how to fix it (may be ``""``).
        line: 1-based line in ``file``, when known.
    """

    def __init__(
        self,
        file: str | Path,
        problem: str,
        fix: str = "",
        *,
        field: str = "",
        line: int | None = None,
    ) -> None:
        self.file = str(file)
        self.field = field
        self.problem = _one_line(problem)
        self.fix = _one_line(fix)
        self.line = line
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line else self.file
        head = f"{where}: {self.field}: " if self.field else f"{where}: "
        return head + self.problem + (f"; {self.fix}" if self.fix else "")


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _custom_error(message: str, field: str = "") -> PydanticCustomError:
    """A validation error with our own ``problem; fix`` text; ``field`` is appended to its path."""
    return PydanticCustomError(_ERROR_TYPE, "{message}", {"message": message, "field": field})


# ------------------------------------------------------------------------------------------
# Reusable field types
# ------------------------------------------------------------------------------------------
def _reject_bool(value: Any) -> Any:
    if isinstance(value, bool):
        raise _custom_error(f"expected a number, got {str(value).lower()}; write a number instead")
    return value


def _fixed_length(n: int, example: str) -> BeforeValidator:
    def check(value: Any) -> Any:
        if isinstance(value, (list, tuple)) and len(value) != n:
            raise _custom_error(f"expected {n} values, got {len(value)}; write it as {example}")
        return value

    return BeforeValidator(check)


Int = Annotated[int, BeforeValidator(_reject_bool)]
Float = Annotated[float, BeforeValidator(_reject_bool)]
Vec3 = Annotated[tuple[Float, Float, Float], _fixed_length(3, "[x, y, z]")]
Pair = Annotated[tuple[Float, Float], _fixed_length(2, "[first, second]")]

_NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"


def _f(default: Any, text: str, unit: str, **constraints: Any) -> Any:
    """A field whose description ends with its unit in brackets."""
    return Field(default, description=f"{text} [{unit}]", **constraints)


def _section(cls: type[BaseModel], text: str) -> Any:
    return Field(default_factory=cls, description=text)


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_default=False)


# ------------------------------------------------------------------------------------------
# env
# ------------------------------------------------------------------------------------------
class PhysicsSpec(_Spec):
    """Physical and numerical parameters of the two Cosserat rods (SPEC §1–2).

    Field names equal those of :class:`softtrack.sim.params.SimParams`; the whole section is
    checked by ``SimParams.validate()``, which enforces the explicit stability limit on ``dt``.
    """

    n_elem: Int = _f(20, "elements per arm (nodes = n_elem + 1)", "-", ge=2)
    length: Float = _f(1.0, "rest length of each arm", "m", gt=0)
    radius: Float = _f(0.05, "cross-section radius, uniform along the arm", "m", gt=0)
    density: Float = _f(1000.0, "mass density rho", "kg/m³", gt=0)
    youngs_modulus: Float = _f(1.0e7, "Young's modulus E", "Pa", gt=0)
    poisson_ratio: Float = _f(
        0.5, "Poisson ratio nu; shear modulus G = E / (2 (1 + nu))", "-", gt=-1, le=0.5
    )
    shear_correction: Float = _f(
        27.0 / 28.0, "shear correction factor alpha_c in the shear stiffness alpha_c·G·A", "-", gt=0
    )
    damping: Float = _f(
        30.0,
        "PyElastica-0.1 dissipation coefficient nu_d (explicit internal damping)",
        "N·s/m²",
        ge=0,
    )
    dt: Float = _f(
        2.0e-4,
        "integration time step (Position Verlet); must not exceed the explicit stability "
        "limit computed from n_elem, the material and the damping (about 2.32e-4 s at the "
        "defaults)",
        "s",
        gt=0,
    )
    steps_per_action: Int = _f(
        10, "integration steps per control step (one action is held this long)", "-", ge=1
    )
    gravity: Float = _f(
        0.0,
        f"gravitational acceleration along -y; 0 = off, true = {STANDARD_GRAVITY}",
        "m/s²",
    )
    torque_scale: Float = _f(75.0, "element torque at a control value of 1 (no clipping)", "N·m")
    base_positions: tuple[Vec3, Vec3] = _f(
        ((-0.1, 0.0, 0.0), (0.1, 0.0, 0.0)), "clamp position (x, y, z) of arm 1 and arm 2", "m"
    )

    @field_validator("gravity", mode="before")
    @classmethod
    def _gravity_switch(cls, value: Any) -> Any:
        if isinstance(value, bool):
            return STANDARD_GRAVITY if value else 0.0
        return value

    @field_validator("base_positions", mode="before")
    @classmethod
    def _two_arms(cls, value: Any) -> Any:
        if isinstance(value, (list, tuple)) and len(value) != 2:
            raise _custom_error(
                f"expected 2 base positions (one per arm), got {len(value)}; "
                "write it as [[x1, y1, z1], [x2, y2, z2]]"
            )
        return value

    @model_validator(mode="after")
    def _check_sim_params(self) -> PhysicsSpec:
        try:
            self.sim_params()
        except InvalidParameterError as exc:
            message = str(exc)
            match = re.match(r"^(\w+)=", message)
            field = match.group(1) if match and match.group(1) in type(self).model_fields else ""
            if ";" not in message:
                message += "; change the value"
            raise _custom_error(message, field) from None
        return self

    def sim_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :class:`SimParams` (tuples, SI units)."""
        return self.model_dump()

    def sim_params(self) -> SimParams:
        """The validated :class:`SimParams` (direction/normal keep their defaults)."""
        params = SimParams(**self.sim_kwargs())
        params.validate()
        return params


class TargetSpec(_Spec):
    """The kinematic target sphere (SPEC §3, "Target"). ``name`` is the training target;
    evaluation uses the trajectories listed in ``training.eval_trajectories`` with these
    geometry parameters."""

    name: Literal["random", "circle", "rectangle", "figure8", "fixed"] = _f(
        "random", "target motion: random (training), circle, rectangle, figure8 or fixed", "-"
    )
    sphere_radius: Float = _f(0.05, "radius of the target sphere", "m", gt=0)
    speed: Float = _f(
        0.3, "speed of the random target (its maximum when speed_min is set)", "m/s", ge=0
    )
    speed_min: Float | None = _f(
        None,
        "null (the study): the random target always moves at speed. A number: every new "
        "direction comes with a speed drawn uniformly in [speed_min, speed], so that the policy "
        "also sees the slower speeds of the evaluation trajectories (0.13-0.27 m/s)",
        "m/s",
        ge=0,
    )
    redirect_interval: Float = _f(
        1.0, "time between new random directions (uniform on the unit sphere)", "s", gt=0
    )
    box_low: Vec3 = _f(
        (-0.6, 0.3, -0.6), "lower corner (x, y, z) of the box the random target stays in", "m"
    )
    box_high: Vec3 = _f(
        (0.6, 0.9, 0.6), "upper corner (x, y, z) of the box the random target stays in", "m"
    )
    center: Vec3 = _f(
        (0.0, 0.6, 0.0), "centre (x, y, z) of the circle, rectangle and figure-eight", "m"
    )
    circle_radius: Float = _f(0.3, "radius of the circle in the x-z plane", "m", gt=0)
    rectangle_size: Pair = _f((0.6, 0.4), "rectangle side lengths along x and along z", "m")
    figure8_amplitude: Pair = _f(
        (0.3, 0.15), "figure-eight amplitudes: x = a_x sin(wt), z = a_z sin(2wt)", "m"
    )
    period: Float = _f(
        10.0, "duration of one lap of the circle, rectangle and figure-eight", "s", gt=0
    )
    fixed_position: Vec3 = _f((0.3, 0.6, 0.0), "position (x, y, z) of the fixed target", "m")

    @field_validator("rectangle_size")
    @classmethod
    def _positive_sides(cls, value: tuple[float, float]) -> tuple[float, float]:
        if min(value) <= 0:
            raise _custom_error(f"sides must be > 0, got {list(value)}; use e.g. [0.6, 0.4]")
        return value

    @model_validator(mode="after")
    def _check_speeds_and_box(self) -> TargetSpec:
        if self.speed_min is not None and self.speed_min > self.speed:
            raise _custom_error(
                f"speed_min={self.speed_min:g} m/s exceeds speed={self.speed:g} m/s; speed is the "
                "largest speed drawn, so make speed_min <= speed (or leave it null)",
                "speed_min",
            )
        for axis, lo, hi in zip("xyz", self.box_low, self.box_high):
            if hi - lo <= 2 * self.sphere_radius:
                raise _custom_error(
                    f"box is too small along {axis} ({lo:g} to {hi:g} m) for a sphere of radius "
                    f"{self.sphere_radius:g} m; make box_high exceed box_low by more than "
                    f"2·sphere_radius on every axis",
                    "box_high",
                )
        return self


class RewardSpec(_Spec):
    """Reward shaping (SPEC §3, "Reward"): r = -(w1 d1² + w2 d2²) + per-arm bonuses
    + cooperative bonus; optional inter-arm collision penalty."""

    arm_weights: Pair = _f((1.0, 1.0), "weights w1, w2 of the squared tip distances", "1/m²")
    bonus_thresholds: tuple[Float, ...] = _f(
        (0.10, 0.075),
        "per-arm bonus distance thresholds; bonus_values[k] is paid when d_i ≤ bonus_thresholds[k]",
        "m",
        min_length=1,
    )
    bonus_values: tuple[Float, ...] = _f(
        (0.5, 1.0), "per-arm bonuses, one per threshold", "reward units", min_length=1
    )
    cooperative_threshold: Float = _f(
        0.05, "both tips within this distance earns the cooperative bonus", "m", gt=0
    )
    cooperative_bonus: Float = _f(1.5, "cooperative bonus", "reward units")
    nonfinite_reward: Float = _f(
        -1000.0,
        "reward of the step on which the state becomes NaN/inf (episode terminates)",
        "reward units",
    )
    collision_penalty: Float = _f(
        0.0,
        "penalty c_col when the arms come closer than r1 + r2 + margin; 0 = off",
        "reward units",
        ge=0,
    )
    collision_margin: Float = _f(
        0.0, "extra clearance added to the sum of the radii in the collision test", "m", ge=0
    )

    @model_validator(mode="after")
    def _check_bonuses(self) -> RewardSpec:
        if len(self.bonus_values) != len(self.bonus_thresholds):
            raise _custom_error(
                f"{len(self.bonus_values)} bonus values for {len(self.bonus_thresholds)} "
                "thresholds; give one value per threshold",
                "bonus_values",
            )
        if any(t <= 0 for t in self.bonus_thresholds):
            raise _custom_error(
                "thresholds must be > 0; use e.g. [0.10, 0.075]", "bonus_thresholds"
            )
        return self


class EnvSpec(_Spec):
    """The dual-arm tracking environment: physics, target, reward and episode length."""

    physics: PhysicsSpec = _section(PhysicsSpec, "rods, actuation scale and integrator (SPEC §1–2)")
    target: TargetSpec = _section(TargetSpec, "the moving target (SPEC §3)")
    reward: RewardSpec = _section(RewardSpec, "reward terms (SPEC §3)")
    episode_duration: Float = _f(
        10.0, "simulated length of a training episode (then truncated)", "s", gt=0
    )

    @model_validator(mode="after")
    def _check_duration(self) -> EnvSpec:
        control_dt = self.physics.dt * self.physics.steps_per_action
        if self.episode_duration < control_dt:
            raise _custom_error(
                f"episode_duration {self.episode_duration:g} s is shorter than one control step "
                f"({control_dt:g} s); use at least {control_dt:g}",
                "episode_duration",
            )
        return self

    @property
    def control_dt(self) -> float:
        """Duration of one control step, s."""
        return self.physics.dt * self.physics.steps_per_action

    @property
    def max_episode_steps(self) -> int:
        """Control steps per training episode (episode_duration / control_dt, rounded)."""
        return max(1, round(self.episode_duration / self.control_dt))

    def sim_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :class:`softtrack.sim.params.SimParams`."""
        return self.physics.sim_kwargs()

    def sim_params(self) -> SimParams:
        """The validated :class:`SimParams`."""
        return self.physics.sim_params()

    def target_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of the env's ``TargetConfig`` (tuples, SI units)."""
        return self.target.model_dump()

    def reward_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of the env's ``RewardConfig``."""
        return self.reward.model_dump()


# ------------------------------------------------------------------------------------------
# algo
# ------------------------------------------------------------------------------------------
NetArch = (
    list[Annotated[int, Field(ge=1)]]
    | dict[Literal["pi", "vf", "qf"], list[Annotated[int, Field(ge=1)]]]
)
_ACTIVATIONS = {
    # spec name: (torch.nn class name, jax.nn function name)
    "relu": ("ReLU", "relu"),
    "tanh": ("Tanh", "tanh"),
    "elu": ("ELU", "elu"),
    "leaky_relu": ("LeakyReLU", "leaky_relu"),
    "gelu": ("GELU", "gelu"),
    "silu": ("SiLU", "silu"),
}


class PolicyKwargsSpec(_Spec):
    """``policy_kwargs`` of the SB3 policy, as data (rl-zoo writes them as Python; we do not eval)."""

    net_arch: NetArch = _f(
        [64, 64],
        "hidden layer sizes of actor and critic(s); a list for all networks, or a mapping "
        "{pi: [...], qf: [...]} (off-policy) / {pi: [...], vf: [...]} (PPO)",
        "units per layer",
    )
    activation_fn: Literal["relu", "tanh", "elu", "leaky_relu", "gelu", "silu"] = _f(
        "relu", "activation of the hidden layers", "-"
    )


class AlgoSpec(_Spec):
    """The RL algorithm and its hyperparameters, with rl-baselines3-zoo key names.

    Defaults are the study's TD3 settings (SPEC §4); the PPO-only keys default to SB3's values.
    Keys an algorithm does not use are ignored for it (see :meth:`sb3_kwargs`).
    """

    name: Literal["td3", "ddpg", "ppo", "sac"] = _f("td3", "algorithm", "-")
    backend: Literal["sb3", "sbx"] = _f(
        "sb3", "implementation: sb3 = Stable-Baselines3 (PyTorch), sbx = SBX (JAX)", "-"
    )
    policy: Literal["MlpPolicy"] = _f("MlpPolicy", "policy class", "-")
    policy_kwargs: PolicyKwargsSpec = _section(PolicyKwargsSpec, "network architecture")
    learning_rate: Float = _f(3.0e-4, "Adam learning rate (constant)", "-", gt=0)
    batch_size: Int = _f(
        128,
        "minibatch size (off-policy: per gradient step; PPO: per minibatch)",
        "transitions",
        ge=1,
    )
    gamma: Float = _f(0.99, "discount factor", "-", gt=0, le=1)
    # off-policy (td3, ddpg, sac)
    buffer_size: Int = _f(2_000_000, "replay buffer capacity (td3, ddpg, sac)", "transitions", ge=1)
    learning_starts: Int = _f(
        50_000, "random-action warm-up before learning starts (td3, ddpg, sac)", "env steps", ge=0
    )
    train_freq: Int = _f(
        1,
        "update the model every train_freq vectorised env steps (td3, ddpg, sac)",
        "vectorised env steps",
        ge=1,
    )
    gradient_steps: Int = _f(
        1,
        "gradient steps per update; -1 = as many as transitions collected (td3, ddpg, sac)",
        "gradient steps",
        ge=-1,
    )
    tau: Float = _f(0.005, "soft target-update coefficient (td3, ddpg, sac)", "-", gt=0, le=1)
    policy_delay: Int = _f(2, "critic updates per actor update (td3)", "gradient steps", ge=1)
    target_policy_noise: Float = _f(
        0.2, "std of the target policy smoothing noise (td3)", "action units", ge=0
    )
    target_noise_clip: Float = _f(
        0.5, "clip of the target policy smoothing noise (td3)", "action units", ge=0
    )
    noise_type: Literal["normal", "ornstein-uhlenbeck"] | None = _f(
        "normal", "exploration noise added to actions (td3, ddpg, sac); null = none", "-"
    )
    noise_std: Float = _f(
        0.1, "std of the exploration noise (td3, ddpg, sac)", "action units", ge=0
    )
    # on-policy (ppo)
    n_steps: Int = _f(
        2048, "rollout length per env between updates (ppo)", "env steps per env", ge=1
    )
    n_epochs: Int = _f(10, "optimisation epochs per rollout (ppo)", "-", ge=1)
    gae_lambda: Float = _f(0.95, "GAE lambda (ppo)", "-", ge=0, le=1)
    clip_range: Float = _f(0.2, "policy ratio clip (ppo)", "-", gt=0)
    vf_coef: Float = _f(0.5, "value loss coefficient (ppo)", "-", ge=0)
    max_grad_norm: Float = _f(0.5, "gradient norm clip (ppo)", "-", gt=0)
    ent_coef: Float | str | None = _f(
        None,
        "entropy coefficient; null = the algorithm's default (ppo 0.0, sac 'auto'); "
        "sac also accepts 'auto' or 'auto_<initial value>'",
        "-",
    )
    normalize: bool = _f(
        False,
        "normalise observations with a running mean/std (VecNormalize); its statistics are "
        "saved with the model and every checkpoint. Caution: a feature that is constant in "
        "training (the random target's speed, 0.3 m/s) is divided by sqrt(1e-8) and saturates "
        "at ±10 on the evaluation trajectories, whose speeds differ",
        "-",
    )
    normalize_reward: bool = _f(False, "also normalise rewards (VecNormalize)", "-")
    device: Literal["auto", "cpu", "cuda"] = _f(
        "auto", "torch device; small [64, 64] networks are often fastest on cpu", "-"
    )

    @field_validator("ent_coef", mode="before")
    @classmethod
    def _check_ent_coef(cls, value: Any) -> Any:
        if isinstance(value, bool):
            raise _custom_error("expected a number, 'auto' or null; write e.g. 0.0 or auto")
        if isinstance(value, str) and not re.fullmatch(
            r"auto(_\d+(\.\d*)?([eE][-+]?\d+)?)?", value
        ):
            raise _custom_error(
                f"invalid value {value!r}; use a number, 'auto' or 'auto_<initial value>'"
            )
        return value

    @property
    def is_off_policy(self) -> bool:
        return self.name in OFF_POLICY_ALGOS

    def sb3_kwargs(self, *, resolve_activation: bool = True) -> dict[str, Any]:
        """Constructor keyword arguments of the chosen algorithm class (SB3 or SBX).

        Only keys that algorithm accepts are included. Left out on purpose: ``env`` and
        ``seed`` (per run), ``action_noise`` (the factory builds it from ``noise_type`` and
        ``noise_std``, which needs the action shape) and ``normalize`` (a VecNormalize wrapper).

        Args:
            resolve_activation: replace ``policy_kwargs.activation_fn`` by the backend's
                callable (``torch.nn.ReLU`` for sb3, ``jax.nn.relu`` for sbx; imported lazily).
                With ``False`` it stays the spec's string, e.g. ``"relu"``.
        """
        common = ["policy", "learning_rate", "batch_size", "gamma"]
        if self.is_off_policy:
            keys = common + [
                "buffer_size",
                "learning_starts",
                "train_freq",
                "gradient_steps",
                "tau",
            ]
            if self.name == "td3":
                keys += ["policy_delay", "target_policy_noise", "target_noise_clip"]
            if self.name == "sac" and self.ent_coef is not None:
                keys.append("ent_coef")
        else:  # ppo
            keys = common + [
                "n_steps",
                "n_epochs",
                "gae_lambda",
                "clip_range",
                "vf_coef",
                "max_grad_norm",
            ]
            if self.ent_coef is not None:
                keys.append("ent_coef")
        kwargs: dict[str, Any] = {key: getattr(self, key) for key in keys}
        if self.backend == "sb3":
            kwargs["device"] = self.device
        policy_kwargs: dict[str, Any] = copy.deepcopy(self.policy_kwargs.model_dump())
        if resolve_activation:
            torch_name, jax_name = _ACTIVATIONS[self.policy_kwargs.activation_fn]
            if self.backend == "sb3":
                import torch.nn  # lazy: importing torch costs seconds

                policy_kwargs["activation_fn"] = getattr(torch.nn, torch_name)
            else:
                import jax.nn

                policy_kwargs["activation_fn"] = getattr(jax.nn, jax_name)
        kwargs["policy_kwargs"] = policy_kwargs
        return kwargs


# ------------------------------------------------------------------------------------------
# training
# ------------------------------------------------------------------------------------------
class TrainingSpec(_Spec):
    """Budget, parallelism, checkpointing and logging of each training run."""

    total_timesteps: Int = _f(
        10_000_000,
        "training budget, summed over all parallel envs (rl-zoo: n_timesteps); per arm for "
        "controller: independent",
        "env steps",
        gt=0,
    )
    n_envs: Int = _f(1, "parallel environments", "-", ge=1)
    checkpoint_interval: Int = _f(
        100_000,
        "save a checkpoint (model + replay buffer + normalisation state) this often; 0 = only "
        "the final model",
        "env steps",
        ge=0,
    )
    keep_checkpoints: Int = _f(
        2,
        "most recent checkpoints kept on disk (a 2e6-transition replay buffer is ~1.5 GB)",
        "checkpoints",
        ge=1,
    )
    save_replay_buffer: bool = _f(
        True, "include the replay buffer in checkpoints (off-policy)", "-"
    )
    log_interval: Int = _f(
        10_000, "progress line (steps/s, recent returns) this often", "env steps", ge=1
    )
    heartbeat_interval: Float = _f(
        30.0, "update run.json's heartbeat and step count this often", "s", gt=0
    )
    torch_threads: Int = _f(1, "torch.set_num_threads per training process", "threads", ge=1)
    eval_trajectories: list[Literal["circle", "rectangle", "figure8"]] = _f(
        ["circle", "rectangle", "figure8"],
        "target trajectories of the deterministic evaluation after training (one episode each)",
        "-",
    )
    eval_duration: Float = _f(10.0, "length of each evaluation episode", "s", gt=0)
    final_stage_fraction: Float = _f(
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
            raise _custom_error(f"duplicate trajectories in {value}; list each at most once")
        return value


# ------------------------------------------------------------------------------------------
# cluster
# ------------------------------------------------------------------------------------------
class ClusterSpec(_Spec):
    """SLURM resources of each run's job (``softtrack sweep --executor slurm``); options of the
    command override them. Not part of the experiment: excluded from :func:`spec_hash`."""

    partition: str | None = _f(None, "SLURM partition (None: the cluster's default)", "-")
    time_min: Int = _f(
        240,
        "time limit of one job; a run that needs longer is requeued and resumes from its "
        "last checkpoint",
        "min",
        ge=1,
    )
    cpus_per_task: Int = _f(1, "CPU cores per job", "cores", ge=1)
    mem_gb: Float = _f(4.0, "memory per job", "GB", gt=0)
    max_requeues: Int = _f(
        10, "how often a job may be requeued after preemption or time-out", "-", ge=0
    )


# ------------------------------------------------------------------------------------------
# experiment
# ------------------------------------------------------------------------------------------
Seed = Annotated[int, BeforeValidator(_reject_bool), Field(ge=0, lt=2**32)]


class ExperimentSpec(_Spec):
    """One experiment: an environment, an algorithm, a budget and a set of seeds.

    It expands to one training run per seed (see :meth:`with_seed`).
    """

    name: str = Field(
        "experiment",
        description="name of the experiment: letters, digits, '_', '-', '.'; at most 64 "
        "characters (defaults to the spec file's name) [-]",
        pattern=_NAME_PATTERN,
    )
    env: EnvSpec = _section(EnvSpec, "the environment")
    algo: AlgoSpec = _section(
        AlgoSpec, "the RL algorithm and its hyperparameters (rl-zoo key names)"
    )
    training: TrainingSpec = _section(TrainingSpec, "budget, parallelism, checkpoints, logging")
    cluster: ClusterSpec = _section(
        ClusterSpec, "SLURM resources per run for `softtrack sweep --executor slurm`"
    )
    seeds: list[Seed] = Field(
        [0, 1, 2],
        description="random seeds, one training run per seed; an int or a list [-]",
        min_length=1,
    )
    controller: Literal["centralized", "independent"] = _f(
        "centralized",
        "centralized: one policy drives both arms; independent: one single-arm policy per arm "
        "(SPEC §3), trained one after the other (arm 0, then arm 1) in the single-arm "
        "environment of its arm, each with the algo settings and training.total_timesteps env "
        "steps, so an independent run takes twice the env steps of a centralized one",
        "-",
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
            raise _custom_error(f"duplicate seeds in {value}; list each seed once")
        return value

    @model_validator(mode="after")
    def _check_budget(self) -> ExperimentSpec:
        a, t = self.algo, self.training
        if a.is_off_policy:
            if a.learning_starts >= t.total_timesteps:
                raise _custom_error(
                    f"learning_starts {a.learning_starts} ≥ training.total_timesteps "
                    f"{t.total_timesteps}, so the agent would never learn; use a value below "
                    "total_timesteps",
                    "algo.learning_starts",
                )
            if a.batch_size > a.buffer_size:
                raise _custom_error(
                    f"batch_size {a.batch_size} > buffer_size {a.buffer_size}; use a batch "
                    "no larger than the buffer",
                    "algo.batch_size",
                )
        elif a.batch_size > a.n_steps * t.n_envs or a.batch_size < 2:
            raise _custom_error(
                f"batch_size {a.batch_size} must lie in [2, n_steps·n_envs = "
                f"{a.n_steps * t.n_envs}] for ppo; lower batch_size or raise n_steps",
                "algo.batch_size",
            )
        control_dt = self.env.control_dt
        if t.eval_duration < control_dt:
            raise _custom_error(
                f"eval_duration {t.eval_duration:g} s is shorter than one control step "
                f"({control_dt:g} s); use at least {control_dt:g}",
                "training.eval_duration",
            )
        return self

    @property
    def n_runs(self) -> int:
        """Training runs this spec expands to (one per seed)."""
        return len(self.seeds)

    def with_seed(self, seed: int) -> ExperimentSpec:
        """A copy with ``seeds = [seed]``: the fully resolved spec of a single run."""
        return self.model_copy(update={"seeds": [int(seed)]}, deep=True)


