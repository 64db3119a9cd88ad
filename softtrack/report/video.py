"""Frames to files: MP4 (H.264 through the ffmpeg that ``imageio-ffmpeg`` ships: no system
download), GIF, a self-contained HTML player, or a PNG film strip. Every file is written to a
temporary beside its destination and renamed into place, so a failed or interrupted write
leaves nothing half-written."""

from __future__ import annotations

import base64
import html
import os
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from softtrack.store.atomic import temp_name

__all__ = ["VIDEO_FORMATS", "VideoError", "film_strip", "video_format", "write_video"]

#: File suffixes :func:`write_video` writes, and what each is.
VIDEO_FORMATS = {".mp4": "H.264 video", ".gif": "animated GIF", ".html": "HTML page with a player"}


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


def write_video(
    frames: Iterable[np.ndarray], path: str | os.PathLike[str], fps: float, title: str = ""
) -> Path:
    """Write (H, W, 3) uint8 ``frames`` to ``path`` (MP4, GIF or HTML by suffix) at ``fps``.

    Raises:
        VideoError: unknown suffix, no ffmpeg, no frames, or the destination cannot be
            written (nothing is left behind).
    """
    path = Path(path)
    suffix = video_format(path)
    if not path.parent.is_dir():
        raise VideoError(f"{path}: its directory {path.parent} does not exist; create it first")
    tmp = temp_name(path)
    try:
        if suffix == ".gif":
            _write_gif(frames, tmp, fps)
        else:
            mp4 = tmp if suffix == ".mp4" else temp_name(path.with_suffix(".mp4"))
            try:
                _write_mp4(frames, mp4, fps)
                if suffix == ".html":
                    tmp.write_text(_player_page(mp4.read_bytes(), title), encoding="utf-8")
            finally:
                if mp4 != tmp:
                    mp4.unlink(missing_ok=True)
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


def _player_page(mp4: bytes, title: str) -> str:
    """A page that plays ``mp4`` from itself (a data URI): play, pause, scrub with the
    browser's own controls, and a speed choice; nothing fetched from a network."""
    data = base64.b64encode(mp4).decode("ascii")
    name = html.escape(title or "softtrack animation")
    speeds = "".join(
        f'<option value="{s}"{" selected" if s == 1 else ""}>{s}×</option>'
        for s in (0.25, 0.5, 1, 2)
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{name}</title>
<style>body{{font-family:sans-serif;margin:1.5em;background:#f4f5f7;color:#222}}
video{{max-width:100%;border:1px solid #ccc;background:#fff}}</style></head>
<body><h1 style="font-size:1.2em">{name}</h1>
<video id="player" controls loop autoplay muted playsinline
 src="data:video/mp4;base64,{data}"></video>
<p><label>speed <select id="speed">{speeds}</select></label></p>
<script>
const player = document.getElementById("player");
document.getElementById("speed").addEventListener("change",
  (event) => {{ player.playbackRate = Number(event.target.value); }});
</script></body></html>
"""


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
    tmp = temp_name(path)
    try:
        Image.fromarray(sheet).save(tmp, format="PNG", optimize=True)
        os.replace(tmp, path)
    except OSError as exc:
        raise VideoError(
            f"{path}: cannot be written ({exc.strerror or exc}); choose another --out"
        ) from None
    finally:
        tmp.unlink(missing_ok=True)
    return path
