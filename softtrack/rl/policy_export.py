"""Export a finished run for users: its policy as ``model.zip``, inference-only models.

Which model is a run's policy depends on its spec (``training.final_policy``,
``training.confirm_episodes``): the last model of training or the best-validated one. An
exported run makes that explicit (:mod:`softtrack.store.run_export`): every policy directory's
``model.zip`` is the policy, so ``sbx.TD3.load("models/<run>/model.zip")`` gives exactly the
controller ``softtrack evaluate`` runs; the other model sits in ``other_models/<last|best>/``;
``policy.json`` records the choice and the steps.

Models are written inference-only (:func:`save_inference_model`). A JAX (sbx) model file holds,
beside the policy network, the critics, the target networks, the optimiser moments, the entropy
coefficient's state (SAC, TQC, CrossQ) and references to training-only classes (e.g. a custom
replay buffer). Evaluation needs none of them: the copy keeps the actor's parameters, so the
file is about a third of the size, loads with the plain algorithm class (``sbx.TD3.load(path)``,
``sbx.SAC``, ``sbx.TQC``, ``sbx.CrossQ``: whose actor keeps its batch renormalisation
statistics) and ``predict`` gives bit-for-bit the actions of the full model. It cannot be
trained further; resume from the run's checkpoints instead. Stable-Baselines3 (PyTorch) models
are copied unchanged.
"""

from __future__ import annotations

import json
import os
import shutil
from functools import partial
from pathlib import Path
from typing import Any, Literal

from softtrack.rl.factory import model_class
from softtrack.rl.policy import candidate_path, policy_choice
from softtrack.rl.target_actor import act_with_target_actor
from softtrack.spec import ExperimentSpec
from softtrack.store.layout import OTHER_MODELS_DIR, PolicyDir
from softtrack.store.model_zip import deflate_model_zip
from softtrack.store.run_export import ModelCopy, export_run
from softtrack.store.runs import RunRecord, RunStore

__all__ = [
    "export_plan",
    "export_policy_run",
    "relayout_exported_run",
    "save_inference_model",
    "strip_training_state",
]

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
    if spec.algo.act_with_target_actor:  # the weights it acts with are all it keeps
        act_with_target_actor(model)
    strip_training_state(model)
    model.save(str(dest))
    deflate_model_zip(dest)  # the libraries store their members uncompressed: half the size


def export_plan(
    record: RunRecord, spec: ExperimentSpec, policy_only: bool = False
) -> tuple[list[ModelCopy], dict[Path, dict[str, Any]]]:
    """The model files to export and each policy directory's ``policy.json``.

    Args:
        policy_only: leave out the other models (``other_models/``: what ``evaluate --model
            last``/``best`` would read), keeping only each policy's ``model.zip``.

    Returns:
        (models, manifests): one :class:`ModelCopy` per existing model of each policy (its
        policy to ``model.zip``, the other, unless ``policy_only``, to
        ``other_models/<name>/model.zip``), and the
        manifest by policy directory relative to the run directory; none for a planner
        (``controller: mpc``), whose spec is the whole controller.
    """
    models: list[ModelCopy] = []
    manifests: dict[Path, dict[str, Any]] = {}
    if spec.controller == "mpc":  # a planner: its spec is the controller, no model files
        return models, manifests
    for policy in PolicyDir.all_of_run(record.path, spec.controller == "independent"):
        relative = policy.path.relative_to(record.path)
        chosen = policy_choice(policy, spec)
        other: Literal["best", "last"] = "last" if chosen == "best" else "best"
        models.append(ModelCopy(candidate_path(policy, chosen), relative / "model.zip"))
        manifest: dict[str, Any] = {
            "model": chosen,
            **_model_state(record, policy, chosen),
            "selected_by": _selection(spec),
            "other_models": {},
        }
        other_path = candidate_path(policy, other)
        if other_path.is_file() and not policy_only:
            dest = relative / OTHER_MODELS_DIR / other / "model.zip"
            models.append(ModelCopy(other_path, dest))
            manifest["other_models"][other] = {
                "path": (Path(OTHER_MODELS_DIR) / other / "model.zip").as_posix(),
                **_model_state(record, policy, other),
            }
        manifests[relative] = manifest
    return models, manifests


def export_policy_run(
    record: RunRecord,
    dest: str | os.PathLike[str],
    policy_only: bool = False,
    *,
    replacing: bool = False,
) -> Path:
    """Export ``record`` to the new directory ``dest`` (module docstring; ``policy_only``:
    :func:`export_plan`; ``replacing``: ``dest`` will take the run's place). Returns ``dest``."""
    spec = record.load_spec()
    models, manifests = export_plan(record, spec, policy_only)
    write = partial(save_inference_model, spec)
    return export_run(record, models, manifests, dest, write, replacing=replacing)


def _selection(spec: ExperimentSpec) -> str:
    if spec.training.final_policy == "last":
        return "training.final_policy: last"
    if spec.training.confirm_episodes < 1:
        return "training.final_policy: best_validated"
    return f"training.confirm_episodes: {spec.training.confirm_episodes}"


def _model_state(record: RunRecord, policy: PolicyDir, model: str) -> dict[str, Any]:
    """``global_step`` at which ``policy``'s ``model`` was saved (``None`` where not recorded)
    and, for the best-validated model, its ``validation_score`` (mean 3-D RMSE, m)."""
    if model == "best":
        state = _read_state(candidate_path(policy, "best").parent / "state.json")
        return {"global_step": state.get("global_step"), "validation_score": state.get("score")}
    if policy.arm is not None:
        return {"global_step": _read_state(policy.state_path).get("global_step")}
    return {"global_step": record.info.global_step}


def _read_state(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def relayout_exported_run(run_dir: Path) -> bool:
    """Give an exported run directory of an earlier version (policy chosen by the spec, best
    models under ``best/``, full training-state model files) the current layout, in place.

    The new directory is exported beside the old one and then takes its place; a directory
    already laid out (``policy.json``), holding checkpoints (a training run, which keeps its
    training layout) or of a planner (no model) is left as it is.

    Returns:
        True if the directory was rewritten.
    """
    run_dir = Path(run_dir)
    record = RunStore(run_dir.parent).get_run(run_dir.name)
    spec = record.load_spec()
    if spec.controller == "mpc":  # a planner's run has no model to lay out
        return False
    policies = PolicyDir.all_of_run(run_dir, spec.controller == "independent")
    if any(p.manifest_path.is_file() or p.checkpoints_dir.exists() for p in policies):
        return False
    fresh = run_dir.with_name(f".{run_dir.name}.relayout")
    old = run_dir.with_name(f".{run_dir.name}.old")
    for leftover in (fresh, old):
        if leftover.exists():
            shutil.rmtree(leftover)
    export_policy_run(record, fresh, replacing=True)
    os.replace(run_dir, old)
    os.replace(fresh, run_dir)
    shutil.rmtree(old)
    return True
