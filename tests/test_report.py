"""``softtrack.report``: a report built from small fake runs holds every figure and table,
the study's values, and the provenance; missing data gives "no data" figures; an empty
selection is a clear error."""

from __future__ import annotations

import itertools
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from softtrack.env import make_config
from softtrack.evaluation import (
    EVAL_TRAJECTORIES,
    metrics_table,
    moments_table,
    run_episode,
    trajectory_table,
)
from softtrack.metrics import ACTION_STATISTICS
from softtrack.report import EmptySelectionError, build_report, select_runs
from softtrack.report.curves import final_stage_table, training_curves
from softtrack.report.data import Group, group_runs, load_runs
from softtrack.report.summaries import controller_differences, metrics_summary, moment_peaks
from softtrack.spec import parse_spec, spec_to_yaml
from softtrack.store.provenance import cpu_description
from softtrack.store.runs import RunNotFoundError, RunRecord, RunStore
from softtrack.store.status import final_stage_return
from softtrack.store.tables import read_table, write_table

BUDGET = 2000
EVAL_DURATION = 0.2  # s: 100 control steps per trajectory keeps the fixture fast
COMMAND = "softtrack report td3 ddpg independent-td3 --out reports/test"


def _spec(name: str, algo: str = "td3", controller: str = "centralized"):
    return parse_spec(
        {
            "name": name,
            "controller": controller,
            "seeds": [0, 1],
            "algo": {"name": algo, "learning_starts": 100},
            "training": {"total_timesteps": BUDGET, "eval_duration": EVAL_DURATION},
        }
    )


def _train_rows(record: RunRecord, level: float, arm: int | None = None) -> list[dict]:
    """Episodes of 100 steps whose return rises from ``level`` − 50 towards ``level``."""
    rng = np.random.default_rng(record.info.seed)
    rows = []
    for i in range(BUDGET // 100):
        row = {
            "run_id": record.run_id,
            "episode": i,
            "global_step": 100 * (i + 1),
            "return": float(level - 50.0 * np.exp(-i / 5) + rng.normal(0, 2)),
            "length": 100,
            "wall_time": 0.1 * i,
        }
        if arm is not None:
            row["arm"] = arm
        rows.append(row)
    return rows


def _bang_bang(value: float):
    """A policy whose actions are ``value`` in arm 1 and flip between ±1 in arm 2."""
    steps = itertools.count()

    def act(observation: np.ndarray) -> np.ndarray:
        return np.concatenate([np.full(12, value), np.full(12, (-1.0) ** next(steps))])

    return act


def _write_eval(record: RunRecord, value: float) -> None:
    """Eval tables from real evaluation episodes of a constant (arm 1) and bang-bang (arm 2)
    policy."""
    config = make_config()
    trajs, metrics, moments = [], [], []
    for trajectory in EVAL_TRAJECTORIES:
        episode = run_episode(_bang_bang(value), config, trajectory, duration=EVAL_DURATION)
        trajs.append(trajectory_table(record.run_id, episode))
        metrics.append(metrics_table(record.run_id, episode))
        moments.append(moments_table(record.run_id, episode))
    write_table(record.table_path("eval_trajectories"), pd.concat(trajs, ignore_index=True))
    write_table(record.table_path("eval_metrics"), pd.concat(metrics, ignore_index=True))
    write_table(record.table_path("eval_moments"), pd.concat(moments, ignore_index=True))


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> RunStore:
    """td3 and ddpg × seeds 0, 1 (complete), one independent td3 run (per-arm episodes), and a
    ppo run with training episodes but no eval tables."""
    store = RunStore(tmp_path_factory.mktemp("report") / "runs")
    for algo, level, action in (("td3", 100.0, 0.02), ("ddpg", 60.0, -0.02)):
        spec = _spec(algo, algo)
        for seed in (0, 1):
            record = store.create_run(spec, seed, ["softtrack", "train", f"{algo}.yaml"])
            write_table(record.table_path("train_episodes"), _train_rows(record, level))
            _write_eval(record, action + 0.01 * seed)
            store.mark_finished(record.run_id, "completed", global_step=BUDGET)
    independent = store.create_run(
        _spec("independent-td3", "td3", "independent"),
        0,
        ["softtrack", "train", "independent-td3.yaml"],
    )
    write_table(
        independent.table_path("train_episodes"),
        _train_rows(independent, 40.0, arm=0) + _train_rows(independent, 30.0, arm=1),
    )
    _write_eval(independent, 0.0)
    ppo_spec = parse_spec(
        {
            "name": "ppo",
            "algo": {"name": "ppo", "n_steps": 64, "batch_size": 32},
            "training": {"total_timesteps": BUDGET},
        }
    )
    ppo = store.create_run(ppo_spec, 0, ["softtrack", "train", "ppo.yaml"])
    write_table(ppo.table_path("train_episodes"), _train_rows(ppo, 20.0))
    return store


@pytest.fixture(scope="module")
def report(store: RunStore, tmp_path_factory: pytest.TempPathFactory) -> Path:
    records = select_runs(store, ["td3", "ddpg", "independent-td3"])
    out = tmp_path_factory.mktemp("out") / "reports" / "test"
    return build_report(records, out, COMMAND)


# ---- selection ------------------------------------------------------------------------------
def test_select_by_name_id_prefix_and_spec(store: RunStore, tmp_path: Path) -> None:
    td3 = select_runs(store, ["td3"])
    assert [r.info.seed for r in td3] == [0, 1] and {r.info.algo for r in td3} == {"td3"}
    one = select_runs(store, [td3[1].run_id[:20], "td3"])  # prefix, then a duplicate by name
    assert [r.run_id for r in one] == [td3[1].run_id, td3[0].run_id]
    spec_file = tmp_path / "ddpg.yaml"
    spec_file.write_text(spec_to_yaml(_spec("ddpg", "ddpg")))
    by_spec = select_runs(store, [str(spec_file)])
    assert {r.info.name for r in by_spec} == {"ddpg"} and len(by_spec) == 2


def test_empty_selection_is_a_clear_error(store: RunStore, tmp_path: Path) -> None:
    with pytest.raises(EmptySelectionError, match="nothing to report"):
        select_runs(store, [])
    with pytest.raises(EmptySelectionError, match="neither an experiment name.*known: ddpg"):
        select_runs(store, ["sac-nonexistent"])
    other = tmp_path / "other.yaml"
    other.write_text("name: other\n")
    with pytest.raises(EmptySelectionError, match="no run .* has this spec"):
        select_runs(store, [str(other)])
    with pytest.raises(EmptySelectionError, match="no runs"):
        build_report([], tmp_path / "out", COMMAND)
    assert not (tmp_path / "out").exists()
    with pytest.raises(RunNotFoundError, match="matches"):
        select_runs(store, ["0"])  # every ULID of this decade starts with 0: ambiguous


# ---- aggregation ----------------------------------------------------------------------------
def test_final_stage_return_matches_the_run_table(store: RunStore) -> None:
    groups = group_runs(load_runs(select_runs(store, ["td3", "independent-td3"])))
    table = final_stage_table(groups)
    td3 = table[table["group"] == "TD3"].iloc[0]
    per_run = [final_stage_return(r.record)[0] for r in groups[0].runs]
    assert td3["values"] == pytest.approx(dict(zip((0, 1), per_run)))
    assert td3["mean"] == pytest.approx(np.mean(per_run))
    assert td3["std"] == pytest.approx(np.std(per_run, ddof=1))
    independent = table[table["group"] == "TD3 (independent)"]
    assert list(independent["arm"]) == [0, 1]  # one row per arm policy
    assert np.isnan(independent["std"]).all()  # one seed: no std
    # `softtrack runs` shows the mean over the arms of the same per-arm final stages
    run = groups[-1].runs[0]
    assert final_stage_return(run.record)[0] == pytest.approx(independent["mean"].mean())


def test_curves_metrics_and_peaks(store: RunStore) -> None:
    groups = group_runs(load_runs(select_runs(store, ["td3", "ddpg", "independent-td3"])))
    assert [g.label for g in groups] == ["TD3", "DDPG", "TD3 (independent)"]
    curves, smoothing = training_curves(groups)
    assert [c.label for c in curves] == [
        "TD3",
        "DDPG",
        "TD3 (independent), arm 1 policy",
        "TD3 (independent), arm 2 policy",
    ]
    assert smoothing.window == pytest.approx(0.05 * BUDGET)
    assert np.isfinite(curves[0].std[10:]).all() and np.isnan(curves[2].std).all()
    assert curves[0].mean[-1] > curves[1].mean[-1]  # td3's fake returns are higher
    summary = metrics_summary(groups)
    assert len(summary) == 3 * 3 * 2
    td3 = groups[0]
    rmse = [
        float(r.metrics.query("trajectory == 'circle' and arm == 0")["rmse_3d"].iloc[0])
        for r in td3.runs
    ]
    row = summary.query("group == 'TD3' and trajectory == 'circle' and arm == 0").iloc[0]
    assert row["rmse_3d_mean"] == pytest.approx(np.mean(rmse))
    peaks = moment_peaks(groups)
    both = peaks.query("group == 'TD3' and trajectory == 'figure8' and arm == -1")
    assert set(both["direction"]) == {"normal", "binormal"}
    arm_max = peaks.query(
        "group == 'TD3' and trajectory == 'figure8' and arm >= 0 and direction == 'normal'"
    )["mean"].max()
    assert both.query("direction == 'normal'")["mean"].iloc[0] >= arm_max - 1e-9


def test_controller_differences_match_welch_t_test_on_the_seeds() -> None:
    """Differences from the seed means and stds agree with scipy's t-test on the raw values."""
    values = {  # (group, trajectory, arm) -> 3-D RMSE of each seed, m
        ("C", "circle", 0): [0.040, 0.044, 0.047],
        ("C", "circle", 1): [0.036, 0.038],
        ("I", "circle", 0): [0.035, 0.036, 0.041],
        ("I", "circle", 1): [0.045],
        ("D", "circle", 0): [0.14, 0.15],
        ("D", "circle", 1): [0.13, 0.12],
    }
    summary = pd.DataFrame([
        {"group": g, "trajectory": t, "arm": a, "rmse_3d_mean": np.mean(v),
         "rmse_3d_std": np.std(v, ddof=1) if len(v) > 1 else np.nan, "rmse_3d_n": len(v)}
        for (g, t, a), v in values.items()
    ])
    groups = [
        Group(algo, controller, label, "0" * 12, label, label)
        for algo, controller, label in (
            ("td3", "centralized", "C"), ("td3", "independent", "I"), ("ddpg", "centralized", "D")
        )
    ]
    diff = controller_differences(summary, groups)
    assert list(diff["group"]) == ["C", "C"] and set(diff["reference"]) == {"I"}
    arm0 = diff[diff["arm"] == 0].iloc[0]
    c, i = values[("C", "circle", 0)], values[("I", "circle", 0)]
    assert arm0["difference"] == pytest.approx(np.mean(c) - np.mean(i))
    welch = stats.ttest_ind(c, i, equal_var=False)
    assert arm0["p_value"] == pytest.approx(welch.pvalue)
    assert arm0["difference"] / arm0["se"] == pytest.approx(welch.statistic)
    arm1 = diff[diff["arm"] == 1].iloc[0]
    assert arm1["difference"] == pytest.approx(0.037 - 0.045)
    assert np.isnan(arm1["se"]) and np.isnan(arm1["p_value"]) and arm1["n_reference"] == 1


# ---- the report -----------------------------------------------------------------------------
EXPECTED_FIGURES = [
    "training_curves.png",
    "final_returns.png",
    "rmse_comparison.png",
    *[
        f"{kind}_{slug}_{t}.png"
        for kind in ("trajectory", "errors")
        for slug in ("td3", "ddpg", "td3-independent")
        for t in EVAL_TRAJECTORIES
    ],
    "moments_td3.png",
    "moments_ddpg.png",
    "moments_td3-independent.png",
]


def test_report_has_every_figure_and_table(report: Path, store: RunStore) -> None:
    out = report.parent
    md = report.read_text(encoding="utf-8")
    page = (out / "index.html").read_text(encoding="utf-8")
    for name in EXPECTED_FIGURES:
        png = out / "figures" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert f"](figures/{name})" in md, name
        assert f'src="figures/{name}"' in page, name
    for heading in (
        "Training curves (study Fig. 3)",
        "Final-stage return (study Table 3)",
        "Tracking error (study Table 4)",
        "Centralized against independent controllers",
        "Trajectories and errors over time (study Figs. 4–9)",
        "Actuation moments (study Fig. 10)",
        "Peak element moments",
        "Policy actions",
    ):
        assert f"## {heading}" in md or f"### {heading}" in md, heading
        assert heading in page
    assert "Model selection" not in md  # no run has validation episodes
    manifest = json.loads((out / "report.json").read_text())
    assert sorted(manifest["files"]) == sorted(
        ["index.md", "index.html", *[f"figures/{n}" for n in EXPECTED_FIGURES]]
    )
    assert not [p for p in out.rglob("*") if ".tmp-" in p.name]


def _table_after(md: str, heading: str) -> list[str]:
    """The Markdown table rows that follow ``heading``."""
    block = md.split(heading, 1)[1].lstrip("\n").split("\n\n", 1)[0]
    return [line for line in block.splitlines() if line.startswith("|")]


def test_report_tables_show_the_study_values(report: Path) -> None:
    md = report.read_text(encoding="utf-8")
    td3 = _table_after(md, "### TD3\n")
    assert "study 3-D RMSE (m)" in td3[0]
    circle1 = next(r for r in td3 if r.startswith("| circle | arm 1 |"))
    assert "| 0.065 |" in circle1 and " ± " in circle1
    assert "| 0.053 |" in next(r for r in td3 if r.startswith("| figure-eight | arm 2 |"))
    ddpg = _table_after(md, "### DDPG\n")
    assert "| — |" in next(r for r in ddpg if r.startswith("| circle | arm 1 |"))
    independent = _table_after(md, "### TD3 (independent)\n")
    assert "| 0.059 |" in next(r for r in independent if r.startswith("| circle | arm 2 |"))
    side = _table_after(md, "### Centralized against independent controllers\n")
    assert side[0].startswith("| controller | seeds | circle arm 1 (m) | circle arm 2 (m) |")
    assert next(r for r in side if r.startswith("| TD3 | 2 |")).count(" ± ") == 6
    assert next(r for r in side if r.startswith("| TD3 (independent) | 1 |")).count(" ± ") == 0
    assert "| 0.065 | 0.043 |" in next(r for r in side if r.startswith("| study centralized TD3 |"))
    assert "| 0.054 | 0.059 |" in next(r for r in side if r.startswith("| study independent TD3 |"))
    diff = _table_after(
        md,
        "**Centralized minus TD3 (independent)** (m; negative: the centralized controller "
        "tracks better):\n",
    )
    assert [r.split(" | ")[0] for r in diff[2:]] == ["| TD3"]  # not DDPG: another algorithm
    assert re.fullmatch(r"\| TD3 \| 2 \|( [+-]0\.\d{4} \|){6}", diff[2])  # no se: one seed
    peaks = _table_after(md, "### Peak element moments\n")
    assert any(
        r.startswith("| TD3 | figure-eight | normal |") and r.endswith("| 138.9 |") for r in peaks
    )
    assert any(
        r.startswith("| TD3 | figure-eight | binormal |") and r.endswith("| 121.7 |") for r in peaks
    )
    final = _table_after(md, "## Final-stage return (study Table 3)\n")
    assert "| 2,000 env steps per run | 10,000,000 env steps per run |" in final[2]
    assert "| 2,000 env steps per arm |" in final[-1]


def test_policy_actions_table(report: Path) -> None:
    md = report.read_text(encoding="utf-8")
    # a subsection of the Table 4 section, after its tables, before the trajectory figures
    assert md.index("## Tracking error (study Table 4)") < md.index("### Policy actions")
    assert md.index("### Policy actions") < md.index("## Trajectories and errors over time")
    rows = _table_after(md, "### Policy actions\n")
    assert rows[0] == (
        "| algorithm | trajectory | arm | action saturation (%) | mean \\|Δa\\| per step "
        "| action RMS | seeds with data |"
    )
    body = rows[2:]
    assert len(body) == 3 * 3 * 2  # groups × trajectories × arms
    # arm 1 holds 0.02 (seed 0) and 0.03 (seed 1): never saturated, no change, RMS 0.025 ± 0.007
    assert "| TD3 | circle | arm 1 | 0.0 ± 0.0 | 0.000 ± 0.000 | 0.025 ± 0.007 | 2 of 2 |" in body
    # arm 2 flips between ±1 at every step: saturated, |Δa| = 2, RMS 1
    assert (
        "| DDPG | figure-eight | arm 2 | 100.0 ± 0.0 | 2.000 ± 0.000 | 1.000 ± 0.000 | 2 of 2 |"
    ) in body
    assert "| TD3 (independent) | rectangle | arm 2 | 100.0 | 2.000 | 1.000 | 1 of 1 |" in body
    text = md.split("### Policy actions\n", 1)[1]
    assert "66 % saturation and a mean change of 0.30" in text.split("\n\n")[1]
    assert text.split("\n\n")[2].startswith("*Behind these numbers*")


def test_old_metrics_tables_without_action_columns_still_build(tmp_path: Path) -> None:
    """Metrics tables written before the action statistics existed: the report builds, the
    other tables keep their numbers and the actions table says "no data"."""
    store = RunStore(tmp_path / "runs")
    spec = _spec("td3")
    for seed in (0, 1):
        record = store.create_run(spec, seed, ["softtrack", "train", "td3.yaml"])
        write_table(record.table_path("train_episodes"), _train_rows(record, 100.0))
        _write_eval(record, 0.02)
        store.mark_finished(record.run_id, "completed", global_step=BUDGET)
        if seed == 0:  # seed 0 has an old table, seed 1 a new one
            path = record.table_path("eval_metrics")
            write_table(path, read_table(path).drop(columns=list(ACTION_STATISTICS)))
    groups = group_runs(load_runs(select_runs(store, ["td3"])))
    summary = metrics_summary(groups)
    assert (summary["action_saturation_n"] == 1).all() and (summary["rmse_3d_n"] == 2).all()
    index = build_report(select_runs(store, ["td3"]), tmp_path / "out", "softtrack report td3")
    rows = _table_after(index.read_text(encoding="utf-8"), "### Policy actions\n")[2:]
    assert "| TD3 | circle | arm 2 | 100.0 | 2.000 | 1.000 | 1 of 2 |" in rows
    # only old tables: no data, and the tracking tables are unaffected
    record = select_runs(store, ["td3"])[1]
    path = record.table_path("eval_metrics")
    write_table(path, read_table(path).drop(columns=list(ACTION_STATISTICS)))
    index = build_report(select_runs(store, ["td3"]), tmp_path / "out", "softtrack report td3")
    md = index.read_text(encoding="utf-8")
    rows = _table_after(md, "### Policy actions\n")[2:]
    assert len(rows) == 3 * 2
    assert all(r.endswith("| no data | no data | no data | 0 of 2 |") for r in rows)
    assert " ± " in next(r for r in _table_after(md, "### TD3\n") if r.startswith("| circle |"))


def test_every_table_has_provenance(report: Path, store: RunStore) -> None:
    md = report.read_text(encoding="utf-8")
    blocks = md.split("\n\n")
    tables = [i for i, b in enumerate(blocks) if b.startswith("|")]
    # runs, final, 3 error tables, side by side, its differences, policy actions, peaks
    assert len(tables) == 1 + 1 + 3 + 1 + 1 + 1 + 1
    for i in tables:
        after = "\n\n".join(blocks[i + 1 : i + 3])
        assert "*Behind these numbers*" in after, blocks[i][:80]
    provenance = next(b for b in blocks if b.startswith("*Behind these numbers*"))
    record = select_runs(store, ["td3"])[0]
    for text in (
        f"`{COMMAND}`",
        "experiment `td3`",
        record.info.spec_hash[:12],
        "seeds 0, 1",
        "budget 2,000 env steps per run",
        "`softtrack train td3.yaml`",
        "Study: 10,000,000 env steps per run (8.5 h",
    ):
        assert text in provenance, text
    if record.info.git_commit:
        assert record.info.git_commit[:12] in provenance


def test_provenance_names_every_commit_a_resumed_run_trained_on(tmp_path: Path) -> None:
    from types import SimpleNamespace

    from softtrack.report.document import commit_text

    store = RunStore(tmp_path)
    run_id = store.create_run(_spec("td3"), 0).run_id
    a, b = "a" * 40, "b" * 40
    store.update_run(run_id, git_commit=a, git_dirty=False, sessions=[])
    assert commit_text(SimpleNamespace(record=store.get_run(run_id))) == a[:12]
    sessions = [{"git_commit": a, "git_dirty": False}, {"git_commit": b, "git_dirty": True}]
    store.update_run(run_id, sessions=sessions)
    text = commit_text(SimpleNamespace(record=store.get_run(run_id)))
    assert text == f"{a[:12]}, then {b[:12]} (+ uncommitted changes)"
    store.update_run(run_id, git_commit=None, sessions=[])
    assert commit_text(SimpleNamespace(record=store.get_run(run_id))) == "unknown"


def test_provenance_names_the_runs_a_derived_run_came_from(
    store: RunStore, tmp_path: Path
) -> None:
    derived = store.create_run(_spec("derived"), 0, notes={
        "derived_from": {"run_id": "01ABC", "name": "base-experiment"}})
    try:
        md = build_report([derived], tmp_path / "derived", "softtrack report derived").read_text(
            encoding="utf-8")
        assert "derived from the runs of `base-experiment` (the same training" in md
    finally:
        shutil.rmtree(derived.path)


def test_missing_eval_tables_give_no_data_figures(store: RunStore, tmp_path: Path) -> None:
    out = tmp_path / "ppo-report"
    (out / "figures").mkdir(parents=True)
    (out / "notes.txt").write_text("mine")  # someone else's file: must survive
    index = build_report(select_runs(store, ["ppo"]), out, "softtrack report ppo --out x")
    md = index.read_text(encoding="utf-8")
    for t in EVAL_TRAJECTORIES:
        assert (out / "figures" / f"trajectory_ppo_{t}.png").is_file()
        assert (out / "figures" / f"errors_ppo_{t}.png").is_file()
    assert (out / "figures" / "moments_ppo.png").is_file()
    assert "No data for PPO on the circle" in md
    assert "No data for PPO: no stored evaluation moments" in md
    assert re.search(r"\| PPO \| both arms \| 1 of 1 \| -?\d+\.\d\d \|", md)
    # a rebuild with fewer figures removes only this report's stale figures
    (out / "figures" / "unrelated.png").write_bytes(b"x")
    records = select_runs(store, ["ppo"])
    build_report(records, out, "again")
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "figures" / "unrelated.png").exists()


def test_missing_training_and_eval_tables(store: RunStore, tmp_path: Path) -> None:
    bare = store.create_run(_spec("bare"), 0)
    try:
        index = build_report([bare], tmp_path / "bare", "softtrack report bare")
        md = index.read_text(encoding="utf-8")
        assert "No data: no selected run has stored training episodes." in md
        assert "| TD3 | both arms | 0 of 1 | no data |" in md
        assert (tmp_path / "bare" / "figures" / "training_curves.png").is_file()
    finally:
        import shutil

        shutil.rmtree(bare.path)


def test_runs_table_gives_training_time_speed_and_cpu(report: Path) -> None:
    md = report.read_text(encoding="utf-8")
    header, _rule, *rows = _table_after(md, "## Runs")
    columns = [c.strip() for c in header.strip("|").split("|")]
    time_col, speed_col = columns.index("training time"), columns.index("env steps/s")
    cpu_col = columns.index("CPU (speed depends on it)")
    steps_col = columns.index("env steps / budget")
    wall = 0.1 * (BUDGET // 100 - 1)  # the fixture's training clock at its last episode, s
    assert rows
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[time_col] == f"{wall / 60:.0f} min"
        steps = int(cells[steps_col].split("/")[0].replace(",", ""))
        assert cells[speed_col] == f"{steps / wall:,.0f}"
        assert cells[cpu_col] == cpu_description()


def test_trajectory_captions_name_the_full_run_id(report: Path, store: RunStore) -> None:
    """Runs started in the same millisecond share their first 10 ULID characters, so a caption
    must give the whole id; one seed is "1 seed"."""
    md = report.read_text(encoding="utf-8")
    captions = [line for line in md.splitlines() if "(median 3-D RMSE of" in line]
    assert captions
    ids = {r.run_id for r in store.list_runs()}
    for line in captions:
        named = line.split(", run ", 1)[1].split(" ", 1)[0]
        assert named in ids, line
    assert any("of 1 seed)" in line for line in captions)
    assert not any("of 1 seeds" in line for line in captions)
