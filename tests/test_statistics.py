"""softtrack.evaluation.statistics against hand-computed cases."""

from __future__ import annotations

import math

import pytest

from softtrack.evaluation.statistics import mean_difference


def test_welch_interval_hand_computed() -> None:
    # means 2 and 5, sample variances 1 and 1: se = sqrt(1/3 + 1/3), dof = 4, t(0.975, 4) =
    # 2.7764451, so the interval is -3 ± 2.7764451·0.8164966 = -3 ± 2.2669579
    d = mean_difference([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])
    assert d.difference == pytest.approx(-3.0)
    assert d.low == pytest.approx(-5.2669579, abs=1e-6)
    assert d.high == pytest.approx(-0.7330421, abs=1e-6)
    assert d.p_value == pytest.approx(0.0213, abs=2e-4)  # 2·P(T₄ > 3.6742)
    assert (d.n_a, d.n_b) == (3, 3)
    assert d.text(2) == "-3.00 [-5.27, -0.73]"


def test_unequal_variances_use_welch_dof() -> None:
    # a: mean 0, var 4 (n 2); b: mean 0, var 0 (n 3) -> se² = 2, dof = (2)²/(2²/1) = 1
    d = mean_difference([-math.sqrt(2), math.sqrt(2)], [0.0, 0.0, 0.0])
    assert d.difference == pytest.approx(0.0, abs=1e-15)
    assert d.high == pytest.approx(12.7062047 * math.sqrt(2), rel=1e-6)  # t(0.975, 1)
    assert d.p_value == pytest.approx(1.0)


def test_small_samples_and_bad_input() -> None:
    one = mean_difference([0.04], [0.05, 0.06])
    assert one.difference == pytest.approx(-0.015) and math.isnan(one.low)
    assert one.text(3) == "-0.015"
    same = mean_difference([0.1, 0.1], [0.1, 0.1])
    assert (same.low, same.high, same.p_value) == (0.0, 0.0, 1.0)
    nan_dropped = mean_difference([1.0, float("nan"), 3.0], [2.0, 2.0])
    assert nan_dropped.n_a == 2
    with pytest.raises(ValueError, match="at least one finite"):
        mean_difference([], [1.0])
    with pytest.raises(ValueError, match="confidence"):
        mean_difference([1.0], [1.0], confidence=1.5)
