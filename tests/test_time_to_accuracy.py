"""benchmarks/bench_time_to_accuracy.py on synthetic validation tables: steps to the study's
accuracy, the validation score, grouping by config, independent runs, throughput rounds, and
the figure and CSV (no training)."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pandas as pd
import pytest

from softtrack.report.reference import STUDY_RMSE_3D
from softtrack.spec import ExperimentSpec
from softtrack.store.tables import read_table, write_table

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_time_to_accuracy.py"
STUDY = STUDY_RMSE_3D["centralized"]
STEPS = [250_000, 500_000, 750_000, 1_000_000]


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_time_to_accuracy", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses resolve their module by name
    spec.loader.exec_module(module)
    return module


tta = _load()


def _rows(
    step: int,
    random: list[float],
    cells: dict[tuple[str, int], float] | None,
    wall_time: float | None = None,
    arms: tuple[int, ...] = (0, 1),
) -> list[dict[str, Any]]:
    """One checkpoint's rows as the validator writes them: random-target episodes (one row per
    episode and arm, ``random`` holds the rmse of each in turn) and, with ``cells``, one row
    per evaluation trajectory and arm."""
    rows: list[dict[str, Any]] = []
    values = iter(random)
    for episode in range(len(random) // len(arms)):
        for arm in arms:
            rows.append(
                {
                    "run_id": "r",
                    "global_step": step,
                    "trajectory": "random",
                    "episode": episode,
                    "seed": 2_000_000 + episode,
                    "arm": arm,
                    "rmse_3d": next(values),
                    "terminated": False,
                    "duration": 10.0,
                }
            )
    for (trajectory, arm), value in (cells or {}).items():
        rows.append(
            {
                "run_id": "r",
                "global_step": step,
                "trajectory": trajectory,
                "episode": 0,
                "seed": 0,
                "arm": arm,
                "rmse_3d": value,
                "terminated": False,
                "duration": 10.0,
            }
        )
    if wall_time is not None:
        for row in rows:
            row["wall_time"] = wall_time
    return rows


def _cells(scale: float = 1.0, bump: tuple[str, int] | None = None) -> dict[tuple[str, int], float]:
    """The six cells at ``scale`` x the study's value; ``bump``'s cell just above it."""
    out = {(t, arm): STUDY[t][arm] * scale for t in STUDY for arm in (0, 1)}
    if bump is not None:
        out[bump] = STUDY[bump[0]][bump[1]] + 1e-4
    return out


def _run_dir(
    root: Path,
    run_id: str,
    name: str,
    seed: int,
    rows: list[dict[str, Any]],
    controller: str = "centralized",
    total: int = 1_000_000,
) -> Path:
    path = root / run_id
    (path / "tables").mkdir(parents=True)
    (path / "run.json").write_text(
        json.dumps(
            {
                "run_id": run_id,
                "name": name,
                "seed": seed,
                "controller": controller,
                "total_timesteps": total,
                "steps_per_second": 500.0,
            }
        )
    )
    write_table(path / "tables" / "validation.parquet", rows)
    return path


def _curve(rows: list[dict[str, Any]], independent: bool = False) -> pd.DataFrame:
    return tta.validation_curve(pd.DataFrame(rows), independent)


def test_steps_to_accuracy_is_the_first_checkpoint_with_all_six_cells_at_the_study() -> None:
    study = tta.study_cells()
    assert len(study) == 6 and study[tta.cell_name("circle", 0)] == 0.065
    rows = (
        _rows(STEPS[0], [0.2] * 4, _cells(2.0), 100.0)
        + _rows(STEPS[1], [0.1] * 4, _cells(0.9, bump=("figure8", 1)), 200.0)
        + _rows(STEPS[2], [0.08] * 4, _cells(1.0), 300.0)  # exactly at the study: reached
        + _rows(STEPS[3], [0.05] * 4, _cells(0.5), 400.0)
    )
    curve = _curve(rows)
    assert curve["global_step"].tolist() == STEPS
    row = tta.first_at_study(curve, study)
    assert row is not None and int(row["global_step"]) == STEPS[2] and row["wall_time"] == 300.0

    # one cell just above the study at a checkpoint → a later one
    rows = _rows(STEPS[0], [0.1] * 4, _cells(0.9, bump=("circle", 0))) + _rows(
        STEPS[1], [0.1] * 4, _cells(0.9)
    )
    row = tta.first_at_study(_curve(rows), study)
    assert row is not None and int(row["global_step"]) == STEPS[1]
    assert math.isnan(row["wall_time"])  # older tables have no wall_time

    # a missing cell never counts as reached
    partial = _cells(0.5)
    del partial[("rectangle", 1)]
    assert tta.first_at_study(_curve(_rows(STEPS[0], [0.1] * 4, partial)), study) is None


def test_worst_cell_ratio_and_validation_cadence() -> None:
    study = tta.study_cells()
    rows = (
        _rows(STEPS[0], [0.2] * 4, _cells(2.0), 30.0)
        + _rows(STEPS[1], [0.1] * 4, _cells(0.9, bump=("figure8", 1)), 90.0)
        + _rows(STEPS[2], [0.08] * 4, _cells(0.5), 150.0)
    )
    curve = _curve(rows)
    ratio = tta.worst_cell_ratio(curve, study)
    assert ratio.tolist() == pytest.approx([2.0, (0.053 + 1e-4) / 0.053, 0.5])
    # gaps from the start of training: 30, 60, 60 s → median 1 min
    assert tta.validation_cadence_min(curve) == pytest.approx(1.0)
    missing = _cells(0.5)
    del missing[("circle", 1)]
    with_gap = _curve(_rows(STEPS[0], [0.1] * 4, _cells(0.5)) + _rows(STEPS[1], [0.1] * 4, missing))
    assert tta.worst_cell_ratio(with_gap, study).tolist() == [0.5, math.inf]
    assert math.isnan(tta.validation_cadence_min(with_gap))  # no stored clock
    with pytest.raises(ValueError, match="no trajectory cells"):
        tta.worst_cell_ratio(_curve(_rows(STEPS[0], [0.1] * 4, None)), study)


def test_not_reached_and_no_trajectory_rows() -> None:
    study = tta.study_cells()
    bumps = [("circle", 0), ("rectangle", 1)]
    rows = [
        r
        for k, step in enumerate(STEPS)
        for r in _rows(step, [0.1] * 4, _cells(0.5, bump=bumps[k % 2]))
    ]
    info = tta.run_info(Path("x"), {"name": "a", "seed": 0, "total_timesteps": 1_000_000})
    result = tta.summarize_run(info, pd.DataFrame(rows), study)
    assert result.tracked and result.reached_step is None

    untracked = tta.summarize_run(info, pd.DataFrame(_rows(STEPS[0], [0.1] * 4, None)), study)
    assert not untracked.tracked and untracked.reached_step is None
    assert not tta.has_cells(untracked.curve, study)
    with pytest.raises(ValueError):
        tta.first_at_study(untracked.curve, study)


def test_the_score_ignores_trajectory_rows() -> None:
    rows = _rows(STEPS[0], [0.10, 0.20, 0.30, 0.40], _cells(50.0)) + _rows(
        STEPS[1], [0.05, 0.05, 0.07, 0.07], _cells(0.1)
    )
    curve = _curve(rows)
    assert curve["score"].tolist() == pytest.approx([0.25, 0.06])
    assert curve[tta.cell_name("circle", 0)].tolist() == pytest.approx([50 * 0.065, 0.1 * 0.065])
    assert tta.best_checkpoint(curve) == (STEPS[1], pytest.approx(0.06))


def test_independent_runs_pair_the_arms_at_equal_per_arm_steps() -> None:
    rows = []
    for arm, clock0 in ((0, 0.0), (1, 1000.0)):  # arm 1 trains after arm 0: its clock continues
        for k, step in enumerate([100, 200]):
            rows += _rows(step, [0.1 + 0.1 * arm + k] * 2, None, clock0 + 500.0 * (k + 1), (arm,))
    curve = _curve(rows, independent=True)
    assert curve["global_step"].tolist() == [200, 400]  # the sum of both arms' steps
    assert curve["score"].tolist() == pytest.approx([0.15, 1.15])  # both arms' episodes
    # both arms trained to s: arm 0's 500 s + arm 1's 500 s; to the end: 1000 s + 1000 s
    assert curve["wall_time"].tolist() == pytest.approx([1000.0, 2000.0])


def test_grouping_statistics_and_throughput_rounds() -> None:
    infos = [
        tta.run_info(Path(f"r{k}"), {"name": name, "seed": seed, "total_timesteps": 10})
        for k, (name, seed) in enumerate([("b", 1), ("a", 0), ("b", 0), ("a", 2)])
    ]
    groups = tta.group_by_config(infos)
    assert list(groups) == ["b", "a"]
    assert [r.seed for r in groups["b"]] == [0, 1] and [r.seed for r in groups["a"]] == [0, 2]

    mean, std = tta.mean_std([1.0, 2.0, 3.0])
    assert mean == 2.0 and std == 1.0  # sample std
    assert math.isnan(tta.mean_std([1.0])[1]) and math.isnan(tta.hours(1e6, None))
    assert tta.hours(3_600_000, 1000.0) == 1.0

    calls: list[str] = []
    seconds = {"a": iter([1.0, 4.0, 2.0]), "b": iter([2.0, 2.0, 8.0])}

    def timer(spec: ExperimentSpec, steps: int) -> float:
        calls.append(spec.name)
        return next(seconds[spec.name])

    specs = {name: ExperimentSpec.model_validate({"name": name}) for name in ("a", "b")}
    rates = tta.measure_throughput(specs, 100, 3, timer)
    assert calls == ["a", "b"] * 3  # interleaved rounds
    assert rates == {"a": 50.0, "b": 50.0}  # median steps/s


def test_throughput_spec_keeps_the_cost_per_step() -> None:
    spec = ExperimentSpec.model_validate(
        {
            "name": "x",
            "algo": {
                "name": "td3",
                "buffer_size": 4_000_000,
                "learning_starts": 50_000,
                "batch_size": 256,
                "gradient_steps": 8,
                "mirror_replay": True,
                "policy_kwargs": {"net_arch": [128, 128]},
            },
            "training": {"n_envs": 8},
        }
    )
    timed = tta.throughput_spec(spec)
    assert timed.algo.buffer_size == 200_000 and timed.algo.learning_starts == 2_000
    assert (
        timed.algo.batch_size,
        timed.algo.gradient_steps,
        timed.algo.mirror_replay,
        timed.training.n_envs,
    ) == (256, 8, True, 8)
    assert timed.algo.policy_kwargs == spec.algo.policy_kwargs


def test_main_prints_tables_and_writes_the_figure_and_csv(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    runs = tmp_path / "runs"
    dirs = [
        _run_dir(
            runs,
            "fast0",
            "fast",
            0,
            _rows(STEPS[0], [0.2] * 4, _cells(2.0), 60.0)
            + _rows(STEPS[1], [0.06] * 4, _cells(0.9), 120.0),
        ),
        _run_dir(
            runs,
            "fast1",
            "fast",
            1,
            _rows(STEPS[0], [0.3] * 4, _cells(2.0), 50.0)
            + _rows(STEPS[1], [0.08] * 4, _cells(1.5), 100.0)
            + _rows(STEPS[2], [0.05] * 4, _cells(0.8), 150.0),
        ),
        _run_dir(
            runs,
            "slow0",
            "slow",
            0,
            _rows(STEPS[0], [0.4] * 4, _cells(3.0)) + _rows(STEPS[1], [0.2] * 4, _cells(2.0)),
        ),
    ]
    figure, csv = tmp_path / "out" / "tta.png", tmp_path / "out" / "tta.csv"
    tta.main(
        [*map(str, dirs), "--throughput-steps", "0", "--figure", str(figure), "--csv", str(csv)]
    )
    out = capsys.readouterr().out
    lines = [line.split() for line in out.splitlines()]
    assert any(w[:3] == ["fast", "0", "500,000"] and "2.0" in w for w in lines)  # min stored
    assert any(w[:3] == ["fast", "1", "750,000"] for w in lines)
    assert any(w[:4] == ["slow", "0", "not", "reached"] for w in lines)
    assert any(w[:4] == ["fast", "2/2", "625,000", "±"] for w in lines)  # mean over both seeds
    assert any(w[:2] == ["slow", "0/1"] for w in lines)

    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    table = pd.read_csv(csv)
    assert len(table) == 2 + 3 + 2
    assert list(table.columns[:6]) == [
        "config",
        "seed",
        "global_step",
        "wall_time",
        "hours_here",
        "score",
    ]
    assert tta.cell_name("figure8", 1) in table.columns
    assert read_table(dirs[0] / "tables" / "validation.parquet")["trajectory"].nunique() == 4
