"""TD3 whose actor pays for leaving tanh's linear range (JAX backend), selected by
``algo.actor_preactivation_penalty``.

SBX's TD3 actor ends in a = tanh(u), u = W·h + b, and maximises min_j Q_j(s, π(s)). Once a
control value reaches ±1, ∂a/∂u = 1 − a² vanishes, so no later gradient of Q brings it
back: the policy goes bang-bang and stays there, whatever the reward says about large actions
(a penalty on a in the reward has the same vanishing gradient). This variant adds to the actor
loss the mean square of the pre-activations,

    L(θ) = −mean_batch min_j Q_j(s, π_θ(s)) + λ · mean_{batch, 24 actions} u²,

which keeps u, and so a, where the gradient lives unless the critic pays for more. Behind an
actuator limit (``env.realism.torque_limit``) the critic learns that control values beyond the
limit buy nothing, and the penalty pulls them back.

Only training changes: the actor network, its parameters and ``predict`` are SBX's, and a saved
model file names SBX's actor (:meth:`PreactivationPenaltyTD3.save`), so a checkpoint or an
inference copy loads with plain ``sbx.TD3.load``; loading with this class restores the
penalty. The factory builds it through the variants'
registry (:mod:`softtrack.rl.variants`, variant ``actor_preactivation_penalty``).
"""

from __future__ import annotations

from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
from sbx import TD3
from sbx.common.policies import Flatten
from sbx.common.type_aliases import RLTrainState
from sbx.td3.policies import Actor

__all__ = ["PenalisedActor", "PreactivationPenaltyTD3"]

PENALTY_COLLECTION = "losses"


class PenalisedActor(nn.Module):
    """SBX's TD3 actor (same layers and parameter names: observations (batch, obs) → actions
    (batch, action_dim) in [−1, 1]) that also sows λ·mean(u²) of its pre-activations u into the
    ``losses`` collection when that collection is mutable."""

    net_arch: Any
    action_dim: int
    activation_fn: Any = nn.relu
    preactivation_penalty: float = 0.0

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        x = Flatten()(x)
        for n_units in self.net_arch:
            x = self.activation_fn(nn.Dense(n_units)(x))
        preactivation = nn.Dense(self.action_dim)(x)
        self.sow(
            PENALTY_COLLECTION,
            "preactivation",
            self.preactivation_penalty * jnp.mean(preactivation**2),
        )
        return nn.tanh(preactivation)


class PreactivationPenaltyTD3(TD3):
    """SBX's TD3 with the pre-activation penalty of the module docstring in its actor loss.

    Args:
        preactivation_penalty: λ ≥ 0, the weight of mean(u²) in the actor loss [-].
        (the others as :class:`sbx.TD3`.)
    """

    preactivation_penalty: float = 0.0  # what a model saved without the attribute loads with

    def __init__(self, *args: Any, preactivation_penalty: float = 0.0, **kwargs: Any) -> None:
        if preactivation_penalty < 0:
            raise ValueError(f"preactivation_penalty must be ≥ 0, got {preactivation_penalty}")
        self.preactivation_penalty = float(preactivation_penalty)
        super().__init__(*args, **kwargs)

    def _setup_model(self) -> None:
        super()._setup_model()
        self._set_actor(
            PenalisedActor(**self._actor_fields(), preactivation_penalty=self.preactivation_penalty)
        )

    def save(self, *args: Any, **kwargs: Any) -> None:
        """SB3's ``save``, with SBX's own actor module in the file (module docstring)."""
        penalised = self.policy.actor_state
        self._set_actor(Actor(**self._actor_fields()))
        try:
            super().save(*args, **kwargs)
        finally:
            self.policy.actor_state = penalised

    def _actor_fields(self) -> dict[str, Any]:
        return {
            "net_arch": self.policy.net_arch_pi,
            "action_dim": int(np.prod(self.action_space.shape)),
            "activation_fn": self.policy.activation_fn,
        }

    def _set_actor(self, actor: nn.Module) -> None:
        self.policy.actor_state = self.policy.actor_state.replace(apply_fn=actor.apply)

    @staticmethod
    @jax.jit
    def update_actor(
        actor_state: RLTrainState,
        qf_state: RLTrainState,
        observations: jax.Array,
        key: jax.Array,
    ) -> tuple[RLTrainState, RLTrainState, jax.Array, jax.Array]:
        """One actor step on observations (batch, obs): SBX's loss plus the sown penalty."""
        key, dropout_key = jax.random.split(key, 2)

        def actor_loss(params: Any) -> jax.Array:
            actions, sown = actor_state.apply_fn(params, observations, mutable=[PENALTY_COLLECTION])
            q = qf_state.apply_fn(
                qf_state.params, observations, actions, rngs={"dropout": dropout_key}
            )
            penalty = sum(jax.tree_util.tree_leaves(sown), jnp.zeros(()))
            return -jnp.min(q, axis=0).mean() + penalty

        loss_value, grads = jax.value_and_grad(actor_loss)(actor_state.params)
        return actor_state.apply_gradients(grads=grads), qf_state, loss_value, key
