"""A trained sbx TD3/DDPG actor as plain NumPy, for validation's batched policy calls.

Validation runs one policy call per control step for a batch of 32 episodes (5,000 steps per
checkpoint). Through sbx each call crosses into JAX (dispatch, a device array, its copy back)
and took about half of a checkpoint's validation time; the same multilayer perceptron in NumPy
float32 (three small matrix products) takes a few percent of it
(``benchmarks/bench_validation.py``). Its rounding differs from XLA's in the last bits, as a
batch's differs from one row's, so evaluation keeps the model's own ``predict`` (its numbers
reproduce bit for bit) and only validation, which already batches, uses this.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from softtrack.evaluation.episodes import Policy

__all__ = ["numpy_actor"]


def numpy_actor(model: Any, normalizer: Any = None) -> Policy | None:
    """``model``'s deterministic actor with its weights as they are now, as a batched NumPy
    policy: (n, obs_dim) observations → (n, act_dim) actions in the action space's units (or
    (obs_dim,) → (act_dim,)), the observation first scaled by ``normalizer`` (a frozen
    ``VecNormalize``) if given.

    Returns ``None`` where the actor is not sbx TD3's plain perceptron (dense layers with ReLU,
    tanh on the output, a bounded action space): another backend, algorithm or activation;
    the caller then uses the model's own ``predict``."""
    policy: Any = getattr(model, "policy", None)
    layers = _dense_layers(policy)
    if layers is None:
        return None
    low = np.asarray(policy.action_space.low, dtype=np.float64)
    high = np.asarray(policy.action_space.high, dtype=np.float64)

    def act(observation: np.ndarray) -> np.ndarray:
        obs = observation if normalizer is None else normalizer.normalize_obs(observation)
        x = np.asarray(obs, dtype=np.float32)
        single = x.ndim == 1
        x = x.reshape(1, -1) if single else x
        for kernel, bias in layers[:-1]:
            x = np.maximum(x @ kernel + bias, np.float32(0.0))
        kernel, bias = layers[-1]
        squashed = np.clip(np.tanh(x @ kernel + bias), -1.0, 1.0).astype(np.float64)
        action = low + 0.5 * (squashed + 1.0) * (high - low)
        return action[0] if single else action

    act.accepts_batches = True  # type: ignore[attr-defined]
    return act


_PROBE = np.array([-2.0, -0.5, 0.0, 0.5, 3.0], dtype=np.float32)


def _is_relu(activation: Any) -> bool:
    """Whether ``activation`` (a loaded model's: not the ``flax.linen.relu`` object itself, a
    copy of it) is ReLU, by name and by its values on a few points."""
    name = getattr(activation, "__name__", "") or getattr(
        getattr(activation, "fun", None), "__name__", ""
    )
    try:
        values = np.asarray(activation(_PROBE), dtype=np.float32)
    except Exception:
        return False
    return name == "relu" and bool(np.array_equal(values, np.maximum(_PROBE, 0.0)))


def _dense_layers(policy: Any) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """The (kernel (in, out), bias (out,)) float32 pairs of an sbx TD3 actor, input to output;
    ``None`` if ``policy`` is not one this module can run. Nothing is imported for another
    backend's policy: importing JAX draws from NumPy's global generator, which Stable-Baselines3's
    action noise uses, and validation must leave training unchanged."""
    if not type(policy).__module__.startswith("sbx."):
        return None
    try:
        import jax
        from gymnasium import spaces
        from sbx.td3.policies import Actor
    except ImportError:
        return None
    actor = getattr(policy, "actor", None)
    state = getattr(policy, "actor_state", None)
    if (
        not isinstance(actor, Actor)
        or not _is_relu(actor.activation_fn)
        or state is None
        or not isinstance(policy.action_space, spaces.Box)
        or not policy.squash_output
    ):
        return None
    params = jax.device_get(state.params).get("params", {})
    names = [f"Dense_{k}" for k in range(len(actor.net_arch) + 1)]
    if set(params) != set(names):
        return None
    return [
        (
            np.asarray(params[name]["kernel"], dtype=np.float32),
            np.asarray(params[name]["bias"], dtype=np.float32),
        )
        for name in names
    ]
