"""The research variants' registry (:mod:`softtrack.rl.variants`) and the old module paths of
moved modules (:mod:`softtrack.rl.moved`) that model files pickled before the move name."""

from __future__ import annotations

import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from softtrack.rl import variants
from softtrack.rl.moved import MOVED_MODULES
from softtrack.spec import parse_spec

REPO = Path(__file__).resolve().parents[1]


def test_a_study_spec_enables_no_variant() -> None:
    spec = parse_spec({})
    assert variants.active_variants(spec) == []
    assert variants.model_class_override(spec) is None
    assert variants.model_kwargs(spec) == {}
    assert variants.vec_env_kwargs(spec) == {}


def test_mirror_replay_gives_its_replay_buffer_class() -> None:
    pytest.importorskip("stable_baselines3")
    from softtrack.rl.variants.mirror import MirrorReplayBuffer

    spec = parse_spec({"algo": {"mirror_replay": True}})
    assert [v.name for v in variants.active_variants(spec)] == ["mirror_replay"]
    assert variants.model_class_override(spec) is None
    assert variants.model_kwargs(spec) == {"replay_buffer_class": MirrorReplayBuffer}
    assert variants.vec_env_kwargs(spec) == {}


def test_per_arm_critics_give_their_algorithm_kwargs_and_env() -> None:
    pytest.importorskip("sbx", reason="sbx-rl (JAX) not installed")
    from softtrack.rl.factory import model_class
    from softtrack.rl.variants.per_arm import PerArmTD3

    spec = parse_spec(
        {
            "algo": {
                "backend": "sbx",
                "critic": "per_arm",
                "per_arm_networks": True,
                "actor_observation": "own_arm",
            }
        }
    )
    assert model_class(spec) is PerArmTD3
    assert variants.model_kwargs(spec) == {
        "n_reward_shares": 2,
        "per_arm_networks": True,
        "actor_observation": "own_arm",
    }
    assert variants.vec_env_kwargs(spec) == {"reward_shares": True}


def test_two_variants_setting_one_class_are_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    twin = variants.Variant("twin", lambda spec: True, replay_buffer_class="a.b:C")
    other = variants.Variant("other", lambda spec: True, replay_buffer_class="d.e:F")
    monkeypatch.setattr(variants, "VARIANTS", (twin, other))
    with pytest.raises(ValueError, match="twin, other"):
        variants.model_kwargs(parse_spec({}))


def test_an_old_module_path_unpickles_as_the_moved_class() -> None:
    """A pickle naming ``softtrack.rl.mirror.MirrorReplayBuffer`` (as replay buffers and models
    saved before the move do) loads, in a fresh interpreter, as the class of its new module."""
    pytest.importorskip("stable_baselines3")
    from softtrack.rl.variants.mirror import MirrorReplayBuffer

    data = pickle.dumps(MirrorReplayBuffer, protocol=0)
    assert b"softtrack.rl.variants.mirror" in data
    old = data.replace(b"softtrack.rl.variants.mirror", b"softtrack.rl.mirror")
    code = (
        "import pickle, sys\n"
        "cls = pickle.loads(sys.stdin.buffer.read())\n"
        "print(cls.__module__, cls.__name__)\n"
        "import softtrack.rl.mirror as old, softtrack.rl.variants.mirror as new\n"
        "assert old is new and cls is new.MirrorReplayBuffer\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], input=old, capture_output=True, check=False, cwd=REPO
    )
    assert result.returncode == 0, result.stderr.decode()
    assert result.stdout.decode().split() == ["softtrack.rl.variants.mirror", "MirrorReplayBuffer"]


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_every_old_module_path_is_its_new_module(old: str) -> None:
    pytest.importorskip("sbx", reason="sbx-rl (JAX) not installed")
    import importlib

    assert importlib.import_module(old) is importlib.import_module(MOVED_MODULES[old])


SHIPPED = REPO / "models"


@pytest.mark.parametrize(
    ("run", "classes"),
    [
        ("td3-sbx-own-arm-actors-4e6-seed0", ("PerArmTD3Policy", "PerArmActor")),
        # (exported mirror-replay models are inference-only: they name no replay buffer class;
        # the old MirrorReplayBuffer path is checked on a pickle above)
    ],
)
def test_shipped_models_saved_with_the_old_module_paths_load(
    run: str, classes: tuple[str, ...]
) -> None:
    pytest.importorskip("sbx", reason="sbx-rl (JAX) not installed")
    import zipfile

    from softtrack.rl.factory import model_class
    from softtrack.spec import load_spec

    path = SHIPPED / run / "model.zip"
    assert path.is_file(), f"{path}: the shipped model is missing"
    with zipfile.ZipFile(path) as archive:
        data = archive.read("data")
    # saved before the move (old paths) or re-saved by `softtrack upgrade` (new paths)
    assert any(
        name in data
        for name in (b"softtrack.rl.per_arm_td3", b"softtrack.rl.mirror", b"softtrack.rl.variants")
    )
    model = model_class(load_spec(SHIPPED / run / "spec.yaml")).load(str(path), device="cpu")
    names = {
        type(model.policy).__name__,
        type(model.policy.actor).__name__,
        getattr(model.replay_buffer_class, "__name__", ""),
    }
    assert set(classes) <= names
