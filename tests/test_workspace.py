"""The transport workspace (softtrack.evaluation.workspace, ``softtrack workspace``): the
action family, the held test, floors against closed forms, the command and its bad input."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.env.settings import make_config
from softtrack.evaluation.workspace import (
    SearchSettings,
    actions_from_parameters,
    boundary_by_height,
    hold_positions,
    path_floors,
    path_points,
    search_workspace,
)

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]
TRANSPORT_SPEC = (
    ROOT / "experiments/variants/td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-long.yaml"
)


def _transport(**settings: object) -> object:
    return make_config(task="transport", sphere={}, contact_k=1e6, contact_nu=600.0, **settings)


def test_the_action_family_shares_a_common_part_and_splits_a_differential_one() -> None:
    parameters = np.zeros((4, 8))
    parameters[1, 0] = 0.4  # common normal offset: both arms alike
    parameters[2, 4] = 0.4  # differential normal offset: the arms opposite
    parameters[3, 1] = 5.0  # a common normal slope beyond the range: clipped
    actions = actions_from_parameters(parameters).reshape(4, 2, 2, 6)  # arm, direction, point
    assert (actions[0] == 0).all()
    np.testing.assert_array_equal(actions[1, 0, 0], np.full(6, 0.4))
    np.testing.assert_array_equal(actions[1, 1, 0], np.full(6, 0.4))
    np.testing.assert_array_equal(actions[2, 0, 0], -actions[2, 1, 0])
    np.testing.assert_array_equal(actions[2, 0, 0], np.full(6, 0.4))
    assert actions[3, 0, 0, 0] == -1.0 and actions[3, 0, 0, -1] == 1.0
    assert (actions[:, :, 1] == 0).all()  # no binormal part asked


def test_floors_against_closed_forms() -> None:
    config = _transport()
    circle = path_points(config, "circle")
    on_path = path_floors(config, circle, ["circle"])
    assert on_path["floor"].iloc[0] == pytest.approx(0.0, abs=1e-12)
    assert on_path["within"].iloc[0] == 1.0
    centre = np.asarray(config.target.center, dtype=float)[None]
    from_centre = path_floors(config, centre, ["circle"], tolerance=0.01)
    assert from_centre["floor"].iloc[0] == pytest.approx(config.target.circle_radius)
    assert from_centre["within"].iloc[0] == 0.0
    above = centre + np.array(
        [0.0, 0.4, 0.0]
    )  # 0.4 m above the centre: every point √(0.3² + 0.4²) away
    assert path_floors(config, above, ["circle"])["floor"].iloc[0] == pytest.approx(0.5)
    assert np.isinf(path_floors(config, np.zeros((0, 3)), ["circle"])["floor"].iloc[0])


def test_boundary_bins_by_height() -> None:
    held = np.array([[0.1, 0.91, 0.0], [-0.2, 0.93, 0.1], [0.0, 0.97, -0.05]])
    table = boundary_by_height(held, 0.05)
    assert list(table["count"]) == [2, 1]
    first = table.iloc[0]
    assert (first["x_min"], first["x_max"], first["z_max"]) == (-0.2, 0.1, 0.1)
    assert first["reach"] == pytest.approx(np.hypot(-0.2, 0.1))
    assert boundary_by_height(np.zeros((0, 3))).empty


def test_the_grip_holds_the_sphere_at_its_start_and_no_grip_does_not() -> None:
    config = _transport()
    gripped = dataclasses.replace(config, task=dataclasses.replace(config.task, grip=0.1))
    held, position = hold_positions(gripped, np.zeros((2, 8)), 0.2, 0.6)
    assert held.all()
    start = np.asarray(config.sim.sphere.center)
    assert np.linalg.norm(position - start, axis=1).max() < 0.02
    loose = dataclasses.replace(config, task=dataclasses.replace(config.task, grip=-0.3))
    held, _ = hold_positions(loose, np.zeros((1, 8)), 0.2, 0.6)
    assert not held.any()


def test_the_search_keeps_every_held_sample_and_checks_its_settings() -> None:
    config = _transport()
    gripped = dataclasses.replace(config, task=dataclasses.replace(config.task, grip=0.1))
    start = np.asarray(config.sim.sphere.center)
    settings = SearchSettings(
        population=8, iterations=2, elite=2, initial_std=0.01, ramp=0.2, hold=0.6
    )
    held = search_workspace(gripped, start[None], settings)
    assert 0 < len(held) <= 16 and held.shape[1] == 3  # seeded: the same samples every run
    with pytest.raises(ValueError, match="elite=9 must not exceed population=8"):
        search_workspace(gripped, start[None], dataclasses.replace(settings, elite=9))
    with pytest.raises(ValueError, match="transport"):
        search_workspace(make_config(), start[None], settings)


def test_the_command_prints_floors_and_writes_its_files(tmp_path: Path) -> None:
    out = tmp_path / "ws"
    args = ["workspace", str(TRANSPORT_SPEC), "--per-path", "1", "--population", "4"]
    result = runner.invoke(
        app,
        [*args, "--iterations", "1", "--torque-scale", "15", "--out", str(out)],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    assert "floor: RMSE" in result.stdout and "circle" in result.stdout
    floors = pd.read_csv(out / "floors.csv")
    assert sorted(floors["torque_scale"].unique()) == [7.5, 15.0]
    assert set(floors["path"]) == {"circle", "rectangle", "figure8"}
    assert (floors["floor"] > 0).all()
    held = pd.read_parquet(out / "held.parquet")
    assert list(held.columns) == ["x", "y", "z", "torque_scale"] and len(held)
    assert (out / "workspace.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--population", "0"], "--population"),
        (["--per-path", "0"], "--per-path 0"),
        (["--torque-scale", "-1"], "--torque-scale -1"),
        (
            "--set env.task.grip=-0.3 --per-path 1 --population 2 --iterations 1".split(),
            "no sample held the sphere at rest (grip -0.3",
        ),
    ],
)
def test_bad_options_are_one_line(extra: list[str], message: str) -> None:
    result = runner.invoke(app, ["workspace", str(TRANSPORT_SPEC), *extra], env={"CI": "1"})
    assert result.exit_code == 2 and message in result.stderr, result.output
    assert "Traceback" not in result.output


def test_a_spec_without_the_sphere_is_one_line() -> None:
    spec = ROOT / "experiments/variants/td3-sbx-128-3e6-mirror-tta.yaml"
    result = runner.invoke(app, ["workspace", str(spec)], env={"CI": "1"})
    assert result.exit_code == 2 and "env.task.name is shared" in result.stderr
