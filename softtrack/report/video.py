"""Frames to files: MP4 (H.264 through the ffmpeg that ``imageio-ffmpeg`` ships: no system
download), GIF or a PNG film strip (and HTML pages, :func:`write_page`). Every file is written to a
temporary beside its destination and renamed into place, so a failed or interrupted write
leaves nothing half-written."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from softtrack.store.atomic import temp_name

__all__ = ["VIDEO_FORMATS", "VideoError", "film_strip", "video_format", "write_video"]

#: File suffixes :func:`write_video` writes, and what each is.
VIDEO_FORMATS = {
    ".mp4": "H.264 video",
    ".gif": "animated GIF",
    ".html": "a page that plays the runs in 3-D (softtrack.report.viewer)",
}


class VideoError(ValueError):
    """An animation cannot be written (an unknown format, a missing encoder, a bad path)."""


def video_format(path: str | os.PathLike[str]) -> str:
    """The format of ``path`` by its suffix (:data:`VIDEO_FORMATS`).

    Raises:
        VideoError: another suffix.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_FORMATS:
        known = ", ".join(VIDEO_FORMATS)
        raise VideoError(
            f"{path}: unknown animation format {suffix or '(none)'}; use one of {known}"
        )
    return suffix


def write_video(frames: Iterable[np.ndarray], path: str | os.PathLike[str], fps: float) -> Path:
    """Write (H, W, 3) uint8 ``frames`` to ``path`` (MP4 or GIF by suffix) at ``fps``.

    Raises:
        VideoError: another suffix, no ffmpeg, no frames, or the destination cannot be
            written (nothing is left behind).
    """
    path = Path(path)
    suffix = video_format(path)
    if suffix == ".html":
        raise VideoError(f"{path}: an .html page is written by softtrack animate, not as a video")
    if not path.parent.is_dir():
        raise VideoError(f"{path}: its directory {path.parent} does not exist; create it first")
    writer = _write_gif if suffix == ".gif" else _write_mp4
    return _write_atomically(path, lambda tmp: writer(frames, tmp, fps))


def write_page(text: str, path: str | os.PathLike[str]) -> Path:
    """Write an HTML page atomically.

    Raises:
        VideoError: the destination cannot be written (nothing is left behind).
    """
    return _write_atomically(Path(path), lambda tmp: tmp.write_text(text, encoding="utf-8"))


def _write_atomically(path: Path, write: Callable[[Path], object]) -> Path:
    """``write`` a temporary beside ``path``, then rename it into place; nothing is left
    behind on failure.

    Raises:
        VideoError: the destination cannot be written.
    """
    tmp = temp_name(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        raise VideoError(
            f"{path}: cannot be written ({exc.strerror or exc}); choose another --out"
        ) from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


def _write_mp4(frames: Iterable[np.ndarray], path: Path, fps: float) -> None:
    try:
        import imageio.v2 as imageio
        import imageio_ffmpeg  # noqa: F401  (the ffmpeg binary)
    except ImportError:
        raise VideoError(
            "MP4 and HTML need imageio and imageio-ffmpeg: pip install imageio imageio-ffmpeg "
            "(or write a .gif)"
        ) from None
    with warnings.catch_warnings():  # ffmpeg is a subprocess: JAX warns about any fork
        warnings.filterwarnings("ignore", message=".*os.fork.*", category=RuntimeWarning)
        _append_frames(imageio, frames, path, fps)


def _append_frames(imageio: Any, frames: Iterable[np.ndarray], path: Path, fps: float) -> None:
    count = 0
    writer = imageio.get_writer(
        str(path),
        format="FFMPEG",
        fps=fps,
        codec="libx264",
        quality=7,
        macro_block_size=2,  # H.264 with yuv420p needs even sizes only
        pixelformat="yuv420p",
        ffmpeg_log_level="error",
    )
    try:
        for frame in frames:
            writer.append_data(np.ascontiguousarray(frame))
            count += 1
    finally:
        writer.close()
    if not count:
        raise VideoError(f"{path}: no frames to write")


def _write_gif(frames: Iterable[np.ndarray], path: Path, fps: float) -> None:
    images = [Image.fromarray(frame) for frame in frames]
    if not images:
        raise VideoError(f"{path}: no frames to write")
    duration_ms = round(1000.0 / fps)
    picks = [images[k] for k in np.linspace(0, len(images) - 1, min(8, len(images))).astype(int)]
    montage = Image.new("RGB", (picks[0].width, picks[0].height * len(picks)))
    for k, image in enumerate(picks):  # one palette for every frame, from a few of them
        montage.paste(image, (0, k * picks[0].height))
    palette = montage.quantize(colors=128, method=Image.Quantize.MEDIANCUT)
    quantized = [image.quantize(palette=palette, dither=Image.Dither.NONE) for image in images]
    quantized[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=quantized[1:],
        duration=duration_ms,
        loop=0,
        optimize=True,
    )


def film_strip(
    frames: Sequence[np.ndarray], path: str | os.PathLike[str], columns: int | None = None
) -> Path:
    """The ``frames`` tiled left to right (and in rows of ``columns``) into one PNG, for a
    paper's figure; written atomically.

    Raises:
        VideoError: no frames, or ``path`` cannot be written.
    """
    if not frames:
        raise VideoError(f"{path}: no frames for a film strip")
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise VideoError(f"{path}: a film strip is a PNG; name it *.png")
    columns = len(frames) if columns is None else max(1, columns)
    rows = -(-len(frames) // columns)
    height, width = frames[0].shape[:2]
    sheet = np.full((rows * height, columns * width, 3), 255, dtype=np.uint8)
    for k, frame in enumerate(frames):
        r, c = divmod(k, columns)
        sheet[r * height : (r + 1) * height, c * width : (c + 1) * width] = frame
    return _write_atomically(
        path, lambda tmp: Image.fromarray(sheet).save(tmp, format="PNG", optimize=True)
    )
