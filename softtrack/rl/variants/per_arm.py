"""TD3 with one critic output per arm (JAX backend), selected by ``algo.critic: per_arm``.

The study's TD3 learns Q(s, a) of the summed reward r = Σᵢ rᵢ (docs/environment.md). Here each of the twin
critics j has A outputs Q_{j,i}(s, a), one per arm i, trained on arm i's share rᵢ of the reward
(:func:`softtrack.env.reward.reward_shares`) with the TD3 target

    yᵢ = rᵢ + γ·(1 − done)·min_j Q'_{j,i}(s', π'(s') + clipped noise),

and the actor maximises Σᵢ min_j Q_{j,i}(s, π(s)). Arm i's critic output then carries no noise
from the other arm's reward (one summed reward cannot tell which arm earned it), while the
centralized actor still sees both arms and the target. The policy network, its actions and the
evaluation are those of plain TD3.

With ``per_arm_networks`` the networks are split by arm as well: arm i's actions come from its
own actor MLP and its Q-values from its own twin critic MLPs, each seeing the full observation
(and the critics all A·12 actions). That is the independent baseline's per-arm networks and
capacity, with the centralized observation and the shared reward's credit. With
``actor_observation: own_arm`` as well, arm i's actor sees only arm i's 37 observation values
and the target's 7 (the independent baseline's input) while its critics still see everything:
centralized training, decentralized execution.

The factory builds it through the variants' registry (:mod:`softtrack.rl.variants`, variant
``per_arm_critic``): :class:`PerArmTD3` in place of TD3, its options as constructor arguments,
and an environment that reports the reward shares.
"""

from __future__ import annotations

from typing import Any, ClassVar

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces
from sbx import TD3
from sbx.common.policies import VectorCritic
from sbx.common.type_aliases import ReplayBufferSamplesNp, RLTrainState
from sbx.td3.policies import Actor, TD3Policy
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.type_aliases import ReplayBufferSamples

from softtrack.env.observation import arm_view_columns
from softtrack.env.vec_env import REWARD_SHARES_KEY

__all__ = [
    "PerArmActor",
    "PerArmCritic",
    "PerArmTD3",
    "PerArmTD3Policy",
    "RewardShareReplayBuffer",
]


class RewardShareReplayBuffer(ReplayBuffer):
    """SB3 replay buffer that also keeps ``info["reward_shares"]`` and samples it as the reward.

    Samples hold ``rewards`` of shape (batch, n_shares), the per-arm shares of each transition's
    reward, instead of SB3's (batch, 1), and ``discounts`` of shape (batch, 1), the factor of
    the bootstrapped target. The environment must report the shares in every step's info
    (``TrackingVecEnv(reward_shares=True)``).

    With ``n_steps`` > 1 each share is an n-step return, Σ_{k<m} γᵏ·r_{i,t+k} up to the
    episode's end (m ≤ n), bootstrapped from the m-th next observation with γᵐ: SB3's
    :class:`~stable_baselines3.common.buffers.NStepReplayBuffer` (``algo.n_step_returns``)
    applied to every share. With ``n_steps`` = 1 it samples exactly as SB3's one-step buffer.

    Args:
        n_shares: A, the number of reward shares (arms).
        n_steps: n of the n-step returns (1 = one-step TD targets).
        gamma: the discount γ of the n-step returns.
        (the others as :class:`stable_baselines3.common.buffers.ReplayBuffer`; the
        memory-optimised variant is not supported.)
    """

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        device: Any = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        n_shares: int = 2,
        n_steps: int = 1,
        gamma: float = 0.99,
    ) -> None:
        if n_steps < 1:
            raise ValueError(f"n_steps must be at least 1, not {n_steps}")
        if optimize_memory_usage:
            raise ValueError("RewardShareReplayBuffer does not support optimize_memory_usage")
        super().__init__(
            buffer_size,
            observation_space,
            action_space,
            device,
            n_envs,
            optimize_memory_usage,
            handle_timeout_termination,
        )
        self.reward_shares = np.zeros((self.buffer_size, self.n_envs, n_shares), dtype=np.float32)
        self.n_steps = n_steps
        self.gamma = gamma

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        try:
            shares = [info[REWARD_SHARES_KEY] for info in infos]
        except KeyError:
            raise ValueError(
                f"per-arm critics need info[{REWARD_SHARES_KEY!r}] from the environment; "
                "build it as TrackingVecEnv(..., reward_shares=True)"
            ) from None
        self.reward_shares[self.pos] = np.asarray(shares, dtype=np.float32)
        super().add(obs, next_obs, action, reward, done, infos)

    def _get_samples(self, batch_inds: np.ndarray, env: Any = None) -> ReplayBufferSamples:
        env_indices = np.random.randint(0, high=self.n_envs, size=(len(batch_inds),))
        # buffers pickled before n-step returns were one-step
        n_steps, gamma = getattr(self, "n_steps", 1), getattr(self, "gamma", 0.99)
        # the newest slot may continue into the oldest one's episode: cut every sequence there
        newest = self.pos - 1
        newest_timeouts = self.timeouts[newest].copy()
        self.timeouts[newest] = np.logical_or(newest_timeouts, np.logical_not(self.dones[newest]))
        try:
            indices = (batch_inds[:, None] + np.arange(n_steps)[None, :]) % self.buffer_size
            ended = np.logical_or(
                self.dones[indices, env_indices[:, None]],
                self.timeouts[indices, env_indices[:, None]],
            )  # (batch, n_steps)
            last = np.where(ended.any(axis=1), ended.argmax(axis=1), n_steps - 1)  # (batch,)
            kept = np.arange(n_steps)[None, :] <= last[:, None]  # (batch, n_steps)
            weights = (gamma ** np.arange(n_steps, dtype=np.float32))[None, :] * kept
            shares = self.reward_shares[indices, env_indices[:, None], :]  # (batch, n, A)
            returns = (shares * weights[:, :, None]).sum(axis=1, dtype=np.float32)  # (batch, A)
            discounts = gamma ** kept.sum(axis=1, keepdims=True).astype(np.float32)  # (batch, 1)
            final = (batch_inds + last) % self.buffer_size
            not_timeout = 1 - self.timeouts[final, env_indices]
            data = (
                self._normalize_obs(self.observations[batch_inds, env_indices, :], env),
                self.actions[batch_inds, env_indices, :],
                self._normalize_obs(self.next_observations[final, env_indices, :], env),
                (self.dones[final, env_indices] * not_timeout).reshape(-1, 1),
                returns,
                discounts,
            )
        finally:
            self.timeouts[newest] = newest_timeouts
        return ReplayBufferSamples(*tuple(map(self.to_torch, data)))


class PerArmActor(nn.Module):
    """One actor MLP per arm: observations (batch, obs) → actions (batch, n_arms·arm_action_dim),
    arm i's block from its own network (SBX's TD3 :class:`~sbx.td3.policies.Actor`).

    Attributes:
        arm_inputs: None = every network sees the whole observation; otherwise
            (n_arms, k) observation columns, row i what arm i's network sees.
    """

    net_arch: Any
    arm_action_dim: int
    n_arms: int
    activation_fn: Any = nn.relu
    arm_inputs: tuple[tuple[int, ...], ...] | None = None

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        if self.arm_inputs is None:
            inputs, in_axis = x, None
        else:
            columns = jnp.asarray(self.arm_inputs)  # (n_arms, k)
            inputs, in_axis = jnp.moveaxis(jnp.take(x, columns, axis=-1), -2, 0), 0
        actors = nn.vmap(
            Actor,
            variable_axes={"params": 0},
            split_rngs={"params": True},
            in_axes=in_axis,
            out_axes=0,
            axis_size=self.n_arms,
        )(net_arch=self.net_arch, action_dim=self.arm_action_dim, activation_fn=self.activation_fn)
        per_arm = actors(inputs)  # (n_arms, batch, arm_action_dim)
        return jnp.concatenate(list(per_arm), axis=-1)


class PerArmCritic(nn.Module):
    """n_critics twin critic MLPs per arm: (observations, actions) → Q (n_critics, batch, n_arms),
    column i from arm i's own networks (SBX's :class:`~sbx.common.policies.VectorCritic`)."""

    net_arch: Any
    n_arms: int
    n_critics: int = 2
    use_layer_norm: bool = False
    dropout_rate: float | None = None
    activation_fn: Any = nn.relu

    @nn.compact
    def __call__(self, obs: jax.Array, action: jax.Array) -> jax.Array:
        q = VectorCritic(
            net_arch=self.net_arch,
            use_layer_norm=self.use_layer_norm,
            dropout_rate=self.dropout_rate,
            n_critics=self.n_critics * self.n_arms,
            activation_fn=self.activation_fn,
        )(obs, action)  # (n_critics·n_arms, batch, 1)
        q = q[..., 0].reshape(self.n_critics, self.n_arms, -1)
        return jnp.swapaxes(q, 1, 2)


class PerArmTD3Policy(TD3Policy):
    """SBX's TD3 policy whose twin critics output one Q-value per reward share.

    Args:
        n_reward_shares: A, outputs per critic (one per arm).
        per_arm_networks: one actor MLP and one twin critic pair per arm (module docstring)
            instead of one actor and one twin critic pair with A outputs.
        actor_observation: with per_arm_networks, ``full`` (each actor sees the whole
            observation) or ``own_arm`` (its arm's block and the target's, module docstring).
        (the others as :class:`sbx.td3.policies.TD3Policy`.)
    """

    # what policies pickled before these options unpickle with
    per_arm_networks: bool = False
    actor_observation: str = "full"

    def __init__(
        self,
        *args: Any,
        n_reward_shares: int = 2,
        per_arm_networks: bool = False,
        actor_observation: str = "full",
        **kwargs: Any,
    ) -> None:
        super().__init__(*args, **kwargs)
        if actor_observation not in ("full", "own_arm"):
            raise ValueError(f"actor_observation {actor_observation!r} is not full or own_arm")
        self.n_reward_shares = n_reward_shares
        self.per_arm_networks = per_arm_networks
        self.actor_observation = actor_observation

    def build(self, key: jax.Array, lr_schedule: Any, qf_learning_rate: float) -> jax.Array:
        key = super().build(key, lr_schedule, qf_learning_rate)
        key, qf_key, dropout_key = jax.random.split(key, 3)
        obs = jnp.array([self.observation_space.sample()])
        action = jnp.array([self.action_space.sample()])
        critic: dict[str, Any] = {
            "net_arch": self.net_arch_qf,
            "n_critics": self.n_critics,
            "use_layer_norm": self.layer_norm,
            "dropout_rate": self.dropout_rate,
            "activation_fn": self.activation_fn,
        }
        if self.per_arm_networks:
            key, actor_key = jax.random.split(key)
            self._build_per_arm_actor(actor_key, obs, lr_schedule)
            # sbx types qf by its own build (VectorCritic); PerArmCritic is called alike
            self.qf = PerArmCritic(  # type: ignore[assignment]
                n_arms=self.n_reward_shares, **critic
            )
        else:
            self.qf = VectorCritic(output_dim=self.n_reward_shares, **critic)
        params = self.qf.init({"params": qf_key, "dropout": dropout_key}, obs, action)
        self.qf_state = RLTrainState.create(
            apply_fn=self.qf.apply,
            params=params,
            target_params=params,
            # sbx keeps SB3's annotation of optimizer_class (a torch optimizer); it is optax's
            tx=self.optimizer_class(  # type: ignore[call-arg]
                learning_rate=qf_learning_rate, **self.optimizer_kwargs
            ),
        )
        self.qf.apply = jax.jit(  # type: ignore[method-assign]
            self.qf.apply, static_argnames=("dropout_rate", "use_layer_norm")
        )
        return key

    def _build_per_arm_actor(self, key: jax.Array, obs: jax.Array, lr_schedule: Any) -> None:
        action_dim = int(np.prod(self.action_space.shape))
        if action_dim % self.n_reward_shares:
            raise ValueError(
                f"{action_dim} actions do not split into {self.n_reward_shares} equal arm blocks"
            )
        arm_inputs = None
        if self.actor_observation == "own_arm":
            obs_dim = int(obs.shape[-1])
            arm_inputs = tuple(
                tuple(int(c) for c in arm_view_columns(arm, self.n_reward_shares, obs_dim))
                for arm in range(self.n_reward_shares)
            )
        # sbx types actor by its own build (Actor); PerArmActor is called alike
        self.actor = PerArmActor(  # type: ignore[assignment]
            net_arch=self.net_arch_pi,
            arm_action_dim=action_dim // self.n_reward_shares,
            n_arms=self.n_reward_shares,
            activation_fn=self.activation_fn,
            arm_inputs=arm_inputs,
        )
        params = self.actor.init(key, obs)
        self.actor_state = RLTrainState.create(
            apply_fn=self.actor.apply,
            params=params,
            target_params=params,
            # as in build: optax's optimizer_class under SB3's torch annotation
            tx=self.optimizer_class(  # type: ignore[call-arg]
                learning_rate=lr_schedule(1), **self.optimizer_kwargs
            ),
        )
        self.actor.apply = jax.jit(self.actor.apply)  # type: ignore[method-assign]


def _discounts(sampled: Any, n: int, gamma: float) -> np.ndarray:
    """(n,) float32 bootstrap factors: the buffer's sampled ones, or γ for a buffer without."""
    if sampled is None:
        return np.full((n,), gamma, dtype=np.float32)
    return np.asarray(sampled.numpy(), dtype=np.float32).reshape(n)


class PerArmTD3(TD3):
    """SBX's TD3 with per-arm critic outputs (module docstring); same constructor arguments.

    The actor update is SBX's: its loss −mean over the batch and the A outputs of
    min_j Q_{j,i}(s, π(s)) is −(1/A)·Σᵢ min_j Q_{j,i}, the module's objective up to a constant
    factor, to which Adam is invariant.

    Args:
        n_reward_shares: A, the number of arms whose reward shares the critics learn.
        per_arm_networks: one actor and one twin critic pair per arm (:class:`PerArmTD3Policy`).
        actor_observation: what each arm's actor sees, ``full`` or ``own_arm``
            (:class:`PerArmTD3Policy`).
        n_steps: n of the n-step returns each share's critic learns from
            (:class:`RewardShareReplayBuffer`).
    """

    policy_aliases: ClassVar[dict[str, type[TD3Policy]]] = {"MlpPolicy": PerArmTD3Policy}

    def __init__(
        self,
        policy: Any,
        env: Any,
        *args: Any,
        n_reward_shares: int = 2,
        per_arm_networks: bool = False,
        actor_observation: str = "full",
        replay_buffer_kwargs: dict[str, Any] | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        **kwargs: Any,
    ) -> None:
        self.n_reward_shares = n_reward_shares
        policy_kwargs = {**(policy_kwargs or {}), "n_reward_shares": n_reward_shares}
        # absent at their defaults: models saved before the options load alike
        if per_arm_networks:
            policy_kwargs["per_arm_networks"] = True
        if actor_observation != "full":
            if not per_arm_networks:
                raise ValueError("actor_observation other than full needs per_arm_networks")
            policy_kwargs["actor_observation"] = actor_observation
        buffer_kwargs = {**(replay_buffer_kwargs or {}), "n_shares": n_reward_shares}
        n_steps = kwargs.pop("n_steps", 1)  # SB3 ignores it beside a buffer class of our own
        if n_steps > 1:
            buffer_kwargs.update(n_steps=n_steps, gamma=kwargs.get("gamma", 0.99))
        # through kwargs: mypy cannot tell that *args stops before these parameters
        kwargs.update(
            replay_buffer_class=RewardShareReplayBuffer,
            replay_buffer_kwargs=buffer_kwargs,
            policy_kwargs=policy_kwargs,
        )
        super().__init__(policy, env, *args, **kwargs)

    def train(self, gradient_steps: int, batch_size: int) -> None:
        assert self.replay_buffer is not None
        sample = self.replay_buffer.sample(batch_size * gradient_steps, env=self._vec_normalize_env)
        self._maybe_reset_params()
        data = ReplayBufferSamplesNp(
            sample.observations.numpy(),
            sample.actions.numpy(),
            sample.next_observations.numpy(),
            sample.dones.numpy().flatten(),
            sample.rewards.numpy(),  # (batch·gradient_steps, A): not flattened
            _discounts(sample.discounts, batch_size * gradient_steps, self.gamma),
        )
        (
            self.policy.qf_state,
            self.policy.actor_state,
            self.key,
            (actor_loss, critic_loss),
        ) = self._train(
            self.tau,
            gradient_steps,
            data,
            self.policy_delay,
            (self._n_updates + 1) % self.policy_delay,
            self.target_policy_noise,
            self.target_noise_clip,
            self.policy.qf_state,
            self.policy.actor_state,
            self.key,
        )
        self._n_updates += gradient_steps
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/actor_loss", actor_loss.item())
        self.logger.record("train/critic_loss", critic_loss.item())

    @staticmethod
    @jax.jit
    def update_critic(
        actor_state: RLTrainState,
        qf_state: RLTrainState,
        observations: jax.Array,
        actions: jax.Array,
        next_observations: jax.Array,
        rewards: jax.Array,
        dones: jax.Array,
        discounts: jax.Array,
        target_policy_noise: float,
        target_noise_clip: float,
        key: jax.Array,
    ) -> tuple[RLTrainState, jax.Array, jax.Array]:
        """One critic step on a batch: rewards (batch, A), dones and discounts (batch,)."""
        key, noise_key, dropout_key_target, dropout_key_current = jax.random.split(key, 4)
        next_actions = actor_state.apply_fn(actor_state.target_params, next_observations)
        noise = jax.random.normal(noise_key, actions.shape) * target_policy_noise
        noise = jnp.clip(noise, -target_noise_clip, target_noise_clip)
        next_actions = jnp.clip(next_actions + noise, -1.0, 1.0)
        next_q = qf_state.apply_fn(
            qf_state.target_params,
            next_observations,
            next_actions,
            rngs={"dropout": dropout_key_target},
        )  # (n_critics, batch, A)
        bootstrap = ((1 - dones) * discounts)[:, None]
        target_q = rewards + bootstrap * jnp.min(next_q, axis=0)  # (batch, A)

        def loss(params: Any, dropout_key: jax.Array) -> jax.Array:
            q = qf_state.apply_fn(params, observations, actions, rngs={"dropout": dropout_key})
            return 0.5 * ((target_q - q) ** 2).mean(axis=1).sum()

        loss_value, grads = jax.value_and_grad(loss)(qf_state.params, dropout_key_current)
        return qf_state.apply_gradients(grads=grads), loss_value, key
