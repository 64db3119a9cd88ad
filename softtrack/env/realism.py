"""Imperfect sensing and actuation, and model error, of the tracking environment
(docs/environment.md, "Realism: sensing and actuation" and "Model error"), in the spirit of
google-research/realworldrl_suite.

:class:`RealismConfig` holds the settings (all off by default); :class:`RealismModel` applies
them to a batch of ``n`` environments between the policy and the simulation. ``TrackingCore``
builds a model only when a setting is not at its default, so a default environment draws no
extra random numbers and computes exactly the transitions it computed before this module.

Observation path, per control step (each stage only when switched on):

1. delay: the observation of ``obs_delay`` control steps ago (at a reset the queue is filled
   with the initial observation);
2. Gaussian noise, one standard deviation per observation group (:func:`observation_groups`):
   node positions (m), target centre (m), tip and target speeds (m/s), tip and target
   velocity directions (unit vectors, noise per component, not renormalised);
3. stuck sensors: each value, not already stuck, gets stuck with ``obs_stuck_probability``
   and then repeats the value it reported on the previous step for ``obs_stuck_steps`` steps
   (the step it gets stuck included);
4. dropped values: each value reads 0 with ``obs_drop_probability`` for that step.

Action path: clip to [−1, 1] (TrackingCore) → delay of ``action_delay`` control steps (zeros
until the first real action comes out; with ``action_delay_max`` a whole number of steps drawn
per episode from ``action_delay`` … ``action_delay_max``) → first-order lag y ← y + α (u − y),
α = 1 − exp(−control_dt / τ), y = 0 at reset → rate limit
|Δ| ≤ ``action_rate_limit``·control_dt per step relative to the value applied on the previous
step (0 at reset) → spline torques (engine) → clip of each element torque to ±``torque_limit``.

The random numbers come from one generator per environment, spawned at every reset from the
environment's own generator (``Generator.spawn``, which draws nothing from it), so the target's
random stream is that of a plain environment and an episode is reproducible from its seed.
Per step and environment the draws are, in this order and only where switched on:
``obs_dim`` standard normals (noise), ``obs_dim`` uniforms (stuck), ``obs_dim`` uniforms (drop).

Model error: ``youngs_modulus_scale``, ``density_scale``, ``radius_scale``, ``damping_scale`` and
``torque_scale_factor`` multiply the physics section's values, each either a fixed factor or a
``(low, high)`` range drawn uniformly per episode and environment (domain randomisation). The
draws come from a generator spawned, at every reset, from that reset's realism generator (so
the sensing noise is the same with and without randomisation): one ``uniform(low, high)`` per
ranged factor, in the order of :data:`~softtrack.sim.params.MODEL_PARAMETERS`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from softtrack.env.observation_layout import observation_labels
from softtrack.numbers import out_of_range, setting
from softtrack.sim.params import MODEL_PARAMETERS, SimParams, model_error_stability

__all__ = [
    "MODEL_PARAMETERS",
    "OBSERVATION_GROUPS",
    "Factor",
    "RealismConfig",
    "RealismModel",
    "observation_groups",
]

Factor = float | tuple[float, float]  # a fixed factor, or a (low, high) range drawn per episode

# Observation group → the noise field of RealismConfig that sets its standard deviation.
OBSERVATION_GROUPS = {
    "node_position": "obs_noise_node_position",
    "target_position": "obs_noise_target_position",
    "speed": "obs_noise_speed",
    "direction": "obs_noise_direction",
}


@dataclass(frozen=True)
class RealismConfig:
    """Sensing and actuation imperfections; every default is "off".

    Attributes:
        obs_noise_node_position: std of the Gaussian noise on node coordinates, m.
        obs_noise_target_position: std of the noise on the target centre, m.
        obs_noise_speed: std of the noise on the tip and target speeds, m/s.
        obs_noise_direction: std of the noise on each component of the tip and target velocity
            directions (unit vectors), -.
        obs_drop_probability: per value and step, probability that it reads 0, in [0, 1).
        obs_stuck_probability: per value and step, probability that it gets stuck, in [0, 1).
        obs_stuck_steps: control steps a stuck value repeats its last reading, ≥ 1.
        obs_delay: the policy sees the observation of this many control steps ago, ≥ 0.
        action_delay: the engine applies the action of this many control steps ago, ≥ 0.
        action_delay_max: ``None``, or the largest delay, ≥ ``action_delay``: each episode's
            delay is then drawn uniformly from the whole numbers ``action_delay`` …
            ``action_delay_max`` (domain randomisation).
        actuator_time_constant: τ of the first-order lag on the control values, s (> 0);
            ``None`` = no lag.
        action_rate_limit: largest |change| of an applied control value per second, 1/s (> 0);
            ``None`` = no limit.
        torque_limit: each element torque is clipped to ±this, N·m (> 0); ``None`` = no limit.
        youngs_modulus_scale, density_scale, radius_scale, damping_scale,
            torque_scale_factor: model error, factors (> 0) on the physics' Young's modulus,
            density, radius, damping and torque scale; a float is a fixed factor, a
            ``(low, high)`` pair a range drawn uniformly per episode; 1 = off.
    """

    obs_noise_node_position: float = setting(0.0, "m", ge=0)
    obs_noise_target_position: float = setting(0.0, "m", ge=0)
    obs_noise_speed: float = setting(0.0, "m/s", ge=0)
    obs_noise_direction: float = setting(0.0, ge=0)
    obs_drop_probability: float = setting(0.0, ge=0, lt=1)
    obs_stuck_probability: float = setting(0.0, ge=0, lt=1)
    obs_stuck_steps: int = setting(1, "control steps", ge=1, whole=True)
    obs_delay: int = setting(0, "control steps", ge=0, whole=True)
    action_delay: int = setting(0, "control steps", ge=0, whole=True)
    action_delay_max: int | None = setting(None, "control steps", ge=0, whole=True, off=True)
    actuator_time_constant: float | None = setting(None, "s", gt=0, off=True)
    action_rate_limit: float | None = setting(None, "control units/s", gt=0, off=True)
    torque_limit: float | None = setting(None, "N·m", gt=0, off=True)
    youngs_modulus_scale: Factor = setting(1.0, number=False)
    density_scale: Factor = setting(1.0, number=False)
    radius_scale: Factor = setting(1.0, number=False)
    damping_scale: Factor = setting(1.0, number=False)
    torque_scale_factor: Factor = setting(1.0, number=False)

    @classmethod
    def from_value(cls, value: RealismConfig | Mapping[str, Any] | None) -> RealismConfig:
        """A config from ``None`` (defaults), a :class:`RealismConfig` or a mapping of fields.

        Raises:
            ValueError: an unknown field name (with the valid ones).
        """
        if value is None:
            return cls()
        if isinstance(value, RealismConfig):
            return value
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(value) - names)
        if unknown:
            raise ValueError(
                f"unknown realism setting {unknown[0]!r}; valid names: {', '.join(sorted(names))}"
            )
        values = dict(value)
        for name in MODEL_PARAMETERS:  # YAML/JSON lists → tuples (the config stays hashable)
            if isinstance(values.get(name), list):
                values[name] = tuple(values[name])
        return cls(**values)

    @property
    def active(self) -> bool:
        """True when any setting differs from its default ("off")."""
        return self != RealismConfig()

    @property
    def model_error_ranges(self) -> dict[str, tuple[float, float]]:
        """Each model-error factor that is not 1 → its (low, high) range ((f, f) when fixed)."""
        out = {}
        for name in MODEL_PARAMETERS:
            value = getattr(self, name)
            pair = (
                (float(value[0]), float(value[1]))
                if isinstance(value, (tuple, list))
                else (float(value), float(value))
            )
            if pair != (1.0, 1.0):
                out[name] = pair
        return out

    @property
    def model_error_active(self) -> bool:
        """True when a model-error factor is not 1."""
        return bool(self.model_error_ranges)

    @property
    def randomised(self) -> bool:
        """True when a model-error factor is a range (drawn at every reset)."""
        return any(low != high for low, high in self.model_error_ranges.values())

    def check_stability(self, sim: SimParams) -> None:
        """Raise ``ValueError`` when ``sim.dt`` is unstable for the worst case of the model
        error (the stiffest, lightest rod of the ranges), naming the factor and the fix."""
        ranges = self.model_error_ranges
        result = model_error_stability(sim, ranges) if ranges else None
        if result is not None:
            name, problem, fix = result
            raise ValueError(f"{name}: {problem}; {fix}")

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid field and how to fix it."""
        problem = out_of_range(self)
        if problem is not None:
            raise ValueError(problem)
        high = self.action_delay_max
        if high is not None and high < self.action_delay:
            raise ValueError(
                f"action_delay_max={high!r} must be a whole number ≥ action_delay "
                f"({self.action_delay}), or None (a fixed delay)"
            )
        for name in MODEL_PARAMETERS:
            value = getattr(self, name)
            pair = value if isinstance(value, (tuple, list)) else (value,)
            if isinstance(value, (tuple, list)) and len(value) != 2:
                raise ValueError(f"{name}={value!r} must be a factor or a (low, high) range")
            if not all(
                isinstance(v, (int, float))
                and not isinstance(v, bool)
                and math.isfinite(v)
                and v > 0
                for v in pair
            ):
                raise ValueError(
                    f"{name}={value!r} must be a finite factor > 0 (1 = off) or a "
                    "(low, high) range of them"
                )
            if len(pair) == 2 and pair[0] > pair[1]:
                raise ValueError(
                    f"{name}={value!r}: low must not exceed high; write ({pair[1]!r}, {pair[0]!r})"
                )


def observation_groups(n_arms: int, n_nodes: int = 21) -> dict[str, np.ndarray]:
    """Column indices of each observation group of :data:`OBSERVATION_GROUPS`.

    ``node_position``: the sampled nodes' x, y, z of every arm; ``target_position``: the target
    centre; ``speed``: each tip speed and the target speed; ``direction``: each tip's and the
    target's velocity direction. Together they cover every column once.
    """
    groups: dict[str, list[int]] = {name: [] for name in OBSERVATION_GROUPS}
    for column, label in enumerate(observation_labels(n_arms, n_nodes)):
        if ".node" in label:
            groups["node_position"].append(column)
        elif label.startswith("target.pos."):
            groups["target_position"].append(column)
        elif label.endswith("speed"):
            groups["speed"].append(column)
        else:  # arm<k>.tip_dir.* and target.dir.*
            groups["direction"].append(column)
    return {name: np.asarray(columns, dtype=np.intp) for name, columns in groups.items()}


def _spawn(rng: np.random.Generator) -> np.random.Generator:
    """A generator of its own for the realism draws, derived from ``rng`` without drawing from
    it (a generator without a seed sequence falls back to one draw)."""
    try:
        return rng.spawn(1)[0]
    except (TypeError, ValueError):
        return np.random.default_rng(int(rng.integers(2**63)))


class RealismModel:
    """The settings of a :class:`RealismConfig` applied to ``n_envs`` environments.

    Args:
        config: the validated settings.
        n_envs: n, environments.
        n_arms: A, arms per environment.
        n_nodes: nodes per arm (for the observation groups).
        control_dt: duration of one control step, s.

    Arrays: observations (n, obs_dim) float32 with obs_dim = A·(3·⌈n_nodes/2⌉ + 4) + 7;
    actions (n, 12·A) float64 control values; torques (n, A, 2, n_elem) N·m.
    """

    def __init__(
        self, config: RealismConfig, n_envs: int, n_arms: int, n_nodes: int, control_dt: float
    ) -> None:
        config.validate()
        self.config = c = config
        self.n_envs = n = int(n_envs)
        groups = observation_groups(n_arms, n_nodes)
        self.obs_dim = d = sum(len(columns) for columns in groups.values())
        self.action_dim = a = 12 * n_arms
        self.control_dt = float(control_dt)
        self.rngs: list[np.random.Generator | None] = [None] * n
        sigma = np.zeros(d)
        for group, field_name in OBSERVATION_GROUPS.items():
            sigma[groups[group]] = float(getattr(c, field_name))
        self.obs_sigma = sigma if sigma.any() else None  # (obs_dim,) std per column
        self._obs_queue = np.zeros((n, c.obs_delay, d), dtype=np.float32)
        self._stuck_left = np.zeros((n, d), dtype=np.int64)  # steps a value stays stuck
        self._last_reading = np.zeros((n, d), dtype=np.float32)  # before dropping
        # the last max_delay + 1 clipped actions (newest last) and each env's episode delay
        self.max_delay = max(c.action_delay, c.action_delay_max or 0)
        self._action_history = np.zeros((n, self.max_delay + 1, a))
        self.action_delays = np.full(n, c.action_delay, dtype=np.intp)
        tau = c.actuator_time_constant
        self.lag_alpha = None if tau is None else -math.expm1(-self.control_dt / tau)
        self._lagged = np.zeros((n, a))
        self.max_change = (
            None if c.action_rate_limit is None else c.action_rate_limit * self.control_dt
        )
        self._applied = np.zeros((n, a))
        self.model_error_ranges = c.model_error_ranges
        self.strength = 1.0

    @property
    def strength(self) -> float:
        """How much of the random perturbations applies, in [0, 1] (1, the default: all).

        A curriculum (``training.randomisation_warmup_steps``) raises it from 0 to 1 during
        training. At strength s, each per-episode range (low, high) of a model-error factor
        becomes (1 + s·(low − 1), 1 + s·(high − 1)), the episode's action delay is drawn from
        d₀ … d₀ + round(s·(``action_delay_max`` − d₀)), d₀ = ``action_delay``, and the
        observation noise's standard deviations and the stuck and drop probabilities are
        multiplied by s. Fixed settings (fixed factors and delays, lag, rate and torque
        limits) are the plant and do not change; the number of random draws does not either.
        It acts at the next reset (ranges, delay) and the next step (noise, stuck, drops).
        """
        return self._strength

    @strength.setter
    def strength(self, value: float) -> None:
        value = float(value)
        if not 0.0 <= value <= 1.0:
            raise ValueError(f"strength={value!r} must lie in [0, 1]")
        self._strength = value

    # ---- reset ------------------------------------------------------------------------------
    def reset(
        self,
        env_indices: Sequence[int] | np.ndarray,
        rngs: Sequence[np.random.Generator],
        observations: np.ndarray,
    ) -> np.ndarray:
        """Restart the listed environments' sensors and actuators.

        Args:
            env_indices: (k,) environment indices.
            rngs: k generators of those environments (each spawns the realism generator).
            observations: (k, obs_dim) their true initial observations.

        Returns:
            (k, obs_dim) float32: the initial observations as the policy sees them (noise and
            drops applied; nothing is stuck yet).
        """
        idx = np.atleast_1d(np.asarray(env_indices, dtype=np.intp))
        for i, rng in zip(idx.tolist(), rngs, strict=True):
            self.rngs[i] = _spawn(rng)
        obs = np.array(observations, dtype=np.float32)
        self._obs_queue[idx] = obs[:, None, :]
        self._stuck_left[idx] = 0
        self._action_history[idx] = 0.0
        if self.config.action_delay_max is not None:
            low = self.config.action_delay
            high = low + round(self._strength * (self.config.action_delay_max - low))
            for i in idx.tolist():
                self.action_delays[i] = _spawn(self._rng(i)).integers(low, high + 1)
        self._lagged[idx] = 0.0
        self._applied[idx] = 0.0
        reading = self._noisy(obs, idx)
        self._last_reading[idx] = reading
        return self._dropped(reading, idx)

    def sample_model_error(self, env_indices: Sequence[int] | np.ndarray) -> dict[str, np.ndarray]:
        """This episode's model-error factors of the listed environments (call after
        :meth:`reset`): name → (k,) factors, for every factor that is not 1; a range is drawn
        uniformly from a generator spawned from the environment's realism generator (the module
        docstring), a fixed factor is repeated."""
        idx = np.atleast_1d(np.asarray(env_indices, dtype=np.intp))
        ranges = self.model_error_ranges
        out = {name: np.empty(idx.size) for name in ranges}
        for row, i in enumerate(idx.tolist()):
            rng = None
            for name, (low, high) in ranges.items():  # MODEL_PARAMETERS order
                if low == high:
                    out[name][row] = low
                    continue
                if rng is None:
                    rng = _spawn(self._rng(i))
                out[name][row] = rng.uniform(*self._narrowed(low, high))
        return out

    def _narrowed(self, low: float, high: float) -> tuple[float, float]:
        """A model-error range at the current :attr:`strength` (itself at strength 1)."""
        s = self._strength
        return (low, high) if s == 1.0 else (1.0 + s * (low - 1.0), 1.0 + s * (high - 1.0))

    # ---- observations -----------------------------------------------------------------------
    def filter_obs(self, observations: np.ndarray) -> np.ndarray:
        """(n, obs_dim) true observations after a step → (n, obs_dim) float32 as the policy
        sees them (delay, noise, stuck values, drops; the module docstring)."""
        idx = np.arange(self.n_envs)
        obs = np.asarray(observations, dtype=np.float32)
        if self.config.obs_delay:
            queue = self._obs_queue
            delayed = queue[:, 0].copy()
            queue[:, :-1] = queue[:, 1:]
            queue[:, -1] = obs
            obs = delayed
        reading = self._noisy(obs, idx)
        p_stuck = self._strength * self.config.obs_stuck_probability
        if self.config.obs_stuck_probability > 0:
            draws = np.stack([self._rng(i).random(self.obs_dim) for i in idx.tolist()])
            left = self._stuck_left
            left[(left == 0) & (draws < p_stuck)] = self.config.obs_stuck_steps
            stuck = left > 0
            reading = np.where(stuck, self._last_reading, reading)
            left[stuck] -= 1
        self._last_reading[...] = reading
        return self._dropped(reading, idx)

    def _rng(self, i: int) -> np.random.Generator:
        rng = self.rngs[i]
        if rng is None:
            raise RuntimeError(f"environment {i} was stepped before its first reset")
        return rng

    def _noisy(self, obs: np.ndarray, idx: np.ndarray) -> np.ndarray:
        if self.obs_sigma is None:
            return obs.astype(np.float32, copy=True)
        noise = np.stack([self._rng(i).standard_normal(self.obs_dim) for i in idx.tolist()])
        return (obs + self._strength * self.obs_sigma * noise).astype(np.float32)

    def _dropped(self, reading: np.ndarray, idx: np.ndarray) -> np.ndarray:
        p_drop = self._strength * self.config.obs_drop_probability
        if self.config.obs_drop_probability <= 0:
            return reading.copy()
        draws = np.stack([self._rng(i).random(self.obs_dim) for i in idx.tolist()])
        return np.where(draws < p_drop, np.float32(0.0), reading).astype(np.float32)

    # ---- actions and torques ----------------------------------------------------------------
    def filter_actions(self, actions: np.ndarray) -> np.ndarray:
        """(n, 12·A) clipped control values → (n, 12·A) float64 values the actuators apply
        (delay, first-order lag, rate limit; the module docstring)."""
        u = np.array(actions, dtype=np.float64)
        if self.max_delay:
            history = self._action_history
            history[:, :-1] = history[:, 1:]
            history[:, -1] = u
            u = history[np.arange(self.n_envs), self.max_delay - self.action_delays]
        if self.lag_alpha is not None:
            self._lagged += self.lag_alpha * (u - self._lagged)
            u = self._lagged.copy()
        if self.max_change is not None:
            step = np.clip(u - self._applied, -self.max_change, self.max_change)
            u = self._applied + step
        self._applied[...] = u
        return u

    def saturate_torques(self, torques: np.ndarray) -> None:
        """Clip (n, A, 2, n_elem) element torques, N·m, to ±torque_limit in place (no-op
        without a limit)."""
        limit = self.config.torque_limit
        if limit is not None:
            np.clip(torques, -limit, limit, out=torques)
