"""Recorded workspace floors (softtrack.evaluation.workspace_floors): the key, the record, the
shipped floors, and the warnings of ``train`` and ``evaluate`` for paths out of reach."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.env.settings import make_config
from softtrack.evaluation import workspace_floors
from softtrack.evaluation.workspace_floors import (
    REACH_TOLERANCE,
    SHIPPED_FLOORS,
    floors_dir,
    known_floors,
    reach_warning,
    record_floors,
    workspace_key,
)
from softtrack.spec import load_spec
from softtrack.spec.env_config import env_config

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[1]
VARIANTS = ROOT / "experiments" / "variants"
STUDY_PATHS = VARIANTS / "td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-long.yaml"
REACHABLE = VARIANTS / "td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-reachable.yaml"
STUDY_RUN = ROOT / "models" / "td3-sbx-128-mirror-fast-transport-fine-10ms-long-gravity-3e6-seed0"
REACHABLE_RUN = ROOT / "models" / "td3-sbx-128-mirror-fast-transport-fine-10ms-reachable-3e6-seed0"


def _transport(**settings: object):  # type: ignore[no-untyped-def]
    return make_config(task="transport", sphere={}, contact_k=1e6, contact_nu=600.0, **settings)


@pytest.fixture
def nothing_shipped(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Only the test's own records count (the package ships the default transport's)."""
    monkeypatch.setattr(workspace_floors, "SHIPPED_FLOORS", tmp_path / "shipped")


def test_the_key_names_physics_grip_and_paths_only() -> None:
    config = _transport()
    assert workspace_key(config) == workspace_key(_transport())
    assert len(workspace_key(config)) == 16
    assert workspace_key(config) != workspace_key(_transport(grip=0.1))
    assert workspace_key(config) != workspace_key(_transport(torque_scale=15.0))
    assert workspace_key(config) != workspace_key(_transport(circle_radius=0.1))
    # what does not move the held region or a path's points leaves the key alone
    assert workspace_key(config) == workspace_key(_transport(period=20.0, hold_bonus=1.0))


def test_a_recorded_floor_warns_once_it_is_out_of_reach(nothing_shipped: None) -> None:
    config = _transport()
    assert known_floors(config) is None
    note = reach_warning(config, "my.yaml")
    assert note is not None and note.startswith("note:") and "softtrack workspace my.yaml" in note
    assert reach_warning(config, "my.yaml", unmeasured_note=False) is None
    path = record_floors(config, {"circle": 0.3335, "rectangle": 0.011, "figure8": 0.3}, 96, "x")
    assert path.parent == floors_dir() and json.loads(path.read_text())["samples"] == 96
    assert known_floors(config) == {"circle": 0.3335, "rectangle": 0.011, "figure8": 0.3}
    warning = reach_warning(config, "my.yaml")
    assert warning is not None and "\n" not in warning
    assert warning.startswith("warning: out of the held sphere's reach: circle 0.334 m, figure8")
    assert "rectangle" not in warning.split("(")[0] and f"at most {REACH_TOLERANCE} m" in warning
    assert reach_warning(config, "my.yaml", paths=("rectangle",)) is None
    assert reach_warning(make_config(), "my.yaml") is None  # not a transport task


@pytest.mark.parametrize(
    "content", ["{not json", '{"floors": {"circle": "far"}}', '{"floors": [1]}', "[]"]
)
def test_an_unreadable_record_is_ignored(content: str, nothing_shipped: None) -> None:
    config = _transport()
    path = floors_dir() / f"{workspace_key(config)}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(content)
    assert known_floors(config) is None
    assert reach_warning(config, "s.yaml", unmeasured_note=False) is None


def test_the_shipped_floors_say_the_study_paths_are_out_of_reach() -> None:
    study = reach_warning(env_config(load_spec(STUDY_PATHS)), str(STUDY_PATHS))
    assert study is not None and study.startswith("warning: out of the held sphere's reach")
    floors = known_floors(env_config(load_spec(STUDY_PATHS)))
    assert floors is not None and all(0.2 < f < 0.5 for f in floors.values())
    assert reach_warning(env_config(load_spec(REACHABLE)), str(REACHABLE)) is None
    reachable = known_floors(env_config(load_spec(REACHABLE)))
    assert reachable is not None and max(reachable.values()) < REACH_TOLERANCE


def test_every_shipped_transport_spec_has_its_floors() -> None:
    """Each transport experiment's physics and paths were measured (softtrack/data/workspace)."""
    missing = []
    for path in sorted(VARIANTS.glob("*.yaml")):
        spec = load_spec(path)
        if spec.env.task.name == "transport":
            key = workspace_key(env_config(spec))
            if not (SHIPPED_FLOORS / f"{key}.json").is_file():
                missing.append(path.name)
    assert not missing, f"run `softtrack workspace` on them and ship the records: {missing}"


def test_train_and_evaluate_print_the_warning(monkeypatch: pytest.MonkeyPatch) -> None:
    """``train`` passes the line on before the first run starts; ``evaluate`` once per run."""
    import softtrack.workflows.evaluate_runs as evaluate_runs
    import softtrack.workflows.training_runs as training_runs

    lines: list[str] = []

    def refuse(*args: object, **kwargs: object) -> None:
        raise RuntimeError("stop before training")

    monkeypatch.setattr(training_runs.RunStore, "create_run", refuse)
    with pytest.raises(RuntimeError, match="stop before training"):
        training_runs.train(STUDY_PATHS, on_warning=lines.append)
    assert len(lines) == 1 and "circle 0.3" in lines[0]

    monkeypatch.setattr(evaluate_runs, "_evaluate_one", lambda *args: [])
    warned: list[tuple[str, str]] = []
    evaluate_runs.evaluate(
        [str(STUDY_RUN), str(REACHABLE_RUN)],
        ["circle"],
        write=False,
        on_warning=lambda record, line: warned.append((record.run_id, line)),
    )
    assert len(warned) == 1 and "circle 0.3" in warned[0][1]
    run_id = json.loads(STUDY_RUN.joinpath("run.json").read_text())["run_id"]
    assert warned[0][0] in (run_id, STUDY_RUN.name)  # a shipped run goes by its folder's name


def test_a_changed_grip_is_unmeasured_and_says_how_to_measure() -> None:
    spec = load_spec(REACHABLE, ["env.task.grip=0.2"])
    note = reach_warning(env_config(spec), "spec.yaml")
    assert note is not None and "`softtrack workspace spec.yaml`" in note


def test_the_workspace_command_records_its_floors() -> None:
    args = ["workspace", str(STUDY_PATHS), "--per-path", "1", "--population", "4"]
    result = runner.invoke(app, [*args, "--iterations", "1"], env={"CI": "1"})
    assert result.exit_code == 0, result.output
    config = env_config(load_spec(STUDY_PATHS))
    record = floors_dir() / f"{workspace_key(config)}.json"
    assert f"recorded the floors at 7.5 N·m per unit in {record}" in result.stdout
    assert set(json.loads(record.read_text())["floors"]) == {"circle", "rectangle", "figure8"}
    assert dataclasses.is_dataclass(config)


def test_a_cache_that_cannot_be_written_loses_only_the_record(tmp_path: Path) -> None:
    blocked = tmp_path / "a-file"
    blocked.write_text("not a directory")
    args = ["workspace", str(REACHABLE), "--per-path", "1", "--population", "4"]
    result = runner.invoke(
        app, [*args, "--iterations", "1"], env={"CI": "1", "SOFTTRACK_CACHE_DIR": str(blocked)}
    )
    assert result.exit_code == 0, result.output
    assert "floor: RMSE" in result.stdout and "Traceback" not in result.output
    assert "warning: the floors could not be recorded in" in result.stderr
    assert "SOFTTRACK_CACHE_DIR" in result.stderr and blocked.read_text() == "not a directory"


def test_a_sphere_held_nowhere_is_recorded_and_warned_about(nothing_shipped: None) -> None:
    config = _transport(grip=0.0)
    record_floors(config, dict.fromkeys(("circle", "rectangle", "figure8"), math.inf), 16, "s")
    assert known_floors(config) == dict.fromkeys(("circle", "rectangle", "figure8"), math.inf)
    warning = reach_warning(config, "s.yaml", unmeasured_note=False)
    assert warning is not None and "found no action that holds the sphere" in warning
