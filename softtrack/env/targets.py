"""Kinematic spherical targets, batched over environments (``docs/environment.md``, "Target").

Modes:

* ``random`` (training): constant speed (or, with ``speed_min``, a speed drawn uniformly in
  [``speed_min``, ``speed``] with every direction), a new direction uniform on the unit sphere every
  ``redirect_interval`` seconds, specular reflection (per velocity component) at the walls of
  the box so that the whole sphere stays inside it.
* ``circle``, ``rectangle``, ``figure8`` (evaluation): closed-form periodic paths in the
  plane y = ``center[1]``, one lap per ``period`` seconds; see :func:`trajectory_position`.
* ``paths`` (held-out validation): per episode, drawn from the environment's generator at
  reset, one of the three trajectories' shapes scaled by a factor uniform in
  :data:`HELD_OUT_SCALE`, its centre moved by up to :data:`HELD_OUT_SHIFT` × ``circle_radius``
  along each axis, started at a phase uniform over the period and run either way round: paths
  like the evaluation's that are not the evaluation's, to select models on
  (``training.validation_paths``); see :func:`held_out_state`.
* ``fixed``: a still target at ``fixed_position``.

Everything is vectorised over environments; the only per-environment Python work is drawing
the random target's new direction (once per ``redirect_interval``) and resets. Each random
environment draws only from its own :class:`numpy.random.Generator`, so stepping N
environments together gives bit-for-bit the numbers of N single-environment instances.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from softtrack.env.target_tables import AheadTable
from softtrack.numbers import is_finite_number, out_of_range, setting
from softtrack.trajectories import EVAL_TRAJECTORIES, TrajectoryName

__all__ = [
    "CLOSED_FORM_MODES",
    "EVAL_TRAJECTORIES",
    "HELD_OUT_SCALE",
    "HELD_OUT_SHIFT",
    "TARGET_MODES",
    "BatchedTargets",
    "MixedTargets",
    "TargetConfig",
    "TargetMode",
    "TrajectoryName",
    "held_out_state",
    "trajectory_position",
    "trajectory_velocity",
]

#: The closed-form trajectories of the evaluation (the study's three), by name: the one place
#: the names are written (specs, the CLI, evaluation and reports take them from here).
#: Every target motion: the random training target, the trajectories, the held-out paths
#: like them, a fixed point.
TargetMode = Literal["random", TrajectoryName, "paths", "fixed"]
TARGET_MODES: tuple[str, ...] = get_args(TargetMode)
CLOSED_FORM_MODES: tuple[str, ...] = (*EVAL_TRAJECTORIES, "fixed")
#: Modes that draw from each environment's generator at reset.
_DRAWN_MODES = ("random", "paths")
#: A held-out path's size relative to its trajectory's: uniform in this range.
HELD_OUT_SCALE = (0.8, 1.2)
#: A held-out path's centre moves by up to this fraction of ``circle_radius`` along each axis.
HELD_OUT_SHIFT = 0.15

# A redirect that is due at t = k·interval still happens on the step that ends at
# k·interval even when the summed time steps fall short of it by rounding (s).
_REDIRECT_TOLERANCE = 1e-9


def _finite_vector(value: object, length: int) -> np.ndarray | None:
    """``value`` as a float array of ``length`` finite entries, or None if it is not one."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    if arr.shape != (length,) or not np.all(np.isfinite(arr)):
        return None
    return arr


@dataclass(frozen=True)
class TargetConfig:
    """Target motion settings (SI units; defaults are the study's, ``docs/environment.md``).

    Attributes:
        name: one of ``random``, ``circle``, ``rectangle``, ``figure8``, ``paths``, ``fixed``.
        sphere_radius: radius of the target sphere, m.
        speed: speed of the random target, m/s (its maximum when ``speed_min`` is set).
        speed_min: ``None`` (the study): constant ``speed``. Otherwise every new direction of the
            random target comes with a speed uniform in [speed_min, speed], m/s.
        redirect_interval: time between two direction draws of the random target, s.
        box_low: (x, y, z) lower corner of the random target's box, m.
        box_high: (x, y, z) upper corner of the random target's box, m.
        center: centre of the circle / rectangle / figure-eight paths, m.
        circle_radius: radius of the circle, m.
        rectangle_size: side lengths of the rectangle (along x, along z), m.
        figure8_amplitude: (x amplitude, z amplitude) of the figure-eight, m.
        period: duration of one lap of the circle, rectangle and figure-eight, s.
        fixed_position: position of the ``fixed`` target, m.
    """

    name: str = setting("random", number=False)
    sphere_radius: float = setting(0.05, "m", gt=0)
    speed: float = setting(0.3, "m/s", gt=0)
    speed_min: float | None = setting(None, "m/s", ge=0, off=True)
    redirect_interval: float = setting(1.0, "s", gt=0)
    box_low: tuple[float, float, float] = setting((-0.6, 0.3, -0.6), "m", number=False)
    box_high: tuple[float, float, float] = setting((0.6, 0.9, 0.6), "m", number=False)
    center: tuple[float, float, float] = setting((0.0, 0.6, 0.0), "m", number=False)
    circle_radius: float = setting(0.3, "m", gt=0)
    rectangle_size: tuple[float, float] = setting((0.6, 0.4), "m", number=False)
    figure8_amplitude: tuple[float, float] = setting((0.3, 0.15), "m", number=False)
    period: float = setting(10.0, "s", gt=0)
    fixed_position: tuple[float, float, float] = setting((0.3, 0.6, 0.0), "m", number=False)

    @property
    def angular_frequency(self) -> float:
        """ω = 2π / period, rad/s."""
        return 2.0 * math.pi / self.period

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field and how to fix it."""
        if self.name not in TARGET_MODES:
            raise ValueError(
                f"target name={self.name!r} is unknown; use one of {', '.join(TARGET_MODES)}"
            )
        problem = out_of_range(self, "target ")
        if problem is not None:
            raise ValueError(problem)
        if self.speed_min is not None and self.speed_min > self.speed:
            raise ValueError(
                f"target speed_min={self.speed_min!r} exceeds speed={self.speed!r}, the largest "
                "speed drawn; make speed_min <= speed (or leave it unset for a constant speed)"
            )
        for field_name, length in (
            ("box_low", 3),
            ("box_high", 3),
            ("center", 3),
            ("fixed_position", 3),
            ("rectangle_size", 2),
            ("figure8_amplitude", 2),
        ):
            if _finite_vector(getattr(self, field_name), length) is None:
                value = getattr(self, field_name)
                raise ValueError(f"target {field_name}={value!r} must be {length} finite numbers")
        for field_name in ("rectangle_size", "figure8_amplitude"):
            if np.any(np.asarray(getattr(self, field_name), dtype=float) <= 0):
                raise ValueError(
                    f"target {field_name}={getattr(self, field_name)!r}: every entry must be > 0"
                )
        low = np.asarray(self.box_low, dtype=float)
        high = np.asarray(self.box_high, dtype=float)
        if np.any(low >= high):
            axis = "xyz"[int(np.argmax(low >= high))]
            raise ValueError(
                f"target box_low={self.box_low!r} must be below box_high={self.box_high!r} "
                f"on every axis (fails along {axis}); swap or widen them"
            )
        if np.any(high - low <= 2.0 * self.sphere_radius):
            axis = "xyz"[int(np.argmax(high - low <= 2.0 * self.sphere_radius))]
            raise ValueError(
                f"target box (box_low={self.box_low!r}, box_high={self.box_high!r}) is not wider "
                f"than the sphere's diameter 2·sphere_radius={2.0 * self.sphere_radius:g} m along "
                f"{axis}; enlarge the box or reduce sphere_radius"
            )


# ---- closed forms --------------------------------------------------------------------------


def _rectangle_state(config: TargetConfig, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rectangle position and velocity offsets (x, z) from the centre, each (..., 2).

    Sides in order: +x from (−w/2, −h/2), +z from (w/2, −h/2), −x from (w/2, h/2),
    −z from (−w/2, h/2); arc length grows at perimeter/period.
    """
    w, h = (float(v) for v in config.rectangle_size)
    perimeter = 2.0 * (w + h)
    speed = perimeter / config.period
    starts = np.array([0.0, w, w + h, 2.0 * w + h])  # arc length at each corner
    corners = np.array(
        [[-0.5 * w, -0.5 * h], [0.5 * w, -0.5 * h], [0.5 * w, 0.5 * h], [-0.5 * w, 0.5 * h]]
    )
    directions = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    s = np.mod(t, config.period) * speed  # arc length from the first corner, in [0, perimeter]
    side = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, 3)
    pos = corners[side] + directions[side] * (s - starts[side])[..., None]
    return pos, speed * directions[side]


def _planar(config: TargetConfig, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, z) offsets from the centre and their time derivatives, each (..., 2)."""
    if config.name == "rectangle":
        return _rectangle_state(config, t)
    omega = config.angular_frequency
    pos = np.empty((*t.shape, 2))
    vel = np.empty((*t.shape, 2))
    if config.name == "circle":
        r = config.circle_radius
        c, s = np.cos(omega * t), np.sin(omega * t)
        pos[..., 0], pos[..., 1] = r * c, r * s
        vel[..., 0], vel[..., 1] = -r * omega * s, r * omega * c
        return pos, vel
    if config.name == "figure8":
        ax, az = (float(v) for v in config.figure8_amplitude)
        pos[..., 0], pos[..., 1] = ax * np.sin(omega * t), az * np.sin(2.0 * omega * t)
        vel[..., 0] = ax * omega * np.cos(omega * t)
        vel[..., 1] = 2.0 * az * omega * np.cos(2.0 * omega * t)
        return pos, vel
    raise AssertionError(config.name)  # pragma: no cover


def _closed_form(config: TargetConfig, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if config.name in _DRAWN_MODES:
        raise ValueError(
            f"the {config.name} target has no closed-form trajectory of its own (each episode "
            f"draws it); use BatchedTargets, or pick one of {', '.join(CLOSED_FORM_MODES)}"
        )
    if config.name not in CLOSED_FORM_MODES:
        config.validate()  # raises with the list of valid names
    t = np.asarray(t, dtype=float)
    if config.name == "fixed":
        pos = np.broadcast_to(np.asarray(config.fixed_position, dtype=float), (*t.shape, 3))
        return pos.copy(), np.zeros((*t.shape, 3))
    planar_pos, planar_vel = _planar(config, t)
    pos = np.empty((*t.shape, 3))
    vel = np.zeros((*t.shape, 3))
    cx, cy, cz = config.center
    pos[..., 0] = float(cx) + planar_pos[..., 0]
    pos[..., 1] = float(cy)
    pos[..., 2] = float(cz) + planar_pos[..., 1]
    vel[..., 0] = planar_vel[..., 0]
    vel[..., 2] = planar_vel[..., 1]
    return pos, vel


def trajectory_position(config: TargetConfig, t: np.ndarray) -> np.ndarray:
    """Target centre of a closed-form mode at times ``t``.

    Args:
        config: a ``circle``, ``rectangle``, ``figure8`` or ``fixed`` target.
        t: times since reset, s, any shape (...).

    Returns:
        (..., 3) positions, m.

    Raises:
        ValueError: for the ``random`` and ``paths`` modes (each episode draws its own) or an
            unknown name.
    """
    return _closed_form(config, t)[0]


def trajectory_velocity(config: TargetConfig, t: np.ndarray) -> np.ndarray:
    """Analytic time derivative of :func:`trajectory_position`, (..., 3) m/s.

    On the rectangle, a corner belongs to the side that starts there.
    """
    return _closed_form(config, t)[1]


@dataclass(frozen=True)
class HeldOutPaths:
    """The drawn parameters of ``n`` held-out paths (``paths`` mode).

    Attributes:
        shape: (n,) index into :data:`EVAL_TRAJECTORIES` of each path's shape.
        scale: (n,) size relative to the trajectory's, in :data:`HELD_OUT_SCALE`.
        shift: (n, 3) move of the centre, m.
        phase: (n,) time along the trajectory at which the path starts, s.
        sign: (n,) +1 to run the trajectory forwards, −1 backwards.
    """

    shape: np.ndarray
    scale: np.ndarray
    shift: np.ndarray
    phase: np.ndarray
    sign: np.ndarray

    def tiled(self, k: int) -> HeldOutPaths:
        """These n paths repeated ``k`` times (k·n paths: row j·n + i is path i)."""
        return HeldOutPaths(
            np.tile(self.shape, k),
            np.tile(self.scale, k),
            np.tile(self.shift, (k, 1)),
            np.tile(self.phase, k),
            np.tile(self.sign, k),
        )

    @classmethod
    def unit(cls, n: int) -> HeldOutPaths:
        """``n`` paths equal to the first trajectory (before any draw)."""
        return cls(np.zeros(n, np.intp), np.ones(n), np.zeros((n, 3)), np.zeros(n), np.ones(n))

    def draw(self, i: int, config: TargetConfig, rng: np.random.Generator) -> None:
        """Draw path ``i``'s parameters from ``rng``: the shape (one integer), the scale (one
        uniform), the shift (three uniforms), the phase (one uniform), the direction (one
        uniform)."""
        self.shape[i] = rng.integers(len(EVAL_TRAJECTORIES))
        self.scale[i] = rng.uniform(*HELD_OUT_SCALE)
        self.shift[i] = rng.uniform(-1.0, 1.0, 3) * HELD_OUT_SHIFT * config.circle_radius
        self.phase[i] = rng.uniform(0.0, config.period)
        self.sign[i] = 1.0 if rng.uniform() < 0.5 else -1.0


@functools.lru_cache(maxsize=16)
def _shapes(config: TargetConfig) -> tuple[TargetConfig, ...]:
    """``config`` as each of the :data:`EVAL_TRAJECTORIES` (built once per config: stepping
    calls this every control step)."""
    return tuple(dataclasses.replace(config, name=name) for name in EVAL_TRAJECTORIES)


def held_out_state(
    config: TargetConfig, paths: HeldOutPaths, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities of held-out paths at times ``t``.

    Args:
        config: the target settings (the trajectories' sizes, centre and period).
        paths: the n paths' drawn parameters.
        t: (n,) each path's time since reset, s.

    Returns:
        (n, 3) positions, m, and (n, 3) velocities, m/s: path k at time t is its shape's
        trajectory at ``phase + sign·t``, scaled about the centre by ``scale`` and moved by
        ``shift``.
    """
    t = np.asarray(t, dtype=float)
    pos = np.empty((len(t), 3))
    vel = np.zeros((len(t), 3))
    for k, shaped in enumerate(_shapes(config)):
        members = np.flatnonzero(paths.shape == k)
        if members.size == 0:
            continue
        along = paths.phase[members] + paths.sign[members] * t[members]
        planar_pos, planar_vel = _planar(shaped, along)
        scale = paths.scale[members, None]
        planar_pos *= scale
        planar_vel *= scale * paths.sign[members, None]
        centre = np.asarray(config.center, dtype=float) + paths.shift[members]
        pos[members, 0] = centre[:, 0] + planar_pos[:, 0]
        pos[members, 1] = centre[:, 1]
        pos[members, 2] = centre[:, 2] + planar_pos[:, 1]
        vel[members, 0] = planar_vel[:, 0]
        vel[members, 2] = planar_vel[:, 1]
    return pos, vel


# ---- batched state ---------------------------------------------------------------------------


class BatchedTargets:
    """The targets of ``n_envs`` environments, advanced together.

    Attributes:
        config: the (validated) settings shared by all environments.
        n_envs: number of environments.
        position: (n_envs, 3) target centres, m.
        velocity: (n_envs, 3) target velocities, m/s.
        time: (n_envs,) time since each environment's last reset, s.

    Random mode needs :meth:`reset` of every environment (with its generator) before
    :meth:`step`; the closed-form modes start at t = 0 and may be stepped at once.
    """

    def __init__(self, config: TargetConfig, n_envs: int) -> None:
        config.validate()
        if not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs={n_envs!r} must be an integer ≥ 1")
        self.config = config
        self.n_envs = int(n_envs)
        self.time = np.zeros(self.n_envs)
        self.position = np.zeros((self.n_envs, 3))
        self.velocity = np.zeros((self.n_envs, 3))
        radius = float(config.sphere_radius)
        # Bounds of the sphere's centre: the box shrunk by the radius.
        self._low = np.asarray(config.box_low, dtype=float) + radius
        self._high = np.asarray(config.box_high, dtype=float) - radius
        self._random = config.name == "random"
        self._drawn = config.name in _DRAWN_MODES
        self._paths = HeldOutPaths.unit(self.n_envs) if config.name == "paths" else None
        self._rngs: list[np.random.Generator | None] = [None] * self.n_envs
        self._since_redirect = np.zeros(self.n_envs)
        self._all_reset = False  # random mode: has every environment got its generator?
        self._ahead = AheadTable(self._states_at)
        if self._random:
            self.position[:] = 0.5 * (self._low + self._high)
        else:
            self.position[:], self.velocity[:] = self._state(self.time)

    def _state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closed-form or held-out paths' (n, 3) positions and velocities at times ``t`` (n,)."""
        if self._paths is not None:
            return held_out_state(self.config, self._paths, t)
        return _closed_form(self.config, t)

    def _states_at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_state` at times (k, n): positions and velocities (k, n, 3)."""
        if self._paths is None:
            return _closed_form(self.config, times)
        k, n = times.shape
        position, velocity = held_out_state(self.config, self._paths.tiled(k), times.reshape(-1))
        return position.reshape(k, n, 3), velocity.reshape(k, n, 3)

    @property
    def shrunk_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) bounds of the random target's centre, each (3,), m."""
        return self._low.copy(), self._high.copy()

    def reset(
        self,
        env_indices: np.ndarray | Sequence[int],
        rngs: Sequence[np.random.Generator] | None = None,
    ) -> None:
        """Restart the listed environments at time 0.

        Args:
            env_indices: (k,) indices of the environments to reset.
            rngs: k generators, ``rngs[i]`` for ``env_indices[i]``; required in random mode
                (and kept for that environment's later direction draws) and in paths mode,
                ignored otherwise. Random mode draws, per environment, the centre uniformly in
                the shrunk box (3 uniforms) and then a direction (3 standard normals,
                normalised); paths mode draws the path (:meth:`HeldOutPaths.draw`).
        """
        idx = np.atleast_1d(np.asarray(env_indices, dtype=np.intp))
        if idx.ndim != 1 or np.any((idx < 0) | (idx >= self.n_envs)):
            raise ValueError(f"env_indices must be a 1-D list of indices in [0, {self.n_envs})")
        if self._drawn:
            if rngs is None or len(rngs) != len(idx):
                raise ValueError(
                    f"{self.config.name} targets need one numpy Generator per reset environment: "
                    f"got {0 if rngs is None else len(rngs)} for {len(idx)} indices"
                )
            for rng in rngs:
                if not isinstance(rng, np.random.Generator):
                    raise TypeError(f"rngs must be numpy.random.Generator objects, not {type(rng)}")
        self.time[idx] = 0.0
        self._since_redirect[idx] = 0.0
        if not self._random:
            if self._paths is not None:
                assert rngs is not None
                for i, rng in zip(idx.tolist(), rngs, strict=True):
                    self._paths.draw(i, self.config, rng)
            self._ahead.clear()
            self.position[:], self.velocity[:] = self._state(self.time)
            return
        assert rngs is not None
        for i, rng in zip(idx.tolist(), rngs, strict=True):
            self._rngs[i] = rng
            self.position[i] = rng.uniform(self._low, self._high)
            self._draw_direction(i)
        self._all_reset = all(rng is not None for rng in self._rngs)

    def _draw_direction(self, i: int) -> None:
        """New velocity of env ``i``: a direction uniform on the unit sphere times ``speed``, or
        times a speed uniform in [``speed_min``, ``speed``] (drawn after the direction)."""
        rng = self._rngs[i]
        assert rng is not None
        while True:
            g = rng.standard_normal(3)
            gx, gy, gz = (float(c) for c in g)
            norm = math.sqrt(gx * gx + gy * gy + gz * gz)
            if norm > 1e-12:  # practically always; redraw the measure-zero degenerate case
                break
        speed = self.config.speed
        if self.config.speed_min is not None:
            speed = float(rng.uniform(self.config.speed_min, speed))
        self.velocity[i] = (speed / norm) * g

    def step(self, dt: float, active: np.ndarray | None = None) -> None:
        """Advance every environment (or the ``active`` ones, a (n,) bool mask; the others keep
        their time, place and velocity) by ``dt`` seconds."""
        if not (is_finite_number(dt) and dt > 0):
            raise ValueError(f"dt={dt!r} must be a finite number > 0")
        if active is not None:
            self._step_some(dt, np.asarray(active, dtype=bool))
            return
        self.time += dt
        if not self._random:  # the closed form, from a table of the next steps
            self.position[:], self.velocity[:] = self._ahead.state(self.time, dt)
            return
        if not self._all_reset:
            missing = [i for i, rng in enumerate(self._rngs) if rng is None]
            raise RuntimeError(f"random targets {missing[:5]} were never reset; call reset first")
        pos = self.position + self.velocity * dt
        vel = self.velocity
        low, high = self._low, self._high
        # Mirror every component that left [low, high] at the wall it crossed, flipping its
        # velocity; repeat in case a huge step crossed the box more than once.
        for _ in range(1000):
            above = pos > high
            below = pos < low
            crossed = above | below
            if not crossed.any():
                break
            pos = np.where(above, 2.0 * high - pos, np.where(below, 2.0 * low - pos, pos))
            vel = np.where(crossed, -vel, vel)
        else:  # pragma: no cover - needs a step thousands of box widths long
            raise RuntimeError(f"dt={dt!r} is too long for the random target's box")
        self.position[:] = pos
        self.velocity[:] = vel
        self._since_redirect += dt
        due = np.flatnonzero(
            self._since_redirect >= self.config.redirect_interval - _REDIRECT_TOLERANCE
        )
        for i in due.tolist():
            self._draw_direction(i)
            self._since_redirect[i] -= self.config.redirect_interval

    def _step_some(self, dt: float, active: np.ndarray) -> None:
        """:meth:`step` for the environments where ``active`` is true, the others untouched."""
        if active.shape != (self.n_envs,):
            raise ValueError(f"active must be a ({self.n_envs},) bool mask, got {active.shape}")
        if active.all():
            self.step(dt)
            return
        if not active.any():
            return
        saved = (
            self.time.copy(),
            self.position.copy(),
            self.velocity.copy(),
            self._since_redirect.copy(),
        )
        resting = np.flatnonzero(~active)
        if self._random:  # a resting environment must not draw: hold it off its redirect
            self._since_redirect[resting] = -np.inf
        self.step(dt)
        time, position, velocity, since_redirect = saved
        self.time[resting] = time[resting]
        self.position[resting] = position[resting]
        self.velocity[resting] = velocity[resting]
        self._since_redirect[resting] = since_redirect[resting]


class MixedTargets:
    """The targets of environments that follow different modes, advanced together: one
    :class:`BatchedTargets` per mode over its environments, so each environment moves
    exactly as in a batch of its own mode (validation runs its random-target episodes and the
    three trajectories as one batch).

    Attributes:
        config: the shared settings (its ``name`` is the first environment's mode).
        names: (n_envs,) each environment's mode.
        n_envs, position, velocity, time: as :class:`BatchedTargets`'s.
    """

    def __init__(self, config: TargetConfig, names: Sequence[str]) -> None:
        self.names = tuple(str(name) for name in names)
        if not self.names:
            raise ValueError("MixedTargets needs at least one environment")
        self.config = dataclasses.replace(config, name=self.names[0])
        self.n_envs = len(self.names)
        self._groups = [
            (
                np.array([i for i, n in enumerate(self.names) if n == name], dtype=np.intp),
                BatchedTargets(dataclasses.replace(config, name=name), self.names.count(name)),
            )
            for name in dict.fromkeys(self.names)
        ]
        self._local = np.empty(self.n_envs, dtype=np.intp)  # each env's index in its group
        for members, _ in self._groups:
            self._local[members] = np.arange(len(members))
        self.time = np.zeros(self.n_envs)
        self.position = np.zeros((self.n_envs, 3))
        self.velocity = np.zeros((self.n_envs, 3))
        self._gather()

    @property
    def shrunk_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) bounds of a random target's centre, each (3,), m."""
        return self._groups[0][1].shrunk_box

    def _gather(self) -> None:
        for members, targets in self._groups:
            self.time[members] = targets.time
            self.position[members] = targets.position
            self.velocity[members] = targets.velocity

    def reset(
        self,
        env_indices: np.ndarray | Sequence[int],
        rngs: Sequence[np.random.Generator] | None = None,
    ) -> None:
        """:meth:`BatchedTargets.reset` of the listed environments, each in its mode's group."""
        idx = np.atleast_1d(np.asarray(env_indices, dtype=np.intp))
        for members, targets in self._groups:
            chosen = np.flatnonzero(np.isin(idx, members))
            if chosen.size:
                group_rngs = None if rngs is None else [rngs[j] for j in chosen.tolist()]
                targets.reset(self._local[idx[chosen]], group_rngs)
        self._gather()

    def step(self, dt: float, active: np.ndarray | None = None) -> None:
        """:meth:`BatchedTargets.step` of every group (``active``: (n,) bool, or all)."""
        for members, targets in self._groups:
            targets.step(dt, None if active is None else np.asarray(active, dtype=bool)[members])
        self._gather()
