"""A straight line seen face-on, and pixel probes along it (shared by the shape, pattern and
transfer tests)."""

from __future__ import annotations

import dataclasses

import numpy as np
from render_scenes import FACE_ON, project, straight

from flowkit.render import render_lines

SIZE = (400, 120)
CAM = dataclasses.replace(FACE_ON, zoom=2.9)  # the line (x from -1 to 1) spans 348 pixels


class Probe:
    """Renders ``lines`` (default: a straight line along x) face-on (orthographic) and maps
    world x to pixel columns; row ``centre`` is the line's centre row."""

    def __init__(self, n=201, **attrs):
        self.lines = straight((-1, 0, 0), (1, 0, 0), n=n, **attrs)
        self.x = self.lines.points[:, 0]
        (c0, self.centre), (c1, _) = project(self.lines.bounds(), CAM, SIZE, [[-1, 0, 0], [1, 0, 0]])
        self.px_per_world = (c1 - c0) / 2.0
        self.c0 = c0

    def render(self, style):
        return render_lines(self.lines, style, SIZE, CAM)

    def world_x(self, col):
        """World x under the centre of pixel column ``col``."""
        return (np.asarray(col) + 0.5 - self.c0) / self.px_per_world - 1.0

    def columns(self, margin=6):
        """Columns whose centre lies on the line, ``margin`` pixels from its ends."""
        lo, hi = self.c0 + margin, self.c0 + 2 * self.px_per_world - margin
        return np.arange(int(np.ceil(lo)), int(hi))

    def attr_at(self, name, col):
        """Attribute ``name`` linearly interpolated at the world x of column ``col``."""
        return np.interp(self.world_x(col), self.x, self.lines.point_data[name])


def half_width(img, col, background=(255, 255, 255)) -> float:
    """Half the number of non-background pixels in a column."""
    return float(np.sum(np.any(img[:, col, :3] != background, axis=1))) / 2.0


def transitions(values: np.ndarray) -> np.ndarray:
    """Sub-pixel positions (in column units, pixel centres at i + 0.5) where a 0..1 signal
    rises through 0.5."""
    v = np.asarray(values, float)
    i = np.flatnonzero((v[:-1] < 0.5) & (v[1:] >= 0.5))
    return i + 0.5 + (0.5 - v[i]) / (v[i + 1] - v[i])
