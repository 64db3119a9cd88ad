"""A pinhole camera: world points (m, y up) to pixels and depths."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

__all__ = ["FRONT", "TOP", "Camera"]


@dataclass(frozen=True)
class Camera:
    """A perspective camera looking from ``eye`` at ``look_at`` (world coordinates, m; y is
    up, the arms' rest direction), with a vertical field of view ``fov_deg``."""

    eye: tuple[float, float, float]
    look_at: tuple[float, float, float]
    fov_deg: float = 40.0
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def basis(self) -> np.ndarray:
        """(3, 3) rows: the camera's right, up and forward unit vectors in world coordinates."""
        return _basis(self.eye, self.look_at, self.up)

    def focal(self, height: int) -> float:
        """The focal length in pixels for an image ``height`` pixels high."""
        return 0.5 * height / float(np.tan(np.radians(self.fov_deg) / 2.0))

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """(..., 3) world points → (..., 3): pixel column, pixel row (down) and depth along
        the view direction (m; ≤ 0 behind the camera)."""
        local = (np.asarray(points, float) - np.asarray(self.eye, float)) @ self.basis().T
        depth = local[..., 2]
        safe = np.where(depth > 1e-6, depth, 1e-6)
        f = self.focal(height)
        u = 0.5 * width + f * local[..., 0] / safe
        v = 0.5 * height - f * local[..., 1] / safe
        return np.stack([u, v, depth], axis=-1)


@cache
def _basis(
    eye_at: tuple[float, float, float],
    look_at: tuple[float, float, float],
    up_vector: tuple[float, float, float],
) -> np.ndarray:
    eye, target = np.asarray(eye_at, float), np.asarray(look_at, float)
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(up_vector, float))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    basis = np.stack([right, up, forward])
    basis.flags.writeable = False
    return basis


#: The default view: in front of the arms, a little to the right and above, the whole reach
#: (the arms' bases at y = 0, their 1-m length up to y = 1) in the frame.
FRONT = Camera(eye=(1.0, 1.1, 2.1), look_at=(0.0, 0.48, 0.0), fov_deg=41.0)
#: Looking down the arms from above (the target paths lie in horizontal planes).
TOP = Camera(eye=(0.0, 2.9, 0.001), look_at=(0.0, 0.5, 0.0), fov_deg=34.0, up=(0.0, 0.0, -1.0))
