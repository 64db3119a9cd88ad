"""The study's published values (docs/environment.md and §5) as data, for display beside measured numbers.

Only what the study publishes is here: the 3-D RMSE per trajectory and arm for centralized TD3 and
for the independent single-arm TD3 baseline, the peak element moments during the figure-eight,
and the training budget. The study's final-stage returns (its Table 3), its axis RMSE/MAE and
mean spatial errors are not published, so they have no reference value (``None``).

Beside them, docs/environment.md states the action statistics of this project's calibration prototype
(a TD3 prototype, not the study), as a yardstick for "bang-bang" control.
"""

from __future__ import annotations

from typing import Final

__all__ = [
    "CALIBRATION_ACTION_CHANGE",
    "CALIBRATION_ACTION_SATURATION",
    "STUDY_ALGORITHMS",
    "STUDY_BUDGET_TEXT",
    "STUDY_PEAK_MOMENTS",
    "STUDY_PEAK_MOMENT_TRAJECTORY",
    "STUDY_RMSE_3D",
    "STUDY_SEEDS",
    "STUDY_TOTAL_TIMESTEPS",
    "STUDY_TRAINING_HARDWARE",
    "STUDY_TRAINING_HOURS",
    "TRAJECTORY_TITLES",
    "study_peak_moment",
    "study_rmse_3d",
]

#: 3-D RMSE (m) of the study, ``[controller][trajectory] = (arm 1, arm 2)``; TD3 only (docs/environment.md).
STUDY_RMSE_3D: Final[dict[str, dict[str, tuple[float, float]]]] = {
    "centralized": {
        "circle": (0.065, 0.043),
        "rectangle": (0.054, 0.050),
        "figure8": (0.062, 0.053),
    },
    "independent": {
        "circle": (0.054, 0.059),
        "rectangle": (0.067, 0.064),
        "figure8": (0.070, 0.066),
    },
}

#: Peak absolute element moment (N·m) over both arms during the figure-eight (docs/environment.md).
STUDY_PEAK_MOMENTS: Final[dict[str, float]] = {"normal": 138.9, "binormal": 121.7}
STUDY_PEAK_MOMENT_TRAJECTORY: Final[str] = "figure8"

#: The study's training protocol (docs/environment.md).
STUDY_TOTAL_TIMESTEPS: Final[int] = 10_000_000  # env steps per run
STUDY_TRAINING_HOURS: Final[float] = 8.5  # wall-clock hours per run
STUDY_TRAINING_HARDWARE: Final[str] = "laptop i7 + RTX 4070"
STUDY_SEEDS: Final[tuple[int, ...]] = (0, 1, 2)
STUDY_ALGORITHMS: Final[tuple[str, ...]] = ("td3", "ddpg", "ppo")
STUDY_BUDGET_TEXT: Final[str] = (
    f"{STUDY_TOTAL_TIMESTEPS:,} env steps per run ({STUDY_TRAINING_HOURS:g} h on a "
    f"{STUDY_TRAINING_HARDWARE}), seeds {', '.join(map(str, STUDY_SEEDS))}"
)

#: The calibration prototype's actions (docs/environment.md, last paragraph): saturated at ±1 66 % of the
#: time, changed by 0.30 on average from one control step to the next.
CALIBRATION_ACTION_SATURATION: Final[float] = 0.66  # fraction of action values
CALIBRATION_ACTION_CHANGE: Final[float] = 0.30  # mean |Δa| per control step

#: Display names of the evaluation trajectories.
TRAJECTORY_TITLES: Final[dict[str, str]] = {
    "circle": "circle",
    "rectangle": "rectangle",
    "figure8": "figure-eight",
}


def study_rmse_3d(algo: str, controller: str, trajectory: str, arm: int) -> float | None:
    """The study's 3-D RMSE (m) for arm ``arm`` (0 or 1), or ``None`` if it reported none.

    The study reported TD3 only (centralized, and the independent baseline).
    """
    if algo.lower() != "td3":
        return None
    values = STUDY_RMSE_3D.get(controller, {}).get(trajectory)
    if values is None or arm not in (0, 1):
        return None
    return values[arm]


def study_peak_moment(algo: str, controller: str, trajectory: str, direction: str) -> float | None:
    """The study's peak element moment (N·m, both arms) for ``direction`` ``normal`` or
    ``binormal``; only centralized TD3 on the figure-eight has one."""
    if algo.lower() != "td3" or controller != "centralized":
        return None
    if trajectory != STUDY_PEAK_MOMENT_TRAJECTORY:
        return None
    return STUDY_PEAK_MOMENTS.get(direction)
