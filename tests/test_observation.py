"""Observation layout (docs/environment.md, "Observation")."""

from __future__ import annotations

import re

import numpy as np
import pytest

from softtrack.env.observation import (
    arm_view_columns,
    build_observation,
    observation_labels,
    observation_size,
)


def _hand_built_state() -> tuple[np.ndarray, ...]:
    """Two environments, two arms; node (e, a, c, k) holds 1000e + 100(a+1) + 10c + k/100."""
    n, arms, n_nodes = 2, 2, 21
    e, a, c, k = np.meshgrid(
        np.arange(n), np.arange(arms), np.arange(3), np.arange(n_nodes), indexing="ij"
    )
    nodes = 1000.0 * e + 100.0 * (a + 1) + 10.0 * c + k / 100.0
    tip_velocity = np.array(
        [
            [[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]],  # env 0: arm 1 at 5 m/s, arm 2 still
            [[0.0, 0.0, -2.0], [1.0, 1.0, 1.0]],  # env 1
        ]
    )
    target_position = np.array([[0.1, 0.6, -0.2], [-0.3, 0.7, 0.25]])
    target_velocity = np.array([[0.0, 0.0, 0.0], [0.0, 0.3, 0.0]])
    return nodes, tip_velocity, target_position, target_velocity


def test_two_arm_layout_index_by_index() -> None:
    nodes, tip_v, target_p, target_v = _hand_built_state()
    obs = build_observation(nodes, tip_v, target_p, target_v)
    assert obs.shape == (2, 81) and obs.dtype == np.float32
    for e in range(2):
        for arm in range(2):
            base = 37 * arm
            for c in range(3):  # x block, then y block, then z block
                for j in range(11):  # nodes 0, 2, ..., 20
                    expected = 1000.0 * e + 100.0 * (arm + 1) + 10.0 * c + (2 * j) / 100.0
                    assert obs[e, base + 11 * c + j] == np.float32(expected), (e, arm, c, j)
    # tip speeds and directions
    assert obs[0, 33] == 5.0
    np.testing.assert_array_equal(obs[0, 34:37], np.float32([0.6, 0.8, 0.0]))
    assert obs[0, 70] == 0.0
    np.testing.assert_array_equal(obs[0, 71:74], [0.0, 0.0, 0.0])  # zero speed → zeros
    assert obs[1, 33] == 2.0
    np.testing.assert_array_equal(obs[1, 34:37], [0.0, 0.0, -1.0])
    assert obs[1, 70] == np.float32(np.sqrt(3.0))
    np.testing.assert_allclose(obs[1, 71:74], np.full(3, 1 / np.sqrt(3.0)), rtol=1e-7)
    # target
    np.testing.assert_array_equal(obs[:, 74:77], target_p.astype(np.float32))
    np.testing.assert_array_equal(obs[0, 77:81], [0.0, 0.0, 0.0, 0.0])  # still target → zeros
    assert obs[1, 77] == np.float32(0.3)
    np.testing.assert_array_equal(obs[1, 78:81], [0.0, 1.0, 0.0])
    assert np.all(np.isfinite(obs))


def test_tip_node_and_base_node_positions() -> None:
    nodes, tip_v, target_p, target_v = _hand_built_state()
    obs = build_observation(nodes, tip_v, target_p, target_v)
    for arm in range(2):
        base = 37 * arm
        np.testing.assert_array_equal(obs[:, [base, base + 11, base + 22]], nodes[:, arm, :, 0])
        np.testing.assert_array_equal(
            obs[:, [base + 10, base + 21, base + 32]], nodes[:, arm, :, 20].astype(np.float32)
        )


def test_single_arm_layout() -> None:
    nodes, tip_v, target_p, target_v = _hand_built_state()
    obs = build_observation(nodes[:, 1:], tip_v[:, 1:], target_p, target_v)
    full = build_observation(nodes, tip_v, target_p, target_v)
    assert obs.shape == (2, 44) and obs.dtype == np.float32
    np.testing.assert_array_equal(obs[:, :37], full[:, 37:74])
    np.testing.assert_array_equal(obs[:, 37:], full[:, 74:])


def test_labels() -> None:
    labels = observation_labels(2)
    assert len(labels) == 81 == observation_size(2) and len(set(labels)) == 81
    assert len(observation_labels(1)) == 44 == observation_size(1)
    expected = {
        0: "arm1.node0.x",
        1: "arm1.node2.x",
        10: "arm1.node20.x",
        11: "arm1.node0.y",
        15: "arm1.node8.y",
        22: "arm1.node0.z",
        32: "arm1.node20.z",
        33: "arm1.tip_speed",
        34: "arm1.tip_dir.x",
        36: "arm1.tip_dir.z",
        37: "arm2.node0.x",
        70: "arm2.tip_speed",
        73: "arm2.tip_dir.z",
        74: "target.pos.x",
        76: "target.pos.z",
        77: "target.speed",
        78: "target.dir.x",
        80: "target.dir.z",
    }
    for index, name in expected.items():
        assert labels[index] == name, index
    assert observation_labels(1)[37:] == labels[74:]


def test_arm_view_columns_are_the_single_arm_layout() -> None:
    labels, single = observation_labels(2), observation_labels(1)
    for arm in (0, 1):
        columns = arm_view_columns(arm, 2, 81)
        assert len(columns) == 44
        seen = [labels[c].replace(f"arm{arm + 1}.", "arm1.") for c in columns]
        assert seen == single
    with pytest.raises(ValueError, match="no arm 2"):
        arm_view_columns(2, 2, 81)
    with pytest.raises(ValueError, match="80-value"):
        arm_view_columns(0, 2, 80)


def test_labels_describe_the_values() -> None:
    """Every node label decodes to the value the hand-built state put at that index."""
    nodes, tip_v, target_p, target_v = _hand_built_state()
    obs = build_observation(nodes, tip_v, target_p, target_v)
    pattern = re.compile(r"arm(\d)\.node(\d+)\.([xyz])")
    matched = 0
    for index, label in enumerate(observation_labels(2)):
        m = pattern.fullmatch(label)
        if m is None:
            continue
        arm, node, axis = int(m[1]) - 1, int(m[2]), "xyz".index(m[3])
        assert obs[1, index] == np.float32(nodes[1, arm, axis, node]), label
        matched += 1
    assert matched == 66


def test_out_argument_and_errors() -> None:
    nodes, tip_v, target_p, target_v = _hand_built_state()
    out = np.full((2, 81), np.nan, dtype=np.float32)
    result = build_observation(nodes, tip_v, target_p, target_v, out=out)
    assert result is out
    np.testing.assert_array_equal(out, build_observation(nodes, tip_v, target_p, target_v))
    with pytest.raises(ValueError, match="out"):
        build_observation(nodes, tip_v, target_p, target_v, out=np.zeros((2, 81)))
    with pytest.raises(ValueError, match="tip_velocity"):
        build_observation(nodes, tip_v[:, :1], target_p, target_v)
    with pytest.raises(ValueError, match="target"):
        build_observation(nodes, tip_v, target_p[:1], target_v)
    with pytest.raises(ValueError, match="nodes"):
        build_observation(nodes[..., 0], tip_v, target_p, target_v)
    with pytest.raises(ValueError, match="odd"):
        build_observation(nodes[..., :20], tip_v, target_p, target_v)
