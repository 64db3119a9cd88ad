"""The environment section of a spec: the rods' physics, the target, the reward and the
episode length. See :mod:`softtrack.spec`."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from softtrack.env.realism import RealismConfig
from softtrack.env.reward_config import RewardConfig
from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import TargetConfig, TargetMode
from softtrack.env.tasks import TaskConfig
from softtrack.sim.params import (
    CONTACT_ON,
    MODEL_PARAMETERS,
    STANDARD_GRAVITY,
    SimParams,
    model_error_stability,
)
from softtrack.sim.sphere import SphereParams
from softtrack.spec.fields import (
    Factor,
    Float,
    Int,
    Pair,
    SpecModel,
    Vec3,
    check_with_dataclass,
    custom_error,
    section_field,
    setting_field,
)

# Each setting's default, unit and range are the engine's and the environment's own dataclass
# field's (one definition: tests/test_settings_once.py); the models here add the description.


class SphereSpec(SpecModel):
    """A rigid sphere held by the arms: the transport task's object
    (:class:`softtrack.sim.sphere.SphereParams`, docs/physics.md "A rigid object")."""

    radius: Float = setting_field(SphereParams, "radius", "radius R")
    density: Float = setting_field(SphereParams, "density", "density (mass 4/3·pi·R³·density)")
    center: Vec3 = setting_field(
        SphereParams,
        "center",
        "centre at every reset; the default lies between the straight arms' tips, touching both",
    )
    contact_k: Float = setting_field(
        SphereParams,
        "contact_k",
        "stiffness of the contact with each arm (PyElastica RodSphereContact k)",
    )
    contact_nu: Float = setting_field(
        SphereParams, "contact_nu", "damping of that contact (RodSphereContact nu)"
    )
    velocity_damping: Float = setting_field(
        SphereParams,
        "velocity_damping",
        "friction's slip damping (RodSphereContact velocity_damping_coefficient): below the "
        "Coulomb limit the friction force is this times the slip speed",
    )
    friction: Float = setting_field(
        SphereParams,
        "friction",
        "Coulomb friction coefficient (RodSphereContact friction_coefficient)",
    )


#: The most integration steps one episode may take: 10 s at 1 µs. A smaller ``dt`` is far
#: below any stability limit of the rods (about 2.3e-4 s at the defaults) and only makes the
#: episode's step count meaningless (``dt = 1e-300``: 1e301 steps).
MAX_EPISODE_INTEGRATION_STEPS = 10_000_000


def check_step_count(duration: float, dt: float, steps_per_action: int, field: str = "dt") -> None:
    """Refuse an episode of ``duration`` s that would take more than
    :data:`MAX_EPISODE_INTEGRATION_STEPS` integration steps of ``dt``."""
    if duration / dt > MAX_EPISODE_INTEGRATION_STEPS:
        smallest = duration / MAX_EPISODE_INTEGRATION_STEPS
        raise custom_error(
            f"dt {dt:g} s makes a {duration:g}-s episode {duration / dt:.3g} integration steps "
            f"(at most {MAX_EPISODE_INTEGRATION_STEPS:,}); the rods are stable up to about "
            f"2.3e-4 s: use a dt of at least {smallest:g} s",
            f"physics.{field}" if field == "dt" else field,
        )


class PhysicsSpec(SpecModel):
    """Physical and numerical parameters of the two Cosserat rods (docs/physics.md).

    Field names equal those of :class:`softtrack.sim.params.SimParams`; the whole section is
    checked by ``SimParams.validate()``, which enforces the explicit stability limit on ``dt``.
    """

    n_elem: Int = setting_field(SimParams, "n_elem", "elements per arm (nodes = n_elem + 1)")
    length: Float = setting_field(SimParams, "length", "rest length of each arm")
    radius: Float = setting_field(
        SimParams, "radius", "cross-section radius, uniform along the arm"
    )
    density: Float = setting_field(SimParams, "density", "mass density rho")
    youngs_modulus: Float = setting_field(SimParams, "youngs_modulus", "Young's modulus E")
    poisson_ratio: Float = setting_field(
        SimParams, "poisson_ratio", "Poisson ratio nu; shear modulus G = E / (2 (1 + nu))"
    )
    shear_correction: Float = setting_field(
        SimParams,
        "shear_correction",
        "shear correction factor alpha_c in the shear stiffness alpha_c·G·A",
    )
    damping: Float = setting_field(
        SimParams,
        "damping",
        "PyElastica-0.1 dissipation coefficient nu_d (explicit internal damping)",
    )
    dt: Float = setting_field(
        SimParams,
        "dt",
        "integration time step (Position Verlet); must not exceed the explicit stability "
        "limit computed from n_elem, the material and the damping (about 2.32e-4 s at the "
        "defaults)",
    )
    steps_per_action: Int = setting_field(
        SimParams,
        "steps_per_action",
        "integration steps per control step (one action is held this long)",
    )
    gravity: Float = setting_field(
        SimParams,
        "gravity",
        f"gravitational acceleration along -y; 0 = off, true = {STANDARD_GRAVITY}",
    )
    torque_scale: Float = setting_field(
        SimParams, "torque_scale", "element torque at a control value of 1 (no clipping)"
    )
    base_positions: tuple[Vec3, Vec3] = setting_field(
        SimParams, "base_positions", "clamp position (x, y, z) of arm 1 and arm 2"
    )
    contact_k: Float = setting_field(
        SimParams,
        "contact_k",
        "stiffness of the contact between the two arms (PyElastica RodRodContact k); 0 = off, "
        f"the arms pass through each other (the study); 'contact on': {CONTACT_ON['contact_k']:g}",
    )
    contact_nu: Float = setting_field(
        SimParams,
        "contact_nu",
        "damping of the contact between the arms (RodRodContact nu); needs contact_k > 0; "
        f"'contact on': {CONTACT_ON['contact_nu']:g}",
    )
    sphere: SphereSpec | None = Field(
        None,
        description="a rigid sphere between the arms, the transport task's object; null (the "
        "default) = none; {} = the default 0.05-m, 500-kg/m³ ball between the tips",
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
            raise custom_error(
                f"expected 2 base positions (one per arm), got {len(value)}; "
                "write it as [[x1, y1, z1], [x2, y2, z2]]"
            )
        return value

    @model_validator(mode="after")
    def _check_sim_params(self) -> PhysicsSpec:
        check_with_dataclass(self, self.sim_params)
        return self

    def sim_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :class:`SimParams` (tuples, SI units; ``sphere`` a
        :class:`SphereParams` or None)."""
        kwargs = self.model_dump()
        if kwargs["sphere"] is not None:
            kwargs["sphere"] = SphereParams.from_mapping(kwargs["sphere"])
        return kwargs

    def sim_params(self) -> SimParams:
        """The validated :class:`SimParams` (direction/normal keep their defaults)."""
        params = SimParams(**self.sim_kwargs())
        params.validate()
        return params


class TargetSpec(SpecModel):
    """The kinematic target sphere (docs/environment.md, "Target"). ``name`` is the training target;
    evaluation uses the trajectories listed in ``training.eval_trajectories`` with these
    geometry parameters."""

    name: TargetMode = setting_field(
        TargetConfig,
        "name",
        "target motion: random (training), circle, rectangle, figure8 or fixed",
    )
    sphere_radius: Float = setting_field(
        TargetConfig, "sphere_radius", "radius of the target sphere"
    )
    speed: Float = setting_field(
        TargetConfig, "speed", "speed of the random target (its maximum when speed_min is set)"
    )
    speed_min: Float | None = setting_field(
        TargetConfig,
        "speed_min",
        "null (the study): the random target always moves at speed. A number: every new "
        "direction comes with a speed drawn uniformly in [speed_min, speed], so that the policy "
        "also sees the slower speeds of the evaluation trajectories (0.13-0.27 m/s)",
    )
    redirect_interval: Float = setting_field(
        TargetConfig,
        "redirect_interval",
        "time between new random directions (uniform on the unit sphere)",
    )
    box_low: Vec3 = setting_field(
        TargetConfig, "box_low", "lower corner (x, y, z) of the box the random target stays in"
    )
    box_high: Vec3 = setting_field(
        TargetConfig, "box_high", "upper corner (x, y, z) of the box the random target stays in"
    )
    center: Vec3 = setting_field(
        TargetConfig, "center", "centre (x, y, z) of the circle, rectangle and figure-eight"
    )
    circle_radius: Float = setting_field(
        TargetConfig, "circle_radius", "radius of the circle in the x-z plane"
    )
    rectangle_size: Pair = setting_field(
        TargetConfig, "rectangle_size", "rectangle side lengths along x and along z"
    )
    figure8_amplitude: Pair = setting_field(
        TargetConfig,
        "figure8_amplitude",
        "figure-eight amplitudes: x = a_x sin(wt), z = a_z sin(2wt)",
    )
    period: Float = setting_field(
        TargetConfig, "period", "duration of one lap of the circle, rectangle and figure-eight"
    )
    fixed_position: Vec3 = setting_field(
        TargetConfig, "fixed_position", "position (x, y, z) of the fixed target"
    )

    @model_validator(mode="after")
    def _check_target(self) -> TargetSpec:
        check_with_dataclass(self, TargetConfig(**self.model_dump()).validate)
        return self


class RewardSpec(SpecModel):
    """Reward shaping (docs/environment.md, "Reward"): r = -(w1 d1² + w2 d2²) + per-arm bonuses
    + cooperative bonus; optional inter-arm collision penalty."""

    arm_weights: Pair = setting_field(
        RewardConfig, "arm_weights", "weights w1, w2 of the squared tip distances"
    )
    bonus_thresholds: tuple[Float, ...] = setting_field(
        RewardConfig,
        "bonus_thresholds",
        "per-arm bonus distance thresholds; bonus_values[k] is paid when d_i ≤ bonus_thresholds[k]",
        min_length=1,
    )
    bonus_values: tuple[Float, ...] = setting_field(
        RewardConfig, "bonus_values", "per-arm bonuses, one per threshold", min_length=1
    )
    cooperative_threshold: Float = setting_field(
        RewardConfig,
        "cooperative_threshold",
        "both tips within this distance earns the cooperative bonus",
    )
    cooperative_bonus: Float = setting_field(RewardConfig, "cooperative_bonus", "cooperative bonus")
    nonfinite_reward: Float = setting_field(
        RewardConfig,
        "nonfinite_reward",
        "reward of the step on which the state becomes NaN/inf (episode terminates)",
    )
    collision_penalty: Float = setting_field(
        RewardConfig,
        "collision_penalty",
        "penalty c_col when the arms come closer than r1 + r2 + margin; 0 = off",
    )
    collision_margin: Float = setting_field(
        RewardConfig,
        "collision_margin",
        "extra clearance added to the sum of the radii in the collision test",
    )
    action_rate_penalty: Float = setting_field(
        RewardConfig,
        "action_rate_penalty",
        "c_rate: subtract c_rate times the mean squared change of the clipped action values "
        "since the previous control step (smooth actuation); 0 = off",
    )
    action_penalty: Float = setting_field(
        RewardConfig,
        "action_penalty",
        "c_act: subtract c_act times the mean squared clipped action value (away from "
        "saturation); 0 = off",
    )

    @model_validator(mode="after")
    def _check_reward(self) -> RewardSpec:
        check_with_dataclass(self, RewardConfig(**self.model_dump()).validate)
        return self


class RealismSpec(SpecModel):
    """Imperfect sensing and actuation (docs/environment.md, "Realism: sensing and actuation"),
    in the spirit of realworldrl_suite. Every default is "off": an env whose section is all
    defaults computes exactly the study's transitions. Field names equal those of
    :class:`softtrack.env.realism.RealismConfig`."""

    obs_noise_node_position: Float = setting_field(
        RealismConfig,
        "obs_noise_node_position",
        "std of Gaussian noise on every observed node coordinate; 0 = off",
    )
    obs_noise_target_position: Float = setting_field(
        RealismConfig,
        "obs_noise_target_position",
        "std of Gaussian noise on each coordinate of the target centre; 0 = off",
    )
    obs_noise_speed: Float = setting_field(
        RealismConfig,
        "obs_noise_speed",
        "std of Gaussian noise on the tip speeds and the target speed; 0 = off",
    )
    obs_noise_direction: Float = setting_field(
        RealismConfig,
        "obs_noise_direction",
        "std of Gaussian noise on each component of the tip and target velocity directions "
        "(unit vectors; not renormalised); 0 = off",
    )
    obs_drop_probability: Float = setting_field(
        RealismConfig,
        "obs_drop_probability",
        "per observed value and control step, probability that it reads 0 (dropped); 0 = off",
    )
    obs_stuck_probability: Float = setting_field(
        RealismConfig,
        "obs_stuck_probability",
        "per observed value and control step, probability that it gets stuck and repeats its "
        "last reading for obs_stuck_steps steps; 0 = off",
    )
    obs_stuck_steps: Int = setting_field(
        RealismConfig,
        "obs_stuck_steps",
        "how long a stuck value repeats its last reading (the step it sticks included)",
    )
    obs_delay: Int = setting_field(
        RealismConfig,
        "obs_delay",
        "the policy sees the observation of this many control steps ago (the initial one "
        "until then); 0 = off",
    )
    action_delay: Int = setting_field(
        RealismConfig,
        "action_delay",
        "the arms apply the action of this many control steps ago (zeros until then); 0 = off",
    )
    action_delay_max: Int | None = setting_field(
        RealismConfig,
        "action_delay_max",
        "null, or the largest action delay: each episode's delay is then drawn uniformly from "
        "the whole numbers action_delay ... action_delay_max (domain randomisation)",
    )
    actuator_time_constant: Float | None = setting_field(
        RealismConfig,
        "actuator_time_constant",
        "time constant tau of a first-order lag on every control value (0 at reset, exact "
        "discretisation alpha = 1 - exp(-control_dt / tau)); null = off",
    )
    action_rate_limit: Float | None = setting_field(
        RealismConfig,
        "action_rate_limit",
        "largest change of an applied control value per second (from 0 at reset); null = off",
    )
    torque_limit: Float | None = setting_field(
        RealismConfig,
        "torque_limit",
        "each element torque is clipped to +-this after the spline; null = off",
    )
    # model error: a fixed factor, or a [low, high] range drawn uniformly per episode and env
    youngs_modulus_scale: Factor = setting_field(
        RealismConfig,
        "youngs_modulus_scale",
        "model error: factor on env.physics.youngs_modulus (stiffness), or a [low, high] range "
        "drawn uniformly per episode and environment; 1 = off",
    )
    density_scale: Factor = setting_field(
        RealismConfig,
        "density_scale",
        "model error: factor on env.physics.density (masses, inertias), or a [low, high] range "
        "drawn per episode; 1 = off",
    )
    radius_scale: Factor = setting_field(
        RealismConfig,
        "radius_scale",
        "model error: factor on env.physics.radius (area, second moments, masses and "
        "stiffnesses follow), or a [low, high] range drawn per episode; 1 = off",
    )
    damping_scale: Factor = setting_field(
        RealismConfig,
        "damping_scale",
        "model error: factor on env.physics.damping, or a [low, high] range drawn per "
        "episode; 1 = off",
    )
    torque_scale_factor: Factor = setting_field(
        RealismConfig,
        "torque_scale_factor",
        "model error: factor on env.physics.torque_scale (actuator gain), or a [low, high] "
        "range drawn per episode; 1 = off",
    )

    @model_validator(mode="after")
    def _check_realism(self) -> RealismSpec:
        check_with_dataclass(self, RealismConfig(**self.realism_kwargs()).validate)
        return self

    def realism_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :class:`softtrack.env.realism.RealismConfig`."""
        return self.model_dump()

    def model_error_ranges(self) -> dict[str, tuple[float, float]]:
        """Each model-error factor that is not 1 → (low, high) ((f, f) when fixed)."""
        out = {}
        for name in MODEL_PARAMETERS:
            value = getattr(self, name)
            pair = tuple(value) if isinstance(value, tuple) else (value, value)
            if pair != (1.0, 1.0):
                out[name] = (float(pair[0]), float(pair[1]))
        return out

    @property
    def active(self) -> bool:
        """True when any field differs from its default ("off")."""
        return self != RealismSpec()

    @property
    def random_perturbations(self) -> bool:
        """True when something is drawn at random: a [low, high] model-error range, an action
        delay range, observation noise, stuck or dropped values."""
        return (
            any(low != high for low, high in self.model_error_ranges().values())
            or (self.action_delay_max or 0) > self.action_delay
            or any(
                getattr(self, name) > 0
                for name in type(self).model_fields
                if name.startswith("obs_noise_") or name.endswith("_probability")
            )
        )


class TaskSpec(SpecModel):
    """What the arms do (:mod:`softtrack.env.tasks`, docs/environment.md): track the shared
    target, track two viewpoints beside it, or carry a sphere along its path."""

    name: Literal["shared", "viewpoints", "transport"] = setting_field(
        TaskConfig,
        "name",
        "shared: both tips track the target centre (the study); viewpoints: each tip tracks "
        "its own point at the standoff from the centre along x (arm 1 at -x, arm 2 at +x); "
        "transport: the arms carry env.physics.sphere and its centre tracks the target",
    )
    standoff: Float = setting_field(
        TaskConfig,
        "standoff",
        "viewpoints: distance of each arm's point from the target centre along x",
    )
    approach: Float = setting_field(
        TaskConfig,
        "approach",
        "transport: the goal moves from the sphere's start to the path's start in this time "
        "(a smoothstep), then follows the path",
    )
    drop_grace: Float = setting_field(
        TaskConfig,
        "drop_grace",
        "transport: the sphere counts as dropped (the episode ends) after this long without "
        "contact with either arm",
    )
    hold_bonus: Float = setting_field(
        TaskConfig, "hold_bonus", "transport: reward per arm touching the sphere"
    )
    squeeze_band: Pair = setting_field(
        TaskConfig,
        "squeeze_band",
        "transport: band [low, high] of each arm's contact force on the sphere; [0, 0] = no "
        "force regulation",
    )
    squeeze_penalty: Float = setting_field(
        TaskConfig,
        "squeeze_penalty",
        "transport: weight c_f of -c_f·(e/high)² per arm, e the force's distance from the band",
    )
    drop_penalty: Float = setting_field(
        TaskConfig, "drop_penalty", "transport: subtracted on the step of a drop"
    )
    reach_penalty: Float = setting_field(
        TaskConfig,
        "reach_penalty",
        "transport: weight c_reach of -c_reach·(g1 + g2), gi the gap between arm i's nearest "
        "node's surface and the sphere's (0 while it touches); leads the arms to the sphere",
    )
    bonus_needs_grip: bool = setting_field(
        TaskConfig,
        "bonus_needs_grip",
        "transport: the distance bonuses count only on steps when both arms touch the sphere",
    )
    grip: Float = setting_field(
        TaskConfig,
        "grip",
        "transport: a constant squeeze added to the normal control values before clipping "
        "(arm 1 -grip, arm 2 +grip), so a zero action holds the sphere; e.g. 0.03",
    )

    @model_validator(mode="after")
    def _check_task(self) -> TaskSpec:
        check_with_dataclass(self, self.task_config().validate)
        return self

    def task_config(self) -> TaskConfig:
        """The environment's :class:`TaskConfig`."""
        return TaskConfig(**self.model_dump())


class EnvSpec(SpecModel):
    """The dual-arm tracking environment: physics, target, reward and episode length."""

    physics: PhysicsSpec = section_field(
        PhysicsSpec, "rods, actuation scale and integrator (docs/physics.md)"
    )
    target: TargetSpec = section_field(TargetSpec, "the moving target (docs/environment.md)")
    reward: RewardSpec = section_field(RewardSpec, "reward terms (docs/environment.md)")
    episode_duration: Float = setting_field(
        TrackingConfig,
        "episode_duration",
        "simulated length of a training episode (then truncated)",
    )
    task: TaskSpec = section_field(
        TaskSpec,
        "what the arms do: track the shared target (the study), two viewpoints, or carry a "
        "sphere (transport)",
    )
    realism: RealismSpec = section_field(
        RealismSpec,
        "imperfect sensing and actuation: observation noise, drops, stuck values and delay; "
        "action delay, actuator lag, rate limit, torque saturation; model error: fixed or "
        "per-episode random factors on Young's modulus, density, radius, damping and torque "
        "scale; all off by default (docs/environment.md)",
    )

    @model_validator(mode="after")
    def _check_object(self) -> EnvSpec:
        carries = self.task.name == "transport"
        if carries and self.physics.sphere is None:
            raise custom_error(
                "task transport needs a sphere to carry: set env.physics.sphere (e.g. {} for "
                "the default 0.05-m ball between the tips)",
                "task",
            )
        if self.physics.sphere is not None and not carries:
            raise custom_error(
                f"env.physics.sphere belongs to the transport task, but env.task.name is "
                f"{self.task.name!r}; set env.task.name: transport or remove the sphere",
                "physics",
            )
        return self

    @model_validator(mode="after")
    def _check_duration(self) -> EnvSpec:
        control_dt = self.physics.dt * self.physics.steps_per_action
        if self.episode_duration < control_dt:
            raise custom_error(
                f"episode_duration {self.episode_duration:g} s is shorter than one control step "
                f"({control_dt:g} s); use at least {control_dt:g}",
                "episode_duration",
            )
        if self.target.period < 2 * control_dt:  # sampled once per step, the path aliases
            raise custom_error(
                f"target period {self.target.period:g} s is shorter than two control steps "
                f"({2 * control_dt:g} s): the sampled path would not go round; use at least "
                f"{2 * control_dt:g}",
                "target",
            )
        check_step_count(self.episode_duration, self.physics.dt, self.physics.steps_per_action)
        ranges = self.realism.model_error_ranges()
        result = model_error_stability(self.sim_params(), ranges) if ranges else None
        if result is not None:
            name, problem, fix = result
            raise custom_error(
                f"{problem.replace('dt = ', 'env.physics.dt = ')}; "
                f"{fix.replace('lower dt', 'lower env.physics.dt')}",
                f"realism.{name}",
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
