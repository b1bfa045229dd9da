"""Colormaps from the ``cmap`` package, as lookup tables and 1-D textures."""

from __future__ import annotations

from functools import lru_cache

import moderngl
import numpy as np

LUT_SIZE = 256  # entries a colormap is sampled at (its colours are linear between them)
TEXELS = 4096  # entries of its texture: the LUT resampled, 8 bits, nearest filtering


@lru_cache(maxsize=64)
def colormap_lut(name: str, n: int = LUT_SIZE) -> np.ndarray:
    """(n, 4) float32 RGBA of colormap ``name`` sampled evenly from its start to its end."""
    import cmap

    return np.ascontiguousarray(cmap.Colormap(name).lut(n), dtype=np.float32)


def colormap_texture(ctx: moderngl.Context, name: str) -> moderngl.Texture:
    """A 1-D RGBA8 texture of the colormap, cached per context: the LUT (linear between its
    LUT_SIZE entries) resampled at TEXELS entries and read with nearest filtering.  A software
    rasterizer (llvmpipe) reads an 8-bit texel as one word and skips the filter, where a float
    LUT filtered linearly costs four texels of four channels each: in a frame of bench_styles.py
    the lookup took ~80 ms of CPU time that way and ~18 ms this way.  The colour moves by at most
    half an 8-bit level (rounding) plus the LUT's change over half a texel (~0.1 level for the
    steepest maps), so within one level of the float lookup; the frame is 8 bits anyway."""
    cache = _ctx_store(ctx).setdefault("cmaps", {})
    tex = cache.get(name)
    if tex is None:
        lut = colormap_lut(name)
        x = np.linspace(0.0, 1.0, TEXELS) * (lut.shape[0] - 1)
        rgba = np.stack([np.interp(x, np.arange(lut.shape[0]), lut[:, c]) for c in range(4)], 1)
        data = np.rint(np.clip(rgba, 0.0, 1.0) * 255).astype(np.uint8)
        # moderngl has no 1-D texture type: a (n x 1) 2-D texture sampled at y = 0.5
        tex = ctx.texture((TEXELS, 1), 4, data.tobytes(), dtype="f1")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        cache[name] = tex
    return tex


def _ctx_store(ctx: moderngl.Context) -> dict:
    if not isinstance(ctx.extra, dict):
        ctx.extra = {}
    return ctx.extra
