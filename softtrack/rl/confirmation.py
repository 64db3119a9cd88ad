"""Confirmation after training: the best-validated and the last model scored on more episodes.

The best-validated model won among all checkpoints on ``training.validation_episodes``
episodes; with few episodes that win is partly luck, and its validation score is biased low.
With ``training.confirm_episodes: N`` (N ≥ 1, ``final_policy: best_validated``), once every
policy of a run has finished training, each policy's two candidates, its best-validated model
(``best``) and its model at the end of training (``last``), each run N more deterministic
episodes of the policy's own random training target, episode k from seed
:data:`~softtrack.evaluation.CONFIRM_SEED` + k: held out from training, validation and
``softtrack evaluate --random``. The candidate with the lower mean 3-D RMSE (the validation
score, :func:`~softtrack.evaluation.validation_score`) becomes the run's policy; a tie keeps
``best``. When the best-validated model is the last checkpoint, the two are one model, which
is scored once.

* ``tables/confirmation.parquet``: one row per candidate, episode and arm: ``candidate``
  (``best``/``last``), ``global_step`` (the candidate's env steps), ``episode``, ``seed`` and
  the columns of :func:`softtrack.evaluation.metrics_table` (an independent run's arm policy
  in its single-arm scene, its rows carry its arm).
* ``<policy>/confirmed.json`` (:attr:`~softtrack.store.layout.PolicyDir.confirmed_path`):
  ``model`` (the chosen candidate), ``global_step``, ``scores`` (candidate → score, m),
  ``steps`` (candidate → env steps), ``episodes``. Written last, so its presence means the
  policy is confirmed; a run stopped during confirmation confirms that policy again when it
  resumes. :meth:`~softtrack.store.layout.PolicyDir.confirmed_choice` reads the choice.
"""

from __future__ import annotations

import json
import sys
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import pandas as pd

from softtrack.evaluation import CONFIRM_SEED, validation_score
from softtrack.rl.policy import load_policy_file
from softtrack.rl.validation import best_model, held_out_rows
from softtrack.spec import ExperimentSpec
from softtrack.spec.env_config import env_config
from softtrack.store.atomic import atomic_write_json
from softtrack.store.layout import PolicyDir
from softtrack.store.runs import RunRecord, utc_now
from softtrack.store.tables import read_table, write_table

__all__ = [
    "CONFIRMATION_TABLE",
    "Candidate",
    "Confirmation",
    "confirm_policy",
    "confirm_run",
]

CONFIRMATION_TABLE = "confirmation"

Candidate = Literal["best", "last"]


@dataclass(frozen=True)
class Confirmation:
    """The outcome of one policy's confirmation.

    Attributes:
        model: the chosen candidate, ``best`` or ``last``.
        scores: candidate → mean 3-D RMSE over the confirmation episodes, m.
        steps: candidate → the candidate's env steps.
        episodes: confirmation episodes per candidate.
    """

    model: Candidate
    scores: dict[str, float]
    steps: dict[str, int]
    episodes: int


def confirm_policy(
    record: RunRecord,
    spec: ExperimentSpec,
    policy: PolicyDir,
    stop_requested: Callable[[], bool] = lambda: False,
    log: Callable[[str], None] | None = None,
) -> Confirmation | None:
    """Confirm one finished policy of ``record`` (module docstring): score its candidates,
    replace its rows of ``tables/confirmation.parquet`` and write its ``confirmed.json``.

    Args:
        spec: the run's spec (``training.confirm_episodes`` ≥ 1).
        policy: the policy; its ``model.zip`` and best-validated model must exist.
        stop_requested: when it turns true, confirmation stops between episodes and writes
            nothing.
        log: where the one-line summary of each candidate goes (default: stderr).

    Returns:
        The outcome, or ``None`` if a stop request cut it short.

    Raises:
        ValueError: ``training.confirm_episodes`` is 0, or the policy has no best model.
    """
    episodes = int(spec.training.confirm_episodes)
    if episodes < 1:
        raise ValueError("training.confirm_episodes is 0; a confirmation needs at least 1")
    best = best_model(policy)
    if best is None:
        raise ValueError(f"{policy.best_dir}: no best-validated model to confirm")
    log = log or (lambda line: print(line, file=sys.stderr, flush=True))
    last_step = _model_step(policy.model_path)
    candidates: dict[Candidate, tuple[Path, int]] = {"best": (policy.best_model_path, best.step)}
    if last_step != best.step:
        candidates["last"] = (policy.model_path, last_step)
    config = env_config(spec, policy.arm)
    name = f"{record.run_id[-8:]} {policy.label}".rstrip()
    duration = float(spec.training.eval_duration)
    scores: dict[str, float] = {}
    parts = []
    for candidate, (path, step) in candidates.items():
        started = time.monotonic()
        rows = held_out_rows(
            record.run_id,
            load_policy_file(spec, path),
            config,
            duration,
            CONFIRM_SEED,
            episodes,
            policy.arm,
            stop_requested,
        )
        if rows is None:
            return None
        rows.insert(1, "candidate", candidate)
        rows.insert(2, "global_step", step)
        parts.append(rows)
        scores[candidate] = validation_score(rows, duration)
        log(
            f"{name} confirmation of the {candidate} model ({step:,} steps): 3-D RMSE "
            f"{scores[candidate]:.4f} m over {episodes} episode{'s' if episodes != 1 else ''} in "
            f"{time.monotonic() - started:.0f} s"
        )
    scores.setdefault("last", scores["best"])
    chosen: Candidate = "last" if scores["last"] < scores["best"] else "best"
    outcome = Confirmation(chosen, scores, {"best": best.step, "last": last_step}, episodes)
    _replace_policy_rows(record, policy, pd.concat(parts, ignore_index=True))
    atomic_write_json(
        policy.confirmed_path,
        {
            "model": chosen,
            "global_step": outcome.steps[chosen],
            "scores": scores,
            "steps": outcome.steps,
            "episodes": episodes,
            "saved": utc_now(),
        },
    )
    log(f"{name} keeps the {chosen} model")
    return outcome


def confirm_run(
    record: RunRecord,
    spec: ExperimentSpec,
    stop_requested: Callable[[], bool] = lambda: False,
    log: Callable[[str], None] | None = None,
) -> bool:
    """Confirm every policy of a run whose training is finished and that has no
    ``confirmed.json`` yet (:func:`confirm_policy`); nothing without
    ``training.confirm_episodes``. Returns ``False`` if a stop request cut it short."""
    if spec.training.confirm_episodes < 1:
        return True
    for policy in PolicyDir.all_of_run(record.path, spec.controller == "independent"):
        done = policy.confirmed_choice() is not None
        if not done and confirm_policy(record, spec, policy, stop_requested, log) is None:
            return False
    return True


def _model_step(path: Path) -> int:
    """The env steps of the SB3/sbx model saved in ``path`` (``num_timesteps`` in its data)."""
    with zipfile.ZipFile(path) as archive:
        return int(json.loads(archive.read("data"))["num_timesteps"])


def _replace_policy_rows(record: RunRecord, policy: PolicyDir, rows: pd.DataFrame) -> None:
    path = record.table_path(CONFIRMATION_TABLE)
    if path.exists():
        old = read_table(path)
        old = old[~policy.row_mask(old)]
        rows = pd.concat([old, rows], ignore_index=True) if len(old) else rows
    write_table(path, rows.reset_index(drop=True))
