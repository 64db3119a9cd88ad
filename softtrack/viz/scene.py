"""Drawing one instant of a scene: both rods as tubes of their real radius, the clamps, the
target (and the viewpoint goals), the held sphere, contact forces as arrows, and the time and
the tips' errors in a corner.

:class:`SceneRenderer` draws a :class:`SceneFrame` to an (H, W, 3) uint8 array with the
z-buffered rasteriser of :mod:`softtrack.viz.raster`, and the arrows and text with
:mod:`softtrack.viz.overlay`. Headless: no
window, no display, no OpenGL.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from PIL import Image, ImageDraw

from softtrack.viz.camera import FRONT, Camera
from softtrack.viz.overlay import draw_arrow, draw_ring, draw_text
from softtrack.viz.raster import Canvas

__all__ = ["ARM_COLORS", "SceneFrame", "SceneRenderer"]

#: Arm 1 blue, arm 2 orange (the report's colours).
ARM_COLORS: tuple[tuple[int, int, int], ...] = ((46, 110, 190), (230, 126, 34))
_TARGET_COLOR = (214, 39, 40)
_GOAL_COLOR = (150, 60, 170)
_SPHERE_COLOR = (90, 170, 90)
_CLAMP_COLOR = (70, 70, 78)
_ARROW_COLOR = (250, 200, 20)
_TEXT_COLOR = (20, 20, 24)
_SKY_TOP, _SKY_BOTTOM = np.array([236, 240, 246]), np.array([206, 212, 222])
_FLOOR_LINE = (178, 184, 196)
_PATH_COLOR = (226, 120, 120)
#: An arrow's length: this many metres times the square root of its force in newtons (a
#: sphere's few newtons and the arms' tens both readable), at most 0.25 m.
ARROW_M_PER_SQRT_N = 0.03
_ARROW_MAX_M = 0.25


@dataclass
class SceneFrame:
    """One instant of a scene, world coordinates in m (y up).

    Attributes:
        rods: (A, 3, N) the arms' centreline nodes.
        radius: the rods' radius, m.
        bases: (A, 3) the clamps' positions.
        time: s since the episode's start.
        target: (3,) the target's centre, or ``None``.
        target_radius: m.
        goals: (A, 3) each tip's own point where it differs from the target (the viewpoints
            task), or ``None``.
        sphere: (3,) the held sphere's centre (transport), or ``None``.
        sphere_radius: m.
        contacts: (point (3,), force (3,) N) pairs drawn as arrows from the point.
        errors: ``{label: distance m}`` shown in the corner: each tip's distance to its
            point (``arm 1``, ``arm 2``), or the sphere's to its goal (``sphere``).
        label: a line drawn above the numbers (e.g. the controller's name).
        path: (P, 3) the target's path over the episode, drawn as a thin line, or ``None``.
    """

    rods: np.ndarray
    radius: float
    bases: np.ndarray
    time: float
    target: np.ndarray | None = None
    target_radius: float = 0.05
    goals: np.ndarray | None = None
    sphere: np.ndarray | None = None
    sphere_radius: float = 0.05
    contacts: Sequence[tuple[np.ndarray, np.ndarray]] = field(default_factory=tuple)
    errors: Mapping[str, float] = field(default_factory=dict)
    label: str | None = None
    path: np.ndarray | None = None


class SceneRenderer:
    """Draws :class:`SceneFrame` s from a fixed camera.

    Args:
        width, height: the image size in pixels.
        camera: the view (default :data:`~softtrack.viz.camera.FRONT`).
    """

    def __init__(self, width: int = 640, height: int = 480, camera: Camera = FRONT) -> None:
        self.width, self.height, self.camera = int(width), int(height), camera
        self.focal = camera.focal(self.height)
        self._text_size = max(11, self.height // 32)
        self._rgb = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._depth = np.empty((self.height, self.width), dtype=np.float32)

    @cached_property
    def _background(self) -> np.ndarray:
        """(H, W, 3) uint8: a soft gradient and the floor's grid (y = 0), drawn once."""
        rows = np.linspace(0.0, 1.0, self.height)[:, None, None]
        sky = (_SKY_TOP * (1.0 - rows) + _SKY_BOTTOM * rows).astype(np.uint8)
        image = Image.fromarray(np.broadcast_to(sky, (self.height, self.width, 3)).copy())
        draw = ImageDraw.Draw(image)
        ticks = np.linspace(-0.8, 0.8, 9)
        for fixed in ticks:
            for line in (
                np.stack([ticks * 0 + fixed, ticks * 0, ticks], axis=1),
                np.stack([ticks, ticks * 0, ticks * 0 + fixed], axis=1),
            ):
                uvz = self.camera.project(line[[0, -1]], self.width, self.height)
                if (uvz[:, 2] > 0).all():
                    draw.line([tuple(uvz[0, :2]), tuple(uvz[1, :2])], fill=_FLOOR_LINE, width=1)
        return np.asarray(image)

    def render(self, frame: SceneFrame) -> np.ndarray:
        """(H, W, 3) uint8: ``frame`` drawn (a new array each call)."""
        project = self._project
        background = self._background
        if frame.path is not None and len(frame.path) > 1:
            background = self._with_path(frame.path)
        np.copyto(self._rgb, background)
        self._depth.fill(np.inf)
        canvas = Canvas(self._rgb, self._depth)
        bases = np.asarray(frame.bases, float)
        rods = np.asarray(frame.rods, float)
        below = bases - np.array([0.0, 0.06, 0.0])
        nodes = project(np.concatenate([below, bases, rods.transpose(0, 2, 1).reshape(-1, 3)]))
        n_bases, n_nodes = len(bases), rods.shape[2]
        ends = nodes[2 * n_bases :].reshape(len(rods), n_nodes, 3)
        starts = np.concatenate([nodes[:n_bases], ends[:, :-1].reshape(-1, 3)])
        stops = np.concatenate([nodes[n_bases : 2 * n_bases], ends[:, 1:].reshape(-1, 3)])
        radii = np.r_[
            np.full(n_bases, 1.5 * frame.radius), np.full(len(rods) * (n_nodes - 1), frame.radius)
        ]
        arm_colors = [ARM_COLORS[arm % len(ARM_COLORS)] for arm in range(len(rods))]
        colors = np.array(
            [_CLAMP_COLOR] * n_bases + [c for c in arm_colors for _ in range(n_nodes - 1)]
        )
        canvas.capsules(starts, stops, radii, self.focal, colors)
        if frame.sphere is not None:
            canvas.sphere(project(frame.sphere), frame.sphere_radius, self.focal, _SPHERE_COLOR)
        if frame.target is not None:
            alpha = 0.45 if frame.sphere is None else 0.3
            centre = project(frame.target)
            canvas.sphere(centre, frame.target_radius, self.focal, _TARGET_COLOR, alpha)
            if centre[2] > frame.target_radius:  # its outline stays visible behind an arm
                ring = self.focal * frame.target_radius / centre[2]
                draw_ring(self._rgb, (centre[0], centre[1]), ring, _TARGET_COLOR)
        if frame.goals is not None:
            for goal in np.asarray(frame.goals, float):
                canvas.sphere(
                    project(goal), 0.4 * frame.target_radius, self.focal, _GOAL_COLOR, 0.6
                )
        self._arrows(frame.contacts)
        draw_text(self._rgb, (10, 8), self._caption(frame), _TEXT_COLOR, self._text_size)
        return self._rgb.copy()

    def _with_path(self, path: np.ndarray) -> np.ndarray:
        """The background with the target's path drawn on it (cached for the last path)."""
        key = (id(path), len(path))
        if getattr(self, "_path_key", None) != key:
            image = Image.fromarray(self._background)
            uvz = self._project(np.asarray(path, float)[:: max(1, len(path) // 400)])
            points = [(float(u), float(v)) for u, v, z in uvz if z > 0]
            ImageDraw.Draw(image).line(points, fill=_PATH_COLOR, width=1)
            self._path_key, self._path_image = key, np.asarray(image)
        return self._path_image

    def _project(self, points: np.ndarray) -> np.ndarray:
        return self.camera.project(np.asarray(points, float), self.width, self.height)

    def _arrows(self, contacts: Sequence[tuple[np.ndarray, np.ndarray]]) -> None:
        for point, force in contacts:
            force = np.asarray(force, float)
            magnitude = float(np.linalg.norm(force))
            if not np.isfinite(magnitude) or magnitude <= 0.0:
                continue
            length = min(_ARROW_MAX_M, ARROW_M_PER_SQRT_N * float(np.sqrt(magnitude)))
            start = np.asarray(point, float)
            end = start + force / magnitude * length
            (u0, v0, z0), (u1, v1, z1) = self._project(np.stack([start, end]))
            if z0 > 0 and z1 > 0:
                draw_arrow(self._rgb, (u0, v0), (u1, v1), _ARROW_COLOR)

    @staticmethod
    def _caption(frame: SceneFrame) -> list[str]:
        lines = [] if frame.label is None else [frame.label]
        lines.append(f"t = {frame.time:5.2f} s")
        if frame.errors:
            lines.append(
                "  ".join(f"{name}: {value:.3f} m" for name, value in frame.errors.items())
            )
        return lines
