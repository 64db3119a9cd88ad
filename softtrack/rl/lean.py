"""Inference-only copies of trained models, for exported runs.

A JAX (sbx) model file holds, beside the policy network, the critics, the target networks,
the optimiser moments, the entropy coefficient's state (SAC, TQC, CrossQ) and references to
training-only classes (e.g. a custom replay buffer).
Evaluation needs none of them: :func:`save_inference_model` keeps the actor's parameters, so
the file is about a third of the size, loads with the plain algorithm class
(``sbx.TD3.load(path)``, ``sbx.SAC``, ``sbx.TQC``, ``sbx.CrossQ``: whose actor keeps its batch
renormalisation statistics) and ``predict`` gives bit-for-bit the actions of the full model.
It cannot be trained further; resume from the run's checkpoints instead. Stable-Baselines3
(PyTorch) models are copied unchanged.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from softtrack.rl.factory import model_class
from softtrack.spec import ExperimentSpec

__all__ = ["save_inference_model", "strip_training_state"]

# Model attributes that only training reads; set to None in an inference copy.
_TRAINING_ONLY = (
    "actor",
    "qf",
    "vf",
    "replay_buffer",
    "action_noise",
    "_last_obs",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
    "ent_coef_state",
)


def strip_training_state(model: Any) -> None:
    """Drop what only training uses from an sbx ``model``, in place (module docstring).

    Each train state of the policy (``*_state``: parameters, target parameters, optimiser
    state) keeps only the parameters of the actor (and a CrossQ actor's ``batch_stats``); the
    critics' and value functions' states (``qf_state``, TQC's ``qf1_state``/``qf2_state``)
    go, and so does the model's entropy coefficient state (``ent_coef_state``). The policy
    itself (``model.policy``) and its ``predict`` are untouched otherwise.
    """
    policy = model.policy
    for name, value in list(vars(policy).items()):
        if not (hasattr(value, "params") and hasattr(value, "opt_state")):
            continue
        if name.startswith("actor"):
            fields = {"opt_state": None}
            if hasattr(value, "target_params"):
                fields["target_params"] = None
            setattr(policy, name, value.replace(**fields))
        else:
            setattr(policy, name, None)
    for name in _TRAINING_ONLY:
        if hasattr(model, name):
            setattr(model, name, None)
    if hasattr(model, "replay_buffer_class"):  # loading builds a buffer: a plain, tiny one
        model.replay_buffer_class = None
        model.replay_buffer_kwargs = {}
        model.buffer_size = 1


def save_inference_model(spec: ExperimentSpec, source: Path, dest: Path) -> None:
    """Write an inference-only copy of the model file ``source`` (a run with ``spec``) to
    ``dest`` (module docstring)."""
    if spec.algo.backend != "sbx":
        shutil.copy2(source, dest)
        return
    model = model_class(spec).load(str(source), device="cpu")
    strip_training_state(model)
    model.save(str(dest))
