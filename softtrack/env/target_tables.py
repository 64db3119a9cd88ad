"""Closed-form targets computed many control steps ahead in one call.

A closed-form or held-out path target is a function of each environment's time alone, and a
validation or evaluation batch steps every environment by the same ``dt`` for thousands of
control steps. Computing the next :data:`ROWS_AHEAD` steps' states in one vectorised call
instead of one small call per step took the targets from about a third of a validation's time
to a few percent (``benchmarks/bench_validation.py``). The times are accumulated exactly as
stepping does (``t += dt``, in order), and each state is elementwise in its time, so a table
row is the state that stepping computes, bit for bit; every new table checks that on its last
row and, on a CPU where it did not hold, computes one step at a time instead.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["ROWS_AHEAD", "AheadTable"]

#: Control steps per table once stepping has gone on (10 s episodes of 2-ms steps: 5000).
ROWS_AHEAD = 256
#: Rows of the first table after a reset, and after a table left early (a step of some
#: environments only): short, so that stepping few steps at a time costs little.
FIRST_ROWS = 16

StateAt = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


class AheadTable:
    """The states of ``n`` environments at their next control steps.

    Args:
        state_at: maps times (k, n) (s) to positions and velocities (k, n, 3) (m, m/s), each
            element from its own time alone.
    """

    def __init__(self, state_at: StateAt) -> None:
        self._state_at = state_at
        self._dt = 0.0
        self._times = np.empty((0, 0))
        self._position = np.empty((0, 0, 3))
        self._velocity = np.empty((0, 0, 3))
        self._row = 0
        self.exact = True

    def clear(self) -> None:
        """Forget the table (a reset moved some environment's time or path)."""
        self._times = np.empty((0, 0))

    def state(self, time: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (n, 3) at ``time`` (n,), s, which the caller reached by
        adding ``dt`` to the previous step's times."""
        row = self._row
        if not (
            self.exact
            and dt == self._dt
            and row < len(self._times)
            and np.array_equal(self._times[row], time)
        ):
            if self.exact:  # a table left early (some environments rested): a short one
                used_up = len(self._times) > 0 and row >= len(self._times)
                self._build(time, dt, ROWS_AHEAD if used_up else FIRST_ROWS)
            if not self.exact:
                position, velocity = self._state_at(time[None])
                return position[0], velocity[0]
            row = 0
        self._row = row + 1
        return self._position[row], self._velocity[row]

    def _build(self, time: np.ndarray, dt: float, rows: int) -> None:
        steps = np.full((rows, len(time)), dt)
        steps[0] = time
        times = np.add.accumulate(steps, axis=0)
        position, velocity = self._state_at(times)
        last_position, last_velocity = self._state_at(times[-1:])
        self.exact = bool(
            np.array_equal(position[-1], last_position[0])
            and np.array_equal(velocity[-1], last_velocity[0])
        )
        self._dt, self._times, self._position, self._velocity = dt, times, position, velocity
        self._row = 0
