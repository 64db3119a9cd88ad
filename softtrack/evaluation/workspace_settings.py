"""How ``softtrack workspace`` searches for the held region (:mod:`softtrack.evaluation.workspace`):
its settings, with their defaults and ranges, in a module light enough for the command line's
``--help`` to show them."""

from __future__ import annotations

from dataclasses import dataclass

from softtrack.numbers import out_of_range, setting

__all__ = ["GOALS_PER_PATH", "JUDGE_WINDOW", "SearchSettings"]

#: Goal points of the search per path (the circle, rectangle and figure-eight of the spec).
GOALS_PER_PATH = 4
#: Seconds at the end of a sample over which holding and rest are judged.
JUDGE_WINDOW = 0.5


@dataclass(frozen=True)
class SearchSettings:
    """How :func:`search_workspace` searches (defaults: 192 samples per goal, 2.5 s each).

    Attributes:
        population: samples per goal and iteration.
        iterations: cross-entropy iterations per goal.
        elite: the samples (closest to the goal among those that held) each iteration's
            distribution is fitted to.
        initial_std: the least spread of the first iteration's samples, each of which has
            its own spread, log-uniform between this and 1 (control units).
        min_std: the least spread an iteration keeps, so the search goes on moving.
        ramp: seconds over which a sample's action is brought in, s.
        hold: seconds it is then kept, s.
        batch: environments stepped together.
        seed: of the samples' random numbers.
    """

    population: int = setting(32, ge=1, whole=True)
    iterations: int = setting(6, ge=1, whole=True)
    elite: int = setting(6, ge=1, whole=True)
    initial_std: float = setting(0.1, "control units", gt=0)
    min_std: float = setting(0.05, "control units", gt=0)
    ramp: float = setting(0.5, "s", ge=0)
    hold: float = setting(2.0, "s", gt=0)
    batch: int = setting(128, ge=1, whole=True)
    seed: int = setting(0, ge=0, whole=True)

    def validate(self) -> None:
        """Raise ValueError naming the first setting out of range and how to fix it."""
        problem = out_of_range(self)
        if problem is not None:
            raise ValueError(problem)
        if self.elite > self.population:
            raise ValueError(f"elite={self.elite} must not exceed population={self.population}")
        if self.hold < JUDGE_WINDOW:
            raise ValueError(f"hold={self.hold} s must be at least the {JUDGE_WINDOW}-s judging")
