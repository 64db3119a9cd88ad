"""The algorithm section of a spec: the RL algorithm, its hyperparameters (rl-baselines3-zoo
key names) and its network architecture. See :mod:`softtrack.spec`."""

from __future__ import annotations

import copy
import re
from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from softtrack.spec.fields import Float, Int, SpecModel, custom_error, section_field, unit_field

OFF_POLICY_ALGOS = frozenset({"td3", "ddpg", "sac", "tqc", "crossq"})
# Off-policy algorithms with a stochastic (squashed Gaussian) policy and an entropy bonus: they
# explore by sampling their policy, so noise_type / noise_std do not apply to them.
ENTROPY_ALGOS = frozenset({"sac", "tqc", "crossq"})
# policy_kwargs keys beyond net_arch and activation_fn, by the algorithm that takes them.
_POLICY_KWARGS_OF = {
    "tqc": ("n_quantiles", "n_critics"),
    "crossq": ("batch_norm", "batch_norm_actor", "batch_norm_momentum", "renorm_warmup_steps"),
}

NetArch = (
    list[Annotated[int, Field(ge=1)]]
    | dict[Literal["pi", "vf", "qf"], list[Annotated[int, Field(ge=1)]]]
)
_ACTIVATIONS = {
    # spec name: (torch.nn class name, jax.nn function name)
    "relu": ("ReLU", "relu"),
    "tanh": ("Tanh", "tanh"),
    "elu": ("ELU", "elu"),
    "leaky_relu": ("LeakyReLU", "leaky_relu"),
    "gelu": ("GELU", "gelu"),
    "silu": ("SiLU", "silu"),
}


class PolicyKwargsSpec(SpecModel):
    """``policy_kwargs`` of the SB3 policy, as data (rl-zoo writes them as Python; we do not eval)."""

    net_arch: NetArch = unit_field(
        [64, 64],
        "hidden layer sizes of actor and critic(s); a list for all networks, or a mapping "
        "{pi: [...], qf: [...]} (off-policy) / {pi: [...], vf: [...]} (PPO)",
        "units per layer",
    )
    activation_fn: Literal["relu", "tanh", "elu", "leaky_relu", "gelu", "silu"] = unit_field(
        "relu", "activation of the hidden layers", "-"
    )
    # tqc (sb3: sb3-contrib's TQC; sbx: sbx's TQC)
    n_quantiles: Int = unit_field(
        25, "quantiles each critic predicts of the return distribution (tqc)", "quantiles", ge=1
    )
    n_critics: Int = unit_field(
        2,
        "critic networks (tqc); backend sbx implements exactly 2",
        "critics",
        ge=1,
    )
    log_std_init: Float = unit_field(
        0.0,
        "initial log standard deviation of the Gaussian policy (ppo): -4 explores with std "
        "0.018 where a fine grip needs it",
        "log action units",
    )
    layer_norm: bool = unit_field(
        False,
        "layer normalisation in the critics' hidden layers (off-policy, backend sbx)",
        "-",
    )
    # crossq (sbx only)
    batch_norm: bool = unit_field(
        True,
        "batch renormalisation layers in the critics (crossq; its critics have no target networks)",
        "-",
    )
    batch_norm_actor: bool = unit_field(
        True, "batch renormalisation layers in the actor (crossq)", "-"
    )
    batch_norm_momentum: Float = unit_field(
        0.99,
        "momentum of the batch renormalisation running statistics (crossq)",
        "-",
        ge=0,
        lt=1,
    )
    renorm_warmup_steps: Int = unit_field(
        100_000,
        "training passes of a batch renormalisation layer before its corrections apply (crossq)",
        "gradient steps",
        ge=0,
    )


class AlgoSpec(SpecModel):
    """The RL algorithm and its hyperparameters, with rl-baselines3-zoo key names.

    Defaults are the study's TD3 settings (docs/environment.md) for every off-policy algorithm (network,
    learning rate, batch, gamma, tau, buffer, warm-up); the keys of one algorithm only default
    to its library's values (PPO's to SB3's, TQC's and SAC's to SB3/sb3-contrib's and sbx's,
    CrossQ's to sbx's; ``policy_delay`` is 3 for crossq where not given). Keys an algorithm does
    not use are ignored for it (see :meth:`sb3_kwargs`).
    """

    name: Literal["td3", "ddpg", "ppo", "sac", "tqc", "crossq"] = unit_field(
        "td3",
        "algorithm; tqc with backend sb3 is sb3-contrib's TQC, crossq is in sbx only (backend sbx)",
        "-",
    )
    backend: Literal["sb3", "sbx"] = unit_field(
        "sb3", "implementation: sb3 = Stable-Baselines3 (PyTorch), sbx = SBX (JAX)", "-"
    )
    policy: Literal["MlpPolicy"] = unit_field("MlpPolicy", "policy class", "-")
    critic: Literal["joint", "per_arm"] = unit_field(
        "joint",
        "joint = each critic learns Q of the summed reward (the study); per_arm = each critic "
        "has one output per arm, trained on that arm's share of the reward (its own terms plus "
        "half the cooperative bonus), and the actor maximises their sum (td3 with backend sbx "
        "and controller centralized only)",
        "-",
    )
    per_arm_networks: bool = unit_field(
        False,
        "with critic: per_arm, one actor network per arm (full observation → that arm's 12 "
        "actions) and one twin critic pair per arm (full observation and all 24 actions → that "
        "arm's Q), each with policy_kwargs.net_arch: the independent baseline's per-arm networks "
        "with the centralized observation; false = one actor and one twin critic pair with an "
        "output per arm",
        "-",
    )
    actor_observation: Literal["full", "own_arm"] = unit_field(
        "full",
        "with per_arm_networks, what each arm's actor sees: full = the whole observation; "
        "own_arm = its own arm's 37 values and the target's 7, the independent baseline's "
        "input, while the critics still see both arms and all actions (centralized training, "
        "decentralized execution)",
        "-",
    )
    mirror_replay: bool = unit_field(
        False,
        "also store every transition's mirror image (x → −x: arms swapped, normal control "
        "values negated) in the replay buffer, which the mirror-symmetric scene makes a "
        "transition it could have produced; each env step then takes two of buffer_size's "
        "slots (off-policy, controller centralized, critic joint, bases mirror images and "
        "equal arm weights only)",
        "-",
    )
    actor_preactivation_penalty: Float = unit_field(
        0.0,
        "weight λ of the mean square of the actor's pre-tanh activations u (a = tanh u) in "
        "the TD3 actor loss, −Q + λ·mean(u²): keeps control values off ±1, where tanh's "
        "gradient vanishes and a policy goes bang-bang (0 = off, the study; td3 with backend "
        "sbx and critic joint only)",
        "-",
        ge=0,
    )
    policy_kwargs: PolicyKwargsSpec = section_field(PolicyKwargsSpec, "network architecture")
    learning_rate: Float = unit_field(
        3.0e-4, "Adam learning rate (constant unless learning_rate_final is set)", "-", gt=0
    )
    learning_rate_final: Float | None = unit_field(
        None,
        "td3, ddpg with backend sbx: the learning rate falls linearly from learning_rate to "
        "this, for the actor and the critics, from learning_rate_decay_from·total_timesteps "
        "env steps to total_timesteps (null = constant)",
        "-",
        gt=0,
    )
    learning_rate_decay_from: Float = unit_field(
        0.0,
        "with learning_rate_final: the fraction of total_timesteps at which the decay starts",
        "-",
        ge=0,
        lt=1,
    )
    batch_size: Int = unit_field(
        128,
        "minibatch size (off-policy: per gradient step; PPO: per minibatch)",
        "transitions",
        ge=1,
    )
    gamma: Float = unit_field(0.99, "discount factor", "-", gt=0, le=1)
    # off-policy (td3, ddpg, sac, tqc, crossq)
    buffer_size: Int = unit_field(
        2_000_000, "replay buffer capacity (off-policy)", "transitions", ge=1
    )
    learning_starts: Int = unit_field(
        50_000, "random-action warm-up before learning starts (off-policy)", "env steps", ge=0
    )
    train_freq: Int = unit_field(
        1,
        "update the model every train_freq vectorised env steps (off-policy)",
        "vectorised env steps",
        ge=1,
    )
    gradient_steps: Int = unit_field(
        1,
        "gradient steps per update; -1 = as many as transitions collected (off-policy)",
        "gradient steps",
        ge=-1,
    )
    n_step_returns: Int = unit_field(
        1,
        "n of the n-step returns the critics learn from (off-policy; SB3's n_steps with its "
        "NStepReplayBuffer): rewards of n transitions, then the discounted bootstrap; 1 = "
        "one-step TD, the study",
        "env steps",
        ge=1,
    )
    tau: Float = unit_field(
        0.005,
        "soft target-update coefficient (td3, ddpg, sac, tqc; crossq has no target networks)",
        "-",
        gt=0,
        le=1,
    )
    policy_delay: Int = unit_field(
        2,
        "critic updates per actor update (td3; crossq, where it is 3 when not given: CrossQ's "
        "default)",
        "gradient steps",
        ge=1,
    )
    target_policy_noise: Float = unit_field(
        0.2, "std of the target policy smoothing noise (td3)", "action units", ge=0
    )
    target_noise_clip: Float = unit_field(
        0.5, "clip of the target policy smoothing noise (td3)", "action units", ge=0
    )
    act_with_target_actor: bool = unit_field(
        False,
        "td3, ddpg: validation, the kept best model, evaluation and export act with the target "
        "actor (the Polyak average of the actor's weights, tau per update) instead of the "
        "actor; training is unchanged (docs/results/time-to-accuracy.md)",
        "-",
    )
    noise_type: Literal["normal", "ornstein-uhlenbeck"] | None = unit_field(
        "normal",
        "exploration noise added to actions (td3, ddpg; sac, tqc and crossq explore by "
        "sampling their stochastic policy and ignore it); null = none",
        "-",
    )
    noise_std: Float = unit_field(
        0.1, "std of the exploration noise (td3, ddpg)", "action units", ge=0
    )
    # entropy-regularised off-policy (sac, tqc, crossq)
    target_entropy: Float | Literal["auto"] = unit_field(
        "auto",
        "entropy the automatic entropy coefficient aims at (sac, tqc, crossq; with ent_coef "
        "'auto…'); auto = −(action dimension): −24 centralized, −12 per arm independent",
        "nats",
    )
    top_quantiles_to_drop_per_net: Int = unit_field(
        2,
        "highest target quantiles dropped per critic against overestimation (tqc)",
        "quantiles",
        ge=0,
    )
    # on-policy (ppo)
    n_steps: Int = unit_field(
        2048, "rollout length per env between updates (ppo)", "env steps per env", ge=1
    )
    n_epochs: Int = unit_field(10, "optimisation epochs per rollout (ppo)", "-", ge=1)
    gae_lambda: Float = unit_field(0.95, "GAE lambda (ppo)", "-", ge=0, le=1)
    clip_range: Float = unit_field(0.2, "policy ratio clip (ppo)", "-", gt=0)
    vf_coef: Float = unit_field(0.5, "value loss coefficient (ppo)", "-", ge=0)
    max_grad_norm: Float = unit_field(0.5, "gradient norm clip (ppo)", "-", gt=0)
    ent_coef: Float | str | None = unit_field(
        None,
        "entropy coefficient; null = the algorithm's default (ppo 0.0; sac, tqc, crossq "
        "'auto': learned, starting at 1); sac, tqc and crossq also accept 'auto' or "
        "'auto_<initial value>'",
        "-",
    )
    normalize: bool = unit_field(
        False,
        "normalise observations with a running mean/std (VecNormalize); its statistics are "
        "saved with the model and every checkpoint. Caution: a feature that is constant in "
        "training (the random target's speed, 0.3 m/s) is divided by sqrt(1e-8) and saturates "
        "at ±10 on the evaluation trajectories, whose speeds differ",
        "-",
    )
    normalize_reward: bool = unit_field(False, "also normalise rewards (VecNormalize)", "-")
    device: Literal["auto", "cpu", "cuda"] = unit_field(
        "auto", "torch device; small [64, 64] networks are often fastest on cpu", "-"
    )

    @field_validator("ent_coef", mode="before")
    @classmethod
    def _check_ent_coef(cls, value: Any) -> Any:
        if isinstance(value, bool):
            raise custom_error("expected a number, 'auto' or null; write e.g. 0.0 or auto")
        if isinstance(value, str) and not re.fullmatch(
            r"auto(_\d+(\.\d*)?([eE][-+]?\d+)?)?", value
        ):
            raise custom_error(
                f"invalid value {value!r}; use a number, 'auto' or 'auto_<initial value>'"
            )
        return value

    @field_validator("target_entropy", mode="before")
    @classmethod
    def _check_target_entropy(cls, value: Any) -> Any:
        if isinstance(value, bool) or (isinstance(value, str) and value != "auto"):
            raise custom_error(f"invalid value {value!r}; use a number (nats) or auto")
        return value

    @model_validator(mode="before")
    @classmethod
    def _crossq_policy_delay(cls, data: Any) -> Any:
        """``policy_delay`` not given: CrossQ's own default, 3, for crossq (2, TD3's, else)."""
        if isinstance(data, dict) and data.get("name") == "crossq" and "policy_delay" not in data:
            data = {**data, "policy_delay": 3}
        return data

    @model_validator(mode="after")
    def _check_algorithm(self) -> AlgoSpec:
        """Raise the spec error of the first setting the chosen algorithm cannot run with."""
        if self.act_with_target_actor and self.name not in ("td3", "ddpg"):
            raise custom_error(
                f"{self.name} has no target actor (td3 and ddpg have one); set "
                "algo.act_with_target_actor: false",
                "act_with_target_actor",
            )
        if self.learning_rate_final is not None and (
            self.name not in ("td3", "ddpg") or self.backend != "sbx"
        ):
            raise custom_error(
                "learning_rate_final (a decaying learning rate) is implemented for td3 and "
                f"ddpg with backend sbx, not {self.name} with backend {self.backend}; remove "
                "algo.learning_rate_final",
                "learning_rate_final",
            )
        if self.learning_rate_decay_from != 0.0 and self.learning_rate_final is None:
            raise custom_error(
                "learning_rate_decay_from applies to a decaying learning rate; set "
                "algo.learning_rate_final or remove learning_rate_decay_from",
                "learning_rate_decay_from",
            )
        if self.name == "crossq" and self.backend != "sbx":
            raise custom_error(
                "crossq is implemented in sbx only (Stable-Baselines3 and sb3-contrib have no "
                "CrossQ); set algo.backend: sbx",
                "backend",
            )
        if self.policy_kwargs.layer_norm and (self.backend != "sbx" or not self.is_off_policy):
            raise custom_error(
                "policy_kwargs.layer_norm is implemented for the off-policy algorithms of "
                f"backend sbx, not {self.name} with backend {self.backend}; set "
                "algo.backend: sbx or policy_kwargs.layer_norm: false",
                "policy_kwargs.layer_norm",
            )
        if self.n_step_returns > 1 and not self.is_off_policy:
            raise custom_error(
                f"n_step_returns {self.n_step_returns} applies to the off-policy algorithms; "
                "ppo has its own n_steps (rollout length) and gae_lambda: set "
                "algo.n_step_returns: 1",
                "n_step_returns",
            )
        if self.name == "tqc":
            kwargs = self.policy_kwargs
            if self.backend == "sbx" and kwargs.n_critics != 2:
                raise custom_error(
                    f"sbx's TQC has exactly 2 critics, not {kwargs.n_critics}; set "
                    "algo.policy_kwargs.n_critics: 2 or algo.backend: sb3 (sb3-contrib's TQC)",
                    "policy_kwargs.n_critics",
                )
            if self.top_quantiles_to_drop_per_net >= kwargs.n_quantiles:
                raise custom_error(
                    f"top_quantiles_to_drop_per_net {self.top_quantiles_to_drop_per_net} drops "
                    f"every one of a critic's n_quantiles {kwargs.n_quantiles}; use a value "
                    "below policy_kwargs.n_quantiles",
                    "top_quantiles_to_drop_per_net",
                )
        return self

    @property
    def is_off_policy(self) -> bool:
        return self.name in OFF_POLICY_ALGOS

    @property
    def explores_by_entropy(self) -> bool:
        """SAC, TQC, CrossQ: a stochastic policy explores; no action noise is added."""
        return self.name in ENTROPY_ALGOS

    def sb3_kwargs(self, *, resolve_activation: bool = True) -> dict[str, Any]:
        """Constructor keyword arguments of the chosen algorithm class (SB3 or SBX).

        Only keys that the core algorithm accepts are included. Left out on purpose: ``env``
        and ``seed`` (per run), ``action_noise`` (the factory builds it from ``noise_type`` and
        ``noise_std`` for td3 and ddpg, which needs the action shape), ``normalize`` (a
        VecNormalize wrapper) and what a research variant adds (e.g. ``per_arm_networks`` for
        ``critic: per_arm``: :func:`softtrack.rl.variants.model_kwargs`).

        Args:
            resolve_activation: replace ``policy_kwargs.activation_fn`` by the backend's
                callable (``torch.nn.ReLU`` for sb3, ``jax.nn.relu`` for sbx; imported lazily).
                With ``False`` it stays the spec's string, e.g. ``"relu"``.
        """
        common = ["policy", "learning_rate", "batch_size", "gamma"]
        if self.is_off_policy:
            keys = [*common, "buffer_size", "learning_starts", "train_freq", "gradient_steps"]
            if self.name != "crossq":  # CrossQ has no target networks
                keys.append("tau")
            if self.name == "td3":
                keys += ["policy_delay", "target_policy_noise", "target_noise_clip"]
            if self.name == "crossq":
                keys.append("policy_delay")
            if self.name == "tqc":
                keys.append("top_quantiles_to_drop_per_net")
            if self.explores_by_entropy:
                keys.append("target_entropy")
                if self.ent_coef is not None:
                    keys.append("ent_coef")
        else:  # ppo
            keys = [
                *common,
                "n_steps",
                "n_epochs",
                "gae_lambda",
                "clip_range",
                "vf_coef",
                "max_grad_norm",
            ]
            if self.ent_coef is not None:
                keys.append("ent_coef")
        kwargs: dict[str, Any] = {key: getattr(self, key) for key in keys}
        if self.is_off_policy and self.n_step_returns > 1:
            kwargs["n_steps"] = self.n_step_returns
        if self.backend == "sb3":
            kwargs["device"] = self.device
        policy_keys = ("net_arch", "activation_fn", *_POLICY_KWARGS_OF.get(self.name, ()))
        if self.policy_kwargs.layer_norm:
            policy_keys = (*policy_keys, "layer_norm")
        if self.name == "ppo" and self.policy_kwargs.log_std_init != 0.0:
            policy_keys = (*policy_keys, "log_std_init")
        policy_kwargs: dict[str, Any] = copy.deepcopy(
            self.policy_kwargs.model_dump(include=set(policy_keys))
        )
        if resolve_activation:
            torch_name, jax_name = _ACTIVATIONS[self.policy_kwargs.activation_fn]
            if self.backend == "sb3":
                import torch.nn  # lazy: importing torch costs seconds

                policy_kwargs["activation_fn"] = getattr(torch.nn, torch_name)
            else:
                import jax.nn

                policy_kwargs["activation_fn"] = getattr(jax.nn, jax_name)
        kwargs["policy_kwargs"] = policy_kwargs
        return kwargs
