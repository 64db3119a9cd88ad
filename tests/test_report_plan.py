"""A report of many controllers: families, at most eight series a figure, one colour each."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from softtrack.evaluation.perturbations import factor_axis_label
from softtrack.report.comparison_figures import budget_text
from softtrack.report.data import Group, group_runs, load_runs
from softtrack.report.families import (
    MAX_SERIES,
    PALETTE,
    assign_colors,
    families,
    kind_of,
    task_of,
    training_groups,
)
from softtrack.report.plan import PER_KIND, headline, plan_figures
from softtrack.spec import parse_spec
from softtrack.store.runs import RunRecord, RunStore
from softtrack.store.tables import write_table


def _run(store: RunStore, spec: dict[str, Any], seed: int = 0) -> RunRecord:
    return store.create_run(parse_spec(spec), seed)


def _episodes(record: RunRecord, value: float, steps: int) -> None:
    rows = [
        {
            "run_id": record.run_id,
            "episode": i,
            "global_step": (i + 1) * steps // 20,
            "return": value,
            "length": steps // 20,
            "wall_time": float(i),
        }
        for i in range(20)
    ]
    write_table(record.table_path("train_episodes"), rows)


def _metrics(record: RunRecord, rmse: float) -> None:
    rows = [
        {"run_id": record.run_id, "trajectory": t, "arm": arm, "rmse_3d": rmse + 0.001 * arm}
        for t in ("circle", "rectangle", "figure8")
        for arm in (0, 1)
    ]
    write_table(record.table_path("eval_metrics"), rows)


def _groups(store: RunStore) -> list[Group]:
    return group_runs(load_runs(store.list_runs()))


def test_kinds_and_tasks(tmp_path: Path) -> None:
    """The study protocol differs from the defaults only in the algorithm, budget and process
    layout; anything else is a variant; contact and the viewpoints task are their own tasks."""
    store = RunStore(tmp_path)
    _run(store, {"name": "protocol", "training": {"total_timesteps": 200_000, "n_envs": 2}})
    _run(store, {"name": "ddpg", "algo": {"name": "ddpg"}})
    _run(store, {"name": "wide", "algo": {"policy_kwargs": {"net_arch": [128, 128]}}})
    _run(store, {"name": "indep", "controller": "independent"})
    _run(store, {"name": "touch", "env": {"physics": {"contact_k": 1e6, "contact_nu": 600}}})
    _run(
        store,
        {
            "name": "views",
            "env": {"task": {"name": "viewpoints"}, "physics": {"contact_k": 1e6}},
        },
    )
    by_name = {g.name: g for g in _groups(store)}
    assert kind_of(by_name["protocol"]) == "study protocol"
    assert kind_of(by_name["ddpg"]) == "study protocol"
    assert kind_of(by_name["wide"]) == "centralized variants"
    assert kind_of(by_name["indep"]) == "independent"
    assert kind_of(by_name["touch"]) == "centralized variants"  # contact is not the study's
    assert task_of(by_name["protocol"]) == "shared target, no contact"
    assert task_of(by_name["touch"]) == "shared target, contact on"
    assert task_of(by_name["views"]) == "viewpoints, contact on"
    titles = [f.title for f in families(list(by_name.values()))]
    assert titles[:3] == [
        "study protocol · shared target, no contact",
        "centralized variants · shared target, no contact",
        "independent · shared target, no contact",
    ]
    assert len(titles) == len(set(titles)) == 5


def test_a_derived_training_is_drawn_once(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    source = _run(store, {"name": "val"})
    derived = _run(store, {"name": "val-confirm", "algo": {"learning_rate": 1e-4}})
    store.update_run(
        derived.run_id, notes={"derived_from": {"run_id": source.run_id, "name": "val"}}
    )
    names = [g.name for g in training_groups(_groups(store))]
    assert names == ["val-confirm"]


def test_panels_draw_at_most_eight_best_first(tmp_path: Path) -> None:
    """Twelve variants: the training panel draws the eight with the highest final-stage
    return and says so; the tracking-error figure draws one of each kind first, at most three
    of a kind, eight at most, and every drawn controller has a colour of its own in each
    figure."""
    store = RunStore(tmp_path)
    short = {"training": {"total_timesteps": 100_000}}
    for i in range(12):
        spec = {"name": f"v{i:02d}", "algo": {"learning_rate": 1e-4 * (i + 1)}, **short}
        _episodes(record := _run(store, spec), 100.0 * i, 100_000)
        _metrics(record, 0.05 + 0.001 * i)
    for i in range(4):
        record = _run(store, {"name": f"ind{i}", "controller": "independent"})
        _metrics(record, 0.03 + 0.001 * i)  # the most accurate, but at most three of a kind
    protocol = _run(store, {"name": "protocol", **short})
    _episodes(protocol, 5.0, 100_000)
    _metrics(protocol, 0.2)
    groups = _groups(store)
    summary = pd.DataFrame(
        [
            {"group": g.label, "trajectory": t, "arm": a, "rmse_3d_mean": v, "rmse_3d_std": 0.0}
            for g in groups
            for r in g.runs
            if r.metrics is not None
            for t, a, v in r.metrics[["trajectory", "arm", "rmse_3d"]].itertuples(index=False)
        ]
    )
    plan = plan_figures(groups, summary)
    variants = next(s for s in plan.training if s.title.startswith("centralized variants"))
    assert [g.name for g in variants.shown] == [f"v{i:02d}" for i in range(11, 3, -1)]
    assert variants.note == "best 8 of 12 by final-stage return"
    shown = headline("shared target, no contact", groups, summary).shown
    kinds = [kind_of(g) for g in shown]
    assert kinds.count("independent") == kinds.count("centralized variants") == PER_KIND
    assert "protocol" in [g.name for g in shown]  # one of each kind, however it scores
    assert len(shown) == 2 * PER_KIND + 1 <= MAX_SERIES
    for selection in (*plan.training, *plan.headline):
        colors = [plan.colors[g.label] for g in selection.shown]
        assert len(set(colors)) == len(colors)


def test_colours_are_stable_and_distinct_within_a_figure() -> None:
    figures = [["a", "b", "c"], ["b", "d"], ["a", "d", "e"], [f"x{i}" for i in range(20)]]
    colors = assign_colors(figures)
    assert colors == assign_colors(figures)
    for labels in figures:
        assert len({colors[label] for label in labels}) == len(labels)
    assert set(colors.values()) <= set(PALETTE)
    # labels that never meet still get different colours while the palette lasts
    assert len({colors[label] for label in "abcde"}) == 5
    assert len({colors[label] for label in itertools.chain(*figures[:3])}) == 5


def test_budget_labels(tmp_path: Path) -> None:
    store = RunStore(tmp_path)
    _run(store, {"name": "c", "training": {"total_timesteps": 1_000_000}})
    _run(
        store,
        {"name": "i", "controller": "independent", "training": {"total_timesteps": 4_000_000}},
    )
    by_name = {g.name: g for g in _groups(store)}
    assert budget_text(by_name["c"]) == "1e6"
    assert budget_text(by_name["i"]) == "4e6/arm"  # an independent budget is per arm policy


@pytest.mark.parametrize(
    ("factor", "label"),
    [
        ("obs_noise", "obs_noise (m)"),
        ("action_delay", "action_delay (control steps)"),
        ("youngs_modulus_scale", "youngs_modulus_scale (× nominal)"),
        ("gravity", "gravity (m/s²)"),
        ("env.physics.damping", "env.physics.damping (N·s/m²)"),
        ("no_such_factor", "no_such_factor"),
    ],
)
def test_robustness_axes_name_their_units(factor: str, label: str) -> None:
    assert factor_axis_label(factor) == label
