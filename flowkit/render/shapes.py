"""Shape mapping functions f(s) (paper section 3.3): a band's width is multiplied by f(s),
s = (x / l + phase) mod 1, x an attribute that increases along the line.

The built-in shapes are small GLSL functions in ``shaders/shapes.glsl`` (only those a style uses
are compiled); the numpy functions here are their exact definitions, used by the tests and the
docs.  s runs in the direction of increasing x (downstream for time or arc length), so arrows
and tadpoles point downstream.  A user shape is piecewise linear through control points
(s, f) and is baked into a ``CURVE_SIZE``-texel texture, so any user shape costs one texture
fetch however many points it has.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from .colormaps import _ctx_store

CURVE_SIZE = 1024  # texels of a baked user shape: error < 1/CURVE_SIZE of a period in s

# arrow: a shaft of width ARROW_SHAFT, then a head from full width at s = ARROW_HEAD to the tip
ARROW_SHAFT, ARROW_HEAD = 0.35, 0.45
DASH_ON = 0.6  # dash: on for this fraction of the period


def _dash(s):
    return np.where(s < DASH_ON, 1.0, 0.0)


def _arrow(s):
    return np.where(s < ARROW_HEAD, ARROW_SHAFT, (1.0 - s) / (1.0 - ARROW_HEAD))


def _tadpole(s):
    # round head (radius 0.2 of the period) at the front, a tail thinning to nothing behind it
    head = np.sqrt(np.clip(1.0 - ((s - 0.75) / 0.2) ** 2, 0.0, 1.0))
    tail = np.where(s < 0.75, 0.3 * s / 0.75, 0.0)
    return np.maximum(head, tail)


def _droplet(s):
    # a teardrop: pointed tail, blunt front, a short gap before the next drop
    u = np.clip(s / 0.9, 0.0, 1.0)
    return np.where(s < 0.9, np.sin(np.pi * u * u), 0.0)


def _diamond(s):
    return np.clip(1.0 - np.abs(s - 0.5) / 0.45, 0.0, 1.0)


def _sine(s):
    return 0.5 + 0.5 * np.sin(2.0 * np.pi * s)


# where each built-in f(s) has its local maxima (tops of its jumps included): with the ends of an
# interval of s they give the largest f over the interval (the strip stage narrows the strip)
PEAKS = {"dash": (0.0,), "arrow": (0.0, ARROW_HEAD), "tadpole": (0.75,),
         "droplet": (0.9 * 0.5**0.5,), "diamond": (0.5,), "sine": (0.25,)}

BUILTIN = {"dash": _dash, "arrow": _arrow, "tadpole": _tadpole, "droplet": _droplet,
           "diamond": _diamond, "sine": _sine}
SHAPE_NAMES = tuple(BUILTIN)


def shape_function(name: str, points=()):
    """f(s) as a numpy function: a built-in ``name`` or the piecewise-linear ``points``."""
    if name in BUILTIN:
        return BUILTIN[name]
    xs, fs = np.asarray(points, float).T
    return lambda s: np.interp(s, xs, fs)


@dataclass(frozen=True)
class ShapeCurve:
    """A user shape's control points: the renderer turns it into a texture (cached)."""

    points: tuple[tuple[float, float], ...]

    def baked(self) -> np.ndarray:
        """f at the CURVE_SIZE texel centres (s = (i + 0.5) / CURVE_SIZE)."""
        s = (np.arange(CURVE_SIZE) + 0.5) / CURVE_SIZE
        return shape_function("custom", self.points)(s).astype(np.float32)


def curve_texture(ctx: moderngl.Context, curve: ShapeCurve) -> moderngl.Texture:
    """(CURVE_SIZE x 1) R32F texture of a user shape, linear filtering, cached per context."""
    cache = _ctx_store(ctx).setdefault("shape_curves", {})
    tex = cache.get(curve)
    if tex is None:
        tex = ctx.texture((CURVE_SIZE, 1), 1, curve.baked().tobytes(), dtype="f4")
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = True  # s wraps: the last texel blends into the first
        tex.repeat_y = False
        cache[curve] = tex
    return tex
