"""Animation: move the shapes and colour patterns along the lines (paper section 6) by stepping
the style's ``phase`` -- one program, only a uniform changes per frame.

Frame k of n has phase + k / n periods, so the last frame leads seamlessly into the first and
the animation loops.  Outputs: numbered PNGs (``out.png`` -> ``out_0000.png``...), an animated
GIF through Pillow, or an MP4 through the optional ``imageio`` + ``imageio-ffmpeg`` (the
``video`` extra).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_path
from .camera import Camera
from .renderer import LineRenderer, save_png
from .style.model import Style

FORMATS = (".png", ".gif", ".mp4")


def frame_styles(style: Style, n: int) -> list[Style]:
    """``n`` copies of ``style`` whose phase advances one period over the whole animation."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"frames = {n!r}: expected an integer >= 1")
    return [dataclasses.replace(style, phase=style.phase + k / n) for k in range(n)]


def render_frames(renderer: LineRenderer, style: Style, n: int, size=(1920, 1080),
                  camera: Camera | None = None, overlays: bool = False) -> Iterator[np.ndarray]:
    """Yield the ``n`` (H, W, 4) uint8 frames one at a time (a long animation never sits in
    memory as a whole); ``overlays``: each with the style's legend and annotations, placed by
    the first frame's lines so that they stay put."""
    from .legend import drawn_pixels

    if not style.animated:
        raise ValueError("the style has no shape or colour pattern to move: an animation would "
                         "repeat one picture (add a band 'shape' or 'pattern')")
    coverage = None
    for s in frame_styles(style, n):
        img = renderer.render(s, size, camera)
        if overlays:
            if coverage is None:
                coverage = drawn_pixels(img, s)
            img = renderer.overlay(img, s, camera, coverage=coverage)
        yield img


def frame_paths(path: str | os.PathLike, n: int) -> list[Path]:
    """out.png -> [out_0000.png, out_0001.png, ...] (at least 4 digits)."""
    p = Path(path)
    digits = max(4, len(str(n - 1)))
    return [p.with_name(f"{p.stem}_{k:0{digits}d}{p.suffix}") for k in range(n)]


def write_animation(frames: Iterable[np.ndarray], path: str | os.PathLike, n: int,
                    fps: float = 12.0, progress=None) -> list[Path]:
    """Write ``n`` frames to ``path`` by its suffix (.png numbered, .gif, .mp4); atomic per
    file.  ``progress`` (a callable) is called after each frame.  Returns the written paths."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"{path}: animation output must end in {', '.join(FORMATS)}")
    if not fps > 0:
        raise ValueError(f"fps = {fps!r}: expected a number > 0")
    tick = progress or (lambda: None)
    if suffix == ".png":
        out = []
        for img, p in zip(frames, frame_paths(path, n)):
            out.append(save_png(img, p))
            tick()
        return out
    if suffix == ".mp4":
        try:
            import imageio.v2 as imageio
        except ImportError:
            raise ValueError(f"{path}: MP4 needs the optional imageio and imageio-ffmpeg "
                             "(pip install 'flowkit[video]'); or write .gif / .png") from None
        with atomic_path(path) as tmp, imageio.get_writer(tmp, format="FFMPEG", fps=fps) as w:
            for img in frames:
                w.append_data(np.ascontiguousarray(img[:, :, :3]))
                tick()
        return [path]
    from PIL import Image

    images, palette = [], None
    for img in frames:  # GIF: the first frame's palette for all; alpha onto white
        rgb = img[:, :, :3].astype(np.float32)
        a = img[:, :, 3:4].astype(np.float32) / 255.0
        flat = np.rint(rgb * a + 255.0 * (1.0 - a)).astype(np.uint8)
        if palette is None:
            q = Image.fromarray(flat, "RGB").quantize(256, dither=Image.Dither.NONE)
            palette = np.array(q.getpalette()[:3 * 256], np.uint8).reshape(-1, 3)
        frame = Image.fromarray(nearest_colours(flat, palette), "P")
        frame.putpalette(palette.ravel().tolist())
        images.append(frame)
        tick()
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                       duration=round(1000.0 / fps), loop=0, optimize=False)
    return [path]


def nearest_colours(rgb: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """(H, W) uint8 index of the nearest ``palette`` colour of every pixel, exactly and the
    same for every frame (Pillow's ``quantize(palette=)`` looks colours up at reduced
    precision: a white background came out 252 on every frame after the first, which
    flickered); computed once per distinct colour."""
    colours, inverse = np.unique(rgb.reshape(-1, 3), axis=0, return_inverse=True)
    d = ((colours[:, None, :].astype(np.int32) - palette[None, :, :].astype(np.int32)) ** 2).sum(2)
    return np.argmin(d, axis=1).astype(np.uint8)[inverse.ravel()].reshape(rgb.shape[:2])
