"""What a fresh seed must reach, per task (``experiments/fresh_seeds.py --criterion``).

* ``study`` (the shared target, arms passing through each other): the kept model at or below
  the study's centralized TD3 3-D RMSE in all six trajectory × arm cells;
* ``contact`` (the shared target with solid arms): the quadratic mean of the two arms' 3-D
  RMSE, sqrt((RMSE₁² + RMSE₂²)/2) per trajectory, averaged over the three trajectories, at or
  below 0.055 m (touching tips are at least 2r = 0.1 m apart, so it cannot go below r = 0.05 m);
* ``viewpoints`` (each tip its own point): the six cells at the study and the arms' surfaces
  never more than 5 mm into each other.

Each applies to a kept model's evaluation (``eval_metrics``) and to a validated checkpoint's
trajectory rows (``validation``) alike.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from softtrack.report.reference import STUDY_RMSE_3D

__all__ = [
    "CELLS",
    "CONTACT_TARGET",
    "CRITERIA",
    "MAX_OVERLAP",
    "TRAJECTORIES",
    "Criterion",
    "at_study",
    "quadratic_means",
    "study_cells",
]

TRAJECTORIES = ("circle", "rectangle", "figure8")
#: (trajectory, arm) in the order every cell tuple of these scripts uses.
CELLS = tuple((t, arm) for t in TRAJECTORIES for arm in (0, 1))
#: The shared target with contact: the quadratic mean of the arms at or below this, m.
CONTACT_TARGET = 0.055
#: The viewpoints task: the deepest overlap of the arms' surfaces at or below this, m.
MAX_OVERLAP = 0.005

Cell = tuple[str, int]


def study_cells() -> tuple[float, ...]:
    """The study's centralized TD3 3-D RMSE per cell (m), in :data:`CELLS` order."""
    return tuple(STUDY_RMSE_3D["centralized"][t][arm] for t, arm in CELLS)


def at_study(cells: Mapping[Cell, float]) -> bool:
    """Whether all six cells (m) are at or below the study's."""
    study = dict(zip(CELLS, study_cells(), strict=True))
    return all(c in cells and cells[c] <= study[c] for c in CELLS)


def quadratic_means(cells: Mapping[Cell, float]) -> tuple[float, ...]:
    """(3,) sqrt((RMSE₁² + RMSE₂²)/2) of each trajectory, m (NaN where an arm is missing)."""
    return tuple(
        math.sqrt((cells[(t, 0)] ** 2 + cells[(t, 1)] ** 2) / 2)
        if (t, 0) in cells and (t, 1) in cells
        else math.nan
        for t in TRAJECTORIES
    )


@dataclass(frozen=True)
class Criterion:
    """A task's target for one model: ``passes(cells, overlap)`` with the six cells' 3-D RMSE
    (m) and the deepest overlap of the arms' surfaces over the three trajectories (m; ``None``
    where it was not recorded)."""

    name: str
    target: str
    passes: Callable[[Mapping[Cell, float], float | None], bool]
    needs_overlap: bool = False


def _contact(cells: Mapping[Cell, float], overlap: float | None) -> bool:
    return bool(np.mean(quadratic_means(cells)) <= CONTACT_TARGET)


def _viewpoints(cells: Mapping[Cell, float], overlap: float | None) -> bool:
    return at_study(cells) and overlap is not None and overlap <= MAX_OVERLAP


CRITERIA = {
    "study": Criterion(
        "study",
        "all six cells at or below the study's 3-D RMSE",
        lambda cells, overlap: at_study(cells),
    ),
    "contact": Criterion(
        "contact",
        f"the arms' quadratic mean, averaged over the trajectories, at or below "
        f"{CONTACT_TARGET:g} m (floor 0.05 m)",
        _contact,
    ),
    "viewpoints": Criterion(
        "viewpoints",
        f"all six cells at or below the study's 3-D RMSE, the arms' deepest overlap at or below "
        f"{1000 * MAX_OVERLAP:g} mm",
        _viewpoints,
        needs_overlap=True,
    ),
}
