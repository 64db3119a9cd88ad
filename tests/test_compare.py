"""``softtrack compare``: controllers across seeds from their stored metrics."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.evaluation.seed_statistics import interquartile_mean
from softtrack.report.compare import MAX_PRINTED_CELLS, compare_selection
from softtrack.report.data import group_runs, load_runs
from softtrack.report.transport_frontier import (
    frontier_figure,
    hold_track_frontier,
    longest_holding,
)
from softtrack.report.transport_section import figure_runs, random_summary
from softtrack.spec import parse_spec
from softtrack.store.runs import RunStore
from softtrack.store.tables import write_table

runner = CliRunner()
TRAJECTORIES = ("circle", "rectangle", "figure8")


def _controller(store: RunStore, name: str, errors: list[float], cpu: str = "CPU A") -> None:
    """One run per value: every cell of seed k has the error errors[k] (+1 mm for arm 2)."""
    spec = parse_spec({"name": name, "training": {"total_timesteps": 100_000}})
    for seed, error in enumerate(errors):
        record = store.create_run(spec, seed)
        rows = [
            {
                "run_id": record.run_id,
                "trajectory": t,
                "arm": arm,
                "rmse_3d": error + 0.001 * arm,
                "cpu": cpu,
            }
            for t in TRAJECTORIES
            for arm in (0, 1)
        ]
        write_table(record.table_path("eval_metrics"), rows)


@pytest.fixture
def store(tmp_path: Path) -> RunStore:
    store = RunStore(tmp_path / "runs")
    _controller(store, "good", [0.040, 0.042, 0.041, 0.043, 0.090])  # one bad seed
    _controller(store, "worse", [0.050, 0.052, 0.051, 0.053], cpu="CPU B")
    return store


def test_the_first_controller_is_compared_with_each_other(store: RunStore) -> None:
    result = compare_selection(["good", "worse"], runs_dir=store.root, reps=200)
    good, worse = result.controllers
    assert good.scores.shape == (5, 6) and worse.scores.shape == (4, 6)
    assert result.overall["good"].value == pytest.approx(interquartile_mean(good.scores))
    assert result.overall["good"].value < 0.045  # the IQM leaves the bad seed out
    # 4 of good's 5 runs beat every run of worse in every cell; the bad seed beats none
    assert result.improvement["worse"].value == pytest.approx(0.8)
    assert good.cpus == {"CPU A": 30} and worse.cpus == {"CPU B": 24}
    text = "\n".join(result.lines())
    assert "P(good improves on worse) = 0.80" in text
    assert "noise floor" in text and "CPU B (24)" in text


def test_cli_prints_the_tables_and_writes_the_profile(store: RunStore, tmp_path: Path) -> None:
    figure = tmp_path / "profile.png"
    out = runner.invoke(
        app,
        [
            "compare",
            "good",
            "worse",
            "--runs-dir",
            str(store.root),
            "--reps",
            "200",
            "--figure",
            str(figure),
        ],
    )
    assert out.exit_code == 0, out.output
    assert "interquartile mean over runs" in out.stdout
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["good"], "needs at least two controllers"),
        (["good", "nobody"], "no run 'nobody': it is neither an experiment name"),
    ],
)
def test_bad_selections_are_one_line(store: RunStore, args: list[str], message: str) -> None:
    out = runner.invoke(app, ["compare", *args, "--runs-dir", str(store.root)])
    assert out.exit_code == 2
    assert message in out.stderr and len(out.stderr.strip().splitlines()) == 1


def test_a_controller_without_metrics_is_one_line(store: RunStore) -> None:
    store.create_run(parse_spec({"name": "fresh"}), 0)
    out = runner.invoke(app, ["compare", "good", "fresh", "--runs-dir", str(store.root)])
    assert out.exit_code == 2
    assert "fresh: no run has rmse_3d in eval_metrics" in out.stderr


def test_unit_scores_use_nan_for_missing_cells(store: RunStore) -> None:
    result = compare_selection(
        ["good", "worse"], runs_dir=store.root, reps=100, trajectories=("circle", "spiral")
    )
    assert np.isnan(result.controllers[0].scores[:, 2:]).all()
    assert result.per_cell["good"][2] is None


def _transport_runs(
    store: RunStore, name: str, carried: list[tuple[float, float | None]], table: str
) -> None:
    """One run per (sphere error while carried in m, drop time in s or None) with 12-s
    evaluation episodes: every trajectory (or random episode) of the run has those values."""
    spec = parse_spec(
        {"name": name, "training": {"total_timesteps": 100_000, "eval_duration": 12.0}}
    )
    for seed, (error, drop_time) in enumerate(carried):
        record = store.create_run(spec, seed)
        cells = TRAJECTORIES if table == "eval_metrics" else range(4)
        rows = [
            {
                "run_id": record.run_id,
                **(
                    {"trajectory": cell}
                    if table == "eval_metrics"
                    else {"trajectory": "random", "episode": cell, "seed": 1_000_000 + cell}
                ),
                "arm": arm,
                "rmse_3d": 0.5,
                "terminated": drop_time is not None,
                "object_rmse_3d": error,
                "dropped": drop_time is not None,
                "drop_time": np.nan if drop_time is None else drop_time,
                "cpu": "CPU A",
            }
            for cell in cells
            for arm in (0, 1)
        ]
        write_table(record.table_path(table), rows)


@pytest.mark.parametrize("table", ["eval_metrics", "eval_random"])
def test_the_carry_score_counts_a_drop_against_the_controller(tmp_path: Path, table: str) -> None:
    store = RunStore(tmp_path / "runs")
    _transport_runs(store, "drops", [(0.10, 3.0), (0.12, 3.0), (0.11, 3.0)], table)
    _transport_runs(store, "carries", [(0.30, None), (0.32, None), (0.31, None)], table)
    random = table == "eval_random"
    on_error = compare_selection(
        ["drops", "carries"], runs_dir=store.root, metric="object_rmse_3d", reps=200, random=random
    )
    assert on_error.improvement["carries"].value == pytest.approx(1.0)  # while carried it's better
    scored = compare_selection(
        ["drops", "carries"],
        runs_dir=store.root,
        metric="object_carry_score",
        reps=200,
        random=random,
    )
    drops, carries = scored.controllers
    # 3 s carried at 0.10 m, then 9 s counted at 1 m: sqrt((0.01·3 + 1·9) / 12)
    assert np.nanmin(drops.scores) == pytest.approx(np.sqrt((0.01 * 3 + 9) / 12))
    assert np.nanmax(carries.scores) == pytest.approx(0.32)
    assert scored.improvement["carries"].value == pytest.approx(0.0)
    assert drops.cpus == {"CPU A": 3 * (4 if random else 3)}  # one row per cell, not per arm
    if random:
        # the sphere's score is the same in both arms' rows: one cell per episode
        assert drops.cells[:3] == (("random 0", 0), ("random 1", 0), ("random 2", 0))
        assert drops.scores.shape == (3, 4)
        assert "random 3  " in "\n".join(scored.lines())  # few cells: printed one by one


def test_random_cells_need_random_evaluations(store: RunStore) -> None:
    out = runner.invoke(
        app, ["compare", "good", "worse", "--random", "--runs-dir", str(store.root)]
    )
    assert out.exit_code == 2
    assert "good: no run has rmse_3d in eval_random" in out.stderr
    assert "softtrack evaluate RUN --random 20" in out.stderr


def test_many_cells_print_only_the_overall_statistics(tmp_path: Path) -> None:
    store = RunStore(tmp_path / "runs")
    _transport_runs(store, "a", [(0.10, None), (0.11, None)], "eval_random")
    _transport_runs(store, "b", [(0.20, None), (0.21, None)], "eval_random")
    spec = parse_spec({"name": "a", "training": {"total_timesteps": 100_000}})
    extra = store.create_run(spec, 5)
    rows = [
        {
            "run_id": extra.run_id,
            "trajectory": "random",
            "episode": k,
            "arm": arm,
            "rmse_3d": 0.1,
            "terminated": False,
            "cpu": "CPU A",
        }
        for k in range(MAX_PRINTED_CELLS + 1)
        for arm in (0, 1)
    ]
    write_table(extra.table_path("eval_random"), rows)
    result = compare_selection(
        ["a", "b"], runs_dir=store.root, metric="object_rmse_3d", reps=200, random=True
    )
    text = "\n".join(result.lines())
    assert f"({MAX_PRINTED_CELLS + 1} cells: the per-cell intervals are left out)" in text
    assert "per cell:" not in text and "P(a improves on b) = 1.00" in text


def test_the_report_summarises_the_random_targets_of_transport(tmp_path: Path) -> None:
    store = RunStore(tmp_path / "runs")
    _transport_runs(store, "drops", [(0.10, 3.0), (0.12, 3.0)], "eval_random")
    _transport_runs(store, "carries", [(0.30, None), (0.32, None), (0.31, None)], "eval_random")
    groups = group_runs(load_runs(store.list_runs()))
    summary = random_summary(groups, reps=200).set_index("group")
    drops = summary.loc[next(g for g in summary.index if "drops" in g)]
    carries = summary.loc[next(g for g in summary.index if "carries" in g)]
    assert (drops["n"], drops["episodes"], drops["carried"]) == (2, 8, 0)
    assert (carries["n"], carries["episodes"], carries["carried"]) == (3, 12, 12)
    assert drops["median_hold"] == pytest.approx(3.0) and carries["median_hold"] == 12.0
    assert carries["score"] == pytest.approx(0.31)
    assert carries["score_low"] <= 0.31 <= carries["score_high"]
    assert drops["score"] > 0.8  # 9 s of 12 counted at 1 m


def test_the_frontier_places_each_run_between_holding_and_carrying(tmp_path: Path) -> None:
    store = RunStore(tmp_path / "runs")
    _transport_runs(store, "drops", [(0.10, 3.0), (0.12, 6.0)], "eval_random")
    _transport_runs(store, "carries", [(0.30, None)], "eval_random")
    _transport_runs(store, "carries", [(0.30, None)], "eval_metrics")
    groups = group_runs(load_runs(store.list_runs()))
    frontier = hold_track_frontier(groups)
    drops = frontier[frontier["group"].str.contains("drops")].sort_values("seed")
    assert list(drops["episodes"]) == ["random", "random"]
    assert list(drops["held_fraction"]) == pytest.approx([3.0 / 12, 6.0 / 12])
    assert list(drops["error"]) == pytest.approx([0.10, 0.12])
    assert list(drops["carried"]) == [0, 0] and list(drops["n"]) == [4, 4]  # arm 0's rows only
    carries = frontier[frontier["group"].str.contains("carries")].set_index("episodes")
    assert carries.loc["random", "held_fraction"] == 1.0
    assert carries.loc["trajectories", "n"] == 3 and carries.loc["trajectories", "carried"] == 3
    path = frontier_figure(frontier, tmp_path / "frontier.png", 0.065, "footer")
    assert path.stat().st_size > 10_000
    kept = longest_holding(frontier, 1)
    assert set(kept["group"]) == set(carries["group"]) and len(kept) == 2  # both its rows


def test_the_transport_figure_skips_controllers_without_per_step_positions(
    tmp_path: Path,
) -> None:
    """A controller whose shipped runs dropped ``eval_trajectories`` takes no place in the
    figure: the next one that kept them is drawn instead."""
    store = RunStore(tmp_path / "runs")
    for name in ("a-lean", "b-kept", "c-kept"):
        _transport_runs(store, name, [(0.30, None)], "eval_metrics")
    for record in store.list_runs():
        if record.info.name != "a-lean":
            positions = [
                {"run_id": record.run_id, "trajectory": "circle", "step": 0, "t": 0.0, "arm": arm}
                for arm in (0, 1)
            ]
            write_table(record.table_path("eval_trajectories"), positions)
    groups = group_runs(load_runs(store.list_runs()))
    assert len(groups) == 3
    drawn = [group.label for group, _ in figure_runs(groups, 4)]
    assert len(drawn) == 2 and not any("a-lean" in label for label in drawn)
    assert figure_runs(groups, 1)[0][0].label == drawn[0]


@pytest.mark.faults("degraded")
def test_a_non_finite_score_is_named_and_left_out(tmp_path: Path) -> None:
    """``inf`` in a metric showed as "no data" and entered no line: now compare names each
    non-finite score (seed and cell) and leaves it out of every statistic."""
    store = RunStore(tmp_path / "runs")
    _controller(store, "good", [0.040, 0.042, float("inf")])
    _controller(store, "worse", [0.050, 0.052, 0.051])
    result = compare_selection(["good", "worse"], runs_dir=store.root, reps=200)
    good = result.controllers[0]
    assert np.isnan(good.scores[2]).all() and len(good.non_finite) == 6
    text = "\n".join(result.lines())
    assert "note: good: 6 stored scores are not a finite number" in text
    assert "seed 2, circle arm 1: inf" in text
    assert result.overall["good"].value == pytest.approx(0.0415, abs=1e-3)
