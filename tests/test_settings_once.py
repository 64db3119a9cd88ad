"""Every setting defined once (issue 61): a spec field's default, unit and range are the
engine's or the environment's own dataclass field's (:func:`softtrack.numbers.setting`),
never written again; the spec's models add the description."""

from __future__ import annotations

import ast
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from softtrack.env.realism import RealismConfig
from softtrack.env.reward_config import RewardConfig
from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import TargetConfig
from softtrack.env.tasks import TaskConfig
from softtrack.evaluation.workspace import SearchSettings
from softtrack.mpc.planner_config import PlannerConfig
from softtrack.numbers import Range, range_of
from softtrack.sim.params import InvalidParameterError, SimParams
from softtrack.sim.sphere import SphereParams
from softtrack.spec import env_models, mpc_models

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


def test_every_spec_setting_is_declared_by_its_dataclass() -> None:
    """In env_models.py and mpc_models.py each setting is ``setting_field(<its dataclass>,
    "<its own name>", text)``: default, unit and range come from the dataclass field, and no
    range keyword (gt, ge, lt, le) is written beside it."""
    owners = {**{model: config.__name__ for model, (config, _) in PAIRS.items()}}
    owners |= {"EnvSpec": "TrackingConfig", "MpcSpec": "PlannerConfig"}
    checked, wrong = 0, []
    for path in (MODELS, Path(mpc_models.__file__)):
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if not isinstance(node, ast.ClassDef) or node.name not in owners:
                continue
            for item in node.body:
                call = item.value if isinstance(item, ast.AnnAssign) else None
                if not isinstance(call, ast.Call):
                    continue
                function = getattr(call.func, "id", "")
                name = item.target.id  # type: ignore[union-attr]
                if function in ("section_field", "Field"):  # a sub-section or a free mapping
                    continue
                checked += 1
                declared = (
                    function == "setting_field"
                    and getattr(call.args[0], "id", "") == owners[node.name]
                    and ast.literal_eval(call.args[1]) == name
                    and not {k.arg for k in call.keywords} & {"gt", "ge", "lt", "le"}
                )
                if not declared:
                    wrong.append(f"{node.name}.{name}")
    assert checked >= 85
    assert wrong == ["MpcSpec.model"]  # which model the planner uses: the spec's own


@pytest.mark.parametrize("model", sorted(PAIRS))
def test_each_spec_range_is_the_dataclass_range(model: str) -> None:
    """The spec refuses exactly what the dataclass's validate() refuses at each bound."""
    spec_model = getattr(env_models, model)
    config, _ = PAIRS[model]
    for name, field in spec_model.model_fields.items():
        if field.default_factory is not None or name == "sphere":  # sub-sections
            continue
        range_ = range_of(config, name)
        bounds = [
            getattr(m, k) for m in field.metadata for k in ("gt", "ge", "lt", "le") if hasattr(m, k)
        ]
        assert sorted(bounds) == sorted(range_.constraints().values()), f"{model}.{name}"


def test_a_range_admits_and_describes() -> None:
    positive = Range("m", gt=0)
    assert positive.admits(0.1) and positive.admits(np.float64(2.0))
    assert not any(positive.admits(v) for v in (0.0, -1.0, math.inf, math.nan, True, "1", None))
    assert positive.describe() == "a finite number > 0 m"
    probability = Range(ge=0, lt=1)
    assert probability.admits(0.0) and not probability.admits(1.0)
    assert probability.describe() == "a finite number in [0, 1)"
    steps = Range("control steps", ge=1, whole=True, off=True)
    assert steps.admits(None) and steps.admits(np.int64(3)) and not steps.admits(2.5)
    assert steps.describe() == "a whole number ≥ 1 control steps (or None = off)"
    assert Range(le=0.5, gt=-1).describe() == "a finite number in (-1, 0.5]"
    assert Range(number=False).admits((1, 2, 3))


@pytest.mark.parametrize(
    ("config", "changes", "message"),
    [
        (TargetConfig, {"speed": 0.0}, "target speed=0.0 must be a finite number > 0 m/s"),
        (
            RewardConfig,
            {"arm_radius": -1.0},
            "reward arm_radius=-1.0 must be a finite number > 0 m",
        ),
        (RealismConfig, {"obs_delay": 1.5}, "obs_delay=1.5 must be a whole number ≥ 0 control"),
        (TaskConfig, {"grip": 2.0}, r"grip=2.0 must be a finite number in \[-1, 1\]"),
        (PlannerConfig, {"samples": 1}, "samples=1 must be a whole number ≥ 2"),
        (SearchSettings, {"hold": 0.0}, "hold=0.0 must be a finite number > 0 s"),
    ],
)
def test_validate_refuses_what_the_range_refuses(
    config: type, changes: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        dataclasses.replace(config(), **changes).validate()


def test_the_spec_refuses_a_still_target_as_the_environment_does() -> None:
    """Before the ranges were declared once the spec took speed 0 and the environment refused it."""
    with pytest.raises(ValidationError, match="greater than 0"):
        env_models.TargetSpec(speed=0.0)


def test_sim_params_refuse_out_of_range_values() -> None:
    with pytest.raises(InvalidParameterError, match="n_elem=1 must be a whole number ≥ 2"):
        SimParams(n_elem=1).validate()


def test_the_episode_length_default_is_the_configs() -> None:
    spec_default = env_models.EnvSpec.model_fields["episode_duration"].default
    assert spec_default == TrackingConfig.episode_duration
