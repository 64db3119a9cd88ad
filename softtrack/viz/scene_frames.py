"""Scene frames from plain arrays (:func:`scene_frame`): the environments draw their state
with it (``softtrack.env.render``), animations a recorded episode's instants
(``softtrack.evaluation.rollout_frames``)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from softtrack.viz.scene import SceneFrame

__all__ = ["closest_points", "contact_arrows", "scene_frame"]


def closest_points(rod_a: np.ndarray, rod_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nearest points of two polylines ((3, N) nodes each, m): (3,) on ``rod_a`` and
    (3,) on ``rod_b`` (node-to-segment distances in both directions; exact for the rods'
    short elements to well below their radius)."""
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    for nodes, other, flip in ((rod_a.T, rod_b.T, False), (rod_b.T, rod_a.T, True)):
        start, end = other[:-1], other[1:]
        seg = end - start
        length2 = np.maximum((seg * seg).sum(axis=1), 1e-12)
        t = np.clip(((nodes[:, None, :] - start[None]) * seg[None]).sum(-1) / length2, 0.0, 1.0)
        foot = start[None] + t[..., None] * seg[None]
        gap = np.linalg.norm(nodes[:, None, :] - foot, axis=-1)
        i, j = np.unravel_index(int(np.argmin(gap)), gap.shape)
        if best is None or gap[i, j] < best[0]:
            pair = (foot[i, j], nodes[i]) if flip else (nodes[i], foot[i, j])
            best = (float(gap[i, j]), pair[0], pair[1])
    assert best is not None
    return best[1], best[2]


def contact_arrows(
    rods: np.ndarray,
    radius: float,
    contact_force: float,
    sphere: np.ndarray | None = None,
    sphere_radius: float = 0.05,
    object_force: np.ndarray | None = None,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Arrows of the contact forces, (point, force N) each: where the two arms touch, the
    force on arm 2 at the middle of their nearest points (and its opposite on arm 1); on the
    sphere, each arm's force at the sphere's surface towards that arm's nearest node, pointing
    into the sphere."""
    arrows: list[tuple[np.ndarray, np.ndarray]] = []
    if len(rods) >= 2 and contact_force > 0.0:
        on_a, on_b = closest_points(rods[0], rods[1])
        gap = on_b - on_a
        norm = float(np.linalg.norm(gap))
        if norm > 1e-9:
            direction = gap / norm
            middle = 0.5 * (on_a + on_b)
            arrows += [(middle, contact_force * direction), (middle, -contact_force * direction)]
    if sphere is not None and object_force is not None:
        for arm, force in enumerate(np.asarray(object_force, float)):
            if arm >= len(rods) or not force > 0.0:
                continue
            nodes = rods[arm].T
            nearest = nodes[int(np.argmin(np.linalg.norm(nodes - sphere, axis=1)))]
            towards = nearest - sphere
            norm = float(np.linalg.norm(towards))
            if norm > 1e-9:
                outward = towards / norm
                arrows.append((sphere + sphere_radius * outward, -force * outward))
    return arrows


def scene_frame(
    rods: np.ndarray,
    radius: float,
    bases: np.ndarray | Sequence[Sequence[float]],
    time: float,
    tips: np.ndarray,
    target: np.ndarray,
    *,
    target_radius: float = 0.05,
    goal_offsets: np.ndarray | None = None,
    arm_numbers: Sequence[int] | None = None,
    sphere: np.ndarray | None = None,
    sphere_radius: float = 0.05,
    contact_force: float = 0.0,
    object_force: np.ndarray | None = None,
    label: str | None = None,
    path: np.ndarray | None = None,
) -> SceneFrame:
    """The frame of one instant (world coordinates, m).

    Args:
        rods: (A, 3, N) nodes; ``radius``: the rods' radius; ``bases``: (A, 3) clamps.
        tips: (A, 3) the tips (their errors are shown).
        target: (3,) the target's centre (transport: the sphere's goal).
        goal_offsets: (A, 3) each arm's point relative to the target (viewpoints task).
        arm_numbers: the arms' 0-based numbers in the dual-arm scene (default 0, 1, ...).
        sphere: (3,) the held sphere (transport), with ``object_force`` (A,) N on it.
        contact_force: N between the arms (an arrow each way where they are nearest).
        path: (P, 3) the target's path, drawn as a line.
    """
    rods = np.asarray(rods, float)
    target = np.asarray(target, float)
    offsets = np.zeros((len(rods), 3)) if goal_offsets is None else np.asarray(goal_offsets, float)
    goals = target[None, :] + offsets[: len(rods)]
    if sphere is not None:
        errors = {"sphere": float(np.linalg.norm(np.asarray(sphere, float) - target))}
    else:
        distances = np.linalg.norm(np.asarray(tips, float) - goals, axis=-1)
        numbers = range(len(rods)) if arm_numbers is None else arm_numbers
        errors = {f"arm {a + 1}": float(d) for a, d in zip(numbers, distances, strict=True)}
    return SceneFrame(
        rods=rods,
        radius=float(radius),
        bases=np.asarray(bases, float)[: len(rods)],
        time=float(time),
        target=target,
        target_radius=float(target_radius),
        goals=goals if sphere is None and np.abs(offsets).max() > 0.0 else None,
        sphere=None if sphere is None else np.asarray(sphere, float),
        sphere_radius=float(sphere_radius),
        contacts=contact_arrows(rods, radius, contact_force, sphere, sphere_radius, object_force),
        errors=errors,
        label=label,
        path=path,
    )
