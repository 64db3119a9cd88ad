"""Target motions (docs/environment.md, "Target")."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from softtrack.env.target_tables import AheadTable
from softtrack.env.targets import (
    EVAL_TRAJECTORIES,
    HELD_OUT_SCALE,
    HELD_OUT_SHIFT,
    BatchedTargets,
    TargetConfig,
    trajectory_position,
    trajectory_velocity,
)

OMEGA = 2.0 * math.pi / 10.0
T = np.linspace(0.0, 20.0, 20_001)  # two laps, 1 ms apart


def _speed(v: np.ndarray) -> np.ndarray:
    return np.linalg.norm(v, axis=-1)


# ---- configuration ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["random", "circle", "rectangle", "figure8", "fixed"])
def test_defaults_are_valid(name: str) -> None:
    TargetConfig(name=name).validate()


def test_defaults_match_spec() -> None:
    c = TargetConfig()
    assert c.name == "random"
    assert (c.sphere_radius, c.speed, c.redirect_interval, c.period) == (0.05, 0.3, 1.0, 10.0)
    assert c.box_low == (-0.6, 0.3, -0.6) and c.box_high == (0.6, 0.9, 0.6)
    assert c.center == (0.0, 0.6, 0.0) and c.circle_radius == 0.3
    assert c.rectangle_size == (0.6, 0.4) and c.figure8_amplitude == (0.3, 0.15)
    assert c.angular_frequency == pytest.approx(OMEGA)


@pytest.mark.parametrize(
    "overrides, field",
    [
        ({"name": "spiral"}, "name"),
        ({"sphere_radius": 0.0}, "sphere_radius"),
        ({"speed": -0.3}, "speed"),
        ({"speed": float("nan")}, "speed"),
        ({"redirect_interval": 0.0}, "redirect_interval"),
        ({"period": 0.0}, "period"),
        ({"circle_radius": -1.0}, "circle_radius"),
        ({"rectangle_size": (0.6, 0.0)}, "rectangle_size"),
        ({"rectangle_size": (0.6,)}, "rectangle_size"),
        ({"figure8_amplitude": (-0.3, 0.15)}, "figure8_amplitude"),
        ({"center": (0.0, 0.6)}, "center"),
        ({"fixed_position": (0.0, float("inf"), 0.0)}, "fixed_position"),
        ({"box_low": (0.6, 0.3, -0.6)}, "box_low"),
        ({"box_low": (-0.6, 0.3, -0.6), "box_high": (0.6, 0.39, 0.6)}, "sphere"),
        ({"sphere_radius": 0.7}, "sphere_radius"),
        ({"speed_min": 0.4}, "speed_min"),
        ({"speed_min": -0.1}, "speed_min"),
        ({"speed_min": float("nan")}, "speed_min"),
    ],
)
def test_validate_names_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        TargetConfig(**overrides).validate()


def test_batched_targets_validate_config() -> None:
    with pytest.raises(ValueError, match="name"):
        BatchedTargets(TargetConfig(name="spiral"), 2)
    with pytest.raises(ValueError, match="n_envs"):
        BatchedTargets(TargetConfig(), 0)


# ---- closed forms ----------------------------------------------------------------------------


def test_circle() -> None:
    c = TargetConfig(name="circle")
    p, v = trajectory_position(c, T), trajectory_velocity(c, T)
    assert p.shape == (T.size, 3) and v.shape == (T.size, 3)
    np.testing.assert_allclose(p[:, 1], 0.6)
    np.testing.assert_allclose(np.hypot(p[:, 0], p[:, 2]), 0.3, atol=1e-15)
    np.testing.assert_allclose(p[:, 0], 0.3 * np.cos(OMEGA * T), atol=1e-15)
    np.testing.assert_allclose(p[:, 2], 0.3 * np.sin(OMEGA * T), atol=1e-15)
    np.testing.assert_allclose(p[0], [0.3, 0.6, 0.0])
    np.testing.assert_allclose(
        trajectory_position(c, np.array([2.5, 5.0, 7.5])),
        [[0.0, 0.6, 0.3], [-0.3, 0.6, 0.0], [0.0, 0.6, -0.3]],
        atol=1e-15,
    )
    np.testing.assert_allclose(_speed(v), 0.3 * OMEGA, rtol=1e-12)  # 0.1885 m/s
    assert 0.3 * OMEGA == pytest.approx(0.1885, abs=1e-4)
    np.testing.assert_allclose(v[:, 1], 0.0)
    np.testing.assert_allclose(trajectory_position(c, T + 10.0), p, atol=1e-12)  # period
    np.testing.assert_allclose(p.mean(axis=0), [0.0, 0.6, 0.0], atol=1e-4)  # centre


def test_rectangle() -> None:
    c = TargetConfig(name="rectangle")
    p, v = trajectory_position(c, T), trajectory_velocity(c, T)
    np.testing.assert_allclose(p[:, 1], 0.6)
    np.testing.assert_allclose(p[0], [-0.3, 0.6, -0.2])
    # corners at arc lengths 0, 0.6, 1.0, 1.6 m at 0.2 m/s: t = 0, 3, 5, 8 s, then back at 10 s
    corners = trajectory_position(c, np.array([0.0, 3.0, 5.0, 8.0, 10.0]))
    np.testing.assert_allclose(
        corners,
        [[-0.3, 0.6, -0.2], [0.3, 0.6, -0.2], [0.3, 0.6, 0.2], [-0.3, 0.6, 0.2], [-0.3, 0.6, -0.2]],
        atol=1e-12,
    )
    # constant speed perimeter / period = 2 (0.6 + 0.4) / 10 = 0.2 m/s, along one axis at a time
    np.testing.assert_allclose(_speed(v), 0.2, rtol=1e-12)
    assert np.all(np.count_nonzero(v, axis=1) == 1)
    # every point lies on the perimeter of the 0.6 × 0.4 rectangle around the centre
    x, z = p[:, 0], p[:, 2]
    on_x_side = np.isclose(np.abs(x), 0.3, atol=1e-12) & (np.abs(z) <= 0.2 + 1e-12)
    on_z_side = np.isclose(np.abs(z), 0.2, atol=1e-12) & (np.abs(x) <= 0.3 + 1e-12)
    assert np.all(on_x_side | on_z_side)
    assert x.min() == pytest.approx(-0.3) and x.max() == pytest.approx(0.3)
    assert z.min() == pytest.approx(-0.2) and z.max() == pytest.approx(0.2)
    # the sides in order: +x, +z, −x, −z
    for t, expected in [
        (1.0, [0.2, 0, 0]),
        (4.0, [0, 0, 0.2]),
        (6.0, [-0.2, 0, 0]),
        (9.0, [0, 0, -0.2]),
    ]:
        np.testing.assert_allclose(trajectory_velocity(c, np.array(t)), expected, atol=1e-15)
    np.testing.assert_allclose(trajectory_position(c, T + 10.0), p, atol=1e-12)  # period


def test_rectangle_visits_corners_in_order() -> None:
    c = TargetConfig(name="rectangle")
    p = trajectory_position(c, T[T < 10.0])
    order = [
        np.argmin(np.linalg.norm(p[:, [0, 2]] - corner, axis=1))
        for corner in ([-0.3, -0.2], [0.3, -0.2], [0.3, 0.2], [-0.3, 0.2])
    ]
    assert order == sorted(order)
    np.testing.assert_allclose(T[order], [0.0, 3.0, 5.0, 8.0], atol=1e-3)


def test_figure8() -> None:
    c = TargetConfig(name="figure8")
    p, v = trajectory_position(c, T), trajectory_velocity(c, T)
    np.testing.assert_allclose(p[:, 0], 0.3 * np.sin(OMEGA * T), atol=1e-15)
    np.testing.assert_allclose(p[:, 2], 0.15 * np.sin(2 * OMEGA * T), atol=1e-15)
    np.testing.assert_allclose(p[:, 1], 0.6)
    np.testing.assert_allclose(p[0], [0.0, 0.6, 0.0])
    np.testing.assert_allclose(trajectory_position(c, np.array(5.0)), [0.0, 0.6, 0.0], atol=1e-15)
    speed = _speed(v)
    # speed² = (0.3ω)²(cos²θ + cos²2θ): min 0.3ω·√(7/16) = 0.1247, max 0.3ω·√2 = 0.2666 m/s
    assert speed.min() == pytest.approx(0.3 * OMEGA * math.sqrt(7 / 16), rel=1e-6)
    assert speed.max() == pytest.approx(0.3 * OMEGA * math.sqrt(2), rel=1e-12)
    assert 0.124 < speed.min() < 0.125 and 0.266 < speed.max() < 0.267
    assert np.abs(p[:, 0]).max() == pytest.approx(0.3)
    assert np.abs(p[:, 2]).max() == pytest.approx(0.15)
    np.testing.assert_allclose(trajectory_position(c, T + 10.0), p, atol=1e-12)  # period


def test_fixed() -> None:
    c = TargetConfig(name="fixed", fixed_position=(0.1, 0.7, -0.2))
    p, v = trajectory_position(c, T[:5]), trajectory_velocity(c, T[:5])
    np.testing.assert_array_equal(p, np.tile([0.1, 0.7, -0.2], (5, 1)))
    np.testing.assert_array_equal(v, 0.0)


@pytest.mark.parametrize("name", ["circle", "rectangle", "figure8", "fixed"])
def test_velocity_is_derivative_of_position(name: str) -> None:
    c = TargetConfig(name=name)
    t = np.linspace(0.0, 20.0, 997) + 0.0123  # avoids the rectangle's corners (multiples of 1 s)
    h = 1e-6
    fd = (trajectory_position(c, t + h) - trajectory_position(c, t - h)) / (2 * h)
    np.testing.assert_allclose(trajectory_velocity(c, t), fd, atol=1e-8)


@pytest.mark.parametrize("name", ["circle", "rectangle", "figure8"])
def test_custom_centre_size_and_period(name: str) -> None:
    base = TargetConfig(name=name)
    c = TargetConfig(
        name=name,
        center=(0.1, 0.5, -0.1),
        circle_radius=0.2,
        rectangle_size=(0.4, 0.8 / 3),
        figure8_amplitude=(0.2, 0.1),
        period=4.0,
    )
    t = np.linspace(0.0, 8.0, 801)
    p = trajectory_position(c, t)
    # the same shape scaled by 2/3 and shifted, traversed 2.5 times as fast
    ref = trajectory_position(base, t * 2.5)
    np.testing.assert_allclose(
        p - [0.1, 0.5, -0.1], (ref - [0, 0.6, 0]) * [2 / 3, 0, 2 / 3], atol=1e-12
    )


def test_random_has_no_closed_form() -> None:
    with pytest.raises(ValueError, match="random"):
        trajectory_position(TargetConfig(), np.zeros(3))


@pytest.mark.parametrize("name", ["circle", "rectangle", "figure8", "fixed"])
def test_batched_closed_forms_follow_trajectory(name: str) -> None:
    c = TargetConfig(name=name)
    targets = BatchedTargets(c, 4)
    np.testing.assert_allclose(targets.position, trajectory_position(c, np.zeros(4)))
    for k in range(1, 1501):
        targets.step(0.002)
        if k == 700:
            targets.reset(np.array([1, 3]))
            np.testing.assert_array_equal(targets.time[[1, 3]], 0.0)
    np.testing.assert_allclose(targets.time, [3.0, 1.6, 3.0, 1.6], atol=1e-12)
    np.testing.assert_allclose(targets.position, trajectory_position(c, targets.time), atol=1e-15)
    np.testing.assert_allclose(targets.velocity, trajectory_velocity(c, targets.time), atol=1e-15)
    np.testing.assert_allclose(
        targets.position[0], trajectory_position(c, np.array(3.0)), atol=1e-10
    )


# ---- random target ---------------------------------------------------------------------------


def _random_targets(seeds: list[int], config: TargetConfig | None = None) -> BatchedTargets:
    targets = BatchedTargets(config or TargetConfig(), len(seeds))
    targets.reset(np.arange(len(seeds)), [np.random.default_rng(s) for s in seeds])
    return targets


def test_random_needs_reset_and_generators() -> None:
    targets = BatchedTargets(TargetConfig(), 2)
    with pytest.raises(RuntimeError, match="reset"):
        targets.step(0.002)
    with pytest.raises(ValueError, match="Generator"):
        targets.reset(np.array([0, 1]))
    targets.reset(np.array([0]), [np.random.default_rng(0)])
    with pytest.raises(RuntimeError, match="reset"):
        targets.step(0.002)
    with pytest.raises(ValueError, match="dt"):
        _random_targets([0]).step(0.0)


def test_random_reset_distribution() -> None:
    targets = _random_targets(list(range(4000)))
    low, high = np.array([-0.55, 0.35, -0.55]), np.array([0.55, 0.85, 0.55])
    assert np.all(targets.position >= low - 1e-12) and np.all(targets.position <= high + 1e-12)
    # uniform in the shrunk box: mean at its centre, std = width / √12
    np.testing.assert_allclose(targets.position.mean(axis=0), [0, 0.6, 0], atol=0.02)
    np.testing.assert_allclose(
        targets.position.std(axis=0), (high - low) / math.sqrt(12), rtol=0.05
    )
    # directions uniform on the unit sphere: zero mean, E[dᵢ²] = 1/3, speed 0.3
    np.testing.assert_allclose(_speed(targets.velocity), 0.3, rtol=1e-14)
    d = targets.velocity / 0.3
    np.testing.assert_allclose(d.mean(axis=0), 0.0, atol=0.05)
    np.testing.assert_allclose((d**2).mean(axis=0), 1 / 3, atol=0.03)
    np.testing.assert_array_equal(targets.time, 0.0)


def test_random_stays_in_box_long_run() -> None:
    """64 environments × 100 s at dt = 0.002: the sphere never leaves the box."""
    targets = _random_targets(list(range(64)))
    low = np.array([-0.6, 0.3, -0.6]) + 0.05
    high = np.array([0.6, 0.9, 0.6]) - 0.05
    lowest = targets.position.copy()
    highest = targets.position.copy()
    reflections = 0
    previous = targets.velocity.copy()
    for k in range(1, 50_001):
        targets.step(0.002)
        np.minimum(lowest, targets.position, out=lowest)
        np.maximum(highest, targets.position, out=highest)
        if k % 500:  # between redirects, velocity components only change sign (reflections)
            flipped = targets.velocity != previous
            assert np.array_equal(targets.velocity[flipped], -previous[flipped])
            reflections += int(flipped.sum())
        previous[:] = targets.velocity
        if k % 5000 == 0:
            np.testing.assert_allclose(_speed(targets.velocity), 0.3, rtol=1e-14)
    assert np.all(lowest >= low - 1e-12), lowest.min(axis=0)
    assert np.all(highest <= high + 1e-12), highest.max(axis=0)
    # the sphere surface (centre ± radius) stays within the box
    assert np.all(lowest - 0.05 >= np.array([-0.6, 0.3, -0.6]) - 1e-12)
    assert np.all(highest + 0.05 <= np.array([0.6, 0.9, 0.6]) + 1e-12)
    assert reflections > 1000  # the walls were actually hit, many times
    # and the box is explored up to its walls
    np.testing.assert_allclose(lowest.min(axis=0), low, atol=0.01)
    np.testing.assert_allclose(highest.max(axis=0), high, atol=0.01)
    np.testing.assert_allclose(targets.time, 100.0, rtol=1e-12)


def test_random_reflection_mirrors_position() -> None:
    targets = _random_targets([0])
    targets.position[0] = [0.55 - 0.001, 0.6, -0.55 + 0.0005]
    targets.velocity[0] = [0.3, 0.0, -0.3]
    targets.step(0.01)  # moves 3 mm: overshoots x by 2 mm and z by 2.5 mm
    np.testing.assert_allclose(targets.position[0], [0.55 - 0.002, 0.6, -0.55 + 0.0025], atol=1e-15)
    np.testing.assert_array_equal(targets.velocity[0], [-0.3, 0.0, 0.3])


def test_random_direction_changes_every_second() -> None:
    targets = _random_targets(list(range(8)))
    changes = np.zeros(8, dtype=int)
    previous = np.abs(targets.velocity)
    for k in range(1, 2501):  # 5 s at 2 ms
        targets.step(0.002)
        current = np.abs(targets.velocity)  # reflections keep |v_i|; a redraw changes it
        changed = np.any(current != previous, axis=1)
        if k % 500 == 0:
            assert np.all(changed), (k, targets.time)
            np.testing.assert_allclose(targets.time, k * 0.002, rtol=1e-12)
        else:
            assert not np.any(changed), k
        changes += changed
        previous = current
    np.testing.assert_array_equal(changes, 5)


def test_random_redirect_interval_is_configurable() -> None:
    targets = _random_targets([3], TargetConfig(redirect_interval=0.25))
    draws = []
    previous = np.abs(targets.velocity[0])
    for k in range(1, 501):
        targets.step(0.002)
        if np.any(np.abs(targets.velocity[0]) != previous):
            draws.append(k)
        previous = np.abs(targets.velocity[0])
    assert draws == [125, 250, 375, 500]


def _speeds(config: TargetConfig, seeds: list[int], steps: int = 5000) -> np.ndarray:
    """(steps, n_envs) speeds of random targets stepped at 2 ms."""
    targets = _random_targets(seeds, config)
    speeds = np.empty((steps, len(seeds)))
    for k in range(steps):
        targets.step(0.002)
        speeds[k] = np.linalg.norm(targets.velocity, axis=1)
    return speeds


def test_random_speed_is_constant_without_speed_min() -> None:
    np.testing.assert_allclose(_speeds(TargetConfig(), [1, 2, 3]), 0.3, rtol=1e-12)


def test_random_speed_min_draws_a_speed_with_every_direction() -> None:
    speeds = _speeds(TargetConfig(speed_min=0.1), list(range(20)))  # 10 s: 10 draws per env
    assert speeds.min() >= 0.1 and speeds.max() <= 0.3
    per_interval = speeds[::500]  # one sample per 1-s direction
    assert len(np.unique(per_interval.round(12))) == per_interval.size  # all different
    # 200 uniform draws on [0.1, 0.3]: mean 0.2 ± 0.004 (std 0.058/sqrt(200)), both ends reached
    assert abs(per_interval.mean() - 0.2) < 0.02
    assert per_interval.min() < 0.12 and per_interval.max() > 0.28
    # between draws a speed only changes by reflection, which keeps it
    np.testing.assert_allclose(speeds[1:499], speeds[0:498], rtol=1e-12)


def test_random_speed_min_equal_to_speed_is_the_constant_speed() -> None:
    np.testing.assert_allclose(
        _speeds(TargetConfig(speed_min=0.3), [4, 5]), _speeds(TargetConfig(), [4, 5]), rtol=1e-12
    )


def _run(seeds: list[int], steps: int = 1500) -> np.ndarray:
    targets = _random_targets(seeds)
    path = np.empty((steps, len(seeds), 3))
    for k in range(steps):
        targets.step(0.002)
        path[k] = targets.position
    return path


def test_random_same_seed_same_path_different_seed_different() -> None:
    a, b, c = _run([7, 8]), _run([7, 8]), _run([9, 8])
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a[:, 0], c[:, 0])
    np.testing.assert_array_equal(a[:, 1], c[:, 1])  # env 1 uses the same seed in both


def test_random_batched_equals_singles_bit_for_bit() -> None:
    seeds = [11, 12, 13, 14, 15, 16, 17, 18]
    batched = _random_targets(seeds)
    singles = [_random_targets([s]) for s in seeds]
    for k in range(1, 3001):
        dt = 0.002 if k < 2000 else 0.003
        batched.step(dt)
        for single in singles:
            single.step(dt)
        if k == 1234:  # reset some environments mid-run with fresh generators
            fresh = [np.random.default_rng(100), np.random.default_rng(101)]
            batched.reset(np.array([2, 5]), fresh)
            singles[2].reset(np.array([0]), [np.random.default_rng(100)])
            singles[5].reset(np.array([0]), [np.random.default_rng(101)])
        if k % 250 == 0 or k == 1234:
            for i, single in enumerate(singles):
                assert np.array_equal(batched.position[i], single.position[0]), (k, i)
                assert np.array_equal(batched.velocity[i], single.velocity[0]), (k, i)
                assert batched.time[i] == single.time[0]


def test_trajectory_names_are_defined_once() -> None:
    """The evaluation trajectories' names come from softtrack.env.targets everywhere: the
    spec default and its allowed values, the target modes, the CLI's --trajectory choices, the
    evaluation and the study's reference values."""
    import typing

    from softtrack.cli import TrajectoryChoice
    from softtrack.env.targets import EVAL_TRAJECTORIES, TARGET_MODES, TrajectoryName
    from softtrack.evaluation import EVAL_TRAJECTORIES as evaluated
    from softtrack.report.reference import STUDY_RMSE_3D
    from softtrack.spec import ExperimentSpec

    assert EVAL_TRAJECTORIES == ("circle", "rectangle", "figure8")
    assert typing.get_args(TrajectoryName) == EVAL_TRAJECTORIES == evaluated
    assert TARGET_MODES == ("random", *EVAL_TRAJECTORIES, "paths", "fixed")
    assert tuple(ExperimentSpec(name="x").training.eval_trajectories) == EVAL_TRAJECTORIES
    assert [c.value for c in TrajectoryChoice] == [*EVAL_TRAJECTORIES, "all", "none"]
    assert all(set(cells) == set(EVAL_TRAJECTORIES) for cells in STUDY_RMSE_3D.values())


def test_held_out_paths_are_the_trajectories_moved_scaled_and_shifted_in_time() -> None:
    """Each ``paths`` environment follows its drawn shape's trajectory at phase + sign·t,
    scaled about the centre and moved; it draws only from its own generator, so a batch is
    its environments alone, and the draws stay in their documented ranges."""
    config = TargetConfig(name="paths")
    n = 24
    batch = BatchedTargets(config, n)
    batch.reset(range(n), [np.random.default_rng(100 + k) for k in range(n)])
    paths = batch._paths
    assert paths is not None
    assert set(paths.shape.tolist()) == {0, 1, 2} and set(paths.sign.tolist()) == {-1.0, 1.0}
    assert np.all((paths.scale >= HELD_OUT_SCALE[0]) & (paths.scale <= HELD_OUT_SCALE[1]))
    assert np.all(np.abs(paths.shift) <= HELD_OUT_SHIFT * config.circle_radius)
    for _ in range(37):
        batch.step(0.05)
    t = batch.time[0]
    centre = np.asarray(config.center)
    for i in range(n):
        shaped = dataclasses.replace(config, name=EVAL_TRAJECTORIES[paths.shape[i]])
        along = paths.phase[i] + paths.sign[i] * t
        expected = (
            centre
            + paths.shift[i]
            + paths.scale[i] * (trajectory_position(shaped, np.array(along)) - centre)
        )
        np.testing.assert_allclose(batch.position[i], expected, atol=1e-12)
        alone = BatchedTargets(config, 1)
        alone.reset([0], [np.random.default_rng(100 + i)])
        for _ in range(37):
            alone.step(0.05)
        np.testing.assert_array_equal(alone.position[0], batch.position[i])
    # the velocity is the position's derivative
    before = batch.position.copy()
    velocity = batch.velocity.copy()
    batch.step(1e-6)
    moved = (batch.position - before) / 1e-6
    smooth = np.abs(moved - velocity).max(axis=1) < 1e-3  # a rectangle corner may fall between
    assert smooth.sum() >= n - 2


def test_held_out_paths_need_generators_and_have_no_closed_form() -> None:
    with pytest.raises(ValueError, match="paths targets need one numpy Generator"):
        BatchedTargets(TargetConfig(name="paths"), 2).reset([0, 1])
    with pytest.raises(ValueError, match="paths target has no closed-form"):
        trajectory_position(TargetConfig(name="paths"), np.zeros(3))


@pytest.mark.parametrize("name", ["circle", "rectangle", "figure8", "fixed", "paths"])
def test_targets_from_a_table_ahead_equal_stepping_bit_for_bit(name: str) -> None:
    """``BatchedTargets`` computes closed-form and held-out path states many steps ahead in
    one call (:mod:`softtrack.env.target_tables`); each step's state equals the closed form at
    the stepped time bit for bit, through a reset of some environments, a step of some of
    them, a change of ``dt`` and several tables."""
    config = dataclasses.replace(TargetConfig(), name=name)
    targets = BatchedTargets(config, 5)
    rngs = [np.random.default_rng(5_000_000 + i) for i in range(5)]
    targets.reset(range(5), rngs)
    for k in range(700):
        if k == 300:
            targets.reset([1, 3], [np.random.default_rng(7), np.random.default_rng(8)])
        active = np.array([True, False, True, True, False]) if k == 400 else None
        targets.step(0.004 if k > 500 else 0.002, active)
        position, velocity = targets._state(targets.time.copy())
        assert np.array_equal(targets.position, position), k
        assert np.array_equal(targets.velocity, velocity), k
    assert targets._ahead.exact


def test_a_table_that_is_not_exact_falls_back_to_one_step_at_a_time() -> None:
    """A state function whose values depend on how many times it is given at once (what a
    CPU's vector code could do to the last bit) is caught on the table's last row: from then
    on each step is computed alone."""

    def state_at(times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        drift = 1e-12 * times.shape[0]
        position = np.repeat((times + drift)[..., None], 3, axis=-1)
        return position, np.zeros_like(position)

    table = AheadTable(state_at)
    time = np.zeros(2)
    for _ in range(40):
        time = time + 0.002
        position, _ = table.state(time, 0.002)
        np.testing.assert_array_equal(position, state_at(time[None])[0][0])
    assert not table.exact
