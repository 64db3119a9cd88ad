"""Validation during training (``training.validation_episodes``): the table, the best model,
``final_policy: best_validated``, resume, and the independent baseline's arms."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml
from test_train import SBX_TD3, _interrupt, _latest_step, _spec
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.evaluation import metrics_table, run_episode
from softtrack.evaluation.episodes import VALIDATION_PATH_SEED
from softtrack.report.data import load_run
from softtrack.report.group_summaries import validation_scores
from softtrack.rl.factory import algo_class
from softtrack.rl.policy import deterministic_policy, model_paths
from softtrack.rl.validation import (
    VALIDATION_SEED,
    checkpoint_rows,
    truncate_validation,
    validation_score,
)
from softtrack.spec import ExperimentSpec
from softtrack.spec.env_config import env_config
from softtrack.store.layout import PolicyDir
from softtrack.store.runs import RunRecord, RunStore
from softtrack.store.status import final_stage_return
from softtrack.store.tables import read_table, write_table

runner = CliRunner()

EPISODES = 2
VALIDATED = {"validation_episodes": EPISODES, "eval_duration": 0.1}


def _train(spec: Path, runs_dir: Path, seed: int = 0) -> RunRecord:
    result = runner.invoke(
        app,
        ["train", str(spec), "--runs-dir", str(runs_dir), "--seed", str(seed)],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    return RunStore(runs_dir).get_run(result.stdout.strip())


def _validation(record: RunRecord) -> pd.DataFrame:
    return read_table(record.table_path("validation"))


def _check_rows(table: pd.DataFrame, steps: list[int], arms: list[int]) -> dict[int, float]:
    """Every step validated once: episodes 0..EPISODES-1 from the validation seeds, each
    with a row per arm. Returns each step's score."""
    assert sorted(set(table["global_step"])) == steps
    for _step, rows in table.groupby("global_step"):
        assert sorted(zip(rows["episode"], rows["arm"], strict=True)) == [
            (k, arm) for k in range(EPISODES) for arm in arms
        ]
        assert (rows["seed"] == VALIDATION_SEED + rows["episode"]).all()
        assert (rows["trajectory"] == "random").all()
    return {int(s): validation_score(rows) for s, rows in table.groupby("global_step")}


def _best_of(scores: dict[int, float]) -> int:
    """The step kept as best: the first one strictly below all earlier scores that nothing
    later beats."""
    best_step, best = None, np.inf
    for step in sorted(scores):
        if scores[step] < best:
            best_step, best = step, scores[step]
    assert best_step is not None
    return best_step


def _episode_metrics(
    model_file: Path, spec: Any, arm: int | None, trajectory: str, seed: int = 0
) -> pd.DataFrame:
    model = algo_class("td3").load(str(model_file), device="cpu")
    policy = deterministic_policy(model)
    episode = run_episode(policy, env_config(spec, arm), trajectory, 0.1, seed=seed)
    return metrics_table("x", episode)


def _report_rows(record: RunRecord, tmp_path: Path) -> list[str]:
    """The rows of the report's model-selection table for ``record``'s experiment."""
    out = tmp_path / "report"
    result = runner.invoke(
        app,
        ["report", record.info.name, "--runs-dir", str(record.path.parent), "--out", str(out)],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    assert (out / "figures" / "validation.png").read_bytes()[:4] == b"\x89PNG"
    md = (out / "index.md").read_text(encoding="utf-8")
    block = md.split("## Model selection (validation during training)\n", 1)[1]
    return [line for line in block.split("\n\n", 1)[0].splitlines() if line.startswith("|")][2:]


def test_validation_keeps_the_best_model_and_evaluation_uses_it(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=800, final_policy="best_validated", **VALIDATED)
    record = _train(spec, tmp_path / "runs")
    run_spec = record.load_spec()
    scores = _check_rows(_validation(record), [200, 400, 600, 800], [0, 1])
    best_step = _best_of(scores)
    # each checkpoint's rows carry the training clock, which validation does not advance
    clock = _validation(record).groupby("global_step")["wall_time"].agg(["min", "max"])
    assert (clock["min"] == clock["max"]).all() and clock["min"].is_monotonic_increasing
    train_clock = read_table(record.table_path("train_episodes"))["wall_time"].max()
    assert 0 < clock["min"].iloc[0] <= train_clock
    policy = PolicyDir.of_run(record.path)
    assert [p.name for p in policy.list_best()] == [f"step-{best_step:012d}"]
    state = json.loads((policy.list_best()[0] / "state.json").read_text())
    assert state["global_step"] == best_step and state["score"] == scores[best_step]
    assert model_paths(record, run_spec) == [policy.best_model_path]

    # the kept model is the one validated at that step: its batch repeats the stored rows bit
    # for bit, and one episode alone (evaluation's one observation per call) to rounding
    rows = _validation(record)
    stored = rows[rows["global_step"] == best_step].drop(columns=["global_step", "wall_time"])
    model = algo_class("td3").load(str(policy.best_model_path), device="cpu")
    batch = checkpoint_rows(
        record.run_id,
        deterministic_policy(model, batches=True),
        env_config(run_spec, None),
        0.1,
        EPISODES,
        [],
        None,
    )
    pd.testing.assert_frame_equal(batch, stored.reset_index(drop=True), check_exact=True)
    alone = _episode_metrics(policy.best_model_path, run_spec, None, "random", VALIDATION_SEED + 1)
    np.testing.assert_allclose(alone["rmse_3d"], stored.iloc[2:]["rmse_3d"], rtol=1e-6)

    # `softtrack evaluate` tracks with the best model, not the last one
    result = runner.invoke(
        app,
        ["evaluate", record.run_id, "-t", "circle", "--runs-dir", str(tmp_path / "runs")],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    evaluated = read_table(record.table_path("eval_metrics"))
    expected = _episode_metrics(policy.best_model_path, run_spec, None, "circle")
    np.testing.assert_allclose(evaluated["rmse_3d"], expected["rmse_3d"], rtol=1e-12)

    # an export's model.zip is the policy (the best model), the last one is kept aside, and
    # it evaluates the same
    out = tmp_path / "exported"
    result = runner.invoke(
        app, ["export", record.run_id, str(out), "--runs-dir", str(tmp_path / "runs")]
    )
    assert result.exit_code == 0, result.output
    manifest = json.loads((out / "policy.json").read_text())
    assert manifest["model"] == "best" and manifest["global_step"] == best_step
    assert manifest["other_models"]["last"]["path"] == "other_models/last/model.zip"
    assert (out / "other_models" / "last" / "model.zip").is_file()
    assert not (out / "checkpoints").exists() and not (out / "best").exists()
    assert (
        _episode_metrics(out / "model.zip", run_spec, None, "circle")["rmse_3d"].tolist()
        == expected["rmse_3d"].tolist()
    )
    result = runner.invoke(app, ["evaluate", str(out), "-t", "circle"], env={"CI": "1"})
    assert result.exit_code == 0, result.output
    exported = read_table(out / "tables" / "eval_metrics.parquet")
    np.testing.assert_allclose(exported["rmse_3d"], expected["rmse_3d"], rtol=1e-12)

    # --model last tracks with the last model and only prints: the tables keep the policy's
    assert model_paths(record, run_spec, "last") == [policy.model_path]
    stored = read_table(record.table_path("eval_metrics"))
    result = runner.invoke(
        app,
        [
            "evaluate",
            record.run_id,
            "-t",
            "circle",
            "--model",
            "last",
            "--runs-dir",
            str(tmp_path / "runs"),
        ],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    last = _episode_metrics(policy.model_path, run_spec, None, "circle").sort_values("arm")
    assert " / ".join(f"{v:.4f}" for v in last["rmse_3d"]) in result.stdout
    pd.testing.assert_frame_equal(read_table(record.table_path("eval_metrics")), stored)

    # the report names the kept checkpoint and plots every validation
    rows = _report_rows(record, tmp_path)
    expected_row = (
        f"| TD3 | 0 | both arms | 4 | {best_step:,} | {scores[best_step]:.4f} | 800 "
        f"| {scores[800]:.4f} | – | best |"
    )
    assert rows == [expected_row]


@pytest.mark.parametrize("algo, backend", [("td3", "sb3"), SBX_TD3])
def test_validation_leaves_training_unchanged(tmp_path: Path, algo: str, backend: str) -> None:
    plain = _train(_spec(tmp_path, algo, backend, total_timesteps=600), tmp_path / "a")
    validated_spec = tmp_path / "validated.yaml"
    data = yaml.safe_load(
        _spec(tmp_path, algo, backend, total_timesteps=600, **VALIDATED).read_text()
    )
    validated_spec.write_text(yaml.safe_dump(data))
    validated = _train(validated_spec, tmp_path / "b")
    returns = [read_table(r.table_path("train_episodes"))["return"] for r in (plain, validated)]
    np.testing.assert_array_equal(returns[0], returns[1])
    assert not plain.table_path("validation").exists()
    _check_rows(_validation(validated), [200, 400, 600], [0, 1])
    # final_policy last: the run's policy stays model.zip even though best/ exists
    assert model_paths(validated, validated.load_spec()) == [validated.model_path]
    assert PolicyDir.of_run(validated.path).list_best()
    best = PolicyDir.of_run(validated.path).best_model_path
    assert model_paths(validated, validated.load_spec(), "best") == [best]
    # a run trained without validation has no best model to evaluate
    result = runner.invoke(
        app,
        ["evaluate", plain.run_id, "--model", "best", "--runs-dir", str(tmp_path / "a")],
        env={"CI": "1"},
    )
    assert result.exit_code == 2
    assert "trained without validation" in result.output and "--model last" in result.output
    assert not plain.table_path("eval_metrics").exists()


def test_validation_trajectories_track_each_checkpoint_without_entering_the_score(
    tmp_path: Path,
) -> None:
    plain = _train(
        _spec(tmp_path, total_timesteps=400, final_policy="best_validated", **VALIDATED),
        tmp_path / "a",
    )
    spec = _spec(
        tmp_path,
        total_timesteps=400,
        final_policy="best_validated",
        validation_trajectories=True,
        eval_trajectories=["circle", "figure8"],
        **VALIDATED,
    )
    tracked = _train(spec, tmp_path / "b")
    table = _validation(tracked)
    random_rows = table[table["trajectory"] == "random"].reset_index(drop=True)
    # the held-out episodes, the scores and the kept model are those of the plain run
    scores = _check_rows(random_rows, [200, 400], [0, 1])
    assert scores == _check_rows(_validation(plain), [200, 400], [0, 1])
    assert {s: validation_score(rows) for s, rows in table.groupby("global_step")} == scores
    # the report reads the trajectory column too, so its scores are the validator's
    reported = validation_scores(load_run(tracked))
    assert dict(zip(reported["global_step"], reported["score"], strict=True)) == scores
    best = PolicyDir.of_run(tracked.path)
    assert [p.name for p in best.list_best()] == [f"step-{_best_of(scores):012d}"]
    # each checkpoint adds one episode per evaluation trajectory and arm, at its training clock
    extra = table[table["trajectory"] != "random"]
    assert sorted(zip(extra["global_step"], extra["trajectory"], extra["arm"], strict=True)) == [
        (step, t, arm) for step in (200, 400) for t in ("circle", "figure8") for arm in (0, 1)
    ]
    assert (extra["episode"] == 0).all() and (extra["seed"] == 0).all()
    clock = table.groupby("global_step")["wall_time"].nunique()
    assert (clock == 1).all()
    # they are the evaluation episodes of the checkpoint's model
    rows = extra[(extra["global_step"] == _best_of(scores)) & (extra["trajectory"] == "figure8")]
    again = _episode_metrics(best.best_model_path, tracked.load_spec(), None, "figure8")
    np.testing.assert_allclose(again["rmse_3d"], rows["rmse_3d"], rtol=1e-6)


def test_a_checkpoint_split_over_several_batches_gives_the_same_rows(tmp_path: Path) -> None:
    """``checkpoint_rows`` in batches of 3 environments (random targets, held-out paths and a
    trajectory spread over three batches) returns the rows of one batch of all of them."""

    def act(observation: np.ndarray) -> np.ndarray:
        return np.tanh(0.1 * np.atleast_2d(observation)[:, :24])

    act.accepts_batches = True  # type: ignore[attr-defined]
    config = env_config(ExperimentSpec(name="x"), None)
    one, split = (
        checkpoint_rows("x", act, config, 0.1, 3, ["circle"], None, paths=3, batch=batch)
        for batch in (32, 3)
    )
    assert one is not None and split is not None and len(one) == 2 * 7
    assert one["trajectory"].tolist() == split["trajectory"].tolist()
    pd.testing.assert_frame_equal(one, split, check_exact=True)


def test_held_out_paths_enter_the_score_and_the_evaluation_trajectories_do_not(
    tmp_path: Path,
) -> None:
    """``training.validation_paths``: each checkpoint also runs that many held-out path
    episodes (target mode ``paths``, seeds from VALIDATION_PATH_SEED, numbered after the
    random ones); the score, the kept model and the report's scores average the random and
    the path episodes, never the evaluation trajectories."""
    spec = _spec(
        tmp_path,
        total_timesteps=400,
        final_policy="best_validated",
        validation_paths=2,
        validation_trajectories=True,
        eval_trajectories=["circle"],
        **VALIDATED,
    )
    record = _train(spec, tmp_path / "runs")
    table = _validation(record)
    paths = table[table["trajectory"] == "paths"]
    assert sorted(zip(paths["global_step"], paths["episode"], paths["seed"], strict=True)) == [
        (step, EPISODES + k, VALIDATION_PATH_SEED + k)
        for step in (200, 400)
        for k in range(2)
        for _arm in (0, 1)
    ]
    scored = table[table["trajectory"].isin(["random", "paths"])]
    scores = {s: float(rows["rmse_3d"].mean()) for s, rows in scored.groupby("global_step")}
    assert {s: validation_score(rows) for s, rows in table.groupby("global_step")} == scores
    reported = validation_scores(load_run(record))
    assert dict(zip(reported["global_step"], reported["score"], strict=True)) == scores
    best = PolicyDir.of_run(record.path)
    assert [p.name for p in best.list_best()] == [f"step-{_best_of(scores):012d}"]
    # a path row is the episode of the checkpoint's model on that drawn path
    rows = paths[(paths["global_step"] == _best_of(scores)) & (paths["episode"] == EPISODES + 1)]
    again = _episode_metrics(
        best.best_model_path, record.load_spec(), None, "paths", VALIDATION_PATH_SEED + 1
    )
    np.testing.assert_allclose(again["rmse_3d"], rows["rmse_3d"], rtol=1e-6)


def test_a_score_on_the_held_out_paths_alone(tmp_path: Path) -> None:
    """``training.validation_score: paths``: the score, the kept model and the report's
    scores average the held-out path rows only; without paths the spec is refused."""
    spec = _spec(
        tmp_path,
        total_timesteps=400,
        final_policy="best_validated",
        validation_paths=2,
        validation_score="paths",
        **VALIDATED,
    )
    record = _train(spec, tmp_path / "runs")
    table = _validation(record)
    paths = table[table["trajectory"] == "paths"]
    scores = {s: float(rows["rmse_3d"].mean()) for s, rows in paths.groupby("global_step")}
    reported = validation_scores(load_run(record))
    assert dict(zip(reported["global_step"], reported["score"], strict=True)) == scores
    best = PolicyDir.of_run(record.path)
    assert [p.name for p in best.list_best()] == [f"step-{_best_of(scores):012d}"]
    refused = runner.invoke(
        app, ["validate", str(_spec(tmp_path, validation_score="paths", **VALIDATED))]
    )
    assert refused.exit_code == 2 and "validation_paths" in refused.output


def test_held_out_paths_alone_validate_without_random_episodes(tmp_path: Path) -> None:
    """``validation_episodes: 0`` with ``validation_paths``: each checkpoint runs the paths
    alone (numbered from 0), scored, kept and stopped on as with random episodes beside them;
    the path episodes are those of a run that also has random ones (training is the same)."""
    settings = {"total_timesteps": 400, "final_policy": "best_validated", "eval_duration": 0.1}
    alone = _train(
        _spec(
            tmp_path,
            "td3",
            "sbx",  # validated through the NumPy actor
            validation_paths=2,
            validation_episodes=0,
            stop_score=1e-9,
            **settings,
        ),
        tmp_path / "alone",
    )
    beside = _train(
        _spec(tmp_path, "td3", "sbx", validation_paths=2, validation_episodes=EPISODES, **settings),
        tmp_path / "beside",
    )
    table = _validation(alone)
    assert set(table["trajectory"]) == {"paths"}
    assert sorted(set(zip(table["episode"], table["seed"], strict=True))) == [
        (k, VALIDATION_PATH_SEED + k) for k in range(2)
    ]
    paths = _validation(beside).query("trajectory == 'paths'")
    np.testing.assert_allclose(
        table.sort_values(["global_step", "seed", "arm"])["rmse_3d"].to_numpy(),
        paths.sort_values(["global_step", "seed", "arm"])["rmse_3d"].to_numpy(),
        rtol=1e-5,
    )
    scores = {s: float(rows["rmse_3d"].mean()) for s, rows in table.groupby("global_step")}
    best = PolicyDir.of_run(alone.path)
    assert [p.name for p in best.list_best()] == [f"step-{_best_of(scores):012d}"]
    neither = runner.invoke(
        app, ["validate", str(_spec(tmp_path, validation_episodes=0, stop_score=0.04))]
    )
    assert neither.exit_code == 2 and "validation_paths" in neither.output


def test_training_ends_early_at_the_stop_score_and_the_run_completes(tmp_path: Path) -> None:
    """``training.stop_score``: the first validation at or below it ends training there; the
    run is completed (not interrupted) with fewer steps than its budget, says so, and its
    policy is the best-validated model; a score never reached trains the whole budget."""
    spec = _spec(
        tmp_path, total_timesteps=800, final_policy="best_validated", stop_score=100.0, **VALIDATED
    )
    result = runner.invoke(
        app,
        ["train", str(spec), "--runs-dir", str(tmp_path / "runs"), "--seed", "0"],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    record = RunStore(tmp_path / "runs").get_run(result.stdout.strip())
    assert record.info.status == "completed" and record.info.global_step == 200
    assert sorted(set(_validation(record)["global_step"])) == [200]
    assert "training ends here" in result.stderr and "finished early: 200/800" in result.stderr
    policy = PolicyDir.of_run(record.path)
    assert model_paths(record, record.load_spec()) == [policy.best_model_path]
    # its final stage is the last tenth of the steps it trained, not of the budget
    mean, episodes, _ = final_stage_return(record)
    assert mean is not None and episodes > 0
    never = _train(
        _spec(tmp_path, total_timesteps=800, stop_score=1e-9, **VALIDATED), tmp_path / "b"
    )
    assert never.info.status == "completed" and never.info.global_step == 800


def test_the_stop_score_needs_validated_checkpoints(tmp_path: Path) -> None:
    result = runner.invoke(app, ["validate", str(_spec(tmp_path, stop_score=0.04))])
    assert result.exit_code == 2
    assert "stop_score" in result.output and "validation_episodes" in result.output


def test_interrupted_run_validates_every_checkpoint_once(tmp_path: Path) -> None:
    total = 2400
    spec = _spec(tmp_path, total_timesteps=total, n_envs=4, **VALIDATED)
    runs_dir = tmp_path / "runs"
    run_dir, _, _ = _interrupt(spec, runs_dir)
    split = _latest_step(run_dir)
    assert 200 <= split < total
    # as if the stop had cut the validation of the checkpoint interval it fell in short
    record = RunStore(runs_dir).get_run(run_dir.name)
    table = read_table(record.table_path("validation"), missing_ok=True)
    if len(table):
        write_table(
            record.table_path("validation"),
            table[table["global_step"] // 200 != split // 200].reset_index(drop=True),
        )
    result = runner.invoke(
        app, ["train", "--resume", run_dir.name, "--runs-dir", str(runs_dir)], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    expected = {step for step in range(200, total + 1, 200) if step // 200 != split // 200}
    scores = _check_rows(_validation(record), sorted(expected | {split}), [0, 1])
    assert [int(p.name.split("-")[1]) for p in record.policy_dir(None).list_best()] == [
        _best_of(scores)
    ]


def test_truncate_validation_keeps_other_arms_and_earlier_steps(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    record = RunRecord("r", run_dir, None)  # type: ignore[arg-type]  # (run.json unused)
    rows = pd.DataFrame(
        {
            "run_id": "r",
            "global_step": [100, 200, 300, 100, 200, 300],
            "episode": 0,
            "arm": [0, 0, 0, 1, 1, 1],
            "rmse_3d": 0.1,
            "terminated": False,
        }
    )
    write_table(record.table_path("validation"), rows)
    arm0 = PolicyDir.of_run(run_dir, 0)
    for step in (100, 300):
        arm0.best_step_dir(step).mkdir(parents=True)
    truncate_validation(record, arm0, 200)
    left = read_table(record.table_path("validation"))
    assert list(zip(left["arm"], left["global_step"], strict=True)) == [
        (0, 100),
        (0, 200),
        (1, 100),
        (1, 200),
        (1, 300),
    ]
    assert [p.name for p in arm0.list_best()] == [f"step-{100:012d}"]
    truncate_validation(record, PolicyDir.of_run(run_dir, 1), None)
    assert set(read_table(record.table_path("validation"))["arm"]) == {0}
    assert not arm0.best_model_path.is_file()  # a best directory without a model is not one


def test_independent_arms_validate_in_their_own_scene(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=400, final_policy="best_validated", **VALIDATED)
    data = yaml.safe_load(spec.read_text())
    data["controller"] = "independent"
    spec.write_text(yaml.safe_dump(data))
    record = _train(spec, tmp_path / "runs")
    table = _validation(record)
    assert (np.diff(table["arm"].to_numpy()) >= 0).all()  # arm 0's rows, then arm 1's
    # each arm alone in its scene: no other arm to keep clear of
    assert table["min_arm_distance"].isna().all() and (table["collision_steps"] == 0).all()
    assert np.isfinite(table["torque_rate_rms"].to_numpy(float)).all()
    run_spec = record.load_spec()
    paths = []
    for arm in (0, 1):
        scores = _check_rows(table[table["arm"] == arm], [200, 400], [arm])
        policy = PolicyDir.of_run(record.path, arm)
        assert [p.name for p in policy.list_best()] == [f"step-{_best_of(scores):012d}"]
        rows = table[(table["arm"] == arm) & (table["global_step"] == _best_of(scores))]
        again = _episode_metrics(policy.best_model_path, run_spec, arm, "random", VALIDATION_SEED)
        np.testing.assert_allclose(  # validation's batched policy calls: equal to rounding
            again["rmse_3d"], rows[rows["episode"] == 0]["rmse_3d"], rtol=1e-6
        )
        paths.append(policy.best_model_path)
    assert model_paths(record, run_spec) == paths
    result = runner.invoke(
        app,
        ["evaluate", record.run_id, "-t", "circle", "--runs-dir", str(tmp_path / "runs")],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    policies = [row.split(" | ")[2] for row in _report_rows(record, tmp_path)]
    assert policies == ["arm 1 policy", "arm 2 policy"]


def test_training_clock_leaves_paused_time_out() -> None:
    import time

    from softtrack.rl.callbacks import TrainingClock

    clock = TrainingClock(offset=10.0)
    before = clock.elapsed()
    with clock.paused():
        time.sleep(0.2)
    assert 10.0 <= before <= clock.elapsed() < before + 0.1


def test_a_checkpoint_whose_episodes_all_drop_is_scored_by_its_hold(tmp_path: Path) -> None:
    """Every validation episode of an untrained transport policy drops the sphere: training
    completes and the checkpoint's score counts the steps after each drop at 1 m
    (``validation_score`` with the episodes' length), finite; a null score in
    ``state.json`` (every episode non-finite) reads back as ∞."""
    from softtrack.rl.validation import best_model

    spec = (
        Path(__file__).parents[1]
        / "experiments/variants/td3-sbx-128-1e6-mirror-fast-transport.yaml"
    )
    settings = {
        "training.total_timesteps": 300,
        "algo.learning_starts": 100,
        "algo.batch_size": 32,
        "training.checkpoint_interval": 150,
        "training.validation_episodes": 1,
        "training.validation_trajectories": "false",
        "training.eval_duration": 0.6,
        "training.n_envs": 1,
    }
    overrides = [arg for key, value in settings.items() for arg in ("--set", f"{key}={value}")]
    result = runner.invoke(
        app,
        ["train", str(spec), "--runs-dir", str(tmp_path), "--seed", "0", *overrides],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    record = RunStore(tmp_path).get_run(result.stdout.strip())
    rows = _validation(record)
    assert rows["terminated"].all() and rows["dropped"].all()
    policy = PolicyDir.of_run(record.path, None)
    state = json.loads((policy.list_best()[-1] / "state.json").read_text(encoding="utf-8"))
    first = rows[rows["global_step"] == state["global_step"]]
    assert state["score"] == pytest.approx(validation_score(first, 0.6))
    assert 0.0 < state["score"] < float("inf") == validation_score(first)
    best = best_model(policy)
    assert best is not None and best.score == state["score"]
    state["score"] = None
    (policy.list_best()[-1] / "state.json").write_text(json.dumps(state), encoding="utf-8")
    best = best_model(policy)
    assert best is not None and best.score == float("inf")
