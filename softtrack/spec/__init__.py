"""The experiment spec: one Pydantic model tree, read from YAML with precise one-line errors.

An experiment is a YAML file with six top-level keys::

    name: td3                 # a safe identifier, used in run listings and report names
    env: {physics: ..., target: ..., reward: ..., episode_duration: 10.0}
    algo: {name: td3, learning_rate: 3.0e-4, ...}   # rl-baselines3-zoo key names
    training: {total_timesteps: 10000000, n_envs: 1, ...}
    seeds: [0, 1, 2]          # one run per seed (an int is accepted too)
    controller: centralized   # or independent (one single-arm policy per arm)

plus an optional ``tune:`` section, the search space of ``softtrack tune``
(:mod:`softtrack.spec.tune_models`, left out of the spec hash), and an optional
``base: <path>``: the spec file this one extends (relative to this file's directory), so a
variant states only what differs; the chain is deep-merged before validation
(:mod:`softtrack.spec.bases`; ``name`` is not inherited) and :func:`spec_chain` lists it.

Every field has a default (the study's setting, ``docs/physics.md``,
``docs/environment.md``), a description and its unit in brackets; :func:`spec_json_schema`
and ``softtrack spec --schema`` expose them. Unknown keys are rejected everywhere. YAML is read
with a *safe* loader (plus YAML-1.2 style floats, so ``1e7`` and ``3e-4`` are numbers, and
duplicate keys are an error); nothing is ever ``eval``-ed.

Errors a user can make raise :class:`SpecError`, whose ``str`` is one line::

    experiments/study/td3-64-1e7.yaml:18: algo.learnig_rate: unknown field 'learnig_rate'; did you mean 'learning_rate'?
"""

from softtrack.spec.algo_models import OFF_POLICY_ALGOS, AlgoSpec, PolicyKwargsSpec
from softtrack.spec.env_models import EnvSpec, PhysicsSpec, RealismSpec, RewardSpec, TargetSpec
from softtrack.spec.fields import SpecError
from softtrack.spec.models import ClusterSpec, ExperimentSpec
from softtrack.spec.spec_io import (
    chain_comment,
    load_spec,
    parse_spec,
    spec_chain,
    spec_hash,
    spec_json_schema,
    spec_to_yaml,
)
from softtrack.spec.training_models import TrainingSpec
from softtrack.spec.tune_models import PrunerSpec, TuneParamSpec, TuneSpec

__all__ = [
    "OFF_POLICY_ALGOS",
    "AlgoSpec",
    "ClusterSpec",
    "EnvSpec",
    "ExperimentSpec",
    "PhysicsSpec",
    "PolicyKwargsSpec",
    "PrunerSpec",
    "RealismSpec",
    "RewardSpec",
    "SpecError",
    "TargetSpec",
    "TrainingSpec",
    "TuneParamSpec",
    "TuneSpec",
    "chain_comment",
    "load_spec",
    "parse_spec",
    "spec_chain",
    "spec_hash",
    "spec_json_schema",
    "spec_to_yaml",
]
