"""Flat drawing on top of a rendered frame, in NumPy: lines, arrows, rings and text.

Text is drawn from glyph masks that Pillow renders once per character and size, so a caption
costs a few array copies per frame instead of a font rasterisation.
"""

from __future__ import annotations

from functools import cache

import numpy as np
from PIL import ImageFont

__all__ = ["draw_arrow", "draw_line", "draw_ring", "draw_text"]


def _blend(
    rgb: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    color: tuple[int, int, int],
    cover: np.ndarray | float = 1.0,
) -> None:
    height, width = rgb.shape[:2]
    keep = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
    rows, cols = rows[keep], cols[keep]
    weight = np.broadcast_to(np.asarray(cover, np.float32), keep.shape)[keep][:, None]
    under = rgb[rows, cols].astype(np.float32)
    rgb[rows, cols] = (under * (1.0 - weight) + np.asarray(color, np.float32) * weight).astype(
        np.uint8
    )


def draw_line(
    rgb: np.ndarray,
    start: tuple[float, float],
    end: tuple[float, float],
    color: tuple[int, int, int],
    width: int = 1,
) -> None:
    """A line from ``start`` to ``end`` (pixel column, row), ``width`` pixels thick."""
    (u0, v0), (u1, v1) = start, end
    n = int(max(abs(u1 - u0), abs(v1 - v0))) + 2
    us, vs = np.linspace(u0, u1, n), np.linspace(v0, v1, n)
    half = (width - 1) // 2
    offsets = np.arange(-half, width - half)
    rows = (np.round(vs)[:, None, None] + offsets[None, :, None]).astype(np.int64).ravel()
    cols = (np.round(us)[:, None, None] + offsets[None, None, :]).astype(np.int64).ravel()
    key = np.unique(rows * rgb.shape[1] + cols + rgb.shape[1])  # each pixel once
    _blend(rgb, key // rgb.shape[1] - 1, key % rgb.shape[1], color)


def draw_arrow(
    rgb: np.ndarray,
    start: tuple[float, float],
    end: tuple[float, float],
    color: tuple[int, int, int],
) -> None:
    """An arrow from ``start`` to ``end`` (pixels): a 3-px shaft, a head and a dot at the start."""
    draw_line(rgb, start, end, color, width=3)
    direction = np.subtract(end, start).astype(float)
    norm = float(np.hypot(*direction))
    if norm > 1e-6:
        direction /= norm
        side = np.array([-direction[1], direction[0]])
        for sign in (1.0, -1.0):
            barb = np.asarray(end) - 8.0 * direction + sign * 4.0 * side
            draw_line(rgb, tuple(barb), end, color, width=2)
    draw_ring(rgb, start, 2.5, color, filled=True)


def draw_ring(
    rgb: np.ndarray,
    centre: tuple[float, float],
    radius: float,
    color: tuple[int, int, int],
    filled: bool = False,
) -> None:
    """A 1-px anti-aliased circle (or, ``filled``, a disc) of ``radius`` pixels."""
    u, v = centre
    reach = int(np.ceil(radius)) + 2
    rows = np.arange(int(v) - reach, int(v) + reach + 1)[:, None]
    cols = np.arange(int(u) - reach, int(u) + reach + 1)[None, :]
    distance = np.hypot(cols + 0.5 - u, rows + 0.5 - v)
    cover = (
        np.clip(radius + 0.5 - distance, 0.0, 1.0)
        if filled
        else np.clip(1.0 - np.abs(distance - radius), 0.0, 1.0)
    )
    rows, cols = np.broadcast_arrays(rows, cols)
    mask = cover > 0.0
    _blend(rgb, rows[mask], cols[mask], color, cover[mask])


@cache
def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    return ImageFont.load_default(size=size)


@cache
def _glyph(char: str, size: int) -> np.ndarray:
    """One character's coverage (0–1) in a cell one line high and one advance wide."""
    font = _font(size)
    height, advance = _line_height(size), max(1, round(font.getlength(char)))
    mask = font.getmask(char, mode="L")
    width, rows = mask.size
    left, top = (max(0, int(v)) for v in font.getbbox(char)[:2])
    cell = np.zeros((height, max(advance, left + width)), dtype=np.float32)
    kept = max(0, min(rows, height - top))
    if width and kept:
        pixels = np.asarray(mask, dtype=np.uint8).reshape(rows, width).astype(np.float32) / 255.0
        cell[top : top + kept, left : left + width] = pixels[:kept]
    return cell


def _line_height(size: int) -> int:
    return round(size * 1.25)


def draw_text(
    rgb: np.ndarray, xy: tuple[int, int], lines: list[str], color: tuple[int, int, int], size: int
) -> None:
    """``lines`` from the top-left ``xy`` (pixels) in Pillow's default font of ``size`` px:
    each line's glyph cells side by side, blended over the frame in one operation."""
    x, y = xy
    height, width = rgb.shape[:2]
    paint = np.asarray(color, np.float32)
    for line in lines:
        if line:
            cover = np.concatenate([_glyph(char, size) for char in line], axis=1)
            h = min(cover.shape[0], height - y)
            w = min(cover.shape[1], width - x)
            if h > 0 and w > 0:
                region = rgb[y : y + h, x : x + w]
                weight = cover[:h, :w, None]
                region[:] = (region * (1.0 - weight) + paint * weight).astype(np.uint8)
        y += _line_height(size)
