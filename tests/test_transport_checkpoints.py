"""``experiments/diagnostics/transport_checkpoints.py``: each checkpoint's held-out score (the
validation score, a drop counted 1 m from then on), its drops and the three paths, on a
transport run's validation table written here."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments" / "diagnostics"))
import transport_checkpoints as tc  # noqa: E402

SPEC = (
    ROOT / "experiments" / "variants" / "td3-sbx-128-6e6-mirror-tta-stop-transport-reachable.yaml"
)


def _rows(step: int, trajectory: str, episode: int, rmse: float, drop: float | None) -> list[dict]:
    return [
        {
            "global_step": step,
            "wall_time": step / 1000.0,
            "trajectory": trajectory,
            "episode": episode,
            "arm": arm,
            "rmse_3d": 0.3,
            "terminated": drop is not None,
            "object_rmse_3d": rmse,
            "dropped": drop is not None,
            "drop_time": drop,
        }
        for arm in (0, 1)
    ]


def _run(tmp_path: Path) -> Path:
    run = tmp_path / "RUN"
    (run / "tables").mkdir(parents=True)
    (run / "spec.yaml").write_text(f"base: {SPEC}\n", encoding="utf-8")
    rows = []
    # checkpoint 1: both held-out paths carried (0.02, 0.04), every evaluation path at <= 0.025
    rows += _rows(1000, "paths", 0, 0.02, None) + _rows(1000, "paths", 1, 0.04, None)
    for name, value in zip(tc.PATHS, (0.021, 0.025, 0.018), strict=True):
        rows += _rows(1000, name, 0, value, None)
    # checkpoint 2: one held-out path dropped after 6 of 12 s, the circle dropped
    rows += _rows(2000, "paths", 0, 0.02, 6.0) + _rows(2000, "paths", 1, 0.02, None)
    for name, value, drop in zip(tc.PATHS, (0.02, 0.03, 0.02), (3.0, None, None), strict=True):
        rows += _rows(2000, name, 0, value, drop)
    pd.DataFrame(rows).to_parquet(run / "tables" / "validation.parquet")
    return run


def test_checkpoints_score_drops_as_validation_does(tmp_path: Path) -> None:
    first, second = tc.read_checkpoints(_run(tmp_path))
    assert first.held_out_score == pytest.approx(0.03) and first.held_out_drops == 0
    assert first.carries_all(0.025) and first.worst_path == pytest.approx(0.025)
    # 12-s episodes: sqrt((0.02² · 6 + 1² · 6) / 12) for the dropped one
    lost = ((0.02**2 * 6 + 6) / 12) ** 0.5
    assert second.held_out_score == pytest.approx((lost + 0.02) / 2)
    assert second.held_out_drops == 1 and second.paths["circle"] == (0.02, True)
    assert not second.carries_all(1.0)


def test_summary_counts_checkpoints_at_the_target(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _run(tmp_path)
    assert tc.main([str(run), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "1 of 2 checkpoints carry all three paths at <= 0.025 m" in out
    assert "best worst path 0.025 m at 1,000" in out
    assert tc.main([str(run), "--quiet", "--at-most", "0.02"]) == 0
    assert "0 of 2 checkpoints" in capsys.readouterr().out


def test_a_directory_without_a_validation_table_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert tc.main([str(tmp_path)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_a_run_without_the_sphere_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = _run(tmp_path)
    table = pd.read_parquet(run / "tables" / "validation.parquet")
    table.drop(columns=["object_rmse_3d"]).to_parquet(run / "tables" / "validation.parquet")
    assert tc.main([str(run)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a transport run" in err[0]
