"""``softtrack.report``: a report built from small fake runs holds every figure and table,
the study's values, and the provenance; missing data gives "no data" figures; an empty
selection is a clear error."""

from __future__ import annotations

import dataclasses
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
    moment_peaks_table,
    moments_table,
    run_episode,
    trajectory_table,
)
from softtrack.evaluation.metrics import ACTION_STATISTICS, SAFETY_STATISTICS, TORQUE_STATISTICS
from softtrack.report import build_report
from softtrack.report.curves import final_stage_table, training_curves
from softtrack.report.data import Group, group_runs, load_runs, representative_run
from softtrack.report.group_summaries import controller_differences, metrics_summary, moment_peaks
from softtrack.spec import parse_spec, spec_to_yaml
from softtrack.store.provenance import cpu_description
from softtrack.store.runs import RunNotFoundError, RunRecord, RunStore
from softtrack.store.selection import EmptySelectionError, select_runs
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
    trajs, metrics, moments, peaks = [], [], [], []
    for trajectory in EVAL_TRAJECTORIES:
        episode = run_episode(_bang_bang(value), config, trajectory, duration=EVAL_DURATION)
        trajs.append(trajectory_table(record.run_id, episode))
        metrics.append(metrics_table(record.run_id, episode))
        moments.append(moments_table(record.run_id, episode))
        peaks.append(moment_peaks_table(record.run_id, episode))
    write_table(record.table_path("eval_trajectories"), pd.concat(trajs, ignore_index=True))
    write_table(record.table_path("eval_metrics"), pd.concat(metrics, ignore_index=True))
    write_table(record.table_path("eval_moments"), pd.concat(moments, ignore_index=True))
    write_table(record.table_path("eval_moment_peaks"), pd.concat(peaks, ignore_index=True))


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
    with pytest.raises(EmptySelectionError, match="nothing selected"):
        select_runs(store, [])
    with pytest.raises(EmptySelectionError, match=r"neither an experiment name.*known: ddpg"):
        select_runs(store, ["sac-nonexistent"])
    other = tmp_path / "other.yaml"
    other.write_text("name: other\n")
    with pytest.raises(EmptySelectionError, match=r"no run .* has this spec"):
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
    assert td3["values"] == pytest.approx(dict(zip((0, 1), per_run, strict=False)))
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
    # one episode every 100 steps: the window is at least two episode spacings
    assert [c.window for c in curves] == pytest.approx([max(0.03 * BUDGET, 200.0)] * 4)
    assert not smoothing.per_second and not any(c.per_second for c in curves)
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
    summary = pd.DataFrame(
        [
            {
                "group": g,
                "trajectory": t,
                "arm": a,
                "rmse_3d_mean": np.mean(v),
                "rmse_3d_std": np.std(v, ddof=1) if len(v) > 1 else np.nan,
                "rmse_3d_n": len(v),
            }
            for (g, t, a), v in values.items()
        ]
    )
    groups = [
        Group(algo, controller, label, "0" * 12, label, label)
        for algo, controller, label in (
            ("td3", "centralized", "C"),
            ("td3", "independent", "I"),
            ("ddpg", "centralized", "D"),
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
EXPECTED_FIGURES = [  # three controllers: every one drawn, side by side per trajectory
    "training_curves.png",
    "final_returns.png",
    "rmse_comparison.png",
    "performance_profile.png",
    *[f"{kind}_{t}.png" for kind in ("trajectory", "errors") for t in EVAL_TRAJECTORIES],
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
        "| action RMS | seeds with data | torque rate RMS (N·m/s) | peak moment (N·m) "
        "| min clearance (m) | collision steps |"
    )
    body = rows[2:]
    assert len(body) == 3 * 3 * 2  # groups × trajectories × arms
    actions = ["|".join(r.split("|")[:8]) + "|" for r in body]  # up to "seeds with data"
    # arm 1 holds 0.02 (seed 0) and 0.03 (seed 1): never saturated, no change, RMS 0.025 ± 0.007
    assert (
        "| TD3 | circle | arm 1 | 0.0 ± 0.0 | 0.000 ± 0.000 | 0.025 ± 0.007 | 2 of 2 |"
    ) in actions
    # arm 2 flips between ±1 at every step: saturated, |Δa| = 2, RMS 1
    assert (
        "| DDPG | figure-eight | arm 2 | 100.0 ± 0.0 | 2.000 ± 0.000 | 1.000 ± 0.000 | 2 of 2 |"
    ) in actions
    assert "| TD3 (independent) | rectangle | arm 2 | 100.0 | 2.000 | 1.000 | 1 of 1 |" in actions
    # smoothness and safety: arm 1's constant torques do not change, arm 2's flip at every
    # step; the arms never touch in 0.2 s, about 0.1 m apart
    cells = [
        [c.strip() for c in r.strip("|").split("|")]
        for r in body
        if r.startswith("| TD3 | circle |")
    ]
    assert cells[0][7] == "0 ± 0"
    rate, peak = float(cells[1][7].split(" ± ")[0]), float(cells[1][8].split(" ± ")[0])
    assert 1e4 < rate <= 2 * peak / 0.002 * 1.001  # 2·RMS of |τ| over the elements, per 2 ms
    for c in cells:
        clearance = float(c[9].split(" ± ")[0])
        assert float(c[8].split(" ± ")[0]) > 0 and 0.05 < clearance <= 0.1
        assert c[10] == "0 ± 0"  # collision steps: whole numbers
    assert cells[0][9] == cells[1][9]  # per episode: the same in both arms' rows
    text = md.split("### Policy actions\n", 1)[1]
    caption = text.split("\n\n")[1]
    assert "66 % saturation and a mean change of 0.30" in caption
    # every run has the statistics: the caption does not speak of missing data
    assert "no data" not in caption.lower() and "stored before" not in caption


def _two_seeds_one_old_table(tmp_path: Path, missing: list[str]) -> RunStore:
    """Two finished td3 runs; seed 0's eval_metrics was written before ``missing`` existed."""
    store = RunStore(tmp_path / "runs")
    spec = _spec("td3")
    for seed in (0, 1):
        record = store.create_run(spec, seed, ["softtrack", "train", "td3.yaml"])
        write_table(record.table_path("train_episodes"), _train_rows(record, 100.0))
        _write_eval(record, 0.02)
        store.mark_finished(record.run_id, "completed", global_step=BUDGET)
        if seed == 0:
            path = record.table_path("eval_metrics")
            write_table(path, read_table(path).drop(columns=missing))
    return store


def test_old_metrics_tables_without_action_columns_still_build(tmp_path: Path) -> None:
    """Metrics tables written before the action statistics existed: the report builds, the
    other tables keep their numbers and the actions table says "no data"."""
    store = _two_seeds_one_old_table(tmp_path, list(ACTION_STATISTICS))
    groups = group_runs(load_runs(select_runs(store, ["td3"])))
    summary = metrics_summary(groups)
    assert (summary["action_saturation_n"] == 1).all() and (summary["rmse_3d_n"] == 2).all()
    index = build_report(select_runs(store, ["td3"]), tmp_path / "out", "softtrack report td3")
    md = index.read_text(encoding="utf-8")
    rows = _table_after(md, "### Policy actions\n")[2:]
    assert any(
        r.startswith("| TD3 | circle | arm 2 | 100.0 | 2.000 | 1.000 | 1 of 2 |") for r in rows
    )
    caption = md.split("### Policy actions\n", 1)[1].split("\n\n")[1]
    assert "Some runs of TD3 have metrics stored before these statistics existed" in caption
    # only old tables: no data, and the tracking tables are unaffected
    record = select_runs(store, ["td3"])[1]
    path = record.table_path("eval_metrics")
    write_table(path, read_table(path).drop(columns=list(ACTION_STATISTICS)))
    index = build_report(select_runs(store, ["td3"]), tmp_path / "out", "softtrack report td3")
    md = index.read_text(encoding="utf-8")
    rows = _table_after(md, "### Policy actions\n")[2:]
    assert len(rows) == 3 * 2
    assert all("| no data | no data | no data | 0 of 2 |" in r for r in rows)
    assert " ± " in next(r for r in _table_after(md, "### TD3\n") if r.startswith("| circle |"))


def test_old_metrics_tables_without_torque_and_clearance_columns_show_a_dash(
    tmp_path: Path,
) -> None:
    """Metrics tables written before the smoothness and safety columns existed: the report
    builds, those cells read "–" and the other cells keep their numbers."""
    new_columns = [*TORQUE_STATISTICS, *SAFETY_STATISTICS]
    store = _two_seeds_one_old_table(tmp_path, new_columns)
    groups = group_runs(load_runs(select_runs(store, ["td3"])))
    summary = metrics_summary(groups)
    assert (summary["torque_rate_rms_n"] == 1).all() and (summary["action_rms_n"] == 2).all()
    index = build_report(select_runs(store, ["td3"]), tmp_path / "out", "softtrack report td3")
    md = index.read_text(encoding="utf-8")
    rows = _table_after(md, "### Policy actions\n")[2:]
    row = next(r for r in rows if r.startswith("| TD3 | circle | arm 2 |"))
    assert "| 100.0 ± 0.0 | 2.000 ± 0.000 | 1.000 ± 0.000 | 2 of 2 |" in row
    assert " ± " not in row.split("| 2 of 2 |")[1]  # one seed with the new columns: no std
    caption = md.split("### Policy actions\n", 1)[1].split("\n\n")[1]
    assert "before the torque and clearance columns existed" in caption
    # only old tables: a dash in each new cell
    record = select_runs(store, ["td3"])[1]
    path = record.table_path("eval_metrics")
    write_table(path, read_table(path).drop(columns=new_columns))
    index = build_report(select_runs(store, ["td3"]), tmp_path / "out", "softtrack report td3")
    md = index.read_text(encoding="utf-8")
    rows = _table_after(md, "### Policy actions\n")[2:]
    assert len(rows) == 3 * 2
    assert all(r.endswith("| 2 of 2 | – | – | – | – |") for r in rows)


def test_provenance_is_stated_once_per_controller(report: Path, store: RunStore) -> None:
    md = report.read_text(encoding="utf-8")
    assert md.count("Behind these numbers") == 1 and "## Behind these numbers" in md
    section = md.split("## Behind these numbers\n", 1)[1].split("\n## ", 1)[0]
    paragraphs = section.strip().split("\n\n")
    assert f"`{COMMAND}`" in paragraphs[0]
    for label in ("TD3", "DDPG", "TD3 (independent)"):  # one paragraph per controller
        assert sum(p.startswith(f"**{label}**:") for p in paragraphs) == 1, label
        assert md.count(f"**{label}**: experiment") == 1, label
    record = select_runs(store, ["td3"])[0]
    td3 = next(p for p in paragraphs if p.startswith("**TD3**:"))
    for text in (
        "experiment `td3`",
        record.info.spec_hash[:12],
        "seeds 0, 1",
        "budget 2,000 env steps per run",
        "`softtrack train td3.yaml`",
    ):
        assert text in td3, text
    if record.info.git_commit:
        assert record.info.git_commit[:12] in td3
    assert paragraphs[-1].startswith("Study: 10,000,000 env steps per run (8.5 h")
    # the answers come first; provenance and the runs table close the report
    assert md.index("## Training") < md.index("## Behind these numbers") < md.index("## Runs")


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


def test_provenance_names_the_runs_a_derived_run_came_from(store: RunStore, tmp_path: Path) -> None:
    derived = store.create_run(
        _spec("derived"), 0, notes={"derived_from": {"run_id": "01ABC", "name": "base-experiment"}}
    )
    try:
        md = build_report([derived], tmp_path / "derived", "softtrack report derived").read_text(
            encoding="utf-8"
        )
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
        assert (out / "figures" / f"trajectory_{t}.png").is_file()
        assert (out / "figures" / f"errors_{t}.png").is_file()
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


# ---- moments: both table formats ------------------------------------------------------------
def test_moment_peaks_read_the_old_and_the_new_table_format(tmp_path: Path) -> None:
    """The episode peak comes from eval_moment_peaks where it has the trajectory, else from the
    per-step max_abs_moment of an older eval_moments; both give the same number."""
    from softtrack.report.data import episode_peaks

    config = make_config()
    new_moments, new_peaks, old_moments = [], [], []
    for trajectory in EVAL_TRAJECTORIES:
        episode = run_episode(_bang_bang(0.5), config, trajectory, duration=EVAL_DURATION)
        new_moments.append(moments_table("r", episode))
        new_peaks.append(moment_peaks_table("r", episode))
        old = moments_table("r", episode)  # the old format: a per-step peak over the elements
        old["max_abs_moment"] = np.abs(episode.element_torques).max(axis=-1).reshape(-1)
        old_moments.append(old)
    moments = pd.concat(new_moments, ignore_index=True)
    peaks = pd.concat(new_peaks, ignore_index=True)
    old = pd.concat(old_moments, ignore_index=True)
    key = ["trajectory", "arm", "direction"]
    from_new = episode_peaks(moments, peaks).sort_values(key).reset_index(drop=True)
    from_old = episode_peaks(old, None).sort_values(key).reset_index(drop=True)
    assert len(from_new) == 3 * 2 * 2
    pd.testing.assert_frame_equal(from_new, from_old, check_dtype=False, rtol=1e-6)
    # a run re-evaluated on the circle only: new peaks there, old column elsewhere
    mixed = episode_peaks(old, peaks[peaks["trajectory"] == "circle"])
    assert sorted(set(mixed["trajectory"])) == sorted(EVAL_TRAJECTORIES)
    assert episode_peaks(moments, None) is None  # new summary table alone: no peak

    # a report of one new-format and one old-format seed has peaks from both
    store = RunStore(tmp_path / "runs")
    for seed in (0, 1):
        record = store.create_run(_spec("td3"), seed, ["softtrack", "train", "td3.yaml"])
        _write_eval(record, 0.02)
        if seed == 1:
            record.table_path("eval_moment_peaks").unlink()
            write_table(record.table_path("eval_moments"), old.assign(run_id=record.run_id))
        store.mark_finished(record.run_id, "completed", global_step=BUDGET)
    groups = group_runs(load_runs(select_runs(store, ["td3"])))
    table = moment_peaks(groups)
    assert (table["n"] == 2).all() and len(table) == 3 * 2 * 3
    md = build_report(select_runs(store, ["td3"]), tmp_path / "out", "x").read_text("utf-8")
    peak_rows = _table_after(md, "### Peak element moments\n")[2:]
    assert peak_rows and not any("no data" in r for r in peak_rows)


# ---- training curves of runs of different lengths -------------------------------------------
def _episode_rows(record: RunRecord, n: int, spacing: int, episode_return: float) -> list[dict]:
    return [
        {
            "run_id": record.run_id,
            "episode": i,
            "global_step": spacing * (i + 1),
            "return": episode_return,
            "length": spacing,
            "wall_time": 0.1 * i,
        }
        for i in range(n)
    ]


def test_training_curves_scale_with_each_run_and_compare_returns_per_second(
    tmp_path: Path,
) -> None:
    """A 10,000-step run with 2-s episodes beside a 1,000,000-step run with 10-s episodes: each
    curve is smoothed over 3 % of its own run (not of the longest), and returns are per
    second of episode; the report's figure draws them in separate panels."""
    from softtrack.report import comparison_figures as cf
    from softtrack.report.plan import plan_figures

    store = RunStore(tmp_path / "runs")
    short = store.create_run(
        parse_spec(
            {
                "name": "short",
                "env": {"episode_duration": 2.0},
                "algo": {"learning_starts": 100},
                "training": {"total_timesteps": 10_000},
            }
        ),
        0,
    )
    long = store.create_run(
        parse_spec({"name": "long", "training": {"total_timesteps": 1_000_000}}), 0
    )
    write_table(short.table_path("train_episodes"), _episode_rows(short, 1000, 10, -400.0))
    write_table(long.table_path("train_episodes"), _episode_rows(long, 1000, 1000, 15000.0))
    groups = group_runs(load_runs([short, long]))
    curves, smoothing = training_curves(groups)
    by_name = {c.group.name: c for c in curves}
    assert by_name["short"].window == pytest.approx(0.03 * 10_000)
    assert by_name["long"].window == pytest.approx(0.03 * 1_000_000)
    assert by_name["short"].steps[-1] == 10_000 and by_name["long"].steps[-1] == 1_000_000
    assert smoothing.per_second and all(c.per_second for c in curves)
    assert np.nanmean(by_name["short"].mean) == pytest.approx(-400.0 / 2.0)
    assert np.nanmean(by_name["long"].mean) == pytest.approx(15000.0 / 10.0)
    assert "per second" in smoothing.describe()
    # the report's figure compares returns at equal episode length only: one panel each
    plan = plan_figures(groups, pd.DataFrame())
    panels = [cf.CurvePanel(s, *training_curves(s.shown)) for s in plan.training]
    assert sorted(len(p.curves) for p in panels) == [1, 1]
    assert not any(p.smoothing.per_second for p in panels)
    path = cf.training_curves_figure(panels, plan.colors, tmp_path / "curves.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # episodes of one length: plain returns
    alone, plain = training_curves(group_runs(load_runs([long])))
    assert not plain.per_second and np.nanmean(alone[0].mean) == pytest.approx(15000.0)


# ---- which controllers get figures ----------------------------------------------------------
def test_featured_groups_are_the_study_protocol_the_best_and_the_independent(
    tmp_path: Path,
) -> None:
    from softtrack.report.featured import featured_groups

    store = RunStore(tmp_path / "runs")
    budgets = {"study": 10_000_000, "good": 4_000_000, "bad": 4_000_000, "ddpg": 1_000_000}
    records = [
        store.create_run(
            parse_spec(
                {
                    "name": name,
                    "algo": {"name": "ddpg" if name == "ddpg" else "td3", "learning_starts": 100},
                    "training": {"total_timesteps": budget},
                }
            ),
            0,
        )
        for name, budget in budgets.items()
    ]
    records += [
        store.create_run(
            parse_spec(
                {
                    "name": name,
                    "controller": "independent",
                    "training": {"total_timesteps": 2_000_000},
                }
            ),
            0,
        )
        for name in ("ind-a", "ind-b")
    ]
    groups = group_runs(load_runs(records))
    label = {g.name: g.label for g in groups}
    rmse = {"study": 0.05, "good": 0.03, "bad": 0.09, "ddpg": 0.2, "ind-a": 0.06, "ind-b": 0.04}
    summary = pd.DataFrame(
        [
            {"group": label[name], "trajectory": t, "arm": arm, "rmse_3d_mean": value}
            for name, value in rmse.items()
            for t in EVAL_TRAJECTORIES
            for arm in (0, 1)
        ]
    )
    featured = featured_groups(groups, summary)
    assert [(f.group.name, f.role) for f in featured] == [
        ("study", "study protocol"),
        ("good", "best centralized"),
        ("ind-b", "best independent"),
    ]
    assert featured[0].title == f"{label['study']} (study protocol)"
    # the study protocol is also the best: drawn once, with both roles
    summary.loc[summary["group"] == label["study"], "rmse_3d_mean"] = 0.01
    featured = featured_groups(groups, summary)
    assert [(f.group.name, f.role) for f in featured] == [
        ("study", "study protocol, best centralized"),
        ("ind-b", "best independent"),
    ]
    assert len(featured_groups(groups, summary, all_groups=True)) == len(groups)
    assert [f.role for f in featured_groups(groups[:3], summary)] == ["", "", ""]


def test_a_report_of_many_controllers_draws_a_few_unless_all_figures(
    store: RunStore, tmp_path: Path
) -> None:
    """Four controllers (more than three): the per-run figures show the best centralized and
    the independent controller, side by side, one figure per trajectory; --all-figures gives
    one per controller and trajectory."""
    selection = ["td3", "ddpg", "independent-td3", "ppo"]
    index = build_report(select_runs(store, selection), tmp_path / "few", "x")
    figures = sorted(p.name for p in (tmp_path / "few" / "figures").iterdir())
    groups = group_runs(load_runs(select_runs(store, selection)))
    best = min(
        ("td3", "ddpg"),
        key=lambda slug: (
            metrics_summary(groups).query(f"group == '{slug.upper()}'")["rmse_3d_mean"].mean()
        ),
    )  # PPO has no evaluation
    assert figures == sorted(
        [
            "training_curves.png",
            "final_returns.png",
            "rmse_comparison.png",
            "performance_profile.png",
            *[f"{kind}_{t}.png" for kind in ("trajectory", "errors") for t in EVAL_TRAJECTORIES],
            f"moments_{best}.png",
            "moments_td3-independent.png",
        ]
    )
    md = index.read_text(encoding="utf-8")
    assert f"Drawn: {best.upper()} (best centralized), TD3 (independent) (best independent)" in md
    assert "`softtrack report … --all-figures` draws every controller" in md
    index = build_report(select_runs(store, selection), tmp_path / "all", "x", all_figures=True)
    figures = {p.name for p in (tmp_path / "all" / "figures").iterdir()}
    for slug in ("td3", "ddpg", "td3-independent", "ppo"):
        assert f"moments_{slug}.png" in figures
        for t in EVAL_TRAJECTORIES:
            assert {f"trajectory_{slug}_{t}.png", f"errors_{slug}_{t}.png"} <= figures
    assert "Every controller of this report is drawn." in index.read_text(encoding="utf-8")


# ---- figure layout ---------------------------------------------------------------------------
def test_trajectory_figure_labels_and_ticks_do_not_overlap(
    store: RunStore, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The 3-D panel's axis labels stay clear of the neighbouring panel's, tick labels do not
    run into each other, and the title fits on its lines."""
    from softtrack.report import figures as fg

    drawn = []
    save = fg.save_figure

    def keep(fig, path, footer):  # type: ignore[no-untyped-def]
        drawn.append(fig)
        return save(fig, path, footer)

    monkeypatch.setattr(fg, "save_figure", keep)
    runs = load_runs(select_runs(store, ["td3", "independent-td3"]))
    rows = []
    for run in runs[:1] + runs[-1:]:
        traj = run.trajectories[run.trajectories["trajectory"] == "figure8"]
        rows.append(
            fg.PathRow(
                f"TD3 [a-rather-long-experiment-name-{run.seed}] (study protocol)",
                traj,
                f"seed {run.seed}, run {run.run_id} (median 3-D RMSE of 3 seeds)",
                {0: 0.055, 1: 0.051},
            )
        )
    path = fg.trajectory_3d_figure(rows, "figure8", tmp_path / "t.png", footer="x · y · z")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig = drawn[-1]
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)

    def box(artist):  # type: ignore[no-untyped-def]
        return artist.get_window_extent(renderer)

    def clear(artists) -> bool:  # type: ignore[no-untyped-def]
        """No two texts closer than 4 px (each box padded by 2 px)."""
        boxes = [box(a).padded(2) for a in artists if a.get_visible() and a.get_text()]
        return not any(a.overlaps(b) for a, b in itertools.combinations(boxes, 2))

    axes3d = [ax for ax in fig.get_axes() if ax.name == "3d"]
    axes2d = [ax for ax in fig.get_axes() if ax.name != "3d"]
    assert len(axes3d) == len(axes2d) == 2
    for ax3, ax2 in zip(axes3d, axes2d, strict=True):
        labels = [ax3.xaxis.label, ax3.yaxis.label, ax3.zaxis.label]
        assert clear([*labels, ax2.yaxis.label, *ax2.get_yticklabels()])
        assert not box(ax3.zaxis.label).overlaps(ax2.get_tightbbox(renderer))
        assert clear(ax2.get_xticklabels()) and clear(ax2.get_yticklabels())
        for axis in (ax3.xaxis, ax3.yaxis, ax3.zaxis):
            assert clear(axis.get_ticklabels())
    titles = [fig._suptitle, *(sub._suptitle for sub in fig.subfigs)]
    assert clear(titles + [ax.title for ax in fig.get_axes()])
    assert fig._suptitle.get_text().count("\n") == 1  # a short title and a one-line subtitle


def test_the_command_line_chooses_the_drawn_controllers(store: RunStore, tmp_path: Path) -> None:
    """`softtrack report --figures-for NAME` (repeatable) and `--all-figures` reach the report;
    an unknown name is a one-line error and writes nothing."""
    from typer.testing import CliRunner

    from softtrack.cli import app

    runner = CliRunner()
    base = ["report", "td3", "ddpg", "independent-td3", "ppo", "--runs-dir", str(store.root)]
    out = tmp_path / "chosen"
    result = runner.invoke(
        app, [*base, "--out", str(out), "--figures-for", "ppo", "--figures-for", "ddpg"]
    )
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (out / "figures").glob("moments_*")) == [
        "moments_ddpg.png",
        "moments_ppo.png",
    ]
    assert "Drawn: PPO, DDPG (chosen with `--figures-for`)" in (out / "index.md").read_text()
    out = tmp_path / "all"
    result = runner.invoke(app, [*base, "--out", str(out), "--all-figures"])
    assert result.exit_code == 0, result.output
    assert (out / "figures" / "trajectory_ppo_circle.png").is_file()
    assert len(list((out / "figures").glob("errors_*"))) == 4 * 3
    result = runner.invoke(app, [*base, "--out", str(tmp_path / "bad"), "--figures-for", "sac"])
    assert result.exit_code == 2
    assert result.stderr.strip().startswith("error: --figures-for sac: no controller")
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad").exists()


def test_across_seeds_tables_and_profile(report: Path) -> None:
    """The report states the headline controllers' IQM with its interval and the probability
    that the best improves on each other, per task, and draws their performance profiles."""
    md = report.read_text(encoding="utf-8")
    section = md.split(
        "## Best controllers per task, across seeds: interquartile mean and probability of "
        "improvement\n"
    )[1]
    rows = [line for line in section.split("\n\n")[1].splitlines() if line.startswith("|")]
    assert rows[0].startswith("| controller | runs | seeds | IQM 3-D RMSE, all cells (m)")
    body = rows[2:]
    assert body[0].split("|")[5].strip() == "—"  # the best is not compared with itself
    assert all(re.search(r"\d\.\d\d \[\d\.\d\d, \d\.\d\d\]", r.split("|")[5]) for r in body[1:])
    assert "noise floor" in section.split("##")[0]
    assert (report.parent / "figures" / "performance_profile.png").is_file()


def test_the_representative_run_does_not_depend_on_which_runs_keep_their_steps(
    tmp_path: Path,
) -> None:
    """The median seed is taken over every run with metrics; a run without per-step tables is
    replaced by the drawable run nearest to it in RMSE."""
    store = RunStore(tmp_path / "runs")
    spec = parse_spec({"name": "five", "training": {"total_timesteps": 100_000}})
    errors = [0.05, 0.01, 0.03, 0.02, 0.04]  # seed 2 is the median
    for seed, error in enumerate(errors):
        record = store.create_run(spec, seed)
        metrics = [{"trajectory": "circle", "arm": a, "rmse_3d": error} for a in (0, 1)]
        write_table(record.table_path("eval_metrics"), metrics)
        if seed != 4:  # seed 4 never kept its per-step tables
            steps = [{"trajectory": "circle", "arm": a, "step": 1} for a in (0, 1)]
            write_table(record.table_path("eval_trajectories"), steps)
    runs = load_runs(store.list_runs())
    group = Group("td3", "centralized", "five", "0" * 12, "five", "five", tuple(runs))
    assert representative_run(group, "circle").seed == 2
    # without seed 2's steps, seeds 0 (0.05), 1 (0.01) and 3 (0.02) are drawable: 0.02 is nearest
    lean = tuple(r if r.seed != 2 else dataclasses.replace(r, trajectories=None) for r in runs)
    group = dataclasses.replace(group, runs=lean)
    assert representative_run(group, "circle").seed == 3
    assert representative_run(group, "rectangle") is None
