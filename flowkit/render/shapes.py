"""Shape mapping functions f(s) (paper section 3.3): a band's width is multiplied by f(s),
s = (x / l + phase) mod 1, x an attribute that increases along the line.

The built-in shapes are one table (``SHAPES``): each is an expression of s built from a few
operations that evaluate with numpy and write themselves as GLSL, so the numpy function (used by
the tests and the docs), its peaks and the shader function (only those a style uses are
compiled) come from the same entry and cannot drift.  s runs in the direction of increasing x
(downstream for time or arc length), so arrows and tadpoles point downstream.  A user shape is
piecewise linear through control points (s, f) and is baked into a ``CURVE_SIZE``-texel texture,
so any user shape costs one texture fetch however many points it has.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import moderngl
import numpy as np

from .colormaps import _ctx_store

CURVE_SIZE = 1024  # texels of a baked user shape: error < 1/CURVE_SIZE of a period in s

# arrow: a shaft of width ARROW_SHAFT, then a head from full width at s = ARROW_HEAD to the tip
ARROW_SHAFT, ARROW_HEAD = 0.35, 0.45
DASH_ON = 0.6  # dash: on for this fraction of the period


@dataclass(frozen=True)
class Expr:
    """An expression of s: ``glsl`` its GLSL text, ``fn`` its numpy evaluation."""

    glsl: str
    fn: Callable

    def _op(self, other, sym, f, swap=False):
        o = _lift(other)
        x, y = (o, self) if swap else (self, o)
        return Expr(f"({x.glsl} {sym} {y.glsl})", lambda s: f(x.fn(s), y.fn(s)))

    def __add__(self, o):
        return self._op(o, "+", np.add)

    def __radd__(self, o):
        return self._op(o, "+", np.add, True)

    def __sub__(self, o):
        return self._op(o, "-", np.subtract)

    def __rsub__(self, o):
        return self._op(o, "-", np.subtract, True)

    def __mul__(self, o):
        return self._op(o, "*", np.multiply)

    def __rmul__(self, o):
        return self._op(o, "*", np.multiply, True)

    def __truediv__(self, o):
        return self._op(o, "/", np.divide)

    def __lt__(self, o):
        return self._op(o, "<", np.less)


def _lift(x) -> Expr:
    if isinstance(x, Expr):
        return x
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"shape constant {x!r} is not finite")
    lit = repr(v) if ("." in repr(v) or "e" in repr(v)) else repr(v) + ".0"
    return Expr(f"({lit})" if v < 0 else lit, lambda s: v)


def _call(name, f, *args) -> Expr:
    xs = [_lift(a) for a in args]
    return Expr(f"{name}({', '.join(x.glsl for x in xs)})", lambda s: f(*(x.fn(s) for x in xs)))


def where(c, a, b) -> Expr:
    c, a, b = _lift(c), _lift(a), _lift(b)
    return Expr(f"({c.glsl} ? {a.glsl} : {b.glsl})",
                lambda s: np.where(c.fn(s), a.fn(s), b.fn(s)))


def clamp(x, lo, hi) -> Expr:
    return _call("clamp", np.clip, x, lo, hi)


def sqrt(x) -> Expr:
    return _call("sqrt", np.sqrt, x)


def sin(x) -> Expr:
    return _call("sin", np.sin, x)


def absolute(x) -> Expr:
    return _call("abs", np.abs, x)


def maximum(x, y) -> Expr:
    return _call("max", np.maximum, x, y)


S = Expr("s", lambda s: s)


@dataclass(frozen=True)
class BuiltinShape:
    """A built-in f(s): the expression, and where f has its local maxima (tops of its jumps
    included): with the ends of an interval of s they give the largest f over the interval (the
    strip stage narrows the strip by them)."""

    name: str
    f: Expr
    peaks: tuple[float, ...]

    def __call__(self, s):
        return np.broadcast_to(self.f.fn(np.asarray(s, float)), np.shape(s)).astype(float)

    def glsl(self) -> str:
        return f"float shape_{self.name}(float s) {{ return {self.f.glsl}; }}"


_TADPOLE_D = (S - 0.75) / 0.2  # round head (radius 0.2 of the period) at the front
_DROPLET_U = clamp(S / 0.9, 0.0, 1.0)
SHAPES = {sh.name: sh for sh in (
    BuiltinShape("dash", where(S < DASH_ON, 1.0, 0.0), (0.0,)),
    BuiltinShape("arrow", where(S < ARROW_HEAD, ARROW_SHAFT, (1.0 - S) / (1.0 - ARROW_HEAD)),
                 (0.0, ARROW_HEAD)),
    # a tail thinning to nothing behind the head
    BuiltinShape("tadpole", maximum(sqrt(clamp(1.0 - _TADPOLE_D * _TADPOLE_D, 0.0, 1.0)),
                                    where(S < 0.75, 0.3 * S / 0.75, 0.0)), (0.75,)),
    # a teardrop: pointed tail, blunt front, a short gap before the next drop
    BuiltinShape("droplet", where(S < 0.9, sin(math.pi * _DROPLET_U * _DROPLET_U), 0.0),
                 (0.9 * 0.5**0.5,)),
    BuiltinShape("diamond", clamp(1.0 - absolute(S - 0.5) / 0.45, 0.0, 1.0), (0.5,)),
    BuiltinShape("sine", 0.5 + 0.5 * sin(2.0 * math.pi * S), (0.25,)),
)}
PEAKS = {n: sh.peaks for n, sh in SHAPES.items()}
BUILTIN = SHAPES  # name -> f(s), callable on numpy arrays
SHAPE_NAMES = tuple(SHAPES)


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
