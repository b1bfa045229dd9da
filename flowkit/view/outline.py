"""The outline of a box (the lines' or the field's bounds, ``domain_bounds`` where their file
records it): twelve 1-pixel edges drawn into the scene with its depth, so lines in front hide
them as in ParaView's outline."""

from __future__ import annotations

import itertools

import moderngl
import numpy as np

from ..lines import Lines

_VS = """
#version 330
uniform mat4 u_mvp;
in vec3 in_pos;
void main() { gl_Position = u_mvp * vec4(in_pos, 1.0); }
"""
_FS = """
#version 330
uniform vec4 u_color;
out vec4 f_color;
void main() { f_color = u_color; }
"""


def domain_bounds(lines: Lines) -> np.ndarray | None:
    """The field's box (3, 2) that ``lines`` were traced in, where their file records it
    (``domain_bounds``: six numbers, as text or an array), else None."""
    value = lines.attrs.get("domain_bounds")
    if value is None:
        return None
    try:
        b = np.asarray(value.split() if isinstance(value, str) else value, float).reshape(3, 2)
    except ValueError:
        return None  # not six numbers: the lines' own box instead
    return b if np.all(np.isfinite(b)) and np.all(b[:, 1] >= b[:, 0]) else None


def box_edges(bounds: np.ndarray) -> np.ndarray:
    """(24, 3): the 12 edges of the box ``bounds`` (3, 2) as pairs of corners."""
    b = np.asarray(bounds, float)
    corners = list(itertools.product((0, 1), repeat=3))
    edges = [(c, d) for c, d in itertools.combinations(corners, 2)
             if sum(i != j for i, j in zip(c, d)) == 1]
    return np.array([[b[k, c[k]] for k in range(3)] for e in edges for c in e])


class Outline:
    def __init__(self, ctx: moderngl.Context, bounds: np.ndarray):
        self.ctx = ctx
        self.bounds = np.asarray(bounds, float)
        self._prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        self._vbo = ctx.buffer(box_edges(self.bounds).astype("f4").tobytes())
        self._vao = ctx.vertex_array(self._prog, [(self._vbo, "3f", "in_pos")])

    def draw(self, setup, background) -> None:
        """Into the bound framebuffer, depth-tested against what is there; a grey that stands
        out from ``background`` (RGBA or None)."""
        bg = background or (0.0, 0.0, 0.0, 0.0)
        light = 0.2126 * bg[0] + 0.7152 * bg[1] + 0.0722 * bg[2] > 0.5 and bg[3] > 0
        grey = 0.25 if light else 0.8
        self._prog["u_mvp"].write((setup.proj @ setup.view).T.astype("f4").tobytes())
        self._prog["u_color"] = (grey, grey, grey, 1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND)
        self._vao.render(moderngl.LINES)

    def release(self) -> None:
        for o in (self._vao, self._vbo, self._prog):
            o.release()
