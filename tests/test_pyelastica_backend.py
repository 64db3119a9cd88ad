"""The PyElastica 1.0.0 backend reproduces the stored reference rollouts (docs/physics.md).

The reference files in ``tests/data/pyelastica`` (shipped with the tests) were made with the
real PyElastica
1.0.0; the backend rebuilds the scenario from ``SimParams`` defaults and must agree with
them to ≤ 1e-6 m at every control step (it agrees to ~1e-14 m).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("elastica")

from softtrack.sim.params import InvalidParameterError, SimParams
from softtrack.sim.pyelastica_backend import (
    PyElasticaDualArm,
    require_pyelastica,
    rollout_pyelastica,
)

pytestmark = pytest.mark.pyelastica

REPO = Path(__file__).resolve().parents[1]
REFERENCE_DIR = REPO / "tests" / "data" / "pyelastica"
REFERENCE_FILES = ["const_actions.npz", "sine_actions.npz"]

TIP_TOL = 1e-6  # m; a differing convention shows up as ≥ 1e-4 m over 2 s


def _load(name: str) -> dict[str, np.ndarray]:
    path = REFERENCE_DIR / name
    assert path.is_file(), f"reference file {path} is missing from the checkout"
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module", params=REFERENCE_FILES)
def reference_and_rollout(request: pytest.FixtureRequest) -> tuple[dict, dict]:
    ref = _load(request.param)
    out = rollout_pyelastica(actions=ref["actions"])
    return ref, out


def test_reference_settings_are_the_defaults() -> None:
    ref = _load(REFERENCE_FILES[0])
    settings = json.loads(str(ref["params_json"]))
    p = SimParams()
    assert settings["n_elem"] == p.n_elem and settings["dt"] == p.dt
    assert settings["steps_per_action"] == p.steps_per_action
    assert settings["nu"] == p.damping and settings["torque_scale"] == p.torque_scale
    assert settings["shear_modulus_used"] == pytest.approx(p.shear_modulus, rel=1e-15)
    assert [b[0] for b in p.base_positions] == settings["base_x"]


def test_tip_matches_reference_every_control_step(reference_and_rollout: tuple) -> None:
    ref, out = reference_and_rollout
    assert out["tip"].shape == ref["tip"].shape
    np.testing.assert_allclose(out["t"], ref["t"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["element_torques"], ref["element_torques"], rtol=0, atol=1e-10)
    err = np.abs(out["tip"] - ref["tip"]).max()
    assert err <= TIP_TOL, f"max tip error {err:.3e} m"


def test_snapshots_match_reference(reference_and_rollout: tuple) -> None:
    ref, out = reference_and_rollout
    idx = ref["snap_index"]
    assert np.abs(out["nodes"][idx] - ref["nodes"]).max() <= TIP_TOL
    assert np.abs(out["directors"][idx] - ref["directors"]).max() <= 1e-6
    assert np.abs(out["velocities"][idx] - ref["velocities"]).max() <= 1e-5
    assert np.abs(out["omegas"][idx] - ref["omegas"]).max() <= 1e-5
    last_directors = out["directors"][:, :, :, :, -1]
    assert np.abs(last_directors - ref["tip_directors"]).max() <= 1e-6


def test_element_torque_input_equals_action_input() -> None:
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.3, 0.3, size=(20, 2, 2, 6))
    by_actions = rollout_pyelastica(actions=actions)
    by_torques = rollout_pyelastica(element_torques=by_actions["element_torques"])
    for key in ("tip", "nodes", "velocities", "directors", "omegas"):
        np.testing.assert_array_equal(by_actions[key], by_torques[key])
    assert by_actions["t"][-1] == pytest.approx(20 * SimParams().control_dt, rel=1e-12)


def test_advance_is_resumable_and_state_is_copied() -> None:
    one, two = PyElasticaDualArm(SimParams()), PyElasticaDualArm(SimParams())
    torques = np.zeros((2, 2, 20))
    torques[0, 0] = 20.0
    torques[1, 1] = -15.0
    one.set_element_torques(torques)
    two.set_element_torques(torques)
    one.advance(30)
    for _ in range(3):
        two.advance(10)
    np.testing.assert_array_equal(one.positions, two.positions)
    assert one.time == pytest.approx(30 * 2e-4, rel=1e-12)
    snapshot = one.positions
    snapshot[...] = 0.0
    assert np.abs(one.positions).max() > 0.5
    # base clamped, the actuated arms moved
    np.testing.assert_allclose(one.positions[:, :, 0], np.array(SimParams().base_positions), atol=0)
    assert np.abs(one.velocities[:, :, -1]).max() > 1e-3


def test_gravity_pulls_a_horizontal_cantilever_down() -> None:
    p = SimParams.from_overrides(
        base_positions=[(0.0, 0.0, 0.0)],
        direction=(1.0, 0.0, 0.0),
        normal=(0.0, 0.0, 1.0),
        gravity=True,
    )
    arm = PyElasticaDualArm(p)
    arm.advance(500)
    tip = arm.positions[0, :, -1]
    assert tip[1] < -1e-3
    assert abs(tip[2]) < 1e-12


def test_invalid_inputs_are_rejected() -> None:
    with pytest.raises(InvalidParameterError):
        rollout_pyelastica()
    with pytest.raises(InvalidParameterError):
        rollout_pyelastica(actions=np.zeros((3, 2, 2, 5)))
    arm = PyElasticaDualArm(SimParams())
    with pytest.raises(InvalidParameterError):
        arm.set_element_torques(np.zeros((2, 20)))
    with pytest.raises(InvalidParameterError):
        arm.set_element_torques(np.full((2, 2, 20), np.nan))


def test_missing_pyelastica_names_the_install_command(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "elastica", None)
    with pytest.raises(ImportError, match=r"pip install pyelastica==1\.0\.0"):
        require_pyelastica()
