"""Across-seed statistics against hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from softtrack.evaluation.seed_statistics import (
    interquartile_mean,
    performance_profile,
    probability_of_improvement,
    stratified_bootstrap,
)


def test_interquartile_mean_trims_a_quarter_from_each_end() -> None:
    assert interquartile_mean([8, 1, 7, 2, 6, 3, 5, 4]) == pytest.approx(4.5)  # mean(3, 4, 5, 6)
    assert interquartile_mean([1, 2, 3, 100]) == pytest.approx(2.5)  # one bad seed left out
    assert interquartile_mean([[1.0, np.nan], [3.0, 2.0]]) == pytest.approx(2.0)  # 3 values
    assert math.isnan(interquartile_mean([np.nan]))


def test_probability_of_improvement_counts_pairs_and_half_ties() -> None:
    # one cell: pairs (1,2) (1,4) (3,4) improve, (3,2) does not → 3/4
    assert probability_of_improvement([1.0, 3.0], [2.0, 4.0], reps=10).value == 0.75
    assert probability_of_improvement([1.0], [1.0], reps=10).value == 0.5  # a tie counts half
    # two cells, averaged: cell 1 always better (1), cell 2 always worse (0)
    both = probability_of_improvement([[1.0, 5.0]], [[2.0, 4.0]], reps=10)
    assert both.value == 0.5
    # cells without scores on both sides are left out
    one = probability_of_improvement([[1.0, np.nan]], [[2.0, 4.0]], reps=10)
    assert one.value == 1.0 and one.low == one.high == 1.0
    with pytest.raises(ValueError, match="same cells"):
        probability_of_improvement([[1.0, 2.0]], [[1.0]])


def test_bootstrap_is_stratified_reproducible_and_brackets_the_estimate() -> None:
    rng = np.random.default_rng(3)
    scores = rng.normal(0.05, 0.01, size=(10, 6))
    scores[7:, 2] = np.nan  # cell 3 has 7 runs
    counts = stratified_bootstrap(scores, lambda m: float(np.isfinite(m).sum()), reps=50)
    assert counts.value == counts.low == counts.high == 57  # every resample keeps each cell's runs
    first = stratified_bootstrap(scores, reps=300, seed=1)
    assert first == stratified_bootstrap(scores, reps=300, seed=1)
    assert first.low < first.value < first.high
    assert first.value == pytest.approx(interquartile_mean(scores))
    constant = stratified_bootstrap(np.full((5, 2), 0.04), reps=20)
    assert constant.low == constant.value == constant.high == pytest.approx(0.04)
    assert constant.text() == "0.0400 [0.0400, 0.0400]"
    with pytest.raises(ValueError, match="no finite score"):
        stratified_bootstrap([np.nan, np.nan])


def test_bootstrap_interval_covers_the_mean_about_as_often_as_it_claims() -> None:
    """Percentile intervals of the mean of 10 normal draws cover the true mean in roughly 95 %
    of 200 repetitions (the percentile bootstrap is a little narrow at n = 10)."""
    rng = np.random.default_rng(0)
    hits = 0
    for k in range(200):
        sample = rng.normal(1.0, 1.0, size=10)
        interval = stratified_bootstrap(sample, np.nanmean, reps=400, seed=k)
        hits += interval.low <= 1.0 <= interval.high
    assert 0.85 <= hits / 200 <= 0.99


def test_performance_profile_is_the_fraction_at_or_below_each_threshold() -> None:
    scores = [[0.1, 0.2], [0.3, np.nan], [0.4, 0.4]]
    profile = performance_profile(scores, [0.05, 0.2, 0.35, 0.4, 0.5])
    np.testing.assert_allclose(profile, [0.0, 0.4, 0.6, 1.0, 1.0])
