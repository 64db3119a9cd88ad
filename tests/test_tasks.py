"""Dual-arm tasks (softtrack.env.tasks): the shared target and viewpoints."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from softtrack.env.core import TrackingCore
from softtrack.env.settings import make_config
from softtrack.env.tasks import TaskConfig
from softtrack.evaluation.episode_tables import metrics_table, trajectory_table
from softtrack.evaluation.episodes import run_episode
from softtrack.sim.params import InvalidParameterError
from softtrack.spec import ExperimentSpec, load_spec, spec_hash
from softtrack.spec.env_config import env_config, env_kwargs

REPO = Path(__file__).resolve().parents[1]


def test_goal_offsets() -> None:
    assert np.array_equal(TaskConfig().goal_offsets(), np.zeros((2, 3)))
    views = TaskConfig("viewpoints", standoff=0.12)
    assert np.allclose(views.goal_offsets(), [[-0.12, 0, 0], [0.12, 0, 0]])
    assert np.allclose(views.goal_offsets((1,)), [[0.12, 0, 0]])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"task": "juggling"}, "task 'juggling' is unknown"),
        ({"task": "viewpoints", "standoff": -0.1}, "standoff=-0.1 must be"),
    ],
)
def test_bad_task_is_rejected(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        make_config(**kwargs)


def test_viewpoints_distances_are_to_each_arms_point() -> None:
    config = make_config(
        task="viewpoints", standoff=0.1, target="fixed", fixed_position=(0.0, 1.0, 0.0)
    )
    core = TrackingCore(1, config)
    core.reset([0], [np.random.default_rng(0)])
    result = core.step(np.zeros((1, 24)))
    tips = core.engine.tip_position[0]  # the arms stay straight: tips at (∓0.1, 1, 0)
    expected = np.linalg.norm(tips - np.array([[-0.1, 1.0, 0.0], [0.1, 1.0, 0.0]]), axis=1)
    assert np.allclose(result.distances[0], expected)
    assert np.all(result.distances[0] < 1e-9)
    shared = TrackingCore(1, make_config(target="fixed", fixed_position=(0.0, 1.0, 0.0)))
    shared.reset([0], [np.random.default_rng(0)])
    assert np.allclose(shared.step(np.zeros((1, 24))).distances[0], 0.1)


def test_viewpoints_episode_metrics_use_each_arms_point() -> None:
    """A still policy with both tips on their points: zero error in the viewpoints task,
    the 0.1-m offset in the shared task; the trajectory table stores each arm's point."""

    def still(observation: np.ndarray) -> np.ndarray:
        return np.zeros(24)

    target = {"target": "fixed", "fixed_position": (0.0, 1.0, 0.0)}
    views = run_episode(still, make_config(task="viewpoints", **target), "fixed", duration=0.1)
    shared = run_episode(still, make_config(**target), "fixed", duration=0.1)
    assert metrics_table("r", views)["rmse_3d"].max() < 1e-9
    assert np.allclose(metrics_table("r", shared)["rmse_3d"], 0.1)
    rows = trajectory_table("r", views)
    assert np.allclose(rows.loc[rows.arm == 0, "target_x"], -0.1)
    assert np.allclose(rows.loc[rows.arm == 1, "target_x"], 0.1)


def test_spec_task_section() -> None:
    spec = ExperimentSpec.model_validate(
        {"env": {"task": {"name": "viewpoints", "standoff": 0.15}}}
    )
    config = env_config(spec)
    assert config.task == TaskConfig("viewpoints", 0.15)
    single = env_config(spec, arm=1)
    assert np.allclose(single.goal_offsets(), [[0.15, 0, 0]])
    assert "task" not in env_kwargs(ExperimentSpec())  # default kwargs as before
    assert spec_hash(spec) != spec_hash(ExperimentSpec())


def test_new_fields_keep_every_shipped_hash() -> None:
    """Contact and task fields at their defaults leave the hash of every shipped run's spec."""
    checked = 0
    for run_json in sorted((REPO / "models").glob("*/run.json"))[:12]:
        stored = json.loads(run_json.read_text())["spec_hash"]
        spec = load_spec(run_json.parent / "spec.yaml")
        assert spec_hash(spec) == stored, run_json.parent.name
        checked += 1
    assert checked > 0


def test_single_arm_scene_has_no_contact() -> None:
    spec = ExperimentSpec.model_validate(
        {"env": {"physics": {"contact_k": 1e6, "contact_nu": 600}}}
    )
    assert env_config(spec).sim.contact_k == 1e6
    assert env_config(spec, arm=0).sim.contact_k == 0.0
    with pytest.raises(InvalidParameterError, match="needs two arms"):
        make_config(n_arms=1, arm=0, contact_k=1e6)
