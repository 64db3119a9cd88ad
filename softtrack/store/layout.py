"""Where one trained policy of a run keeps its files.

A centralized run has one policy, stored in the run directory itself; an independent run
(docs/environment.md, "Independent baseline") has one per arm, each in ``models/arm<k>/``::

    <run>/model.zip, <run>/vecnormalize.pkl, <run>/checkpoints/step-…/     centralized
    <run>/models/arm<k>/model.zip, …/vecnormalize.pkl, …/checkpoints/step-…/   independent

An arm directory also holds ``state.json`` (the arm's final step count, episode count and
training wall time), written just before ``model.zip``: an arm is finished exactly when its
``model.zip`` exists.

With ``training.validation_episodes`` a policy also keeps its best-validated model in
``best/step-<step>/`` (``model.zip``, ``vecnormalize.pkl`` when normalising, ``state.json``
with the step and validation score; see :mod:`softtrack.rl.validation`). Each directory is
written atomically and only when it beats the previous one, so the newest is the best.
With ``training.confirm_episodes`` it also gets ``confirmed.json`` after training, naming the
model its confirmation kept (:mod:`softtrack.rl.confirmation`).

An *exported* policy directory (``softtrack export``, :mod:`softtrack.store.run_export`) is laid
out for users instead: ``model.zip`` is the policy itself, whichever model the run selected,
the other models sit in ``other_models/<last|best>/``, and ``policy.json`` says which model
``model.zip`` is::

    <policy>/model.zip, <policy>/policy.json, <policy>/other_models/last/model.zip
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from softtrack.store.atomic import is_temp_file

__all__ = [
    "MANIFEST_NAME",
    "MODEL_CHOICES",
    "OTHER_MODELS_DIR",
    "ModelChoice",
    "PolicyDir",
    "arm_dir",
]

ModelChoice = Literal["policy", "last", "best"]
"""Which model of a run to load: ``policy``, the run's policy (``training.final_policy``);
``last``, the model at the end of training; ``best``, the best-validated model (runs trained
with ``training.validation_episodes`` ≥ 1)."""

MODEL_CHOICES: tuple[ModelChoice, ...] = ("policy", "last", "best")

MANIFEST_NAME = "policy.json"
"""The file that marks an exported policy directory and names the model ``model.zip`` is."""
OTHER_MODELS_DIR = "other_models"
"""The folder of an exported policy's models other than its policy, one sub-folder each."""


def arm_dir(run_path: Path, arm: int) -> Path:
    """``<run>/models/arm<arm>/``: the directory of arm ``arm``'s policy in an independent run."""
    return run_path / "models" / f"arm{int(arm)}"


@dataclass(frozen=True)
class PolicyDir:
    """The files of one policy of a run.

    Attributes:
        path: the run directory (centralized) or ``models/arm<k>/`` (independent).
        arm: ``None`` for the centralized policy, else the arm index (0 or 1).
    """

    path: Path
    arm: int | None = None

    @classmethod
    def of_run(cls, run_path: Path, arm: int | None = None) -> PolicyDir:
        """The policy directory of ``arm`` (``None``: the centralized policy) in a run."""
        return cls(run_path if arm is None else arm_dir(run_path, arm), arm)

    @classmethod
    def all_of_run(cls, run_path: Path, independent: bool) -> list[PolicyDir]:
        """Every policy directory of a run: arm 0's and arm 1's for an independent run, else
        the centralized one."""
        return [cls.of_run(run_path, arm) for arm in ((0, 1) if independent else (None,))]

    @property
    def model_path(self) -> Path:
        """The final (last) model (SB3 zip); it exists once this policy's training is finished.
        In an exported directory whose policy is another model: ``other_models/last/``."""
        return self._exported_path("last") or self.path / "model.zip"

    @property
    def policy_path(self) -> Path | None:
        """``model.zip`` of an exported directory (the policy itself); ``None`` in a training
        run's directory, where the policy is chosen by the spec (:func:`softtrack.rl.policy.
        model_paths`)."""
        return self.path / "model.zip" if self.manifest_path.is_file() else None

    @property
    def manifest_path(self) -> Path:
        """``policy.json`` of an exported directory (see the module docstring)."""
        return self.path / MANIFEST_NAME

    def read_manifest(self) -> dict[str, Any] | None:
        """The content of ``policy.json``, or ``None`` outside an exported directory."""
        return _read_json(self.manifest_path)

    def other_model_path(self, model: str) -> Path:
        """``other_models/<model>/model.zip`` of an exported directory."""
        return self.path / OTHER_MODELS_DIR / model / "model.zip"

    def _exported_path(self, model: str) -> Path | None:
        manifest = self.read_manifest()
        if manifest is None:
            return None
        return (
            self.path / "model.zip"
            if manifest.get("model") == model
            else self.other_model_path(model)
        )

    @property
    def vecnormalize_path(self) -> Path:
        """The final observation/reward normalisation statistics (``algo.normalize``)."""
        return self.path / "vecnormalize.pkl"

    @property
    def state_path(self) -> Path:
        """``state.json`` of a finished arm (not written for the centralized policy)."""
        return self.path / "state.json"

    def read_state(self) -> dict[str, Any] | None:
        """A finished arm's ``state.json`` (``None`` if missing or unreadable)."""
        return _read_json(self.state_path)

    @property
    def checkpoints_dir(self) -> Path:
        return self.path / "checkpoints"

    def checkpoint_dir(self, step: int) -> Path:
        """``checkpoints/step-<12-digit step>/`` (sorts by step); write it with ``atomic_dir``."""
        return self.checkpoints_dir / f"step-{int(step):012d}"

    def list_checkpoints(self) -> list[Path]:
        """Complete checkpoint directories, oldest first (temporary ones skipped)."""
        return _step_dirs(self.checkpoints_dir)

    @property
    def best_dir(self) -> Path:
        """``best/``: the best-validated models, one ``step-<12-digit step>/`` each."""
        return self.path / "best"

    def best_step_dir(self, step: int) -> Path:
        """``best/step-<12-digit step>/``; write it with ``atomic_dir``."""
        return self.best_dir / f"step-{int(step):012d}"

    def list_best(self) -> list[Path]:
        """Complete best-model directories, oldest (and worst) first."""
        return _step_dirs(self.best_dir)

    @property
    def best_model_path(self) -> Path:
        """``model.zip`` of the newest (so best) validated model; ``best/model.zip``, which
        never exists, while there is none. In an exported directory: ``model.zip`` or
        ``other_models/best/model.zip``."""
        exported = self._exported_path("best")
        if exported is not None:
            return exported
        best = self.list_best()
        return (best[-1] if best else self.best_dir) / "model.zip"

    @property
    def confirmed_path(self) -> Path:
        """``confirmed.json``: which candidate the confirmation after training kept
        (``training.confirm_episodes``, :mod:`softtrack.rl.confirmation`)."""
        return self.path / "confirmed.json"

    def read_confirmed(self) -> dict[str, Any] | None:
        """The content of ``confirmed.json``, or ``None`` if it is missing or unreadable."""
        return _read_json(self.confirmed_path)

    def confirmed_choice(self) -> Literal["best", "last"] | None:
        """The model (``best`` or ``last``) that ``confirmed.json`` names, or ``None`` if it
        has none (not confirmed yet) or it cannot be read."""
        model = (self.read_confirmed() or {}).get("model")
        return model if model in ("best", "last") else None

    def row_mask(self, df: Any) -> np.ndarray:
        """Which rows of a run table with an ``arm`` column per policy (``train_episodes`` of
        an independent run, ``validation``) are this policy's: all rows for the centralized
        policy, those with ``arm`` equal to its arm otherwise. (n_rows,) bool."""
        if self.arm is None:
            return np.ones(len(df), dtype=bool)
        if "arm" not in df.columns:
            return np.zeros(len(df), dtype=bool)
        return (df["arm"] == self.arm).to_numpy(dtype=bool, copy=True)

    @property
    def label(self) -> str:
        """``arm0``/``arm1``, or ``""`` for the centralized policy."""
        return "" if self.arm is None else f"arm{self.arm}"


def _read_json(path: Path) -> dict[str, Any] | None:
    """A JSON object file's content, or ``None`` if it is missing, unreadable or not an object."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _step_dirs(parent: Path) -> list[Path]:
    """``step-…`` directories in ``parent``, oldest first (temporary ones skipped)."""
    if not parent.is_dir():
        return []
    return sorted(
        p
        for p in parent.iterdir()
        if p.is_dir() and p.name.startswith("step-") and not is_temp_file(p)
    )
