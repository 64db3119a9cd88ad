"""A learning rate that falls linearly over training (``algo.learning_rate_final``), for sbx's
TD3 and DDPG.

sbx builds their optimizers with a constant rate (``optax.adam(learning_rate=...)``) and never
changes it. With ``learning_rate_final`` the factory builds them through :func:`settable_adam`
(Adam whose rate is a hyperparameter of its state), and :class:`LearningRateDecay` sets that
rate on the actor's and the critics' optimizers after every vectorised env step, before the
updates that follow it:

    lr(t) = lr₀                                      for t ≤ f·T
    lr(t) = lr₀ + (lr₁ − lr₀)·(t − f·T) / (T − f·T)  for f·T < t ≤ T

with t the env steps so far, T ``total_timesteps``, f ``learning_rate_decay_from``, lr₀
``learning_rate`` and lr₁ ``learning_rate_final``. The rate is a function of the env step alone,
so a resumed run continues on the same schedule.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

__all__ = ["LearningRateDecay", "learning_rate_at", "settable_adam"]


def settable_adam(learning_rate: float, **kwargs: Any) -> Any:
    """optax's Adam with its learning rate in the optimizer state (``optax.inject_hyperparams``),
    where :class:`LearningRateDecay` changes it; the same updates as ``optax.adam`` at a
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


class LearningRateDecay(BaseCallback):
    """Sets the learning rate of an sbx TD3/DDPG model's actor and critic optimizers (built with
    :func:`settable_adam`) from the env steps so far, at the start and after each vectorised
    step (so before the updates that follow it).

    Args:
        total_timesteps: T, the run's budget (env steps).
        initial: lr₀. final: lr₁. decay_from: f, the fraction of T where the decay starts.
    """

    def __init__(self, total_timesteps: int, initial: float, final: float, decay_from: float):
        super().__init__(verbose=0)
        self.total_timesteps = int(total_timesteps)
        self.initial, self.final, self.decay_from = float(initial), float(final), float(decay_from)

    def _set_rate(self) -> None:
        rate = learning_rate_at(
            int(self.model.num_timesteps),
            self.total_timesteps,
            self.initial,
            self.final,
            self.decay_from,
        )
        policy: Any = self.model.policy
        for state in (policy.actor_state, policy.qf_state):
            hyperparams = getattr(state.opt_state, "hyperparams", None)
            if hyperparams is None or "learning_rate" not in hyperparams:
                raise ValueError(
                    "a decaying learning rate needs optimizers built by "
                    "softtrack.rl.learning_rate.settable_adam"
                )
            # a float32 array: the jitted update sees the same argument type every time
            hyperparams["learning_rate"] = np.asarray(rate, dtype=np.float32)
        self.logger.record("train/learning_rate", rate)

    def _on_training_start(self) -> None:
        self._set_rate()

    def _on_step(self) -> bool:
        self._set_rate()
        return True
