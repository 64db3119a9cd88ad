"""A learning rate that falls linearly over training (``algo.learning_rate_final``), for sbx's
TD3 and DDPG.

sbx builds their optimizers with a constant rate (``optax.adam(learning_rate=...)``) and never
changes it. With ``learning_rate_final`` the factory builds them through :func:`settable_adam`
(Adam whose rate is a hyperparameter of its state), and a training callback sets that
rate on the actor's and the critics' optimizers
(:class:`softtrack.rl.callbacks.LearningRateDecay`) after every vectorised env step, before the
updates that follow it:

    lr(t) = lr₀                                      for t ≤ f·T
    lr(t) = lr₀ + (lr₁ − lr₀)·(t − f·T) / (T − f·T)  for f·T < t ≤ T

with t the env steps so far, T ``total_timesteps``, f ``learning_rate_decay_from``, lr₀
``learning_rate`` and lr₁ ``learning_rate_final``. The rate is a function of the env step alone,
so a resumed run continues on the same schedule.
"""

from __future__ import annotations

from typing import Any

__all__ = ["learning_rate_at", "settable_adam"]


def settable_adam(learning_rate: float, **kwargs: Any) -> Any:
    """optax's Adam with its learning rate in the optimizer state (``optax.inject_hyperparams``),
    where :class:`softtrack.rl.callbacks.LearningRateDecay` changes it; the same updates as ``optax.adam`` at a
    constant rate. A module-level function, so saved models pickle it by name."""
    import optax

    return optax.inject_hyperparams(optax.adam)(learning_rate=learning_rate, **kwargs)


def learning_rate_at(
    step: int, total: int, initial: float, final: float, decay_from: float = 0.0
) -> float:
    """The learning rate after ``step`` of ``total`` env steps (module docstring's lr(t))."""
    start = decay_from * total
    if step <= start or total <= start:
        return float(initial)
    fraction = min(1.0, (step - start) / (total - start))
    return float(initial + (final - initial) * fraction)
