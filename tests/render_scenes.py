"""Synthetic lines and helpers shared by the rendering tests (no pytest here)."""

from __future__ import annotations

import numpy as np

from flowkit.lines import Lines
from flowkit.render import Band, Camera, LineStyle, Style

# Looking along +y: x to the right, z up; y is depth (smaller y = nearer the viewer).  The
# bounding sphere fills the image's height (a line from -1 to 1: 50 pixels per unit on 100 rows).
FACE_ON = Camera(azimuth=-90, elevation=0, up=(0, 0, 1), projection="orthographic", fit="sphere")


def straight(a, b, n=64, **attrs) -> Lines:
    """One straight line from a to b with n vertices; attrs: name -> (n,) values or a constant."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    pts = (1 - t) * np.asarray(a, float) + t * np.asarray(b, float)
    pd = {k: np.broadcast_to(np.asarray(v, float), (n,)).copy() for k, v in attrs.items()}
    return Lines(pts, [0, n], pd)


def helices(n_lines=12, n=300, turns=3.0) -> Lines:
    parts = []
    t = np.linspace(0, 2 * np.pi * turns, n)
    for k in range(n_lines):
        ph = 2 * np.pi * k / n_lines
        r = 1.0 + 0.3 * np.sin(3 * ph)
        pts = np.stack([r * np.cos(t + ph), r * np.sin(t + ph), t / (2 * np.pi)], axis=1)
        parts.append(Lines(pts, [0, n], {"speed": 0.5 + 0.5 * np.sin(t + ph),
                                         "arc": np.linspace(0, 1, n)}))
    return Lines.concatenate(parts)


def style(*bands: Band, **kw) -> Style:
    return Style(styles={"default": LineStyle(tuple(bands))}, **kw)


def project(lines_bounds, camera: Camera, size, points) -> np.ndarray:
    """Pixel coordinates (column, row from the top; pixel centres at +0.5) of world points."""
    w, h = size
    cam = camera.setup(lines_bounds, w, h)
    p = np.c_[np.atleast_2d(points), np.ones(len(np.atleast_2d(points)))] @ (cam.proj @ cam.view).T
    ndc = p[:, :3] / p[:, 3:]
    return np.stack([(ndc[:, 0] + 1) / 2 * w, (1 - ndc[:, 1]) / 2 * h], axis=1)
