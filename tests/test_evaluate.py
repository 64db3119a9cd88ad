"""``softtrack evaluate`` and ``softtrack report`` on tiny trained runs: tables, metrics
recomputed from the stored trajectories, copied run directories, errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.evaluation.metrics import (
    ACTION_STATISTICS,
    SAFETY_STATISTICS,
    TORQUE_STATISTICS,
    action_statistics,
    safety_statistics,
    torque_statistics,
    tracking_metrics,
)
from softtrack.rl.policy import load_policy
from softtrack.store.runs import RunStore
from softtrack.store.tables import read_table

runner = CliRunner()
EVAL_DURATION = 0.4  # s: 200 control steps per trajectory keeps the test fast


def _train_tiny(tmp_path: Path, controller: str = "centralized") -> tuple[Path, str]:
    spec: dict[str, Any] = {
        "name": f"tiny-{controller}",
        "controller": controller,
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "device": "cpu",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 2000,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {
            "total_timesteps": 200,
            "n_envs": 2,
            "checkpoint_interval": 0,
            "eval_duration": EVAL_DURATION,
        },
    }
    path = tmp_path / f"{controller}.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["train", str(path), "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    run_id = result.output.split()[0]
    return runs, run_id


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    return _train_tiny(tmp_path_factory.mktemp("eval"))


def _own_copy(trained: tuple[Path, str], tmp_path: Path) -> Path:
    """A runs directory under ``tmp_path`` holding a copy of the trained run (its tables
    included), for a test that changes them."""
    runs, run_id = trained
    fresh = tmp_path / "runs"
    shutil.copytree(runs / run_id, fresh / run_id)
    return fresh


def _report_index(run_id: str, runs: Path, out: Path) -> str:
    """``softtrack report`` of one run into ``out``; the text of its index.md."""
    result = runner.invoke(app, ["report", run_id, "--runs-dir", str(runs), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return (out / "index.md").read_text(encoding="utf-8")


def test_evaluate_writes_tables_and_metrics_match_trajectories(trained: tuple[Path, str]) -> None:
    runs, run_id = trained
    result = runner.invoke(app, ["evaluate", run_id, "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    assert result.output.count("3-D RMSE arm 1 / arm 2") == 3
    tables = runs / run_id / "tables"
    trajectories = read_table(tables / "eval_trajectories.parquet")
    metrics = read_table(tables / "eval_metrics.parquet")
    moments = read_table(tables / "eval_moments.parquet")
    peaks = read_table(tables / "eval_moment_peaks.parquet")
    n_steps = round(EVAL_DURATION / 0.002)
    assert sorted(metrics["trajectory"].unique()) == ["circle", "figure8", "rectangle"]
    assert len(trajectories) == 3 * 2 * n_steps
    assert trajectories["tip_x"].dtype == np.float32
    assert len(moments) == 3 * 2 * 2 * n_steps
    assert list(moments.columns) == [
        "run_id",
        "trajectory",
        "step",
        "t",
        "arm",
        "direction",
        "rms_moment",
    ]
    assert moments["rms_moment"].dtype == np.float32
    assert len(peaks) == 3 * 2 * 2 * 20
    assert not (tables / "eval_element_moments.parquet").exists()  # only on request
    for (trajectory, arm), rows in trajectories.groupby(["trajectory", "arm"]):
        rows = rows.sort_values("step")
        assert rows["t"].iloc[0] == pytest.approx(0.002) and len(rows) == n_steps
        tip = rows[["tip_x", "tip_y", "tip_z"]].to_numpy()
        target = rows[["target_x", "target_y", "target_z"]].to_numpy()
        recomputed = tracking_metrics(tip, target)
        stored = metrics[(metrics["trajectory"] == trajectory) & (metrics["arm"] == arm)].iloc[0]
        for key, value in recomputed.items():  # positions are stored as float32
            assert stored[key] == pytest.approx(value, rel=1e-5, abs=1e-6), key
    # every row has the per-arm action statistics, in range
    for key in ACTION_STATISTICS:
        assert metrics[key].notna().all(), key
    assert metrics["action_saturation"].between(0.0, 1.0).all()
    assert metrics["action_change"].between(0.0, 2.0).all()
    assert metrics["action_rms"].between(0.0, 1.0).all()
    # and the torque and clearance columns: finite, the clearance per episode (both arms' rows)
    for key in (*TORQUE_STATISTICS, *SAFETY_STATISTICS):
        assert np.isfinite(metrics[key].to_numpy(float)).all(), key
    assert (metrics.groupby("trajectory")["min_arm_distance"].nunique() == 1).all()
    for (trajectory, arm), rows in peaks.groupby(["trajectory", "arm"]):
        stored = metrics[(metrics["trajectory"] == trajectory) & (metrics["arm"] == arm)]
        assert np.float32(stored["peak_moment"].iloc[0]) == rows["peak_abs_moment"].max()


def test_full_moments_on_request_agree_with_the_summaries(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    runs = _own_copy(trained, tmp_path)
    run_id = trained[1]
    tables = runs / run_id / "tables"
    result = runner.invoke(
        app, ["evaluate", run_id, "--runs-dir", str(runs), "-t", "circle", "--full-moments"]
    )
    assert result.exit_code == 0, result.output
    full = read_table(tables / "eval_element_moments.parquet")
    assert set(full["trajectory"]) == {"circle"}
    moments = read_table(tables / "eval_moments.parquet").query("trajectory == 'circle'")
    peaks = read_table(tables / "eval_moment_peaks.parquet").query("trajectory == 'circle'")
    assert list(full[["step", "arm", "direction"]].itertuples(index=False)) == list(
        moments[["step", "arm", "direction"]].itertuples(index=False)
    )
    torques = np.stack(full["element_torques"].to_numpy()).astype(np.float64)  # (rows, 20)
    assert np.allclose(np.sqrt((torques**2).mean(axis=1)), moments["rms_moment"], rtol=1e-6)
    for (arm, direction), rows in full.groupby(["arm", "direction"]):
        expected = np.abs(np.stack(rows["element_torques"].to_numpy())).max(axis=0)
        stored = peaks[(peaks["arm"] == arm) & (peaks["direction"] == direction)]
        assert np.array_equal(stored.sort_values("element")["peak_abs_moment"], expected)
    # evaluating again without the option drops the now stale full history
    result = runner.invoke(app, ["evaluate", run_id, "--runs-dir", str(runs), "-t", "circle"])
    assert result.exit_code == 0, result.output
    assert not (tables / "eval_element_moments.parquet").exists()


def test_stored_action_statistics_match_the_episode_actions(trained: tuple[Path, str]) -> None:
    from softtrack import api

    runs, run_id = trained
    episodes = []
    api.evaluate(
        [run_id],
        ["circle", "figure8"],
        runs_dir=runs,
        on_episode=lambda record, episode, metrics: episodes.append(episode),
    )
    metrics = read_table(runs / run_id / "tables" / "eval_metrics.parquet")
    assert [e.trajectory for e in episodes] == ["circle", "figure8"]
    for episode in episodes:
        assert episode.actions.shape == (len(episode.t), 24)
        for arm in (0, 1):
            expected = action_statistics(episode.actions[:, 12 * arm : 12 * (arm + 1)])
            stored = metrics[
                (metrics["trajectory"] == episode.trajectory) & (metrics["arm"] == arm)
            ].iloc[0]
            for key, value in expected.items():
                assert stored[key] == pytest.approx(value, rel=1e-12, abs=1e-15), key
            expected = {
                **torque_statistics(episode.element_torques[:, arm], episode.t),
                **safety_statistics(episode.clearance, episode.collision_margin),
            }
            for key, value in expected.items():
                assert stored[key] == pytest.approx(value, rel=1e-12, abs=1e-15), key


def test_evaluate_one_trajectory_keeps_the_others(trained: tuple[Path, str]) -> None:
    runs, run_id = trained
    assert runner.invoke(app, ["evaluate", run_id, "--runs-dir", str(runs)]).exit_code == 0
    before = read_table(runs / run_id / "tables" / "eval_metrics.parquet")
    result = runner.invoke(app, ["evaluate", run_id, "-t", "circle", "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    after = read_table(runs / run_id / "tables" / "eval_metrics.parquet")
    assert len(after) == len(before) == 6
    key = ["trajectory", "arm"]
    merged = before.sort_values(key).reset_index(drop=True)
    # deterministic policy and physics: re-evaluating gives the same numbers
    assert np.allclose(after.sort_values(key)["rmse_3d"].to_numpy(), merged["rmse_3d"].to_numpy())


def test_old_metrics_tables_without_action_columns_stay_valid(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    from softtrack.evaluation.run_evaluation import has_evaluation
    from softtrack.store.tables import write_table

    run_id = trained[1]
    fresh = _own_copy(trained, tmp_path)
    assert runner.invoke(app, ["evaluate", run_id, "--runs-dir", str(fresh)]).exit_code == 0
    path = fresh / run_id / "tables" / "eval_metrics.parquet"
    new_columns = [*ACTION_STATISTICS, *TORQUE_STATISTICS, *SAFETY_STATISTICS]
    write_table(path, read_table(path).drop(columns=new_columns))  # as written before
    record = RunStore(fresh).get_run(run_id)
    assert has_evaluation(record)  # an old table is still a complete evaluation
    # re-evaluating one trajectory adds the columns for it; the old rows have none
    result = runner.invoke(app, ["evaluate", run_id, "-t", "circle", "--runs-dir", str(fresh)])
    assert result.exit_code == 0, result.output
    metrics = read_table(path)
    circle = metrics["trajectory"] == "circle"
    assert len(metrics) == 6 and metrics.loc[circle, "action_rms"].notna().all()
    assert metrics.loc[circle, [*TORQUE_STATISTICS, *SAFETY_STATISTICS]].notna().all().all()
    assert metrics.loc[~circle, new_columns].isna().all().all()
    assert has_evaluation(record)
    assert "### Policy actions" in _report_index(run_id, fresh, tmp_path / "report")


def test_random_target_episodes_are_held_out_seeded_and_reported(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    from softtrack.evaluation import RANDOM_TARGET_SEED
    from softtrack.evaluation.run_evaluation import evaluate_random_targets

    run_id = trained[1]
    fresh = _own_copy(trained, tmp_path)
    for table in (fresh / run_id / "tables").glob("eval_*.parquet"):
        table.unlink()
    result = runner.invoke(
        app, ["evaluate", run_id, "-t", "none", "--random", "2", "--runs-dir", str(fresh)]
    )
    assert result.exit_code == 0, result.output
    assert "circle" not in result.output  # -t none: only the random-target episodes
    assert not (fresh / run_id / "tables" / "eval_metrics.parquet").exists()
    line = next(x for x in result.output.splitlines() if " random     3-D RMSE" in x)
    assert "(mean ± std over 2 episodes)" in line
    table = read_table(fresh / run_id / "tables" / "eval_random.parquet")
    assert len(table) == 4 and set(table["trajectory"]) == {"random"}
    assert sorted(set(table["seed"])) == [RANDOM_TARGET_SEED, RANDOM_TARGET_SEED + 1]
    arm1 = table[table["arm"] == 0].sort_values("episode")["rmse_3d"].to_numpy()
    assert arm1[0] != arm1[1]  # two different target paths
    assert f"{arm1.mean():.4f} ± {arm1.std(ddof=1):.4f} /" in line

    # the stored rows are the metrics of the episodes, and repeat exactly
    record = RunStore(fresh).get_run(run_id)
    episodes: list[Any] = []
    again = evaluate_random_targets(
        record, 2, lambda _r, episode, _m: episodes.append(episode), load=load_policy, write=False
    )
    np.testing.assert_array_equal(again["rmse_3d"].to_numpy(), table["rmse_3d"].to_numpy())
    for k, episode in enumerate(episodes):
        expected = tracking_metrics(episode.tips[:, 1], episode.target)["rmse_3d"]
        stored = table[(table["episode"] == k) & (table["arm"] == 1)]["rmse_3d"].item()
        assert stored == pytest.approx(expected, rel=1e-12)
    assert not np.allclose(episodes[0].target, episodes[1].target)

    index = _report_index(run_id, fresh, tmp_path / "report")
    assert "### Random training targets (held-out episodes)" in index
    assert f"| {arm1.mean():.4f} |" in index


def test_a_copied_run_directory_evaluates(trained: tuple[Path, str], tmp_path: Path) -> None:
    runs, run_id = trained
    copy = tmp_path / "elsewhere" / run_id
    shutil.copytree(runs / run_id, copy)
    shutil.rmtree(copy / "tables", ignore_errors=True)
    result = runner.invoke(app, ["evaluate", str(copy), "-t", "figure8"])
    assert result.exit_code == 0, result.output
    assert (copy / "tables" / "eval_metrics.parquet").is_file()


def test_report_evaluates_runs_without_evaluation(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    run_id = trained[1]
    fresh = _own_copy(trained, tmp_path)
    (fresh / run_id / "tables" / "eval_metrics.parquet").unlink(missing_ok=True)
    out = tmp_path / "report"
    index = _report_index(run_id, fresh, out)
    assert (fresh / run_id / "tables" / "eval_metrics.parquet").is_file()
    assert "0.065" in index  # the study's circle value beside the measured one
    assert (out / "figures" / "training_curves.png").is_file()


def test_independent_run_evaluates_with_one_policy_per_arm(tmp_path: Path) -> None:
    runs, run_id = _train_tiny(tmp_path, controller="independent")
    result = runner.invoke(app, ["evaluate", run_id, "-t", "rectangle", "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    metrics = read_table(runs / run_id / "tables" / "eval_metrics.parquet")
    assert sorted(metrics["arm"]) == [0, 1]


@pytest.mark.parametrize(
    "args, message",
    [
        (["evaluate", "NOSUCHRUN"], "no run"),
        (["evaluate", "X", "-t", "spiral"], "spiral"),
        (["evaluate", "X", "--random", "-1"], "--random"),
        (["evaluate", "X", "-t", "none"], "add --random N"),
        (["report", "nothing-here"], ""),
    ],
)
def test_user_errors_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    extra = ["--out", str(tmp_path / "r")] if args[0] == "report" else []
    result = runner.invoke(app, [*args, "--runs-dir", str(runs), *extra])
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert not (tmp_path / "r").exists()


def test_unfinished_run_has_no_model(tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    from softtrack.spec import ExperimentSpec

    record = RunStore(runs).create_run(ExperimentSpec(name="unfinished"), 0)
    result = runner.invoke(app, ["evaluate", record.run_id, "--runs-dir", str(runs)])
    assert result.exit_code == 2
    assert "no trained model" in result.output
    assert not (record.path / "tables" / "eval_metrics.parquet").exists()


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file()}


def test_export_keeps_what_evaluation_needs_and_drops_checkpoints(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    runs, run_id = trained
    source = runs / run_id
    (source / "checkpoints" / "step-000000100").mkdir(parents=True, exist_ok=True)
    (source / "checkpoints" / "step-000000100" / "replay_buffer.pkl").write_bytes(b"x" * 1000)
    dest = tmp_path / "models" / "tiny-seed0"
    result = runner.invoke(app, ["export", run_id, str(dest), "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    assert "exported:" in result.output
    exported = _tree(dest)
    assert {"spec.yaml", "run.json", "model.zip", "policy.json"} <= exported
    assert not any(name.startswith(("checkpoints", "run.lock")) for name in exported)
    expected = {n for n in _tree(source) if not n.startswith("checkpoints") and n != "run.lock"}
    assert exported == expected | {"policy.json"}
    assert json.loads((dest / "policy.json").read_text())["model"] == "last"
    # the export is a run directory: evaluation and reports take it as they are
    result = runner.invoke(app, ["evaluate", str(dest), "-t", "circle", "--in-place"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "report"
    result = runner.invoke(
        app, ["report", "tiny-centralized", "--runs-dir", str(dest.parent), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert "tiny-seed0" in (out / "index.md").read_text(encoding="utf-8")


def test_export_refuses_an_existing_destination_and_unfinished_runs(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    runs, run_id = trained
    dest = tmp_path / "taken"
    dest.mkdir()
    (dest / "keep.txt").write_text("mine", encoding="utf-8")
    result = runner.invoke(app, ["export", run_id, str(dest), "--runs-dir", str(runs)])
    assert result.exit_code == 2 and "already exists" in result.output
    assert _tree(dest) == {"keep.txt"}

    from softtrack.spec import ExperimentSpec

    record = RunStore(runs).create_run(ExperimentSpec(name="unfinished"), 0)
    result = runner.invoke(
        app, ["export", record.run_id, str(tmp_path / "new"), "--runs-dir", str(runs)]
    )
    assert result.exit_code == 2 and "no final model" in result.output
    assert not (tmp_path / "new").exists()
    shutil.rmtree(record.path)


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_evaluate_without_writing_leaves_the_run_untouched(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    from softtrack import api

    runs, run_id = trained
    shipped = tmp_path / "shipped"
    shutil.copytree(runs / run_id, shipped)
    assert runner.invoke(app, ["evaluate", str(shipped)]).exit_code == 0
    before = _files(shipped)
    live = api.evaluate([str(shipped)], write=False)
    assert _files(shipped) == before
    stored = read_table(shipped / "tables" / "eval_metrics.parquet")
    key = ["trajectory", "arm"]
    assert np.array_equal(
        live.sort_values(key)["rmse_3d"].to_numpy(), stored.sort_values(key)["rmse_3d"].to_numpy()
    )


TINY_QUICKSTART = [
    "--set",
    "training.total_timesteps=200",
    "--set",
    "training.n_envs=2",
    "--set",
    "training.checkpoint_interval=0",
    "--set",
    f"training.eval_duration={EVAL_DURATION}",
    "--set",
    "env.episode_duration=0.1",
    "--set",
    "algo.learning_starts=50",
    "--set",
    "algo.batch_size=16",
    "--set",
    "algo.buffer_size=2000",
    "--set",
    "algo.policy_kwargs.net_arch=[16, 16]",
]


def test_quickstart_reports_the_shipped_policy_beside_its_own_run(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    runs, run_id = trained
    shipped = tmp_path / "models" / "shipped-td3"
    assert (
        runner.invoke(app, ["export", run_id, str(shipped), "--runs-dir", str(runs)]).exit_code == 0
    )
    assert runner.invoke(app, ["evaluate", str(shipped), "--in-place"]).exit_code == 0
    before = _files(shipped)
    out = tmp_path / "report"
    result = runner.invoke(
        app,
        [
            "quickstart",
            *TINY_QUICKSTART,
            "--runs-dir",
            str(tmp_path / "runs"),
            "--out",
            str(out),
            "--pretrained",
            str(shipped),
        ],
    )
    assert result.exit_code == 0, result.output
    assert "3/4 the shipped policy" in result.output
    assert result.output.count("3-D RMSE arm 1 / arm 2") == 6  # own run + shipped policy
    assert _files(shipped) == before
    index = (out / "index.md").read_text(encoding="utf-8")
    assert "shipped-td3" in index and "quickstart" in index

    result = runner.invoke(
        app,
        [
            "quickstart",
            *TINY_QUICKSTART,
            "--runs-dir",
            str(tmp_path / "runs"),
            "--out",
            str(tmp_path / "r2"),
            "--pretrained",
            str(tmp_path / "nothing"),
        ],
    )
    assert result.exit_code == 2 and "not a run directory" in result.output
    assert not (tmp_path / "r2").exists()


def test_shipped_runs_are_read_only_unless_in_place(tmp_path: Path) -> None:
    """`softtrack evaluate models/<run>` (a README command) stores this machine's results in
    the run's copy in the runs directory; the shipped files stay byte for byte; --in-place
    writes into the shipped run on purpose."""
    shipped = Path("models/td3-sbx-1e7-seed0")
    before = _files(shipped)
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["evaluate", str(shipped), "-t", "circle", "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    assert "read-only" in result.stderr and str(runs / shipped.name) in result.stderr
    assert _files(shipped) == before
    copy = runs / shipped.name
    assert read_table(copy / "tables" / "eval_metrics.parquet")["trajectory"].tolist() == [
        "circle",
        "circle",
    ]
    assert json.loads((copy / "run.json").read_text())["notes"]["copy_of"] == str(shipped)
    result = runner.invoke(
        app,
        [
            "robustness",
            str(shipped),
            "-t",
            "circle",
            "--grid",
            "obs_noise=0.01",
            "--runs-dir",
            str(runs),
        ],
    )
    assert result.exit_code == 0, result.output
    assert _files(shipped) == before and (copy / "tables" / "eval_robustness.parquet").is_file()
    assert (copy / "tables" / "eval_metrics.parquet").is_file()  # the copy is reused, kept
    result = runner.invoke(app, ["evaluate", shipped.name, "--runs-dir", "models"])
    assert result.exit_code == 2 and "--in-place" in result.stderr
    mine = tmp_path / "mine"
    shutil.copytree(shipped, mine / shipped.name)
    result = runner.invoke(
        app, ["evaluate", str(mine / shipped.name), "-t", "circle", "--full-moments", "--in-place"]
    )
    assert result.exit_code == 0 and "read-only" not in result.stderr
    # written where asked (the circle's rows may come out byte-identical on this CPU: the
    # element moments are a table the shipped run does not have)
    assert (mine / shipped.name / "tables" / "eval_element_moments.parquet").is_file()
    # the rows written now name the run by its run.json id, not by its directory's name
    run_id = json.loads((shipped / "run.json").read_text())["run_id"]
    rows = read_table(mine / shipped.name / "tables" / "eval_metrics.parquet")
    assert set(rows.loc[rows["trajectory"] == "circle", "run_id"]) == {run_id}


def test_random_progress_measures_the_rate_after_the_first_batch(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Episodes finish in batches of 16 (the first after compiling): no rate until a batch
    after the first has closed, then that batches' rate; a planner's one-by-one episodes read
    as seconds per episode."""
    from types import SimpleNamespace

    from softtrack.commands.evaluate_commands import _RandomProgress

    now = [100.0]
    progress = _RandomProgress(clock=lambda: now[0])
    record = SimpleNamespace(run_id="01ABCDEFGH12345678")
    for batch, seconds in enumerate((30.0, 8.0, 4.0)):  # compile + 16, then 16 in 8 s, 8 in 4 s
        now[0] += seconds
        for done in range(16 * batch + 1, min(16 * batch + 16, 40) + 1):
            progress(record, done, 40)  # type: ignore[arg-type]
            now[0] += 0.0001
    lines = capsys.readouterr().err.splitlines()
    counted = {int(line.split("/")[0].split()[-1]): line for line in lines}
    assert all("episodes/s" not in counted[d] for d in counted if d <= 32)
    assert counted[34].startswith("12345678 random targets: 34/40 episodes (85%), 2.0 episodes/s")
    assert "0.1 min left" in counted[34]  # 6 more at 2 per second
    assert counted[40] == "12345678 random targets: 40/40 episodes (100%), 2.0 episodes/s"

    planner = _RandomProgress(clock=lambda: now[0])
    for done in (1, 2, 3):  # one episode at a time, 90 s each
        now[0] += 90.0
        planner(record, done, 20)  # type: ignore[arg-type]
    last = capsys.readouterr().err.splitlines()[-1]
    assert "3/20 episodes (15%), 90 s per episode, 25.5 min left" in last
