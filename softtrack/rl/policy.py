"""Deterministic policies loaded from a run directory, for evaluation.

A centralized run keeps ``model.zip`` (and ``vecnormalize.pkl`` when observations were
normalised) in its directory; an independent run keeps one per arm under ``models/arm<k>/``.
"""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np

from softtrack.evaluation import Policy, independent_policy
from softtrack.rl.factory import model_class
from softtrack.spec import ExperimentSpec
from softtrack.store.runs import RunRecord, RunStoreError

__all__ = ["load_policy", "model_paths"]


def model_paths(record: RunRecord, spec: ExperimentSpec) -> list[Path]:
    """The model file(s) of a run: one for a centralized run, one per arm otherwise."""
    if spec.controller == "independent":
        return [record.path / "models" / f"arm{k}" / "model.zip" for k in range(2)]
    return [record.model_path]


def _load_single(spec: ExperimentSpec, path: Path) -> Policy:
    if not path.is_file():
        raise RunStoreError(
            f"{path}: no trained model in this run (status may be unfinished); "
            "finish it with `softtrack train --resume RUN_ID`"
        )
    try:
        device = "cpu" if spec.algo.backend == "sb3" else "auto"
        model: Any = model_class(spec).load(str(path), device=device)
    except Exception as exc:  # noqa: BLE001 - any failure to load means an unusable model file
        raise RunStoreError(f"{path}: unreadable model ({type(exc).__name__}: {exc})") from None
    normalizer = None
    stats = path.parent / "vecnormalize.pkl"
    if stats.is_file():
        with stats.open("rb") as handle:
            normalizer = pickle.load(handle)
        normalizer.training = False

    def act(observation: np.ndarray) -> np.ndarray:
        obs = observation if normalizer is None else normalizer.normalize_obs(observation)
        action, _ = model.predict(obs, deterministic=True)
        return np.asarray(action, dtype=np.float64)

    return act


def load_policy(record: RunRecord, spec: ExperimentSpec) -> Policy:
    """The run's deterministic dual-arm policy: observation (81,) → action (24,).

    Raises:
        RunStoreError: a model file is missing or unreadable.
    """
    import torch

    torch.set_num_threads(1)
    policies = [_load_single(spec, path) for path in model_paths(record, spec)]
    if spec.controller == "independent":
        return independent_policy(policies)
    return policies[0]
