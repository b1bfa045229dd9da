"""Colormaps from the ``cmap`` package, as lookup tables and 1-D textures."""

from __future__ import annotations

from functools import lru_cache

import moderngl
import numpy as np

LUT_SIZE = 256


@lru_cache(maxsize=64)
def colormap_lut(name: str, n: int = LUT_SIZE) -> np.ndarray:
    """(n, 4) float32 RGBA of colormap ``name`` sampled evenly from its start to its end."""
    import cmap

    return np.ascontiguousarray(cmap.Colormap(name).lut(n), dtype=np.float32)


def lut_coordinate(t: np.ndarray | float, n: int = LUT_SIZE):
    """Texture coordinate of normalised value t in [0, 1]: texel centres at both ends, so t=0
    gives exactly the first LUT entry and t=1 the last (the shaders use the same formula)."""
    return np.asarray(t) * (n - 1) / n + 0.5 / n


def colormap_texture(ctx: moderngl.Context, name: str) -> moderngl.Texture:
    """A 1-D RGBA32F texture of the colormap, linear filtering, cached per context."""
    cache = _ctx_store(ctx).setdefault("cmaps", {})
    tex = cache.get(name)
    if tex is None:
        lut = colormap_lut(name)
        # moderngl has no 1-D texture type: a (n x 1) 2-D texture sampled at y = 0.5
        tex = ctx.texture((lut.shape[0], 1), 4, lut.tobytes(), dtype="f4")
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        cache[name] = tex
    return tex


def _ctx_store(ctx: moderngl.Context) -> dict:
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    return ctx.extra
