"""Every setting defined once (issue 61): a spec field's default is the engine's or the
environment's own dataclass default, referenced, never written again as a literal; the spec's
models add the unit, the range and the description."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path
from typing import Any

import pytest

from softtrack.env.realism import RealismConfig
from softtrack.env.reward_config import RewardConfig
from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import TargetConfig
from softtrack.env.tasks import TaskConfig
from softtrack.sim.params import SimParams
from softtrack.sim.sphere import SphereParams
from softtrack.spec import env_models

MODELS = Path(env_models.__file__)

#: spec model → (the dataclass it configures, the name of its default instance in env_models)
PAIRS: dict[str, tuple[type, str]] = {
    "PhysicsSpec": (SimParams, "_SIM"),
    "SphereSpec": (SphereParams, "_SPHERE"),
    "TargetSpec": (TargetConfig, "_TARGET"),
    "RewardSpec": (RewardConfig, "_REWARD"),
    "RealismSpec": (RealismConfig, "_REALISM"),
    "TaskSpec": (TaskConfig, "_TASK"),
}


def _plain(value: Any) -> Any:
    return tuple(_plain(v) for v in value) if isinstance(value, (list, tuple)) else value


@pytest.mark.parametrize("model", sorted(PAIRS))
def test_each_spec_default_is_the_dataclass_default(model: str) -> None:
    spec_model = getattr(env_models, model)
    config, _ = PAIRS[model]
    defaults = config()
    names = {f.name for f in dataclasses.fields(config)}
    for name, field in spec_model.model_fields.items():
        if field.default_factory is not None:  # a sub-section (the sphere): its own model
            continue
        assert name in names, f"{model}.{name} configures nothing in {config.__name__}"
        assert _plain(field.default) == _plain(getattr(defaults, name)), f"{model}.{name}"


def test_no_spec_default_is_written_as_a_literal() -> None:
    """In env_models.py each setting's default is ``_INSTANCE.<its own name>``."""
    tree = ast.parse(MODELS.read_text(encoding="utf-8"))
    checked, written = 0, []
    for node in tree.body:
        if not isinstance(node, ast.ClassDef) or node.name not in {*PAIRS, "EnvSpec"}:
            continue
        instance = PAIRS[node.name][1] if node.name in PAIRS else "TrackingConfig"
        for item in node.body:
            call = item.value if isinstance(item, ast.AnnAssign) else None
            if not (isinstance(call, ast.Call) and getattr(call.func, "id", "") == "unit_field"):
                continue
            checked += 1
            first = call.args[0]
            name = item.target.id  # type: ignore[union-attr]
            if not (
                isinstance(first, ast.Attribute)
                and isinstance(first.value, ast.Name)
                and (first.value.id, first.attr) == (instance, name)
            ):
                written.append(f"{node.name}.{name}: {ast.unparse(first)}")
    assert checked >= 75
    assert not written, written


def test_the_episode_length_default_is_the_configs() -> None:
    spec_default = env_models.EnvSpec.model_fields["episode_duration"].default
    assert spec_default == TrackingConfig.episode_duration
