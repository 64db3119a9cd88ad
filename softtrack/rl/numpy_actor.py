"""A trained sbx TD3/DDPG, SAC/TQC or CrossQ actor as plain NumPy, for validation's batched policy calls.

Validation runs one policy call per control step for a batch of 32 episodes (5,000 steps per
checkpoint). Through sbx each call crosses into JAX (dispatch, a device array, its copy back)
and took about half of a checkpoint's validation time; the same multilayer perceptron in NumPy
float32 (three small matrix products) takes a few percent of it
(``benchmarks/bench_validation.py``). Its rounding differs from XLA's in the last bits, as a
batch's differs from one row's, so evaluation keeps the model's own ``predict`` (its numbers
reproduce bit for bit) and only validation, which already batches, uses this.

CrossQ's actor normalises its input and every hidden layer with batch renormalisation; in
evaluation each of those is an affine map per feature (its running mean and variance, its scale
and bias), which folds into the next dense layer's kernel and bias, and its deterministic action
is the tanh of the Gaussian's mean. SAC's and TQC's actor (sbx ``SquashedGaussianActor``) is a
plain perceptron with a mean and a log-std head; its deterministic action is the tanh of the mean
too. So every one of these actors runs as the same few matrix products.
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

    Returns ``None`` where the actor is not sbx TD3's, SAC's/TQC's or CrossQ's perceptron (dense layers
    with ReLU, tanh on the output, a bounded action space): another backend, algorithm or
    activation; the caller then uses the model's own ``predict``."""
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
    """The (kernel (in, out), bias (out,)) float32 pairs of an sbx TD3, SAC/TQC or CrossQ actor,
    input to output (CrossQ's normalisations folded in, the Gaussian actors' log-std head left
    out); ``None`` if ``policy`` is not one this module can run. Nothing is imported for another
    backend's policy: importing JAX draws from NumPy's global generator, which
    Stable-Baselines3's action noise uses, and validation must leave training unchanged."""
    if not type(policy).__module__.startswith("sbx."):
        return None
    try:
        import jax
        from gymnasium import spaces
        from sbx.common.policies import SquashedGaussianActor
        from sbx.crossq.policies import Actor as CrossQActor
        from sbx.td3.policies import Actor
    except ImportError:
        return None
    actor = getattr(policy, "actor", None)
    state = getattr(policy, "actor_state", None)
    if (
        not isinstance(actor, (Actor, CrossQActor, SquashedGaussianActor))
        or not _is_relu(actor.activation_fn)
        or state is None
        or not isinstance(policy.action_space, spaces.Box)
        or not policy.squash_output
    ):
        return None
    if isinstance(actor, CrossQActor):  # its parameters are not nested under "params"
        stats = jax.device_get(getattr(state, "batch_stats", None))
        params = jax.device_get(state.params)
        return _crossq_layers(params, stats, len(actor.net_arch), actor.use_batch_norm)
    params = jax.device_get(state.params).get("params", {})
    heads = 2 if isinstance(actor, SquashedGaussianActor) else 1  # the mean's, the log-std's
    names = [f"Dense_{k}" for k in range(len(actor.net_arch) + heads)]
    if set(params) != set(names):
        return None
    return [_dense(params[name]) for name in names[: len(actor.net_arch) + 1]]


def _dense(layer: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    return (
        np.asarray(layer["kernel"], dtype=np.float32),
        np.asarray(layer["bias"], dtype=np.float32),
    )


_RENORM_EPSILON = 1e-3  # sbx's BatchRenorm default, which its CrossQ actor keeps


def _crossq_layers(
    params: dict[str, Any], stats: Any, n_hidden: int, batch_norm: bool
) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """CrossQ's actor (sbx ``crossq.policies.Actor``) as dense layers: n_hidden hidden ones and
    the Gaussian mean's (``Dense_{n_hidden}``; the log-std head does not act), each batch
    renormalisation before a layer folded into it."""
    dense = [f"Dense_{k}" for k in range(n_hidden + 2)]
    # without batch norm the actor still builds an unused first renormalisation
    renorm = [f"BatchRenorm_{k}" for k in range(n_hidden + 1 if batch_norm else 1)]
    if not isinstance(params, dict) or set(params) != set(dense) | set(renorm):
        return None
    if batch_norm and (not isinstance(stats, dict) or not set(renorm) <= set(stats)):
        return None
    layers = []
    for k in range(n_hidden + 1):
        kernel, bias = _dense(params[dense[k]])
        if batch_norm:
            # y = (x − μ)·s/√(σ² + ε) + b = x·a + c, then (x·a + c)·K + β = x·(a K) + (c K + β)
            mean = np.asarray(stats[renorm[k]]["mean"], dtype=np.float64)
            var = np.asarray(stats[renorm[k]]["var"], dtype=np.float64)
            scale = np.asarray(params[renorm[k]]["scale"], dtype=np.float64)
            shift = np.asarray(params[renorm[k]]["bias"], dtype=np.float64)
            a = scale / np.sqrt(var + _RENORM_EPSILON)
            c = shift - mean * a
            kernel64 = kernel.astype(np.float64)
            kernel, bias = (
                (a[:, None] * kernel64).astype(np.float32),
                (c @ kernel64 + bias).astype(np.float32),
            )
        layers.append((kernel, bias))
    return layers
