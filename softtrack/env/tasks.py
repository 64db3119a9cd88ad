"""Dual-arm tasks: what each arm's tip tracks (docs/environment.md, "Tasks").

* ``shared`` (the study's task, the default): both tips track the target centre. Two real arms
  of radius r cannot both reach one point: with their surfaces touching, the tips are at least
  2r apart, so the quadratic mean of the two arms' errors is at least r per step (the floor of
  docs/results.md, "Contact").
* ``viewpoints`` (the study's motivating application, coordinated multi-view inspection): each
  tip tracks its own point at a standoff d from the target centre along x, arm 1 (base at
  x < 0) at centre − d·x̂ and arm 2 at centre + d·x̂, so the two tips look at the target from
  opposite sides. The trajectories, metrics, reward terms and cooperative bonus are those of
  the shared task, measured against each arm's own point.

The observation keeps the study's 81 values in both tasks: the target block (indices 74–80)
holds the target centre, its speed and direction; an arm's point is that centre plus the
task's fixed offset, so the policy needs nothing more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["N_ARMS", "TASKS", "TaskConfig"]

#: Arms of the dual-arm scene. An independent run trains one policy per arm, each to the
#: spec's ``training.total_timesteps`` (run.json ``arm_total_timesteps``; ``total_timesteps``
#: is their sum).
N_ARMS = 2
TASKS = ("shared", "viewpoints")


@dataclass(frozen=True)
class TaskConfig:
    """Which point each arm tracks.

    Attributes:
        name: ``shared`` or ``viewpoints`` (module docstring).
        standoff: d, the distance of each arm's point from the target centre along x in the
            ``viewpoints`` task, m (ignored by ``shared``).
    """

    name: str = "shared"
    standoff: float = 0.1

    def validate(self) -> None:
        """Raise ``ValueError`` naming the invalid field and the fix."""
        if self.name not in TASKS:
            raise ValueError(f"task {self.name!r} is unknown; use one of {', '.join(TASKS)}")
        if not (
            isinstance(self.standoff, (int, float))
            and math.isfinite(self.standoff)
            and self.standoff >= 0
        ):
            raise ValueError(f"standoff={self.standoff!r} must be a finite number ≥ 0 m")

    def goal_offsets(self, arms: tuple[int, ...] = (0, 1)) -> np.ndarray:
        """(len(arms), 3) offset of each listed arm's point from the target centre, m.

        Args:
            arms: the dual-arm indices of the scene's arms: (0, 1) for the dual-arm scene,
                (k,) for the single-arm scene of arm k.
        """
        offsets = np.zeros((len(arms), 3))
        if self.name == "viewpoints":
            for row, arm in enumerate(arms):
                offsets[row, 0] = (-1.0 if arm == 0 else 1.0) * self.standoff
        return offsets
