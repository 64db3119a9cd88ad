"""Sampling MPC (``controller: mpc``): engine state round trip, the planner against a zero-action
baseline, determinism, the spec section, `softtrack train` refusing and `softtrack evaluate`
creating and evaluating its run, the report's planning table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.env.settings import make_config
from softtrack.evaluation.episode_tables import metrics_table
from softtrack.evaluation.episodes import run_episode
from softtrack.mpc.controller import MpcController
from softtrack.mpc.planner import interpolation_matrix
from softtrack.mpc.planner_config import PlannerConfig
from softtrack.sim.engine import RodBatch
from softtrack.sim.params import SimParams
from softtrack.spec import ExperimentSpec, SpecError, load_spec
from softtrack.store.tables import read_table

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]
FIXED = (0.25, 0.75, 0.1)  # m: a target off the arms' straight line
SMALL = PlannerConfig(samples=8, horizon=25, knots=3, replan_interval=5)


def test_state_get_set_round_trip_is_bit_exact() -> None:
    batch = RodBatch(3, SimParams())
    rng = np.random.default_rng(0)
    batch.set_actions(rng.uniform(-1, 1, (3, 2, 2, 6)))
    batch.advance(40)
    saved = batch.get_state([1])
    batch.advance(10)
    after = batch.get_state([1])
    copy = RodBatch(5, SimParams())
    copy.set_state(saved)  # one state branched into five environments
    copy.set_element_torques(np.broadcast_to(batch.torques[1], copy.torques.shape))
    copy.advance(10)
    for name in ("position", "velocity", "directors", "omega", "time"):
        got, want = getattr(copy.get_state(), name), getattr(after, name)
        np.testing.assert_array_equal(got, np.broadcast_to(want, got.shape), err_msg=name)
    batch.set_state(saved, [2])
    np.testing.assert_array_equal(batch.get_state([2]).position, saved.position)
    with pytest.raises(ValueError, match="does not fit"):
        batch.set_state(copy.get_state())


def test_interpolation_matrix() -> None:
    np.testing.assert_array_equal(interpolation_matrix(4, 4), np.eye(4))
    weights = interpolation_matrix(5, 3)  # knots at steps 0, 2, 4
    np.testing.assert_allclose(weights @ np.array([0.0, 1.0, 0.0]), [0, 0.5, 1, 0.5, 0])
    np.testing.assert_allclose(weights.sum(axis=1), 1.0)


def _fixed_config() -> object:
    return make_config(target="fixed", fixed_position=FIXED, episode_duration=0.3)


def test_short_horizon_mpc_beats_zero_actions_on_a_fixed_target() -> None:
    config = _fixed_config()
    zero = metrics_table("z", run_episode(lambda obs: np.zeros(24), config, "fixed", 0.3))
    planned = run_episode(MpcController(SMALL, seed=0), config, "fixed", 0.3)
    mpc = metrics_table("m", planned)
    # measured: 0.44 / 0.31 m without actions, 0.20 / 0.21 m with this 50-ms MPC
    assert (mpc["rmse_3d"].to_numpy() < zero["rmse_3d"].to_numpy() - 0.05).all()
    assert planned.planning_time is not None and (planned.planning_time > 0).all()
    assert {"planning_time", "planning_time_max"} <= set(mpc.columns)


def test_mpc_is_deterministic_with_a_seed() -> None:
    config = _fixed_config()
    first = run_episode(MpcController(SMALL, seed=3), config, "fixed", 0.1)
    again = run_episode(MpcController(SMALL, seed=3), config, "fixed", 0.1)
    other = run_episode(MpcController(SMALL, seed=4), config, "fixed", 0.1)
    np.testing.assert_array_equal(first.actions, again.actions)
    assert not np.array_equal(first.actions, other.actions)


def test_cem_and_a_wrong_model_run() -> None:
    config = _fixed_config()
    cem = PlannerConfig(
        method="cem",
        samples=8,
        horizon=10,
        knots=3,
        replan_interval=5,
        iterations=2,
        elite_fraction=0.25,
    )
    episode = run_episode(
        MpcController(cem, seed=0, model_scales={"youngs_modulus_scale": 0.7}), config, "fixed", 0.1
    )
    assert np.isfinite(episode.tips).all()


@pytest.mark.parametrize(
    ("mpc", "message"),
    [
        ({"knots": 20, "horizon": 10}, "knots"),
        ({"replan_interval": 20, "horizon": 10}, "replan_interval"),
        ({"model_scales": {"stiffness": 2.0}}, "unknown factor 'stiffness'"),
        ({"samples": 1}, "samples"),
    ],
)
def test_mpc_section_errors_name_the_field(mpc: dict, message: str) -> None:
    with pytest.raises(SpecError, match=message):
        from softtrack.spec.spec_io import parse_spec

        parse_spec({"controller": "mpc", "mpc": mpc})


def test_a_default_mpc_section_keeps_every_spec_hash() -> None:
    from softtrack.spec import spec_hash

    spec = ExperimentSpec()
    with_section = ExperimentSpec.model_validate({"mpc": {"samples": 64}})
    assert spec_hash(spec) == spec_hash(with_section)
    assert spec_hash(spec) != spec_hash(ExperimentSpec.model_validate({"mpc": {"samples": 32}}))


def _mpc_spec(tmp_path: Path) -> Path:
    path = tmp_path / "mpc.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "tiny-mpc",
                "controller": "mpc",
                "seeds": [0],
                "mpc": {"samples": 4, "horizon": 6, "knots": 3, "replan_interval": 3},
                "training": {"eval_duration": 0.1},
            }
        ),
        encoding="utf-8",
    )
    return path


def test_train_refuses_and_evaluate_creates_the_run(tmp_path: Path) -> None:
    spec = _mpc_spec(tmp_path)
    runs = tmp_path / "runs"
    refused = runner.invoke(app, ["train", str(spec), "--runs-dir", str(runs)])
    assert refused.exit_code == 2
    assert "nothing to train" in refused.output and "softtrack evaluate" in refused.output
    assert not runs.exists() or not any(runs.iterdir())
    result = runner.invoke(app, ["evaluate", str(spec), "--runs-dir", str(runs), "-t", "circle"])
    assert result.exit_code == 0, result.output
    assert "created: tiny-mpc seed 0 (controller mpc, mppi)" in result.output
    (run,) = [p for p in runs.iterdir() if (p / "run.json").is_file()]
    metrics = read_table(run / "tables" / "eval_metrics.parquet")
    assert (metrics["planning_time"] > 0).all()
    assert load_spec(run / "spec.yaml").controller == "mpc"
    report = runner.invoke(
        app, ["report", "tiny-mpc", "--runs-dir", str(runs), "--out", str(tmp_path / "report")]
    )
    assert report.exit_code == 0, report.output
    index = (tmp_path / "report" / "index.md").read_text(encoding="utf-8")
    assert "### Planning cost (MPC)" in index and "MPC (MPPI)" in index
    assert "no training (planner)" in index
    exported = tmp_path / "models" / "tiny-mpc-seed0"
    moved = runner.invoke(app, ["export", run.name, str(exported), "--runs-dir", str(runs)])
    assert moved.exit_code == 0, moved.output  # a planner exports its spec and tables only
    assert (exported / "tables" / "eval_metrics.parquet").is_file()
    assert not list(exported.rglob("*.zip")) and not list(exported.rglob("policy.json"))


def test_evaluate_of_an_untrained_spec_says_to_train_it(tmp_path: Path) -> None:
    """A spec file selects the runs trained from it (as in every command); a learned
    controller's spec without runs is one line that says how to train it."""
    path = tmp_path / "td3.yaml"
    path.write_text(yaml.safe_dump({"name": "td3", "seeds": [0]}), encoding="utf-8")
    result = runner.invoke(app, ["evaluate", str(path), "--runs-dir", str(tmp_path / "runs")])
    assert result.exit_code == 2
    assert (
        "no run in" in result.output and f"train it with `softtrack train {path}`" in result.output
    )


def test_budget_benchmark_writes_its_table_and_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_mpc_budget.py"
    module_spec = importlib.util.spec_from_file_location("bench_mpc_budget", path)
    assert module_spec is not None and module_spec.loader is not None
    bench = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(bench)
    assert bench.parse_budgets("16x50,8x25x2,8x25x2x1", 5) == [
        (16, 50, 1, 5),
        (8, 25, 2, 5),
        (8, 25, 2, 1),
    ]
    csv, figure = tmp_path / "b.csv", tmp_path / "b.png"
    spec = str(_mpc_spec(tmp_path))
    assert (
        bench.main(
            [
                "--spec",
                spec,
                "--budgets",
                "4x6,4x6x2",
                "--duration",
                "0.06",
                "--trajectories",
                "circle",
                "--csv",
                str(csv),
                "--figure",
                str(figure),
            ]
        )
        == 0
    )
    table = pd.read_csv(csv)
    assert sorted(set(zip(table["samples"], table["iterations"], strict=True))) == [(4, 1), (4, 2)]
    assert set(table["replan_interval"]) == {3}  # the spec's
    assert (table["planning_time"] > 0).all() and figure.stat().st_size > 10_000
    assert "at or below 0.5 × the study in all six cells: none" in capsys.readouterr().out
    # a sweep in pieces: one more budget, merged with the first piece's rows
    merged = tmp_path / "merged.csv"
    assert (
        bench.main(
            [
                "--spec",
                spec,
                "--budgets",
                "4x6x1x1",
                "--duration",
                "0.06",
                "--trajectories",
                "circle",
                "--merge",
                str(csv),
                "--csv",
                str(merged),
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert all(f"  {label} " in out for label in ("4x6x1x3", "4x6x2x3", "4x6x1x1"))
    assert len(pd.read_csv(merged)) == 3 * 2


def test_evaluate_takes_overrides_of_an_mpc_spec_only(tmp_path: Path) -> None:
    """``--set`` changes an MPC spec evaluated without training; with a run (which keeps the
    spec it was trained with) it is one line, exit 2, and nothing is created."""
    spec = ROOT / "experiments/variants/mpc-mppi-64x50-transport-fine-10ms-reachable.yaml"
    bad = runner.invoke(
        app,
        ["evaluate", str(spec), "--set", "env.task.grip=7", "--runs-dir", str(tmp_path)],
        env={"CI": "1"},
    )
    assert bad.exit_code == 2 and "grip" in bad.stderr and "Traceback" not in bad.output
    shipped = ROOT / "models" / "mpc-mppi-64x50-seed0"
    runs = tmp_path / "mixed"
    mixed = runner.invoke(
        app,
        [
            "evaluate",
            str(spec),
            str(shipped),
            "--set",
            "env.task.grip=0.1",
            "--runs-dir",
            str(runs),
        ],
        env={"CI": "1"},
    )
    assert mixed.exit_code == 2, mixed.output
    assert mixed.stderr.startswith("error: --set: ") and "keeps the spec" in mixed.stderr
    assert len(mixed.stderr.strip().splitlines()) == 1 and not runs.exists()


def test_evaluate_applies_overrides_to_the_planner_spec(tmp_path: Path) -> None:
    spec = _mpc_spec(tmp_path)
    runs = tmp_path / "runs"
    result = runner.invoke(
        app,
        ["evaluate", str(spec), "--set", "mpc.samples=6", "--runs-dir", str(runs), "-t", "circle"],
    )
    assert result.exit_code == 0, result.output
    (run,) = [p for p in runs.iterdir() if (p / "run.json").is_file()]
    assert load_spec(run / "spec.yaml").mpc.samples == 6
