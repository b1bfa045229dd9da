"""Style edits as data, for the panel and for tests: the list of editable parameters of a Style
and a pure ``replace_at`` that returns a new (validated) Style with one value changed."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ..render.style.model import ColorMap, Range, Style, WidthMap

KINDS = ("float", "color", "range", "cmap", "shape", "attribute")


@dataclass(frozen=True)
class Param:
    """One editable value: ``path`` into the Style (attribute names, dict keys, tuple indices),
    ``kind`` (KINDS) picks the widget, ``low`` the smallest allowed number (floats)."""

    group: str
    label: str
    path: tuple
    kind: str
    value: object
    low: float | None = None


def get_at(obj, path: tuple):
    for key in path:
        obj = obj[key] if isinstance(obj, dict | tuple) else getattr(obj, key)
    return obj


def replace_at(obj, path: tuple, value):
    """``obj`` with the value at ``path`` replaced; frozen dataclasses are rebuilt with
    ``dataclasses.replace`` (a Style validates itself: StyleError on a bad value)."""
    if not path:
        return value
    key, rest = path[0], path[1:]
    if isinstance(obj, dict):
        return {**obj, key: replace_at(obj[key], rest, value)}
    if isinstance(obj, tuple):
        items = list(obj)
        items[key] = replace_at(obj[key], rest, value)
        return tuple(items)
    return dataclasses.replace(obj, **{key: replace_at(getattr(obj, key), rest, value)})


def _color(group, label, path, c) -> list[Param]:
    if isinstance(c, ColorMap):
        return [Param(group, f"{label} colormap", path + ("cmap",), "cmap", c.cmap),
                Param(group, f"{label} attribute", path + ("attribute",), "attribute", c.attribute),
                Param(group, f"{label} range", path + ("range",), "range", c.range)]
    return [Param(group, label, path, "color", c)]


def params(style: Style) -> list[Param]:
    """Every parameter the panel shows, in display order."""
    out = [Param("scene", "scale", ("scale",), "float", style.scale, 1e-3)]
    if style.background is not None:
        out.append(Param("scene", "background", ("background",), "color", style.background))
    out.append(Param("scene", "phase", ("phase",), "float", style.phase))
    for name, ls in style.styles.items():
        for i, b in enumerate(ls.bands):
            g, base = f"{name}: band {i + 1}", ("styles", name, "bands", i)
            out += _color(g, "colour", base + ("color",), b.color)
            if isinstance(b.width, WidthMap):
                w = b.width
                out += [Param(g, "width range", base + ("width", "range"), "range", w.range),
                        Param(g, "width min", base + ("width", "min"), "float", w.min, 0.0),
                        Param(g, "width max", base + ("width", "max"), "float", w.max, 0.0)]
            else:
                out.append(Param(g, "width", base + ("width",), "float", b.width, 0.0))
            out.append(Param(g, "depth offset", base + ("depth_offset",), "float",
                             b.depth_offset, 0.0))
            if b.shape is not None:
                if b.shape.name != "custom":
                    out.append(Param(g, "shape", base + ("shape", "name"), "shape", b.shape.name))
                out.append(Param(g, "shape length", base + ("shape", "length"), "float",
                                 b.shape.length, 1e-6))
            if b.pattern is not None:
                p, pb = b.pattern, base + ("pattern",)
                out += [Param(g, "pattern length", pb + ("length",), "float", p.length, 1e-6),
                        Param(g, "pattern slope", pb + ("slope",), "float", p.slope),
                        Param(g, "pattern curve", pb + ("curve",), "float", p.curve, 1e-6),
                        Param(g, "pattern fraction", pb + ("fraction",), "float", p.fraction, 0.0)]
                out += _color(g, "pattern colour", pb + ("color",), p.color)
    if style.transfer is not None:
        tf = style.transfer
        for i, r in enumerate(tf.ranges):
            out.append(Param("transfer", f"range {i + 1} ({r.style or 'hidden'})",
                             ("transfer", "ranges", i, "range"), "range", r.range))
        out.append(Param("transfer", "blend", ("transfer", "blend"), "float", tf.blend, 0.0))
    return out


def colormapped(style: Style) -> list[tuple]:
    """Paths of every colour-mapped colour (band colours and pattern colours)."""
    paths = []
    for name, ls in style.styles.items():
        for i, b in enumerate(ls.bands):
            base = ("styles", name, "bands", i)
            if isinstance(b.color, ColorMap):
                paths.append(base + ("color",))
            if b.pattern is not None and isinstance(b.pattern.color, ColorMap):
                paths.append(base + ("pattern", "color"))
    return paths


def auto_range(spec: Range) -> Range:
    """What a range becomes when its map reads another attribute: a percentile spec holds for any
    attribute and stays; numbers belong to the old attribute, so the new one's data range."""
    return spec if isinstance(spec, str) else None


def with_color_attribute(style: Style, attribute: str, value_range: Range | bool = True) -> Style:
    """Every colour-mapped colour reads ``attribute``, over ``value_range`` (True: each map's
    ``auto_range``)."""
    for path in colormapped(style):
        cm = get_at(style, path)
        r = auto_range(cm.range) if value_range is True else value_range
        style = replace_at(style, path, ColorMap(cm.cmap, attribute, r))
    return style
