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

* ``transport`` (cooperative transport, :mod:`softtrack.env.transport_env`): the two arms hold
  a rigid sphere (``SimParams.sphere``) between their tips, and the sphere's centre must
  follow the target. The goal starts at the sphere's centre and moves to the path's start
  over ``approach`` seconds (a smoothstep), then follows the path from its t = 0; the episode
  ends early when no arm has touched the sphere for ``drop_grace`` seconds (a drop).

The observation keeps the study's 81 values in the shared and viewpoints tasks: the target
block (indices 74–80) holds the target centre, its speed and direction; an arm's point is that
centre plus the task's fixed offset, so the policy needs nothing more. The transport task's
layout is in :mod:`softtrack.env.transport_env` (88 values).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from softtrack.numbers import out_of_range, setting
from softtrack.sim.actuation import N_CONTROL_POINTS

__all__ = ["N_ARMS", "TASKS", "TaskConfig"]

#: Arms of the dual-arm scene. An independent run trains one policy per arm, each to the
#: spec's ``training.total_timesteps`` (run.json ``arm_total_timesteps``; ``total_timesteps``
#: is their sum).
N_ARMS = 2
TASKS = ("shared", "viewpoints", "transport")


@dataclass(frozen=True)
class TaskConfig:
    """Which point each arm tracks.

    Attributes:
        name: ``shared``, ``viewpoints`` or ``transport`` (module docstring).
        standoff: d, the distance of each arm's point from the target centre along x in the
            ``viewpoints`` task, m (ignored by the others).
        approach: transport: seconds over which the goal moves from the sphere's start to
            the path's start.
        drop_grace: transport: seconds without contact between the sphere and either arm
            after which the sphere counts as dropped and the episode ends.
        hold_bonus: transport: reward per arm touching the sphere on a control step.
        squeeze_band: transport: (low, high) band of each arm's mean contact force on the
            sphere, N; (0, 0) = no force regulation.
        squeeze_penalty: transport: weight c_f of −c_f·(e/high)² per arm, e the force's
            distance from the band, N.
        drop_penalty: transport: subtracted on the step of a drop.
        reach_penalty: transport: c_reach, the weight of −c_reach·Σᵢ gᵢ with gᵢ the gap
            between arm i's nearest node's surface and the sphere's, m (0 while it touches):
            leads the arms to the sphere.
        bonus_needs_grip: transport: the study's distance bonuses count only on steps when
            both arms touch the sphere (a sphere left where the goal starts earns nothing).
        grip: transport: a constant squeeze added to the normal control values (arm 1 −grip,
            arm 2 +grip: both curl onto the sphere) before they are clipped to [−1, 1], so a
            zero action holds the sphere and a policy learns what to add to the squeeze.
    """

    name: str = setting("shared", number=False)
    standoff: float = setting(0.1, "m", ge=0)
    approach: float = setting(2.0, "s", ge=0)
    drop_grace: float = setting(0.5, "s", ge=0)
    hold_bonus: float = setting(0.25, "reward units", ge=0)
    squeeze_band: tuple[float, float] = setting((0.0, 0.0), "N", number=False)
    squeeze_penalty: float = setting(0.0, "reward units", ge=0)
    drop_penalty: float = setting(100.0, "reward units", ge=0)
    reach_penalty: float = setting(2.0, "reward units per m", ge=0)
    bonus_needs_grip: bool = setting(True, number=False)
    grip: float = setting(0.0, ge=-1, le=1)

    @property
    def carries_object(self) -> bool:
        """True for the transport task."""
        return self.name == "transport"

    def validate(self) -> None:
        """Raise ``ValueError`` naming the invalid field and the fix."""
        if self.name not in TASKS:
            raise ValueError(f"task {self.name!r} is unknown; use one of {', '.join(TASKS)}")
        problem = out_of_range(self)
        if problem is not None:
            raise ValueError(problem)
        band = self.squeeze_band
        if (
            len(band) != 2
            or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in band)
            or not 0 <= band[0] <= band[1]
        ):
            raise ValueError(
                f"squeeze_band={band!r} must be (low, high) with 0 ≤ low ≤ high N; "
                "(0, 0) switches force regulation off"
            )
        if self.grip and not self.carries_object:
            raise ValueError(
                f"grip={self.grip!r} squeezes a sphere, which only the transport task has; "
                "set task name: transport or grip: 0"
            )
        if self.squeeze_penalty > 0 and band[1] == 0:
            raise ValueError(
                f"squeeze_penalty={self.squeeze_penalty!r} needs a squeeze_band (low, high) "
                "with high > 0 N, e.g. (5, 40)"
            )

    def action_offset(self) -> np.ndarray:
        """(24,) what is added to the dual-arm action before clipping: −grip on arm 1's six
        normal control values, +grip on arm 2's (zeros without a grip)."""
        offset = np.zeros(N_ARMS * 2 * N_CONTROL_POINTS)
        offset[0:N_CONTROL_POINTS] = -self.grip
        offset[2 * N_CONTROL_POINTS : 3 * N_CONTROL_POINTS] = self.grip
        return offset

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
