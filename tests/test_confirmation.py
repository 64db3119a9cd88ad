"""Confirmation after training (``training.confirm_episodes``): the candidates' rows, the
kept model, evaluation with it, a stop during confirmation, and the independent baseline."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from test_train import _spec
from test_validation import VALIDATED, _episode_metrics, _report_rows, _train
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.evaluation import CONFIRM_SEED, validation_score
from softtrack.rl.confirmation import confirm_policy, confirm_run
from softtrack.rl.policy import model_paths
from softtrack.store.atomic import atomic_write_json
from softtrack.store.layout import PolicyDir
from softtrack.store.runs import RunRecord, RunStore
from softtrack.store.tables import read_table

runner = CliRunner()

CONFIRMED = {**VALIDATED, "final_policy": "best_validated", "confirm_episodes": 3}


def _confirmation(record: RunRecord) -> pd.DataFrame:
    return read_table(record.table_path("confirmation"))


def _check_candidates(rows: pd.DataFrame, policy: PolicyDir, arms: list[int]) -> dict[str, float]:
    """Each candidate scored once on episodes 0..2 from the confirmation seeds, a row per arm;
    ``confirmed.json`` keeps the lower score (ties: best). Returns candidate → score."""
    scores = {}
    for candidate, part in rows.groupby("candidate"):
        assert sorted(zip(part["episode"], part["arm"], strict=True)) == [
            (k, arm) for k in range(3) for arm in arms
        ]
        assert (part["seed"] == CONFIRM_SEED + part["episode"]).all()
        assert part["global_step"].nunique() == 1
        scores[str(candidate)] = validation_score(part)
    state = json.loads(policy.confirmed_path.read_text())
    assert state["scores"]["best"] == scores["best"]
    assert state["scores"]["last"] == scores.get("last", scores["best"])
    expected = "last" if state["scores"]["last"] < state["scores"]["best"] else "best"
    assert state["model"] == expected == policy.confirmed_choice()
    assert state["episodes"] == 3
    return scores


def _make_best_an_early_checkpoint(policy: PolicyDir, step: int) -> None:
    """Replace ``policy``'s best model by its checkpoint at ``step`` (with a low score), so
    that best and last are two different models."""
    shutil.rmtree(policy.best_dir)
    target = policy.best_step_dir(step)
    target.mkdir(parents=True)
    shutil.copy2(policy.checkpoint_dir(step) / "model.zip", target / "model.zip")
    atomic_write_json(target / "state.json", {"global_step": step, "score": 0.0, "episodes": 2})


def test_confirmation_keeps_the_better_candidate_and_evaluation_uses_it(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=800, keep_checkpoints=4, **CONFIRMED)
    record = _train(spec, tmp_path / "runs")
    run_spec = record.load_spec()
    policy = PolicyDir.of_run(record.path)
    scores = _check_candidates(_confirmation(record), policy, [0, 1])
    assert set(scores) == (
        {"best"} if policy.list_best()[-1].name.endswith("800") else {"best", "last"}
    )

    # two distinct candidates, confirmed again from scratch
    _make_best_an_early_checkpoint(policy, 200)
    policy.confirmed_path.unlink()
    outcome = confirm_run(record, run_spec, log=lambda _line: None)
    assert outcome
    rows = _confirmation(record)
    scores = _check_candidates(rows, policy, [0, 1])
    assert set(scores) == {"best", "last"}
    steps = rows.groupby("candidate")["global_step"].first().to_dict()
    assert steps == {"best": 200, "last": 800}
    chosen = policy.confirmed_choice()
    assert chosen is not None
    path = policy.best_model_path if chosen == "best" else policy.model_path
    assert model_paths(record, run_spec) == [path]

    for candidate, model in (("last", policy.model_path), ("best", policy.best_model_path)):
        atomic_write_json(policy.confirmed_path, {"model": candidate})
        assert model_paths(record, run_spec) == [model]
    atomic_write_json(policy.confirmed_path, {"model": chosen})

    # the stored rows are the chosen model's episodes
    stored = rows[(rows["candidate"] == chosen) & (rows["episode"] == 2)]
    again = _episode_metrics(path, run_spec, None, "random", CONFIRM_SEED + 2)
    np.testing.assert_allclose(again["rmse_3d"], stored["rmse_3d"], rtol=1e-12)


def test_a_stopped_confirmation_writes_nothing(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=400, **CONFIRMED)
    record = _train(spec, tmp_path / "runs")
    policy = PolicyDir.of_run(record.path)
    before = _confirmation(record)
    policy.confirmed_path.unlink()
    calls = iter([False, True])  # checked before each batch of episodes: stops at the second
    assert confirm_policy(record, record.load_spec(), policy, lambda: next(calls)) is None
    assert policy.confirmed_choice() is None
    pd.testing.assert_frame_equal(_confirmation(record), before)
    # until it is confirmed, the run's policy is its best-validated model
    assert model_paths(record, record.load_spec()) == [policy.best_model_path]

    # as if the process had been stopped there: resuming confirms the policy again
    store = RunStore(record.path.parent)
    store.mark_finished(record.run_id, "interrupted")
    result = runner.invoke(
        app,
        ["train", "--resume", record.run_id, "--runs-dir", str(record.path.parent)],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    assert store.get_run(record.run_id).info.status == "completed"
    _check_candidates(_confirmation(record), policy, [0, 1])
    pd.testing.assert_frame_equal(_confirmation(record), before)


def test_independent_arms_are_confirmed_in_their_own_scene(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=400, **CONFIRMED)
    data = yaml.safe_load(spec.read_text())
    data["controller"] = "independent"
    spec.write_text(yaml.safe_dump(data))
    record = _train(spec, tmp_path / "runs")
    rows = _confirmation(record)
    paths = []
    for arm in (0, 1):
        policy = PolicyDir.of_run(record.path, arm)
        _check_candidates(rows[rows["arm"] == arm], policy, [arm])
        chosen = policy.confirmed_choice()
        paths.append(policy.best_model_path if chosen == "best" else policy.model_path)
        first = rows[(rows["arm"] == arm) & (rows["candidate"] == chosen) & (rows["episode"] == 0)]
        again = _episode_metrics(paths[-1], record.load_spec(), arm, "random", CONFIRM_SEED)
        np.testing.assert_allclose(again["rmse_3d"], first["rmse_3d"], rtol=1e-12)
    assert model_paths(record, record.load_spec()) == paths

    # the report's model-selection table shows both scores and the kept model
    rows_md = [row.strip("| ").split(" | ") for row in _report_rows(record, tmp_path)]
    for arm, cells in enumerate(rows_md):
        state = json.loads(PolicyDir.of_run(record.path, arm).confirmed_path.read_text())
        scores = state["scores"]
        assert cells[-2:] == [f"{scores['best']:.4f} / {scores['last']:.4f}", state["model"]]
