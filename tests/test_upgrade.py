"""Runs stored in the earlier table format are rewritten to equal a fresh evaluation's tables."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.evaluation import (
    Episode,
    metrics_table,
    moment_peaks_table,
    moments_table,
    trajectory_table,
)
from softtrack.evaluation.metrics import moment_rms
from softtrack.store.tables import read_table, write_table
from softtrack.store.upgrade import upgrade_run_tables

runner = CliRunner()


def _episode(trajectory: str, seed: int, n: int = 50) -> Episode:
    rng = np.random.default_rng(seed)
    return Episode(
        trajectory,
        np.arange(1, n + 1) * 0.002,
        rng.normal(size=(n, 2, 3)),
        rng.normal(size=(n, 3)),
        80 * rng.normal(size=(n, 2, 2, 20)),
        rng.uniform(-1, 1, size=(n, 24)),
        False,
    )


def _old_moments(run_id: str, episode: Episode) -> pd.DataFrame:
    """``eval_moments`` as versions before the docs/environment.md summaries stored it."""
    torques = episode.element_torques
    n = len(torques)
    return pd.DataFrame(
        {
            "run_id": run_id,
            "trajectory": episode.trajectory,
            "step": np.repeat(np.arange(1, n + 1), 4),
            "t": np.repeat(episode.t, 4),
            "arm": np.tile(np.repeat(np.arange(2), 2), n),
            "direction": np.tile(np.arange(2), 2 * n),
            "rms_moment": moment_rms(torques).reshape(-1),
            "max_abs_moment": np.abs(torques).max(axis=-1).reshape(-1),
            "element_torques": list(torques.reshape(4 * n, 20).astype(np.float32)),
        }
    )


def _old_run(tmp_path: Path) -> tuple[Path, list[Episode]]:
    run = tmp_path / "run"
    episodes = [_episode("circle", 0), _episode("figure8", 1)]
    write_table(
        run / "tables" / "eval_moments.parquet",
        pd.concat([_old_moments("R", e) for e in episodes], ignore_index=True),
    )
    old_trajectories = pd.concat([trajectory_table("R", e) for e in episodes], ignore_index=True)
    for column in old_trajectories.columns:
        if column.startswith(("tip_", "target_")):  # the old format's float64 positions
            old_trajectories[column] = old_trajectories[column].astype(np.float64)
    write_table(run / "tables" / "eval_trajectories.parquet", old_trajectories)
    return run, episodes


def _fresh(make_table, episodes: list[Episode]) -> pd.DataFrame:  # type: ignore[no-untyped-def]
    return pd.concat([make_table("R", e) for e in episodes], ignore_index=True)


def test_upgrade_equals_a_fresh_evaluation_and_is_idempotent(tmp_path: Path) -> None:
    run, episodes = _old_run(tmp_path)
    written = upgrade_run_tables(run)
    assert written == ["eval_moment_peaks", "eval_moments", "eval_trajectories"]
    tables = run / "tables"
    for name, make_table in (
        ("eval_moments", moments_table),
        ("eval_moment_peaks", moment_peaks_table),
        ("eval_trajectories", trajectory_table),
    ):
        pd.testing.assert_frame_equal(
            read_table(tables / f"{name}.parquet"), _fresh(make_table, episodes), check_exact=True
        )
    assert not (tables / "eval_element_moments.parquet").exists()
    before = {p.name: p.read_bytes() for p in tables.iterdir()}
    assert upgrade_run_tables(run) == []
    assert {p.name: p.read_bytes() for p in tables.iterdir()} == before


def test_upgrade_can_keep_the_full_torque_history(tmp_path: Path) -> None:
    run, episodes = _old_run(tmp_path)
    assert upgrade_run_tables(run, keep_full_moments=True)[0] == "eval_element_moments"
    full = read_table(run / "tables" / "eval_element_moments.parquet")
    expected = np.concatenate([e.element_torques.reshape(-1, 20) for e in episodes])
    assert np.array_equal(np.stack(full["element_torques"].to_numpy()), expected.astype(np.float32))


def test_upgrade_of_a_missing_directory_is_one_line(tmp_path: Path) -> None:
    result = runner.invoke(app, ["upgrade", str(tmp_path / "nowhere")])
    assert result.exit_code == 2
    assert len(result.output.strip().splitlines()) == 1 and "nowhere" in result.output


def test_upgrade_adds_the_peak_moment_of_older_metrics(tmp_path: Path) -> None:
    """Metrics stored before ``peak_moment`` existed get it from ``eval_moment_peaks``, equal
    (to float32 precision) to the column a fresh evaluation writes; other columns unchanged."""
    run, episodes = _old_run(tmp_path)
    fresh = _fresh(metrics_table, episodes)
    write_table(run / "tables" / "eval_metrics.parquet", fresh.drop(columns=["peak_moment"]))
    assert upgrade_run_tables(run)[-1] == "eval_metrics"
    upgraded = read_table(run / "tables" / "eval_metrics.parquet")
    np.testing.assert_allclose(upgraded["peak_moment"], fresh["peak_moment"], rtol=1e-6)
    pd.testing.assert_frame_equal(
        upgraded.drop(columns=["peak_moment"]), fresh.drop(columns=["peak_moment"])
    )
    assert upgrade_run_tables(run) == []
