"""Colour and width ranges from the data: a style's ``range`` left out (the attribute's minimum
to maximum over the lines drawn) or given as ``"pA..pB"`` (its A-th to B-th percentiles, for data
with outliers) becomes two numbers here, before the style reaches the shaders or a legend."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from .style.check import StyleError, percentiles
from .style.model import Band, ColorMap, Range, Style, WidthMap

CLIP = 0.05  # a fixed range leaving more of the data outside is reported


def data_range(values: np.ndarray, spec: Range, name: str = "attribute") -> tuple[float, float]:
    """(low, high) of the finite ``values`` for ``spec`` (None: min..max, "pA..pB": percentiles;
    a pair is returned as it is).  A constant attribute gets a range of +-1 % about its value
    (+-0.5 at 0), so the colormap's middle shows it and a legend still has ticks."""
    if isinstance(spec, tuple):
        return spec
    v = np.asarray(values, np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        raise StyleError(f"attribute '{name}' has no finite value on these lines: its range "
                         f"cannot come from the data; give range = [low, high]")
    pct = percentiles(spec) if spec is not None else (0.0, 100.0)
    lo, hi = (float(x) for x in np.percentile(v, pct))
    if hi - lo <= 1e-12 * max(abs(lo), abs(hi)):
        half = 0.01 * abs(lo) if lo != 0 else 0.5
        lo, hi = lo - half, lo + half
    return lo, hi


def _band_maps(ls):
    """The colour and width maps of a line style's bands."""
    for b in ls.bands:
        for m in (b.color, b.width, b.pattern.color if b.pattern is not None else None):
            if isinstance(m, (ColorMap, WidthMap)):
                yield m


def fixed_ranges(style: Style):
    """(where, map) of the colour and width maps with a range fixed in numbers, in the line
    styles drawn; ``where`` names the key as a style file spells it ("band 1 color")."""
    for n in style.used_styles():
        for i, b in enumerate(style.styles[n].bands):
            where = f"style '{n}' band {i + 1}" if len(style.styles) > 1 else f"band {i + 1}"
            pc = b.pattern.color if b.pattern is not None else None
            for key, m in (("color", b.color), ("width", b.width), ("pattern.color", pc)):
                if isinstance(m, (ColorMap, WidthMap)) and isinstance(m.range, tuple):
                    yield f"{where} {key}", m


def resolve_ranges(style: Style, range_of: Callable[[str, Range], tuple[float, float]]) -> Style:
    """``style`` with every automatic range replaced by ``range_of(attribute, spec)`` (e.g.
    ``data_range`` of the attribute's values over the lines drawn).  A style with none is returned unchanged.  Line
    styles no transfer range picks are never drawn: their automatic ranges become (0, 1)."""
    if not all(isinstance(m.range, tuple) for ls in style.styles.values() for m in _band_maps(ls)):
        drawn = set(style.used_styles())

        def fix(m, use: bool):
            if not isinstance(m, (ColorMap, WidthMap)) or isinstance(m.range, tuple):
                return m
            return dataclasses.replace(m, range=range_of(m.attribute, m.range) if use else (0.0, 1.0))

        def band(b: Band, use: bool) -> Band:
            pattern = b.pattern
            if pattern is not None:
                pattern = dataclasses.replace(pattern, color=fix(pattern.color, use))
            return dataclasses.replace(b, color=fix(b.color, use), width=fix(b.width, use),
                                       pattern=pattern)

        styles = {n: dataclasses.replace(ls, bands=tuple(band(b, n in drawn) for b in ls.bands))
                  for n, ls in style.styles.items()}
        style = dataclasses.replace(style, styles=styles)
    return style
