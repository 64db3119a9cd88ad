"""Research variants of the core algorithms, behind one registry that the factory consults.

The core (:mod:`softtrack.rl.factory`) builds the study's algorithms from a spec; a *variant*
is a research idea switched on by spec fields that changes what the factory builds. Each one
is a module of this package and one :class:`Variant` entry in :data:`VARIANTS` below, so a new
idea touches this folder (and its spec fields), not the factory:

* ``per_arm_critic`` (``algo.critic: per_arm``, :mod:`~softtrack.rl.variants.per_arm`): TD3
  whose critics learn each arm's share of the reward (optionally one network per arm, and
  actors that see only their arm); its environment reports the reward shares.
* ``mirror_replay`` (``algo.mirror_replay``, :mod:`~softtrack.rl.variants.mirror`): a replay
  buffer that also stores every transition's mirror image (with ``algo.n_step_returns`` > 1,
  ``mirror_replay_n_step``: SB3's n-step buffer with the mirror images as more columns).
* ``actor_preactivation_penalty`` (``algo.actor_preactivation_penalty``,
  :mod:`~softtrack.rl.variants.bounded_actor`): TD3 whose actor loss also penalises the
  actor's pre-tanh activations, keeping its actions off ±1.

The factory asks :func:`model_class_override`, :func:`model_kwargs` and :func:`vec_env_kwargs`.
A variant's classes are named as ``"module:attribute"`` and imported only when a spec enables
it (they import JAX or torch); this module itself is light. The spec fields and their checks
(which settings a variant cannot run with) stay in :mod:`softtrack.spec`.

Model files pickled before the variants moved here name their old modules
(``softtrack.rl.per_arm_td3``, ``softtrack.rl.mirror``); :mod:`softtrack.rl.moved` maps those
names to the modules of this package.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from softtrack.spec import ExperimentSpec

__all__ = [
    "VARIANTS",
    "Variant",
    "active_variants",
    "model_class_override",
    "model_kwargs",
    "vec_env_kwargs",
]


def _no_kwargs(_spec: ExperimentSpec) -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class Variant:
    """One research variant: when it applies and what it changes in the factory's output.

    Attributes:
        name: a short name (errors, listings).
        enabled: spec → whether the spec switches the variant on.
        algo_class: ``"module:attribute"`` of the algorithm class that replaces the core one
            (trains and loads the spec's models), or ``None``.
        replay_buffer_class: ``"module:attribute"`` of the replay buffer class the algorithm
            gets (``replay_buffer_class`` keyword), or ``None``.
        model_kwargs: spec → further keyword arguments of the algorithm's constructor.
        env_kwargs: spec → keyword arguments of the training environment
            (:class:`~softtrack.env.vec_env.TrackingVecEnv`).
    """

    name: str
    enabled: Callable[[ExperimentSpec], bool]
    algo_class: str | None = None
    replay_buffer_class: str | None = None
    model_kwargs: Callable[[ExperimentSpec], dict[str, Any]] = _no_kwargs
    env_kwargs: Callable[[ExperimentSpec], dict[str, Any]] = _no_kwargs


def _per_arm_kwargs(spec: ExperimentSpec) -> dict[str, Any]:
    return {
        "n_reward_shares": 2,  # the centralized dual-arm scene
        "per_arm_networks": spec.algo.per_arm_networks,
        "actor_observation": spec.algo.actor_observation,
    }


VARIANTS: tuple[Variant, ...] = (
    Variant(
        name="per_arm_critic",
        enabled=lambda spec: spec.algo.critic == "per_arm",
        algo_class="softtrack.rl.variants.per_arm:PerArmTD3",
        model_kwargs=_per_arm_kwargs,
        env_kwargs=lambda spec: {"reward_shares": True},
    ),
    Variant(
        name="mirror_replay",
        enabled=lambda spec: bool(spec.algo.mirror_replay) and spec.algo.n_step_returns == 1,
        replay_buffer_class="softtrack.rl.variants.mirror:MirrorReplayBuffer",
    ),
    Variant(
        name="mirror_replay_n_step",
        enabled=lambda spec: bool(spec.algo.mirror_replay) and spec.algo.n_step_returns > 1,
        replay_buffer_class="softtrack.rl.variants.mirror:MirrorNStepReplayBuffer",
        model_kwargs=lambda spec: {
            "replay_buffer_kwargs": {"n_steps": spec.algo.n_step_returns, "gamma": spec.algo.gamma}
        },
    ),
    Variant(
        name="actor_preactivation_penalty",
        enabled=lambda spec: spec.algo.actor_preactivation_penalty > 0,
        algo_class="softtrack.rl.variants.bounded_actor:PreactivationPenaltyTD3",
        model_kwargs=lambda spec: {"preactivation_penalty": spec.algo.actor_preactivation_penalty},
    ),
)
"""Every variant, in the order their keyword arguments are merged."""


def _load(name: str) -> Any:
    module, _, attribute = name.partition(":")
    return getattr(importlib.import_module(module), attribute)


def active_variants(spec: ExperimentSpec) -> list[Variant]:
    """The variants ``spec`` switches on."""
    return [variant for variant in VARIANTS if variant.enabled(spec)]


def _one(spec: ExperimentSpec, field: str) -> Any:
    """The class the active variants name in ``field`` (``None`` if none); two are an error."""
    named = {getattr(v, field): v.name for v in active_variants(spec) if getattr(v, field)}
    if len(named) > 1:
        raise ValueError(f"variants {', '.join(named.values())} each set the {field}")
    return _load(next(iter(named))) if named else None


def model_class_override(spec: ExperimentSpec) -> Any:
    """The algorithm class an active variant puts in place of the core one, or ``None``."""
    return _one(spec, "algo_class")


def model_kwargs(spec: ExperimentSpec) -> dict[str, Any]:
    """The algorithm constructor's keyword arguments that the active variants add
    (``replay_buffer_class`` and each variant's own)."""
    kwargs: dict[str, Any] = {}
    buffer = _one(spec, "replay_buffer_class")
    if buffer is not None:
        kwargs["replay_buffer_class"] = buffer
    for variant in active_variants(spec):
        kwargs.update(variant.model_kwargs(spec))
    return kwargs


def vec_env_kwargs(spec: ExperimentSpec) -> dict[str, Any]:
    """The training environment's keyword arguments that the active variants add."""
    kwargs: dict[str, Any] = {}
    for variant in active_variants(spec):
        kwargs.update(variant.env_kwargs(spec))
    return kwargs
