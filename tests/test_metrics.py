"""Metrics against closed forms: known offsets and known sinusoids."""

import numpy as np
import pytest

from softtrack.evaluation import Episode, metrics_table
from softtrack.evaluation.metrics import (
    ACTION_STATISTICS,
    action_statistics,
    moment_peak,
    moment_rms,
    tracking_metrics,
)


def test_constant_offset() -> None:
    n = 1000
    target = np.random.default_rng(0).normal(size=(n, 3))
    offset = np.array([0.03, -0.04, 0.12])
    m = tracking_metrics(target + offset, target)
    for axis, value in zip("xyz", offset, strict=False):
        assert m[f"rmse_{axis}"] == pytest.approx(abs(value), rel=1e-12)
        assert m[f"mae_{axis}"] == pytest.approx(abs(value), rel=1e-12)
    norm = float(np.linalg.norm(offset))  # 0.13
    assert m["mean_spatial_error"] == pytest.approx(norm, rel=1e-12)
    assert m["rmse_3d"] == pytest.approx(norm, rel=1e-12)
    assert m["max_error"] == pytest.approx(norm, rel=1e-12)


def test_sinusoidal_error() -> None:
    # e_x = A sin(ωt) over whole periods: RMSE = A/√2, MAE = 2A/π.
    n = 4000
    t = np.arange(n) / n * 2.0  # two periods of 1 s
    amplitude = 0.2
    target = np.zeros((n, 3))
    tip = np.zeros((n, 3))
    tip[:, 0] = amplitude * np.sin(2 * np.pi * t)
    m = tracking_metrics(tip, target)
    assert m["rmse_x"] == pytest.approx(amplitude / np.sqrt(2), rel=1e-9)
    assert m["mae_x"] == pytest.approx(2 * amplitude / np.pi, rel=1e-4)
    assert m["rmse_y"] == 0.0 and m["mae_z"] == 0.0
    assert m["mean_spatial_error"] == pytest.approx(2 * amplitude / np.pi, rel=1e-4)
    assert m["rmse_3d"] == pytest.approx(amplitude / np.sqrt(2), rel=1e-9)
    assert m["max_error"] == pytest.approx(amplitude, rel=1e-5)


def test_circular_error_has_constant_spatial_error() -> None:
    # The tip circles the target at radius ρ: d(t) = ρ, per-axis RMSE ρ/√2 in the plane.
    n, rho = 3600, 0.05
    phase = np.linspace(0, 2 * np.pi, n, endpoint=False)
    target = np.column_stack([np.cos(phase), np.full(n, 0.6), np.sin(phase)])
    tip = target + rho * np.column_stack([np.cos(3 * phase), np.zeros(n), np.sin(3 * phase)])
    m = tracking_metrics(tip, target)
    assert m["rmse_3d"] == pytest.approx(rho, rel=1e-12)
    assert m["mean_spatial_error"] == pytest.approx(rho, rel=1e-12)
    assert m["rmse_x"] == pytest.approx(rho / np.sqrt(2), rel=1e-9)
    assert m["rmse_z"] == pytest.approx(rho / np.sqrt(2), rel=1e-9)
    assert m["rmse_y"] == 0.0


def test_rmse_3d_is_root_sum_of_axis_rmse_squares() -> None:
    rng = np.random.default_rng(1)
    tip, target = rng.normal(size=(500, 3)), rng.normal(size=(500, 3))
    m = tracking_metrics(tip, target)
    assert m["rmse_3d"] ** 2 == pytest.approx(
        m["rmse_x"] ** 2 + m["rmse_y"] ** 2 + m["rmse_z"] ** 2
    )
    assert m["mean_spatial_error"] <= m["rmse_3d"] <= m["max_error"]


def test_bad_shapes() -> None:
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        tracking_metrics(np.zeros((5, 2)), np.zeros((5, 2)))
    with pytest.raises(ValueError):
        tracking_metrics(np.zeros((5, 3)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="time step"):
        tracking_metrics(np.zeros((0, 3)), np.zeros((0, 3)))


def test_moments() -> None:
    torques = np.zeros((3, 2, 2, 20))  # steps, arms, directions, elements
    torques[1, 0, 0, :] = 10.0  # uniform 10 N·m: RMS 10
    torques[2, 1, 1, 5] = -138.9  # one element: RMS 138.9/√20, peak 138.9
    rms = moment_rms(torques)
    assert rms.shape == (3, 2, 2)
    assert rms[1, 0, 0] == pytest.approx(10.0)
    assert rms[2, 1, 1] == pytest.approx(138.9 / np.sqrt(20))
    assert rms[0].max() == 0.0
    peak = moment_peak(torques)
    assert peak.shape == (2, 2)
    assert peak[0, 0] == pytest.approx(10.0)
    assert peak[1, 1] == pytest.approx(138.9)
    assert peak[0, 1] == 0.0


# ---- action statistics ----------------------------------------------------------------------
def test_constant_actions_do_not_change() -> None:
    m = action_statistics(np.full((50, 12), -0.5))
    assert set(m) == set(ACTION_STATISTICS)
    assert m["action_saturation"] == 0.0
    assert m["action_change"] == 0.0
    assert m["action_rms"] == pytest.approx(0.5, rel=1e-12)


def test_alternating_full_actions_are_bang_bang() -> None:
    # ±1 flipping every step: all saturated, |Δa| = 2 at every step, RMS 1
    signs = np.where(np.arange(40) % 2 == 0, 1.0, -1.0)
    m = action_statistics(np.tile(signs[:, None], (1, 12)))
    assert m == {"action_saturation": 1.0, "action_change": 2.0, "action_rms": 1.0}
    # the same beyond the clip limits: the environment applies ±1
    assert action_statistics(np.tile(5 * signs[:, None], (1, 12))) == m


def test_ramp_is_clipped_before_the_statistics() -> None:
    # a = −2, −1, 0, 1, 2 → clipped −1, −1, 0, 1, 1: 4 of 5 saturated,
    # |Δa| = 0, 1, 1, 0 (mean 0.5), RMS sqrt(4/5)
    ramp = np.linspace(-2.0, 2.0, 5)
    m = action_statistics(np.tile(ramp[:, None], (1, 12)))
    assert m["action_saturation"] == pytest.approx(0.8, rel=1e-12)
    assert m["action_change"] == pytest.approx(0.5, rel=1e-12)
    assert m["action_rms"] == pytest.approx(np.sqrt(0.8), rel=1e-12)
    # an unclipped ramp 0, 0.1, …, 0.5: none saturated, |Δa| = 0.1, RMS sqrt(0.55/6)
    m = action_statistics(np.tile(0.1 * np.arange(6)[:, None], (1, 12)))
    assert m["action_saturation"] == 0.0
    assert m["action_change"] == pytest.approx(0.1, rel=1e-12)
    assert m["action_rms"] == pytest.approx(np.sqrt(0.55 / 6), rel=1e-12)


def test_saturation_threshold_and_mixed_values() -> None:
    actions = np.array([[0.99, -0.989, 1.0, 0.0], [-0.995, 0.5, 3.0, 0.0]])
    m = action_statistics(actions)
    assert m["action_saturation"] == pytest.approx(4 / 8)  # 0.99, 1.0, −0.995, 3.0
    assert m["action_change"] == pytest.approx((1.985 + 1.489 + 0.0 + 0.0) / 4)
    assert m["action_rms"] == pytest.approx(
        np.sqrt((0.99**2 + 0.989**2 + 1 + 0.995**2 + 0.25 + 1) / 8)
    )


def test_one_step_has_no_change_and_bad_shapes_fail() -> None:
    m = action_statistics(np.full((1, 12), 2.0))
    assert m == {"action_saturation": 1.0, "action_change": 0.0, "action_rms": 1.0}
    with pytest.raises(ValueError, match="time step"):
        action_statistics(np.zeros((0, 12)))
    with pytest.raises(ValueError, match=r"\(N, M\)"):
        action_statistics(np.zeros(12))


def _episode(actions: np.ndarray, terminated: bool = False) -> Episode:
    n = len(actions)
    return Episode(
        trajectory="circle",
        t=0.002 * np.arange(1, n + 1),
        tips=np.zeros((n, 2, 3)),
        target=np.ones((n, 3)),
        element_torques=np.zeros((n, 2, 2, 20)),
        actions=actions,
        terminated=terminated,
    )


def test_metrics_table_splits_the_actions_per_arm() -> None:
    # arm 1: columns 0–11 constant 0.25; arm 2: columns 12–23 alternating ±1
    n = 10
    actions = np.zeros((n, 24))
    actions[:, :12] = 0.25
    actions[:, 12:] = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]
    table = metrics_table("run", _episode(actions)).set_index("arm")
    assert table.loc[0, "action_saturation"] == 0.0
    assert table.loc[0, "action_change"] == 0.0
    assert table.loc[0, "action_rms"] == pytest.approx(0.25)
    assert table.loc[1, "action_saturation"] == 1.0
    assert table.loc[1, "action_change"] == 2.0
    assert table.loc[1, "action_rms"] == 1.0
    # an episode that diverged after one step holds only that step's actions
    short = metrics_table("run", _episode(actions[:1] * 3, terminated=True)).set_index("arm")
    assert list(short["action_change"]) == [0.0, 0.0]
    assert list(short["action_saturation"]) == [0.0, 1.0]
    assert bool(short["terminated"].all())
    with pytest.raises(ValueError, match="actions have shape"):
        metrics_table("run", _episode(actions[:, :12]))
