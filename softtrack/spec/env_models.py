"""The environment section of a spec: the rods' physics, the target, the reward and the
episode length. See :mod:`softtrack.spec`."""

from __future__ import annotations

import re
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
    InvalidParameterError,
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
    custom_error,
    section_field,
    unit_field,
)

# The defaults of every setting are the engine's and the environment's own (one definition:
# tests/test_settings_once.py); the models here add the unit, the range and the description.
_SIM = SimParams()
_SPHERE = SphereParams()
_TARGET = TargetConfig()
_REWARD = RewardConfig()
_REALISM = RealismConfig()
_TASK = TaskConfig()


class SphereSpec(SpecModel):
    """A rigid sphere held by the arms: the transport task's object
    (:class:`softtrack.sim.sphere.SphereParams`, docs/physics.md "A rigid object")."""

    radius: Float = unit_field(_SPHERE.radius, "radius R", "m", gt=0)
    density: Float = unit_field(_SPHERE.density, "density (mass 4/3·pi·R³·density)", "kg/m³", gt=0)
    center: Vec3 = unit_field(
        _SPHERE.center,
        "centre at every reset; the default lies between the straight arms' tips, touching both",
        "m",
    )
    contact_k: Float = unit_field(
        _SPHERE.contact_k,
        "stiffness of the contact with each arm (PyElastica RodSphereContact k)",
        "N/m",
        ge=0,
    )
    contact_nu: Float = unit_field(
        _SPHERE.contact_nu, "damping of that contact (RodSphereContact nu)", "N·s/m", ge=0
    )
    velocity_damping: Float = unit_field(
        _SPHERE.velocity_damping,
        "friction's slip damping (RodSphereContact velocity_damping_coefficient): below the "
        "Coulomb limit the friction force is this times the slip speed",
        "N·s/m",
        ge=0,
    )
    friction: Float = unit_field(
        _SPHERE.friction,
        "Coulomb friction coefficient (RodSphereContact friction_coefficient)",
        "-",
        ge=0,
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

    n_elem: Int = unit_field(_SIM.n_elem, "elements per arm (nodes = n_elem + 1)", "-", ge=2)
    length: Float = unit_field(_SIM.length, "rest length of each arm", "m", gt=0)
    radius: Float = unit_field(
        _SIM.radius, "cross-section radius, uniform along the arm", "m", gt=0
    )
    density: Float = unit_field(_SIM.density, "mass density rho", "kg/m³", gt=0)
    youngs_modulus: Float = unit_field(_SIM.youngs_modulus, "Young's modulus E", "Pa", gt=0)
    poisson_ratio: Float = unit_field(
        _SIM.poisson_ratio,
        "Poisson ratio nu; shear modulus G = E / (2 (1 + nu))",
        "-",
        gt=-1,
        le=0.5,
    )
    shear_correction: Float = unit_field(
        _SIM.shear_correction,
        "shear correction factor alpha_c in the shear stiffness alpha_c·G·A",
        "-",
        gt=0,
    )
    damping: Float = unit_field(
        _SIM.damping,
        "PyElastica-0.1 dissipation coefficient nu_d (explicit internal damping)",
        "N·s/m²",
        ge=0,
    )
    dt: Float = unit_field(
        _SIM.dt,
        "integration time step (Position Verlet); must not exceed the explicit stability "
        "limit computed from n_elem, the material and the damping (about 2.32e-4 s at the "
        "defaults)",
        "s",
        gt=0,
    )
    steps_per_action: Int = unit_field(
        _SIM.steps_per_action,
        "integration steps per control step (one action is held this long)",
        "-",
        ge=1,
    )
    gravity: Float = unit_field(
        _SIM.gravity,
        f"gravitational acceleration along -y; 0 = off, true = {STANDARD_GRAVITY}",
        "m/s²",
    )
    torque_scale: Float = unit_field(
        _SIM.torque_scale, "element torque at a control value of 1 (no clipping)", "N·m"
    )
    base_positions: tuple[Vec3, Vec3] = unit_field(
        _SIM.base_positions, "clamp position (x, y, z) of arm 1 and arm 2", "m"
    )
    contact_k: Float = unit_field(
        _SIM.contact_k,
        "stiffness of the contact between the two arms (PyElastica RodRodContact k); 0 = off, "
        f"the arms pass through each other (the study); 'contact on': {CONTACT_ON['contact_k']:g}",
        "N/m",
        ge=0,
    )
    contact_nu: Float = unit_field(
        _SIM.contact_nu,
        "damping of the contact between the arms (RodRodContact nu); needs contact_k > 0; "
        f"'contact on': {CONTACT_ON['contact_nu']:g}",
        "N·s/m",
        ge=0,
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
        try:
            self.sim_params()
        except InvalidParameterError as exc:
            message = str(exc)
            match = re.match(r"^(\w+)=", message)
            field = match.group(1) if match and match.group(1) in type(self).model_fields else ""
            if ";" not in message:
                message += "; change the value"
            raise custom_error(message, field) from None
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

    name: TargetMode = unit_field(
        _TARGET.name, "target motion: random (training), circle, rectangle, figure8 or fixed", "-"
    )
    sphere_radius: Float = unit_field(
        _TARGET.sphere_radius, "radius of the target sphere", "m", gt=0
    )
    speed: Float = unit_field(
        _TARGET.speed, "speed of the random target (its maximum when speed_min is set)", "m/s", ge=0
    )
    speed_min: Float | None = unit_field(
        _TARGET.speed_min,
        "null (the study): the random target always moves at speed. A number: every new "
        "direction comes with a speed drawn uniformly in [speed_min, speed], so that the policy "
        "also sees the slower speeds of the evaluation trajectories (0.13-0.27 m/s)",
        "m/s",
        ge=0,
    )
    redirect_interval: Float = unit_field(
        _TARGET.redirect_interval,
        "time between new random directions (uniform on the unit sphere)",
        "s",
        gt=0,
    )
    box_low: Vec3 = unit_field(
        _TARGET.box_low, "lower corner (x, y, z) of the box the random target stays in", "m"
    )
    box_high: Vec3 = unit_field(
        _TARGET.box_high, "upper corner (x, y, z) of the box the random target stays in", "m"
    )
    center: Vec3 = unit_field(
        _TARGET.center, "centre (x, y, z) of the circle, rectangle and figure-eight", "m"
    )
    circle_radius: Float = unit_field(
        _TARGET.circle_radius, "radius of the circle in the x-z plane", "m", gt=0
    )
    rectangle_size: Pair = unit_field(
        _TARGET.rectangle_size, "rectangle side lengths along x and along z", "m"
    )
    figure8_amplitude: Pair = unit_field(
        _TARGET.figure8_amplitude, "figure-eight amplitudes: x = a_x sin(wt), z = a_z sin(2wt)", "m"
    )
    period: Float = unit_field(
        _TARGET.period, "duration of one lap of the circle, rectangle and figure-eight", "s", gt=0
    )
    fixed_position: Vec3 = unit_field(
        _TARGET.fixed_position, "position (x, y, z) of the fixed target", "m"
    )

    @field_validator("rectangle_size")
    @classmethod
    def _positive_sides(cls, value: tuple[float, float]) -> tuple[float, float]:
        if min(value) <= 0:
            raise custom_error(f"sides must be > 0, got {list(value)}; use e.g. [0.6, 0.4]")
        return value

    @model_validator(mode="after")
    def _check_speeds_and_box(self) -> TargetSpec:
        if self.speed_min is not None and self.speed_min > self.speed:
            raise custom_error(
                f"speed_min={self.speed_min:g} m/s exceeds speed={self.speed:g} m/s; speed is the "
                "largest speed drawn, so make speed_min <= speed (or leave it null)",
                "speed_min",
            )
        for axis, lo, hi in zip("xyz", self.box_low, self.box_high, strict=False):
            if hi - lo <= 2 * self.sphere_radius:
                raise custom_error(
                    f"box is too small along {axis} ({lo:g} to {hi:g} m) for a sphere of radius "
                    f"{self.sphere_radius:g} m; make box_high exceed box_low by more than "
                    f"2·sphere_radius on every axis",
                    "box_high",
                )
        return self


class RewardSpec(SpecModel):
    """Reward shaping (docs/environment.md, "Reward"): r = -(w1 d1² + w2 d2²) + per-arm bonuses
    + cooperative bonus; optional inter-arm collision penalty."""

    arm_weights: Pair = unit_field(
        _REWARD.arm_weights, "weights w1, w2 of the squared tip distances", "1/m²"
    )
    bonus_thresholds: tuple[Float, ...] = unit_field(
        _REWARD.bonus_thresholds,
        "per-arm bonus distance thresholds; bonus_values[k] is paid when d_i ≤ bonus_thresholds[k]",
        "m",
        min_length=1,
    )
    bonus_values: tuple[Float, ...] = unit_field(
        _REWARD.bonus_values, "per-arm bonuses, one per threshold", "reward units", min_length=1
    )
    cooperative_threshold: Float = unit_field(
        _REWARD.cooperative_threshold,
        "both tips within this distance earns the cooperative bonus",
        "m",
        gt=0,
    )
    cooperative_bonus: Float = unit_field(
        _REWARD.cooperative_bonus, "cooperative bonus", "reward units"
    )
    nonfinite_reward: Float = unit_field(
        _REWARD.nonfinite_reward,
        "reward of the step on which the state becomes NaN/inf (episode terminates)",
        "reward units",
    )
    collision_penalty: Float = unit_field(
        _REWARD.collision_penalty,
        "penalty c_col when the arms come closer than r1 + r2 + margin; 0 = off",
        "reward units",
        ge=0,
    )
    collision_margin: Float = unit_field(
        _REWARD.collision_margin,
        "extra clearance added to the sum of the radii in the collision test",
        "m",
        ge=0,
    )
    action_rate_penalty: Float = unit_field(
        _REWARD.action_rate_penalty,
        "c_rate: subtract c_rate times the mean squared change of the clipped action values "
        "since the previous control step (smooth actuation); 0 = off",
        "reward units",
        ge=0,
    )
    action_penalty: Float = unit_field(
        _REWARD.action_penalty,
        "c_act: subtract c_act times the mean squared clipped action value (away from "
        "saturation); 0 = off",
        "reward units",
        ge=0,
    )

    @model_validator(mode="after")
    def _check_bonuses(self) -> RewardSpec:
        if len(self.bonus_values) != len(self.bonus_thresholds):
            raise custom_error(
                f"{len(self.bonus_values)} bonus values for {len(self.bonus_thresholds)} "
                "thresholds; give one value per threshold",
                "bonus_values",
            )
        if any(t <= 0 for t in self.bonus_thresholds):
            raise custom_error("thresholds must be > 0; use e.g. [0.10, 0.075]", "bonus_thresholds")
        return self


class RealismSpec(SpecModel):
    """Imperfect sensing and actuation (docs/environment.md, "Realism: sensing and actuation"),
    in the spirit of realworldrl_suite. Every default is "off": an env whose section is all
    defaults computes exactly the study's transitions. Field names equal those of
    :class:`softtrack.env.realism.RealismConfig`."""

    obs_noise_node_position: Float = unit_field(
        _REALISM.obs_noise_node_position,
        "std of Gaussian noise on every observed node coordinate; 0 = off",
        "m",
        ge=0,
    )
    obs_noise_target_position: Float = unit_field(
        _REALISM.obs_noise_target_position,
        "std of Gaussian noise on each coordinate of the target centre; 0 = off",
        "m",
        ge=0,
    )
    obs_noise_speed: Float = unit_field(
        _REALISM.obs_noise_speed,
        "std of Gaussian noise on the tip speeds and the target speed; 0 = off",
        "m/s",
        ge=0,
    )
    obs_noise_direction: Float = unit_field(
        _REALISM.obs_noise_direction,
        "std of Gaussian noise on each component of the tip and target velocity directions "
        "(unit vectors; not renormalised); 0 = off",
        "-",
        ge=0,
    )
    obs_drop_probability: Float = unit_field(
        _REALISM.obs_drop_probability,
        "per observed value and control step, probability that it reads 0 (dropped); 0 = off",
        "-",
        ge=0,
        lt=1,
    )
    obs_stuck_probability: Float = unit_field(
        _REALISM.obs_stuck_probability,
        "per observed value and control step, probability that it gets stuck and repeats its "
        "last reading for obs_stuck_steps steps; 0 = off",
        "-",
        ge=0,
        lt=1,
    )
    obs_stuck_steps: Int = unit_field(
        _REALISM.obs_stuck_steps,
        "how long a stuck value repeats its last reading (the step it sticks included)",
        "control steps",
        ge=1,
    )
    obs_delay: Int = unit_field(
        _REALISM.obs_delay,
        "the policy sees the observation of this many control steps ago (the initial one "
        "until then); 0 = off",
        "control steps",
        ge=0,
    )
    action_delay: Int = unit_field(
        _REALISM.action_delay,
        "the arms apply the action of this many control steps ago (zeros until then); 0 = off",
        "control steps",
        ge=0,
    )
    action_delay_max: Int | None = unit_field(
        _REALISM.action_delay_max,
        "null, or the largest action delay: each episode's delay is then drawn uniformly from "
        "the whole numbers action_delay ... action_delay_max (domain randomisation)",
        "control steps",
        ge=0,
    )
    actuator_time_constant: Float | None = unit_field(
        _REALISM.actuator_time_constant,
        "time constant tau of a first-order lag on every control value (0 at reset, exact "
        "discretisation alpha = 1 - exp(-control_dt / tau)); null = off",
        "s",
        gt=0,
    )
    action_rate_limit: Float | None = unit_field(
        _REALISM.action_rate_limit,
        "largest change of an applied control value per second (from 0 at reset); null = off",
        "control units/s",
        gt=0,
    )
    torque_limit: Float | None = unit_field(
        _REALISM.torque_limit,
        "each element torque is clipped to +-this after the spline; null = off",
        "N·m",
        gt=0,
    )
    # model error: a fixed factor, or a [low, high] range drawn uniformly per episode and env
    youngs_modulus_scale: Factor = unit_field(
        _REALISM.youngs_modulus_scale,
        "model error: factor on env.physics.youngs_modulus (stiffness), or a [low, high] range "
        "drawn uniformly per episode and environment; 1 = off",
        "-",
    )
    density_scale: Factor = unit_field(
        _REALISM.density_scale,
        "model error: factor on env.physics.density (masses, inertias), or a [low, high] range "
        "drawn per episode; 1 = off",
        "-",
    )
    radius_scale: Factor = unit_field(
        _REALISM.radius_scale,
        "model error: factor on env.physics.radius (area, second moments, masses and "
        "stiffnesses follow), or a [low, high] range drawn per episode; 1 = off",
        "-",
    )
    damping_scale: Factor = unit_field(
        _REALISM.damping_scale,
        "model error: factor on env.physics.damping, or a [low, high] range drawn per "
        "episode; 1 = off",
        "-",
    )
    torque_scale_factor: Factor = unit_field(
        _REALISM.torque_scale_factor,
        "model error: factor on env.physics.torque_scale (actuator gain), or a [low, high] "
        "range drawn per episode; 1 = off",
        "-",
    )

    @model_validator(mode="after")
    def _check_delay_range(self) -> RealismSpec:
        if self.action_delay_max is not None and self.action_delay_max < self.action_delay:
            raise custom_error(
                f"{self.action_delay_max} is below action_delay ({self.action_delay}); give "
                "the largest delay of the per-episode range, or null for a fixed delay",
                "action_delay_max",
            )
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

    name: Literal["shared", "viewpoints", "transport"] = unit_field(
        _TASK.name,
        "shared: both tips track the target centre (the study); viewpoints: each tip tracks "
        "its own point at the standoff from the centre along x (arm 1 at -x, arm 2 at +x); "
        "transport: the arms carry env.physics.sphere and its centre tracks the target",
        "-",
    )
    standoff: Float = unit_field(
        _TASK.standoff,
        "viewpoints: distance of each arm's point from the target centre along x",
        "m",
        ge=0,
    )
    approach: Float = unit_field(
        _TASK.approach,
        "transport: the goal moves from the sphere's start to the path's start in this time "
        "(a smoothstep), then follows the path",
        "s",
        ge=0,
    )
    drop_grace: Float = unit_field(
        _TASK.drop_grace,
        "transport: the sphere counts as dropped (the episode ends) after this long without "
        "contact with either arm",
        "s",
        ge=0,
    )
    hold_bonus: Float = unit_field(
        _TASK.hold_bonus, "transport: reward per arm touching the sphere", "reward units", ge=0
    )
    squeeze_band: Pair = unit_field(
        _TASK.squeeze_band,
        "transport: band [low, high] of each arm's contact force on the sphere; [0, 0] = no "
        "force regulation",
        "N",
    )
    squeeze_penalty: Float = unit_field(
        _TASK.squeeze_penalty,
        "transport: weight c_f of -c_f·(e/high)² per arm, e the force's distance from the band",
        "reward units",
        ge=0,
    )
    drop_penalty: Float = unit_field(
        _TASK.drop_penalty, "transport: subtracted on the step of a drop", "reward units", ge=0
    )
    reach_penalty: Float = unit_field(
        _TASK.reach_penalty,
        "transport: weight c_reach of -c_reach·(g1 + g2), gi the gap between arm i's nearest "
        "node's surface and the sphere's (0 while it touches); leads the arms to the sphere",
        "reward units per m",
        ge=0,
    )
    bonus_needs_grip: bool = unit_field(
        _TASK.bonus_needs_grip,
        "transport: the distance bonuses count only on steps when both arms touch the sphere",
        "-",
    )
    grip: Float = unit_field(
        _TASK.grip,
        "transport: a constant squeeze added to the normal control values before clipping "
        "(arm 1 -grip, arm 2 +grip), so a zero action holds the sphere; e.g. 0.03",
        "-",
        ge=-1,
        le=1,
    )

    @model_validator(mode="after")
    def _check_task(self) -> TaskSpec:
        try:
            self.task_config().validate()
        except ValueError as err:
            message = str(err)
            field = message.split("=", 1)[0] if "=" in message else ""
            raise custom_error(message, field if field in type(self).model_fields else "") from None
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
    episode_duration: Float = unit_field(
        TrackingConfig.episode_duration,
        "simulated length of a training episode (then truncated)",
        "s",
        gt=0,
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
