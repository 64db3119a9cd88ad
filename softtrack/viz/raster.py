"""A small z-buffered software rasteriser for what the scenes are made of: capsules (a rod's
elements, the clamps) and spheres, shaded as lit 3-D solids, in NumPy.

Each capsule is drawn over its own bounding box by one compiled loop (numba, cached on disk):
per pixel the distance to the projected axis, the depth of the surface there against the
depth buffer, and Lambert and specular shading from a fixed light (docs/rendering.md has
the measured speed).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["Canvas"]

#: Light direction in camera coordinates (right, up, towards the viewer), normalised.
_LIGHT = np.array([-0.45, 0.6, 0.66]) / np.linalg.norm([-0.45, 0.6, 0.66])
_LX, _LY, _LZ = (float(x) for x in _LIGHT)
_AMBIENT = 0.38
_DIFFUSE = 0.62
_SPECULAR = 0.35


class Canvas:
    """An RGB image with a depth buffer.

    Args:
        rgb: (H, W, 3) uint8, drawn on in place.
        depth: (H, W) float32 depth buffer (m; ``inf``: nothing there), updated in place;
            default all ``inf``.
    """

    def __init__(self, rgb: np.ndarray, depth: np.ndarray | None = None) -> None:
        self.rgb = rgb
        self.height, self.width = rgb.shape[:2]
        if depth is None:
            depth = np.full((self.height, self.width), np.inf, dtype=np.float32)
        self.depth = depth

    def image(self) -> np.ndarray:
        """(H, W, 3) uint8."""
        return self.rgb

    def capsules(
        self,
        a: np.ndarray,
        b: np.ndarray,
        radius: float | np.ndarray,
        focal: float,
        colors: np.ndarray,
        alpha: float = 1.0,
    ) -> None:
        """Solid swept spheres from ``a`` to ``b`` ((C, 3) each, projected: pixel column, row
        and depth in m), of ``radius`` m (scalar or (C,)), coloured ``colors`` ((C, 3) or
        (3,), 0–255); ``focal``: the camera's focal length in pixels. ``alpha`` < 1 blends
        them over what is behind without hiding it (and without writing depth)."""
        a = np.ascontiguousarray(np.atleast_2d(a), dtype=np.float64)
        b = np.ascontiguousarray(np.atleast_2d(b), dtype=np.float64)
        count = len(a)
        radii = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, np.float64), (count,)))
        shades = np.ascontiguousarray(np.broadcast_to(np.asarray(colors, np.float64), (count, 3)))
        _draw_capsules(self.rgb, self.depth, a, b, radii, float(focal), shades, float(alpha))

    def capsule(
        self,
        a: np.ndarray,
        b: np.ndarray,
        radius: float,
        focal: float,
        color: tuple[int, int, int],
        alpha: float = 1.0,
    ) -> None:
        """One capsule (see :meth:`capsules`): ``a``, ``b`` (3,) projected."""
        self.capsules(
            np.asarray(a)[None], np.asarray(b)[None], radius, focal, np.asarray(color), alpha
        )

    def sphere(
        self,
        centre: np.ndarray,
        radius: float,
        focal: float,
        color: tuple[int, int, int],
        alpha: float = 1.0,
    ) -> None:
        """A lit sphere of ``radius`` m at ``centre`` (pixel column, row, depth)."""
        self.capsule(centre, centre, radius, focal, color, alpha)


@njit(cache=True)
def _draw_capsules(
    rgb: np.ndarray,
    zbuf: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    radius: np.ndarray,
    focal: float,
    colors: np.ndarray,
    alpha: float,
) -> None:  # pragma: no cover  (compiled; tested through Canvas)
    height, width = zbuf.shape
    for k in range(a.shape[0]):
        ua, va, za = a[k, 0], a[k, 1], a[k, 2]
        ub, vb, zb = b[k, 0], b[k, 1], b[k, 2]
        r = radius[k]
        if za <= r or zb <= r:
            continue
        rho_a, rho_b = focal * r / za, focal * r / zb
        reach = max(rho_a, rho_b)
        u0 = max(0, int(math.floor(min(ua, ub) - reach)))  # noqa: RUF046 (numba)
        u1 = min(width, int(math.ceil(max(ua, ub) + reach)) + 1)  # noqa: RUF046
        v0 = max(0, int(math.floor(min(va, vb) - reach)))  # noqa: RUF046
        v1 = min(height, int(math.ceil(max(va, vb) + reach)) + 1)  # noqa: RUF046
        du, dv = ub - ua, vb - va
        length2 = du * du + dv * dv
        for row in range(v0, v1):
            pv = row + 0.5
            for col in range(u0, u1):
                pu = col + 0.5
                t = 0.0
                if length2 > 1e-9:
                    t = min(1.0, max(0.0, ((pu - ua) * du + (pv - va) * dv) / length2))
                off_u, off_v = pu - (ua + t * du), pv - (va + t * dv)
                rho = rho_a + t * (rho_b - rho_a)
                s2 = (off_u * off_u + off_v * off_v) / max(rho * rho, 1e-9)
                if s2 >= 1.0:
                    continue
                bulge = math.sqrt(1.0 - s2)
                depth = za + t * (zb - za) - bulge * r
                if depth >= zbuf[row, col]:
                    continue
                lambert = max(0.0, off_u / rho * _LX - off_v / rho * _LY + bulge * _LZ)
                highlight = max(0.0, 2.0 * lambert * bulge - _LZ) ** 12
                light = _AMBIENT + _DIFFUSE * lambert
                for channel in range(3):
                    value = min(255.0, light * colors[k, channel] + _SPECULAR * 255.0 * highlight)
                    if alpha < 1.0:
                        value = (1.0 - alpha) * rgb[row, col, channel] + alpha * value
                    rgb[row, col, channel] = np.uint8(value)
                if alpha >= 1.0:
                    zbuf[row, col] = depth
