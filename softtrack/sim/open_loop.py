"""Open-loop rollouts: hold a sequence of actions (or element torques) and record the arms."""

from __future__ import annotations

from typing import Any

import numpy as np

from softtrack.sim.actuation import N_CONTROL_POINTS
from softtrack.sim.engine import RodBatch
from softtrack.sim.params import InvalidParameterError, SimParams

__all__ = ["rollout", "validate_open_loop_input"]


def validate_open_loop_input(
    actions: np.ndarray | None, element_torques: np.ndarray | None, params: SimParams
) -> tuple[str, np.ndarray]:
    """Check that exactly one input is given, with the right shape and finite values.

    Returns:
        ("actions" | "element_torques", the input as a float64 array).

    Raises:
        InvalidParameterError: with a message naming the problem and the expected shape.
    """
    if (actions is None) == (element_torques is None):
        raise InvalidParameterError("give exactly one of actions= or element_torques=")
    n_arms = params.n_arms
    if actions is not None:
        kind, given, trailing = "actions", actions, (n_arms, 2, N_CONTROL_POINTS)
    else:
        assert element_torques is not None  # exactly one is given
        kind, given, trailing = "element_torques", element_torques, (n_arms, 2, params.n_elem)
    data = np.asarray(given, dtype=np.float64)
    if data.ndim != 4 or data.shape[1:] != trailing or data.shape[0] < 1:
        expected = "(T, " + ", ".join(str(d) for d in trailing) + ")"
        raise InvalidParameterError(
            f"{kind} has shape {data.shape}; expected {expected} = "
            "[control step, arm, direction (0 normal, 1 binormal), "
            f"{'point' if kind == 'actions' else 'element'}] with T ≥ 1"
        )
    if not np.all(np.isfinite(data)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(data))[0])
        raise InvalidParameterError(f"{kind} contains a non-finite value at index {bad}")
    return kind, data


def rollout(
    actions: np.ndarray | None = None,
    element_torques: np.ndarray | None = None,
    **params: Any,
) -> dict[str, np.ndarray]:
    """Simulate both arms open-loop and record their state after every control step.

    Each control step's input is held for ``steps_per_action`` integration steps. Actions are
    mapped through the spline actuation matrix without clipping.

    Args:
        actions: (T, A, 2, 6) control values [control step, arm, direction (0 normal,
            1 binormal), point].
        element_torques: (T, A, 2, N) N·m, per-element couples bypassing the spline.
        **params: overrides of any :class:`~softtrack.sim.params.SimParams` field
            (``n_elem``, ``dt``, ``steps_per_action``, ``damping``, ``gravity``,
            ``torque_scale``, ...).

    Returns:
        ``t`` (T+1,) s; ``tip`` (T+1, A, 3) m; ``nodes`` (T+1, A, 3, N+1) m; ``velocities``
        (T+1, A, 3, N+1) m/s; ``directors`` (T+1, A, 3, 3, N); ``omegas`` (T+1, A, 3, N)
        rad/s local frame; ``element_torques`` (T, A, 2, N) N·m as applied. Index 0 is the
        initial (straight, resting) state.

    Raises:
        InvalidParameterError: unknown or invalid parameters (e.g. an unstable ``dt``),
            wrong input shapes, non-finite inputs.
    """
    p = SimParams.from_overrides(**params)
    kind, data = validate_open_loop_input(actions, element_torques, p)
    engine = RodBatch(1, p)
    n_steps = data.shape[0]
    nodes = np.empty((n_steps + 1, p.n_arms, 3, p.n_nodes))
    velocities = np.empty_like(nodes)
    directors = np.empty((n_steps + 1, p.n_arms, 3, 3, p.n_elem))
    omegas = np.empty((n_steps + 1, p.n_arms, 3, p.n_elem))
    applied = np.empty((n_steps, p.n_arms, 2, p.n_elem))

    def record(k: int) -> None:
        nodes[k] = engine.position[0]
        velocities[k] = engine.velocity[0]
        directors[k] = engine.directors[0]
        omegas[k] = engine.omega[0]

    record(0)
    for k in range(n_steps):
        if kind == "actions":
            engine.set_actions(data[k][None])
        else:
            engine.set_element_torques(data[k][None])
        applied[k] = engine.torques[0]
        engine.advance()
        record(k + 1)
    return {
        "t": np.arange(n_steps + 1) * p.control_dt,
        "tip": nodes[:, :, :, -1].copy(),
        "nodes": nodes,
        "velocities": velocities,
        "directors": directors,
        "omegas": omegas,
        "element_torques": applied,
    }
