"""``softtrack robustness``: settings from grid axes, perturbed specs, the eval_robustness
table (nominal rows equal `softtrack evaluate`'s), resumption, worker processes, errors."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.evaluation.perturbations import (
    ROBUSTNESS_TABLE,
    Setting,
    expand_settings,
    factor_paths,
    merge_parts,
    part_path,
    perturbed_spec,
)
from softtrack.spec import ExperimentSpec, SpecError
from softtrack.store.selection import select_one_run
from softtrack.store.tables import read_table
from softtrack.workers import robustness_main as worker_main
from tests.test_evaluate import _train_tiny

runner = CliRunner()


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    return _train_tiny(tmp_path_factory.mktemp("robustness"))


def _copy(trained: tuple[Path, str], tmp_path: Path) -> Path:
    runs, run_id = trained
    shutil.copytree(runs / run_id, tmp_path / run_id)
    return tmp_path / run_id


def _table(run: Path) -> object:
    return read_table(run / "tables" / f"{ROBUSTNESS_TABLE}.parquet")


# ---- settings and specs ------------------------------------------------------------------------
def test_one_factor_at_a_time_and_full_grid() -> None:
    grid = [("obs_noise", ["0", "0.005"]), ("action_delay", ["0", "2"])]
    one = expand_settings(grid)
    assert [s.key for s in one] == [
        "nominal",
        "obs_noise=0",
        "obs_noise=0.005",
        "action_delay=0",
        "action_delay=2",
    ]
    assert [s.level for s in one[1:]] == [0.0, 0.005, 0.0, 2.0]
    assert math.isnan(one[0].level) and one[0].overrides() == []
    full = expand_settings(grid, full=True)
    assert len(full) == 1 + 4
    assert full[-1].key == "obs_noise=0.005 action_delay=2"
    assert full[-1].perturbation == "obs_noise+action_delay"
    assert math.isnan(full[-1].level)
    assert Setting(()).key == "nominal"


def test_factor_paths_aliases_fields_and_unknown() -> None:
    assert factor_paths("obs_noise") == (
        "env.realism.obs_noise_node_position",
        "env.realism.obs_noise_target_position",
    )
    assert factor_paths("action_delay") == ("env.realism.action_delay",)
    assert factor_paths("env.physics.damping") == ("env.physics.damping",)
    with pytest.raises(SpecError, match="unknown perturbation 'obs_nosie'"):
        expand_settings([("obs_nosie", ["0.01"])])
    with pytest.raises(SpecError, match="no perturbation"):
        expand_settings([])


def test_perturbed_spec_resets_realism_unless_kept() -> None:
    spec = ExperimentSpec.model_validate(
        {"env": {"realism": {"obs_delay": 3, "youngs_modulus_scale": [0.9, 1.1]}}}
    )
    setting = Setting((("gravity", "on"), ("action_delay", "2")))
    idealised = perturbed_spec(spec, setting)
    assert idealised.env.physics.gravity == pytest.approx(9.81)
    assert idealised.env.realism.action_delay == 2
    assert idealised.env.realism.obs_delay == 0
    assert idealised.env.realism.youngs_modulus_scale == 1.0
    kept = perturbed_spec(spec, setting, keep_realism=True)
    assert kept.env.realism.obs_delay == 3 and kept.env.realism.action_delay == 2
    assert perturbed_spec(spec, Setting(()), keep_realism=True) == spec


def test_perturbed_spec_of_a_curriculum_run_drops_the_warmup() -> None:
    """A run trained with training.randomisation_warmup_steps is evaluated without its
    randomisation (nothing left to ramp) and with it at full size."""
    spec = ExperimentSpec.model_validate(
        {
            "env": {"realism": {"youngs_modulus_scale": [0.9, 1.1]}},
            "training": {"randomisation_warmup_steps": 1000},
        }
    )
    for keep in (False, True):
        for setting in (Setting(()), Setting((("action_delay", "2"),))):
            assert perturbed_spec(spec, setting, keep).training.randomisation_warmup_steps == 0
    assert perturbed_spec(spec, Setting(()), True).env.realism == spec.env.realism


def test_contact_factor_switches_both_contact_fields() -> None:
    """``--grid contact=on,off,2e6``: the "contact on" defaults, off, or a stiffness."""
    spec = ExperimentSpec()
    on, off, stiff = (
        perturbed_spec(spec, Setting((("contact", level),))) for level in ("on", "off", "2e6")
    )
    assert (on.env.physics.contact_k, on.env.physics.contact_nu) == (1e6, 600.0)
    assert (off.env.physics.contact_k, off.env.physics.contact_nu) == (0.0, 0.0)
    assert (stiff.env.physics.contact_k, stiff.env.physics.contact_nu) == (2e6, 600.0)
    assert Setting((("contact", "on"),)).level == 1.0
    with pytest.raises(SpecError, match="contact_k"):
        perturbed_spec(spec, Setting((("contact", "1e9"),)))


def test_an_unstable_setting_names_itself() -> None:
    with pytest.raises(SpecError) as info:
        perturbed_spec(ExperimentSpec(), Setting((("youngs_modulus_scale", "3"),)))
    assert str(info.value).startswith("--grid youngs_modulus_scale=3: ")
    assert "dt" in str(info.value)


# ---- the command -------------------------------------------------------------------------------
def test_robustness_table_nominal_rows_equal_evaluate(
    trained: tuple[Path, str], tmp_path: Path
) -> None:
    run = _copy(trained, tmp_path)
    result = runner.invoke(
        app,
        [
            "robustness",
            str(run),
            "--grid",
            "action_delay=0,2",
            "--grid",
            "obs_noise=0.02",
            "-t",
            "circle",
        ],
    )
    assert result.exit_code == 0, result.output
    # action_delay=0 is the nominal setting of this run: its episode runs once
    assert result.output.count("3-D RMSE arm 1 / arm 2") == 3
    assert "action_delay=0 equal the nominal setting" in result.output
    table = _table(run)
    assert len(table) == 4 * 2  # settings (nominal first) × arms
    assert list(table.columns[:8]) == [
        "run_id",
        "perturbation",
        "level",
        "setting",
        "baseline",
        "episode",
        "seed",
        "trajectory",
    ]
    assert set(table["setting"]) == {
        "nominal",
        "action_delay=0",
        "action_delay=2",
        "obs_noise=0.02",
    }
    assert {
        "action_saturation",
        "torque_rate_rms",
        "peak_moment",
        "min_arm_distance",
        "collision_steps",
        "cpu",
    } <= set(table.columns)
    result = runner.invoke(app, ["evaluate", str(run), "-t", "circle"])
    assert result.exit_code == 0, result.output
    nominal = read_table(run / "tables" / "eval_metrics.parquet").sort_values("arm")
    for key in ("nominal", "action_delay=0"):
        rows = table[table["setting"] == key].sort_values("arm")
        np.testing.assert_array_equal(rows["rmse_3d"].to_numpy(), nominal["rmse_3d"].to_numpy())
    delayed = table[table["setting"] == "action_delay=2"].sort_values("arm")
    noisy = table[table["setting"] == "obs_noise=0.02"].sort_values("arm")
    assert not np.array_equal(delayed["rmse_3d"].to_numpy(), nominal["rmse_3d"].to_numpy())
    assert not np.array_equal(noisy["rmse_3d"].to_numpy(), nominal["rmse_3d"].to_numpy())

    again = runner.invoke(
        app, ["robustness", str(run), "--grid", "action_delay=0,2", "-t", "circle"]
    )
    assert again.exit_code == 0, again.output
    assert "3-D RMSE" not in again.output
    assert "3 settings already stored" in again.output
    redo = runner.invoke(
        app,
        [
            "robustness",
            str(run),
            "--grid",
            "action_delay=2",
            "-t",
            "circle",
            "--redo",
            "--episodes",
            "2",
        ],
    )
    assert redo.exit_code == 0, redo.output
    table = _table(run)
    assert len(table) == 6 * 2  # nominal and action_delay=2 now have two episodes each
    assert sorted(table.loc[table["setting"] == "action_delay=2", "seed"].unique()) == [
        4_000_000,
        4_000_001,
    ]

    out = tmp_path / "report"
    report = runner.invoke(
        app, ["report", run.name, "--runs-dir", str(tmp_path), "--out", str(out)]
    )
    assert report.exit_code == 0, report.output
    index = (out / "index.md").read_text(encoding="utf-8")
    section = index.split("### Robustness to perturbations")[1].split("###")[0]
    assert "`action_delay=2`" in section and "`obs_noise=0.02`" in section
    assert "(1.00×)" in section  # nominal and action_delay=0 are the baseline
    assert (out / "figures" / "robustness.png").is_file()


def test_full_grid_and_worker_parts_merge(trained: tuple[Path, str], tmp_path: Path) -> None:
    run = _copy(trained, tmp_path)
    record = select_one_run(str(run))
    setting = Setting((("obs_noise", "0.01"), ("action_delay", "1")))
    # a worker that ended after writing its part, before the parent merged it
    assert (
        worker_main(
            [
                str(run),
                "--level",
                "obs_noise=0.01",
                "--level",
                "action_delay=1",
                "--trajectories",
                "circle",
            ]
        )
        == 0
    )
    assert part_path(record, setting, ["circle"], 1, False).is_file()
    result = runner.invoke(
        app,
        [
            "robustness",
            str(run),
            "--grid",
            "obs_noise=0.01",
            "--grid",
            "action_delay=1,2",
            "--full-grid",
            "-t",
            "circle",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "1 settings already stored" in result.output
    table = _table(run)
    assert set(table["setting"]) == {
        "nominal",
        "obs_noise=0.01 action_delay=1",
        "obs_noise=0.01 action_delay=2",
    }
    assert set(table["perturbation"]) == {"nominal", "obs_noise+action_delay"}
    assert table["level"].isna().all()
    assert merge_parts(record) == 0
    assert not (run / "tables" / "eval_robustness-parts").exists()


def test_robustness_in_worker_processes(trained: tuple[Path, str], tmp_path: Path) -> None:
    run = _copy(trained, tmp_path)
    result = runner.invoke(
        app,
        [
            "robustness",
            str(run),
            "--grid",
            "damping_scale=0.9,1.1",
            "-t",
            "rectangle",
            "--workers",
            "2",
        ],
    )
    assert result.exit_code == 0, result.output
    table = _table(run)
    assert sorted(table["setting"].unique()) == [
        "damping_scale=0.9",
        "damping_scale=1.1",
        "nominal",
    ]
    assert (run / "robustness.log").is_file()


def test_robustness_as_slurm_array_via_submitit_local(
    trained: tuple[Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("submitit")
    monkeypatch.setenv("SOFTTRACK_SUBMITIT_CLUSTER", "local")
    run = _copy(trained, tmp_path)
    result = runner.invoke(
        app,
        [
            "robustness",
            str(run),
            "--grid",
            "action_delay=1",
            "-t",
            "circle",
            "--executor",
            "slurm",
            "--time",
            "5",
        ],
    )
    assert result.exit_code == 0, result.output
    assert sorted(_table(run)["setting"].unique()) == ["action_delay=1", "nominal"]
    assert not (run / "tables" / "eval_robustness-parts").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--grid", "obs_nosie=0.01"], "unknown perturbation 'obs_nosie'"),
        (["--grid", "youngs_modulus_scale=1,3"], "--grid youngs_modulus_scale=3:"),
        (["--grid", "action_delay"], "malformed grid axis"),
        ([], "no perturbation given"),
        (["--grid", "action_delay=1", "--detach"], "cannot be detached"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    trained: tuple[Path, str], tmp_path: Path, args: list[str], message: str
) -> None:
    run = _copy(trained, tmp_path)
    result = runner.invoke(app, ["robustness", str(run), *args])
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert not (run / "tables" / f"{ROBUSTNESS_TABLE}.parquet").exists()


def test_a_missing_run_is_a_user_error(tmp_path: Path) -> None:
    result = runner.invoke(
        app, ["robustness", "nope", "--runs-dir", str(tmp_path), "--grid", "action_delay=1"]
    )
    assert result.exit_code == 2, result.output
