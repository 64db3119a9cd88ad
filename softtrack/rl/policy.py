"""Deterministic policies loaded from a run directory, for evaluation.

A centralized run keeps ``model.zip`` (and ``vecnormalize.pkl`` when observations were
normalised) in its directory; an independent run keeps one per arm under ``models/arm<k>/``.
With ``training.final_policy: best_validated`` the run's policy is each policy directory's
best-validated model (``best/step-…/model.zip``) instead, and with ``training.confirm_episodes``
the one of the two its confirmation chose (``confirmed.json``, :mod:`softtrack.rl.confirmation`;
the best-validated model until it is written). Either model can also be chosen
explicitly (:data:`ModelChoice`), e.g. to compare the last model with the kept one.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any, Literal

import numpy as np

from softtrack.evaluation import Policy, independent_policy
from softtrack.rl.factory import model_class
from softtrack.rl.target_actor import act_with_target_actor
from softtrack.spec import ExperimentSpec
from softtrack.store.disk import check_address_space
from softtrack.store.layout import MODEL_CHOICES, ModelChoice, PolicyDir
from softtrack.store.runs import RunRecord, RunStoreError

__all__ = [
    "MODEL_CHOICES",
    "ModelChoice",
    "candidate_path",
    "deterministic_policy",
    "load_policy",
    "load_policy_file",
    "model_paths",
    "mpc_controller",
    "policy_choice",
    "require_model",
]


def model_paths(
    record: RunRecord, spec: ExperimentSpec, model: ModelChoice = "policy"
) -> list[Path]:
    """The model file(s) of ``model`` (:data:`ModelChoice`): one for a centralized run, one per
    arm otherwise. The files need not exist (an unfinished run, a run without validation)."""
    if model not in MODEL_CHOICES:
        raise ValueError(f"model={model!r}; choose from {', '.join(MODEL_CHOICES)}")
    if spec.controller == "mpc":
        return []  # a planner: nothing stored
    policies = PolicyDir.all_of_run(record.path, spec.controller == "independent")
    if model != "policy":
        return [candidate_path(policy, model) for policy in policies]
    return [
        policy.policy_path or candidate_path(policy, policy_choice(policy, spec))
        for policy in policies
    ]


def require_model(
    record: RunRecord, spec: ExperimentSpec, model: ModelChoice = "policy"
) -> list[Path]:
    """:func:`model_paths`, checked to exist.

    Raises:
        RunStoreError: a model file is missing (the run is unfinished, or ``best`` of a run
            trained without validation), with the command that fixes it.
    """
    if model != "policy" and spec.controller == "mpc":
        raise RunStoreError(
            f"run {record.run_id} is an MPC controller: it has no last or "
            "best model; evaluate it without --model"
        )
    if model == "best" and not spec.training.validates:
        raise RunStoreError(
            f"run {record.run_id} was trained without validation "
            "(training.validation_episodes and validation_paths: 0), so it has no "
            "best-validated model; "
            "evaluate its last model with --model last"
        )
    paths = model_paths(record, spec, model)
    missing = [p for p in paths if not p.is_file()]
    if missing and model != "policy" and _exported_policy_only(record, spec):
        raise RunStoreError(
            f"{missing[0]}: run {record.run_id} was exported with its policy only (no "
            f"{model} model beside it); evaluate its policy without --model, or the run it was "
            "exported from"
        )
    if missing:
        raise RunStoreError(
            f"{missing[0]}: run {record.run_id} has no trained model (status "
            f"{record.info.status}); finish it with `softtrack train --resume {record.run_id}`"
        )
    return paths


def _exported_policy_only(record: RunRecord, spec: ExperimentSpec) -> bool:
    """Whether ``record`` is an exported run (``policy.json`` beside its policies) whose
    policies list no other model."""
    policies = PolicyDir.all_of_run(record.path, spec.controller == "independent")
    manifests = [policy.read_manifest() for policy in policies]
    return all(m is not None and not m.get("other_models") for m in manifests)


def policy_choice(policy: PolicyDir, spec: ExperimentSpec) -> Literal["best", "last"]:
    """Which of its models is ``policy``'s policy: the one its ``policy.json`` names in an
    exported directory, else the one ``training.final_policy`` (and a confirmation) chose."""
    manifest = policy.read_manifest()
    if manifest is not None and manifest.get("model") in ("best", "last"):
        return manifest["model"]
    if spec.training.final_policy == "last":
        return "last"
    if spec.training.confirm_episodes < 1:
        return "best"
    return policy.confirmed_choice() or "best"


def candidate_path(policy: PolicyDir, model: Literal["best", "last"]) -> Path:
    """The model file of ``policy``'s ``best`` (best-validated) or ``last`` model."""
    return policy.best_model_path if model == "best" else policy.model_path


def deterministic_policy(model: Any, normalizer: Any = None, batches: bool = False) -> Policy:
    """``model``'s deterministic action for one observation: (obs_dim,) → (act_dim,).

    Args:
        model: an SB3 or sbx model.
        normalizer: a ``VecNormalize`` whose (frozen) statistics scale the observation first.
        batches: mark the policy as taking (n, obs_dim) → (n, act_dim) in one call
            (:func:`~softtrack.evaluation.accepts_batches`). A batch's matrix products may
            round a row differently from the row alone, so evaluation leaves this off (its
            numbers reproduce bit for bit); validation turns it on (one call per control step).
    """

    def act(observation: np.ndarray) -> np.ndarray:
        obs = observation if normalizer is None else normalizer.normalize_obs(observation)
        action, _ = model.predict(obs, deterministic=True)
        return np.asarray(action, dtype=np.float64)

    act.accepts_batches = batches  # type: ignore[attr-defined]
    return act


def load_policy_file(spec: ExperimentSpec, path: Path) -> Policy:
    """The deterministic policy of one model file of a run with ``spec`` (its
    ``vecnormalize.pkl`` beside it, if any): observation → action.

    Raises:
        RunStoreError: the file is missing or unreadable.
    """
    if not path.is_file():
        raise RunStoreError(
            f"{path}: no trained model in this run (status may be unfinished); "
            "finish it with `softtrack train --resume RUN_ID`"
        )
    check_address_space("load a policy")
    try:
        device = "cpu" if spec.algo.backend == "sb3" else "auto"
        model: Any = model_class(spec).load(str(path), device=device)
    except Exception as exc:
        raise RunStoreError(f"{path}: unreadable model ({type(exc).__name__}: {exc})") from None
    normalizer = None
    stats = path.parent / "vecnormalize.pkl"
    if stats.is_file():
        with stats.open("rb") as handle:
            normalizer = pickle.load(handle)
        normalizer.training = False
    if spec.algo.act_with_target_actor:
        act_with_target_actor(model)
    return deterministic_policy(model, normalizer)


def mpc_controller(spec: ExperimentSpec, seed: int) -> Policy:
    """The sampling MPC of ``spec``'s ``mpc:`` section (arm weights from ``env.reward``)."""
    # the planner: loaded for planner runs only
    from softtrack.mpc.controller import MpcController
    from softtrack.mpc.planner_config import PlannerConfig

    config = PlannerConfig(
        **spec.mpc.planner_kwargs(), arm_weights=tuple(spec.env.reward.arm_weights)
    )
    return MpcController(config, seed, spec.mpc.model, spec.mpc.model_scales)


def load_policy(record: RunRecord, spec: ExperimentSpec, model: ModelChoice = "policy") -> Policy:
    """The run's deterministic dual-arm policy: observation (81,) → action (24,), from the
    model(s) ``model`` picks (:func:`model_paths`).

    An MPC run (``controller: mpc``) gives its planner
    (:class:`~softtrack.mpc.controller.MpcController`, seeded with the run's seed).

    Raises:
        RunStoreError: a model file is missing or unreadable.
    """
    if spec.controller == "mpc":
        return mpc_controller(spec, record.info.seed)
    import torch

    torch.set_num_threads(1)
    policies = [load_policy_file(spec, path) for path in model_paths(record, spec, model)]
    if spec.controller == "independent":
        return independent_policy(policies)
    return policies[0]
