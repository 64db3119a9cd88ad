"""Metrics against closed forms: known offsets and known sinusoids."""

import numpy as np
import pytest

from softtrack.metrics import moment_peak, moment_rms, tracking_metrics


def test_constant_offset() -> None:
    n = 1000
    target = np.random.default_rng(0).normal(size=(n, 3))
    offset = np.array([0.03, -0.04, 0.12])
    m = tracking_metrics(target + offset, target)
    for axis, value in zip("xyz", offset):
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
    assert m["rmse_3d"] ** 2 == pytest.approx(m["rmse_x"] ** 2 + m["rmse_y"] ** 2 + m["rmse_z"] ** 2)
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
    torques[1, 0, 0, :] = 10.0          # uniform 10 N·m: RMS 10
    torques[2, 1, 1, 5] = -138.9        # one element: RMS 138.9/√20, peak 138.9
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
