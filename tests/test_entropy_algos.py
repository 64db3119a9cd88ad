"""SAC, TQC and CrossQ (the off-policy algorithms with a stochastic policy and an entropy bonus)
on both backends, with tiny budgets: train with validation, confirmation and mirror replay or
the independent controller, evaluate, export, load with the plain library class; interrupt and
resume; their spec fields and errors."""

from __future__ import annotations

import importlib.util
import inspect
import json
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from test_train import _interrupt, _latest_step, _resume_and_check
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.rl.policy import model_paths
from softtrack.spec import AlgoSpec, SpecError, parse_spec, spec_hash
from softtrack.store.runs import RunStore
from softtrack.store.tables import read_table

runner = CliRunner()
N_ENVS = 2

_NO_SBX = pytest.mark.skipif(
    importlib.util.find_spec("sbx") is None, reason="sbx-rl (JAX) not installed"
)
_NO_CONTRIB = pytest.mark.skipif(
    importlib.util.find_spec("sb3_contrib") is None, reason="sb3-contrib not installed"
)


def _case(
    algo: str,
    backend: str,
    controller: str = "centralized",
    mirror: bool = False,
    slow: bool = False,
) -> Any:
    marks = [_NO_SBX] if backend == "sbx" else [_NO_CONTRIB] if algo == "tqc" else []
    marks += [pytest.mark.slow] if slow else []
    tags = (
        [algo, backend]
        + (["independent"] if controller == "independent" else [])
        + (["mirror"] if mirror else [])
    )
    return pytest.param((algo, backend, controller, mirror), marks=marks, id="-".join(tags))


# Each algorithm on each backend it has; the independent controller and mirror replay spread over
# them (one training each keeps the module fast: an sbx training compiles its JAX functions).
CASES = [
    _case("sac", "sb3", mirror=True),
    _case("sac", "sbx"),
    _case("sac", "sbx", controller="independent", slow=True),  # 20 s: compiles for each arm
    _case("tqc", "sb3", controller="independent"),
    _case("tqc", "sbx", mirror=True),
    _case("crossq", "sbx", mirror=True),
]


def _plain_class(algo: str, backend: str) -> Any:
    """The library's own class, as a user without softtrack would load the exported file."""
    if backend == "sbx":
        import sbx

        return {"sac": sbx.SAC, "tqc": sbx.TQC, "crossq": sbx.CrossQ}[algo]
    if algo == "tqc":
        import sb3_contrib

        return sb3_contrib.TQC
    import stable_baselines3

    return stable_baselines3.SAC


def _algo_section(algo: str, backend: str, mirror: bool = False) -> dict[str, Any]:
    section: dict[str, Any] = {
        "name": algo,
        "backend": backend,
        "device": "cpu",
        "batch_size": 16,
        "learning_starts": 50,
        "buffer_size": 2000,
        "mirror_replay": mirror,
        "policy_kwargs": {"net_arch": [16, 16]},
    }
    if algo == "tqc":
        section["policy_kwargs"]["n_quantiles"] = 5
        section["top_quantiles_to_drop_per_net"] = 1
    if algo == "crossq":
        section["policy_kwargs"]["batch_norm_momentum"] = 0.9
    return section


def _write(tmp_path: Path, data: dict[str, Any], name: str) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.mark.parametrize("case", CASES)
def test_trains_evaluates_exports_and_loads_with_the_plain_class(
    case: tuple[str, str, str, bool], tmp_path: Path
) -> None:
    """A tiny run, validated every 100 steps, its best-validated and last model confirmed on
    one more episode; its checkpoints' replay buffers; ``softtrack evaluate``; ``softtrack
    export``, whose model files load with the library's own class and act as the run's."""
    algo, backend, controller, mirror = case
    data = {
        "name": f"tiny-{algo}-{backend}",
        "seeds": [0],
        "controller": controller,
        "env": {"episode_duration": 0.1},
        "algo": _algo_section(algo, backend, mirror),
        "training": {
            "total_timesteps": 200,
            "n_envs": N_ENVS,
            "checkpoint_interval": 100,
            "eval_duration": 0.1,
            "eval_trajectories": ["circle"],
            "validation_episodes": 1,
            "final_policy": "best_validated",
            "confirm_episodes": 1,
        },
    }
    runs = tmp_path / "runs"
    result = runner.invoke(
        app, ["train", str(_write(tmp_path, data, algo)), "--runs-dir", str(runs)], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    run_id = result.stdout.strip()
    record = RunStore(runs).get_run(run_id)
    spec = record.load_spec()
    assert record.info.status == "completed" and record.info.algo == algo
    independent = spec.controller == "independent"
    validation = read_table(record.path / "tables" / "validation.parquet")
    assert sorted(set(validation["global_step"])) == [100, 200]
    assert (record.path / "tables" / "confirmation.parquet").is_file()
    policies = model_paths(record, spec)
    assert len(policies) == (2 if independent else 1) and all(p.is_file() for p in policies)
    policy_dir = record.path / "models" / "arm1" if independent else record.path
    checkpoint = max((policy_dir / "checkpoints").iterdir())
    with (checkpoint / "replay_buffer.pkl").open("rb") as handle:
        buffer = pickle.load(handle)
    step = int(checkpoint.name.split("-")[1])
    # mirror replay: every vector step stores its transitions and their mirror images (the
    # checkpoint is written before the step's own transitions are stored)
    assert buffer.pos == (2 if mirror else 1) * (step // N_ENVS - 1)
    assert (type(buffer).__name__ == "MirrorReplayBuffer") == mirror

    result = runner.invoke(app, ["evaluate", run_id, "-t", "circle", "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    assert result.output.count("3-D RMSE arm 1 / arm 2") == 1
    dest = tmp_path / "exported"
    result = runner.invoke(app, ["export", run_id, str(dest), "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    cls = _plain_class(algo, backend)
    observations = (
        np.random.default_rng(0).normal(size=(16, 44 if independent else 81)).astype(np.float32)
    )
    exported_record = RunStore(dest.parent).get_run(dest.name)
    pairs = list(zip(policies, model_paths(exported_record, spec), strict=True))
    for source, exported in pairs:
        assert exported.parent.relative_to(dest) in (
            Path(),
            Path("models/arm0"),
            Path("models/arm1"),
        )
        manifest = json.loads((exported.parent / "policy.json").read_text(encoding="utf-8"))
        assert manifest["model"] in ("best", "last")
        full = cls.load(str(source), device="cpu")
        lean = cls.load(str(exported), device="cpu")
        expected, _ = full.predict(observations, deterministic=True)
        actions, _ = lean.predict(observations, deterministic=True)
        np.testing.assert_array_equal(actions, expected)
        if backend == "sbx":  # inference-only: no critics, optimiser or entropy state
            assert exported.stat().st_size < 0.7 * source.stat().st_size
            assert getattr(lean, "ent_coef_state", None) is None
    result = runner.invoke(app, ["evaluate", str(dest), "-t", "circle", "--in-place"])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(
    "algo, backend",
    [
        pytest.param("tqc", "sb3", marks=_NO_CONTRIB),
        pytest.param("crossq", "sbx", marks=[_NO_SBX, pytest.mark.slow]),  # 30 s: compiles twice
    ],
)
def test_resumes_after_an_interrupted_run(tmp_path: Path, algo: str, backend: str) -> None:
    total, n_envs = 1200, 4
    data = {
        "name": f"tiny-{algo}",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": _algo_section(algo, backend),
        "training": {
            "total_timesteps": total,
            "n_envs": n_envs,
            "checkpoint_interval": 200,
            "heartbeat_interval": 0.5,
        },
    }
    runs = tmp_path / "runs"
    run_dir, out, err = _interrupt(_write(tmp_path, data, algo), runs)
    assert "--resume" in err and "Traceback" not in err
    split = _latest_step(run_dir)
    assert 0 < split < total
    assert (run_dir / "checkpoints" / f"step-{split:012d}" / "replay_buffer.pkl").is_file()
    _resume_and_check(runs, out.strip(), split, total, n_envs, n_envs)


def test_report_groups_and_labels_the_new_algorithms(tmp_path: Path) -> None:
    from softtrack.report.data import group_runs, load_runs

    store = RunStore(tmp_path / "runs")
    records = [
        store.create_run(parse_spec({"name": name, "algo": algo}), 0)
        for name, algo in [
            ("c", {"name": "crossq", "backend": "sbx"}),
            ("t", {"name": "tqc"}),
            ("s", {"name": "sac"}),
            ("d", {"name": "td3"}),
            ("p", {"name": "ppo"}),
        ]
    ]
    groups = group_runs(load_runs(records))
    assert [g.label for g in groups] == ["TD3", "PPO", "SAC", "TQC", "CrossQ"]
    assert [g.slug for g in groups][-1] == "crossq"


# ---- spec -----------------------------------------------------------------------------------
def _algo(**algo: Any) -> AlgoSpec:
    return parse_spec({"algo": algo}).algo


@pytest.mark.parametrize(
    "name, backend",
    [("sac", "sb3"), ("sac", "sbx"), ("tqc", "sb3"), ("tqc", "sbx"), ("crossq", "sbx")],
)
def test_kwargs_are_accepted_by_the_library_classes(name: str, backend: str) -> None:
    pytest.importorskip("sbx" if backend == "sbx" else "sb3_contrib")
    from softtrack.rl.factory import algo_class

    algo = _algo(name=name, backend=backend, ent_coef="auto_0.5", target_entropy=-3.0)
    kwargs = algo.sb3_kwargs(resolve_activation=False)
    cls = algo_class(name, backend)
    assert set(kwargs) <= set(inspect.signature(cls.__init__).parameters)
    assert kwargs["ent_coef"] == "auto_0.5" and kwargs["target_entropy"] == -3.0
    assert ("tau" in kwargs) == (name != "crossq")  # CrossQ has no target networks
    assert ("policy_delay" in kwargs) == (name == "crossq")
    assert ("top_quantiles_to_drop_per_net" in kwargs) == (name == "tqc")
    policy_cls = cls.policy_aliases["MlpPolicy"]
    extra = set(kwargs["policy_kwargs"]) - {"net_arch", "activation_fn"}
    assert (
        extra
        == {
            "tqc": {"n_quantiles", "n_critics"},
            "sac": set(),
            "crossq": {
                "batch_norm",
                "batch_norm_actor",
                "batch_norm_momentum",
                "renorm_warmup_steps",
            },
        }[name]
    )
    assert extra <= set(inspect.signature(policy_cls.__init__).parameters)
    # the spec's defaults of these keys are the library's
    defaults = {k: p.default for k, p in inspect.signature(cls.__init__).parameters.items()}
    for key in {"top_quantiles_to_drop_per_net", "policy_delay"} & set(kwargs):
        assert defaults[key] == getattr(AlgoSpec(name=name, backend=backend), key)
    policy_defaults = inspect.signature(policy_cls.__init__).parameters
    for key in extra:
        assert policy_defaults[key].default == getattr(AlgoSpec().policy_kwargs, key)


def test_crossq_policy_delay_defaults_to_crossqs_own() -> None:
    assert _algo(name="crossq", backend="sbx").policy_delay == 3
    assert _algo(name="crossq", backend="sbx", policy_delay=1).policy_delay == 1
    assert _algo(name="td3").policy_delay == _algo(name="sac").policy_delay == 2


def test_stochastic_algorithms_get_no_action_noise() -> None:
    from softtrack.rl.factory import make_action_noise

    for name, backend in [("sac", "sb3"), ("tqc", "sb3"), ("crossq", "sbx")]:
        spec = parse_spec({"algo": {"name": name, "backend": backend, "noise_type": "normal"}})
        assert make_action_noise(spec, 24, 1) is None
    assert make_action_noise(parse_spec({}), 24, 1) is not None  # td3


def test_new_fields_at_their_defaults_keep_every_spec_hash() -> None:
    """Runs recorded before the fields existed keep their hash (softtrack.spec.spec_io)."""
    spec = parse_spec({})
    changed = parse_spec({"algo": {"target_entropy": -5.0}})
    assert spec_hash(spec) != spec_hash(changed)
    data = spec.model_dump(mode="json")
    for key in ("target_entropy", "top_quantiles_to_drop_per_net"):
        del data["algo"][key]
    for key in (
        "n_quantiles",
        "n_critics",
        "batch_norm",
        "batch_norm_actor",
        "batch_norm_momentum",
        "renorm_warmup_steps",
    ):
        del data["algo"]["policy_kwargs"][key]
    assert spec_hash(parse_spec(data)) == spec_hash(spec)


@pytest.mark.parametrize(
    "algo, field, message",
    [
        ({"name": "crossq"}, "algo.backend", "set algo.backend: sbx"),
        (
            {"name": "sac", "backend": "sbx", "critic": "per_arm"},
            "algo.critic",
            "set algo.name: td3",
        ),
        (
            {"name": "tqc", "backend": "sbx", "policy_kwargs": {"n_critics": 3}},
            "algo.policy_kwargs.n_critics",
            "n_critics: 2",
        ),
        (
            {"name": "tqc", "top_quantiles_to_drop_per_net": 25},
            "algo.top_quantiles_to_drop_per_net",
            "below policy_kwargs.n_quantiles",
        ),
        ({"name": "sac", "target_entropy": "high"}, "algo.target_entropy", "auto"),
        ({"name": "tqc", "ent_coef": "automatic"}, "algo.ent_coef", "auto_<initial value>"),
    ],
)
def test_spec_errors(algo: dict[str, Any], field: str, message: str) -> None:
    with pytest.raises(SpecError) as info:
        parse_spec({"algo": algo})
    assert info.value.field == field and message in info.value.fix


def test_crossq_with_sb3_is_a_one_line_cli_error(tmp_path: Path) -> None:
    path = _write(tmp_path, {"algo": {"name": "crossq"}}, "crossq")
    result = runner.invoke(app, ["train", str(path), "--runs-dir", str(tmp_path / "runs")])
    assert result.exit_code == 2 and result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1
    assert "algo.backend: crossq is implemented in sbx only" in result.stderr
