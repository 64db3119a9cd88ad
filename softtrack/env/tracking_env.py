"""Gymnasium environments: two soft arms (or one) tracking a moving target."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from softtrack.env.core import TrackingCore
from softtrack.env.render import core_frame
from softtrack.env.settings import TrackingConfig, make_config
from softtrack.sim.params import CONTACT_ON
from softtrack.viz.scene import SceneRenderer

__all__ = ["DualArmTrackingEnv", "DualArmTransportEnv", "SingleArmTrackingEnv"]


class _TrackingEnv(gym.Env[np.ndarray, np.ndarray]):
    """A single-environment view of :class:`TrackingCore` (shared by both envs)."""

    # declared as gym.Env declares it (not ClassVar: mypy rejects that override); each
    # instance sets ``render_fps`` to its control rate (one frame per step, real time)
    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 500}  # noqa: RUF012

    def __init__(self, config: TrackingConfig, render_mode: str | None = None) -> None:
        super().__init__()
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use render_mode='rgb_array' "
                "(frames as (480, 640, 3) uint8 arrays) or leave it out"
            )
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / config.sim.control_dt)}
        self.config = config
        self.core = TrackingCore(1, config)
        self._renderer: SceneRenderer | None = None
        self.action_space = gym.spaces.Box(-1.0, 1.0, (self.core.action_dim,), dtype=np.float32)
        self.observation_space = gym.spaces.Box(
            -np.inf, np.inf, (self.core.obs_dim,), dtype=np.float32
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        obs = self.core.reset([0], [self.np_random])[0]
        distances = np.linalg.norm(
            self.core.engine.tip_position[0] - self.core.goal_positions()[0], axis=-1
        )[None]
        return obs, self.core.info(0, distances)

    def render(self) -> np.ndarray | None:
        """With ``render_mode="rgb_array"``: (480, 640, 3) uint8, the arms, clamps, target and
        contact forces now, the time and the tips' errors in a corner
        (:mod:`softtrack.viz`); ``None`` otherwise."""
        if self.render_mode != "rgb_array":
            return None
        if self._renderer is None:
            self._renderer = SceneRenderer()
        return self._renderer.render(core_frame(self.core, 0))

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        result = self.core.step(np.asarray(action, dtype=np.float64).reshape(1, -1))
        return (
            result.observation[0],
            float(result.reward[0]),
            bool(result.terminated[0]),
            bool(result.truncated[0]),
            self.core.info(0, result.distances),
        )


class DualArmTrackingEnv(_TrackingEnv):
    """Two soft Cosserat-rod arms, clamped 0.2 m apart, track one moving target.

    ## Description
    Each arm is a 1 m shearable, extensible Cosserat rod (20 elements) clamped at its base,
    pointing along +y, actuated by distributed torques: per arm and bending direction, six
    control values are interpolated by a cubic spline onto the 20 elements (75 N·m per element
    at a value of 1). Both tips should reach a spherical target (radius 0.05 m) that moves
    randomly (training) or along a circle, rectangle or figure-eight (evaluation). One control
    step holds the action for 10 integration steps of 0.2 ms (500 Hz). Physics as in
    PyElastica 1.0.0 (see ``softtrack.sim``).

    ## Action Space
    ``Box(-1, 1, (24,), float32)``; out-of-range values are clipped, NaN/inf raise an error.

    | index | arm | direction | meaning |
    |---|---|---|---|
    | 0–5 | 1 | normal d₁ | spline control values a₁…a₆ (positive curls toward −x) |
    | 6–11 | 1 | binormal d₂ | a₁…a₆ (positive curls toward +z) |
    | 12–17 | 2 | normal d₁ | a₁…a₆ |
    | 18–23 | 2 | binormal d₂ | a₁…a₆ |

    ## Observation Space
    ``Box(-inf, inf, (81,), float32)``, SI units:

    | index | observation |
    |---|---|
    | 0–10, 11–21, 22–32 | arm 1: x, then y, then z of nodes 0, 2, …, 20 (m) |
    | 33 | arm 1 tip speed (m/s) |
    | 34–36 | arm 1 tip velocity direction (zeros when still) |
    | 37–73 | arm 2, same layout |
    | 74–76 | target centre (m) |
    | 77 | target speed (m/s) |
    | 78–80 | target velocity direction (zeros when still) |

    ## Rewards
    With dᵢ the distance of tip i to its point after the step (m): the target centre in the
    ``shared`` task (the study), centre ∓ ``standoff``·x̂ in the ``viewpoints`` task:
    ``r = −(w₁d₁² + w₂d₂²) + Σᵢ [0.5·1(dᵢ ≤ 0.10) + 1.0·1(dᵢ ≤ 0.075)] + 1.5·1(d₁ ≤ 0.05 and
    d₂ ≤ 0.05)``, w₁ = w₂ = 1; thresholds, bonuses and weights are arguments. An optional
    penalty −c_col applies when the arms come closer than 2·radius + margin (off by default).
    A non-finite state gives −1000.

    ## Starting State
    Both arms straight along +y and at rest; the target starts per its mode (random: uniform in
    the box shrunk by its radius, with a random direction; closed forms: their t = 0 point).

    ## Episode End
    ``terminated`` when any value of either arm's state becomes NaN or inf (reward −1000);
    ``truncated`` after ``episode_duration`` = 10 s (5000 control steps).

    ## Info
    ``tip_positions`` (2, 3) m, ``target_position`` (3,) m, ``distances`` (2,) m,
    ``element_torques`` (2 arms, 2 directions, 20 elements) N·m as applied, ``time`` s; with
    model error (``realism``), ``parameters``: the episode's factors; with contact on,
    ``penetration`` (m) and ``contact_force`` (N).

    ## Arguments
    Any field of ``SimParams`` (``n_elem``, ``dt``, ``damping``, ``gravity``,
    ``torque_scale``, ``base_positions``, …), of ``TargetConfig`` (``speed``, ``center``,
    ``period``, ``circle_radius``, …) or of ``RewardConfig`` (``bonus_thresholds``,
    ``collision_penalty``, …), plus ``target`` (``random``, ``circle``, ``rectangle``,
    ``figure8``, ``fixed``), ``episode_duration`` (s) and ``realism`` (observation noise,
    delays, actuator lag, rate and torque limits, model error: fixed or per-episode random
    factors on E, density, radius, damping and torque scale; a mapping of ``RealismConfig``
    fields, all off by default; docs/environment.md); ``task`` (``shared`` or ``viewpoints``)
    and ``standoff`` (m); ``contact_k`` (N/m) and ``contact_nu`` (N·s/m), the contact between
    the arms (0: off, the study's ghosts; docs/physics.md)::

        gymnasium.make("softtrack/DualArmTracking-v0", target="circle", gravity=True)
        gymnasium.make("softtrack/DualArmTracking-v0", task="viewpoints",
                       contact_k=1e6, contact_nu=600.0)

    ## Version History
    * v0: the study's setting (docs/physics.md, docs/environment.md); contact and the
      viewpoints task are arguments whose defaults keep that setting.
    """

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(make_config(n_arms=2, **kwargs), render_mode)


class SingleArmTrackingEnv(_TrackingEnv):
    """One soft arm tracks the target: the building block of the independent baseline.

    Same physics and target as :class:`DualArmTrackingEnv`, with one arm at either base.

    ## Action Space
    ``Box(-1, 1, (12,), float32)``: normal a₁…a₆, then binormal a₁…a₆.

    ## Observation Space
    ``Box(-inf, inf, (44,), float32)``: the arm's 37 values (layout of the dual-arm env's
    indices 0–36) followed by the target's 7 (centre, speed, direction).

    ## Rewards
    ``r = −d² + 0.5·1(d ≤ 0.10) + 1.5·1(d ≤ 0.05)`` (the original single-arm reward); −1000
    on a non-finite state.

    ## Starting State, Episode End, Info
    As the dual-arm env, with arrays for one arm.

    ## Arguments
    ``arm``: 0 (base at x = −0.1 m, default) or 1 (x = +0.1 m); otherwise as the dual-arm env
    (in the ``viewpoints`` task the arm tracks its own point), except contact: one arm has
    nothing to touch, and ``contact_k`` > 0 is an error.

    ## Version History
    * v0: the study's setting (docs/physics.md, docs/environment.md).
    """

    def __init__(self, arm: int = 0, render_mode: str | None = None, **kwargs: Any) -> None:
        self.arm = arm
        super().__init__(make_config(n_arms=1, arm=arm, **kwargs), render_mode)


class DualArmTransportEnv(_TrackingEnv):
    """Two soft arms carry a rigid sphere held between their tips along the target's path.

    ## Description
    The dual-arm scene of :class:`DualArmTrackingEnv` with contact between the arms
    (``contact_k`` = 1e6 N/m, ``contact_nu`` = 600 N·s/m by default) and a rigid sphere
    (``SimParams.sphere``; default radius 0.05 m, 500 kg/m³, centred between the straight
    arms' tips, touching both, with friction μ = 0.5). Its centre must follow the goal: from
    its start to the path's start over ``approach`` seconds, then the target's path
    (``softtrack.env.transport_env``).

    ## Action Space
    ``Box(-1, 1, (24,), float32)``, as :class:`DualArmTrackingEnv`.

    ## Observation Space
    ``Box(-inf, inf, (88,), float32)``: the arms (0–73), the sphere's centre, speed and
    direction (74–80), the goal's centre, speed and direction (81–87); SI units.

    ## Rewards
    −w̄·d² + the study's bonuses on the sphere's distance d from the goal while both arms
    touch it, ``hold_bonus`` per arm touching it, −``reach_penalty`` × each other arm's gap to
    the sphere, an optional squeeze band penalty, −``drop_penalty`` on a drop
    (``softtrack.env.transport_env``).

    ## Starting State
    Both arms straight and at rest, the sphere at rest at its centre, the goal there.

    ## Episode End
    ``terminated`` on a non-finite state or when no arm has touched the sphere for
    ``drop_grace`` (0.5 s); ``truncated`` after ``episode_duration`` (the approach + 10 s).

    ## Info
    As :class:`DualArmTrackingEnv`, plus ``object_position``, ``goal_position`` (3,) m,
    ``object_force`` (2,) N (each arm's mean contact force on the sphere over the step),
    ``object_overlap`` (2,) m, ``touching`` (2,) bool, ``dropped`` bool.

    ## Arguments
    Those of :class:`DualArmTrackingEnv`, ``sphere`` (a mapping of ``SphereParams``
    fields: ``radius``, ``density``, ``center``, ``contact_k``, ``contact_nu``,
    ``velocity_damping``, ``friction``) and the task's ``approach``, ``drop_grace``,
    ``hold_bonus``, ``squeeze_band``, ``squeeze_penalty``, ``drop_penalty``,
    ``reach_penalty``, ``bonus_needs_grip`` and ``grip`` (a squeeze added to the normal control
    values, so a zero action holds the sphere)::

        gymnasium.make("softtrack/DualArmTransport-v0", target="circle", gravity=True)

    ## Version History
    * v0: first version (docs/environment.md, "Transport").
    """

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        settings: dict[str, Any] = {**CONTACT_ON, "sphere": {}, **kwargs, "task": "transport"}
        super().__init__(make_config(n_arms=2, **settings), render_mode)
