"""Checks of every style value, once, shared by Styles built in Python (``validate``, which a
Style runs on itself) and by style files (``toml`` reads through the same checkers).  Errors
name the file, the key path, the value and what is allowed.  The renderer only ever turns the
checked model into numbers (uniforms, textures) and into integer/enum template flags -- never
pastes a string from it into shader source.
"""

from __future__ import annotations

import math
import re

from ..length_forms import FORMS as LENGTH_FORMS
from ..length_forms import parse as parse_length
from ..shapes import SHAPE_NAMES
from . import model
from .model import (
    ANTIALIAS,
    PLACEMENTS,
    RGBA,
    STYLE_VERSION,
    UNITS,
    ColorMap,
    LineStyle,
    Pattern,
    Range,
    Shape,
    Style,
    Transfer,
    WidthMap,
)

MAX_BANDS = 8
MAX_RANGES = 8  # transfer function ranges
MAX_CURVE_POINTS = 256  # control points of a user shape
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]*$")
_PERCENTILES = re.compile(r"^p(\d+(?:\.\d*)?)\.\.p(\d+(?:\.\d*)?)$")


class StyleError(ValueError):
    """A style value that is not allowed; the message names where, what and what is allowed."""


def _fail(where: str, key: str, value, allowed: str):
    raise StyleError(f"{where}: {key} = {value!r} is not allowed; expected {allowed}")


def _number(where, key, v, lo=-math.inf, hi=math.inf, lo_open=False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        _fail(where, key, v, "a finite number")
    if v < lo or v > hi or (lo_open and v == lo):
        lo_s = f"> {lo}" if lo_open else f">= {lo}"
        _fail(where, key, v, f"a number {lo_s}" + (f" and <= {hi}" if hi < math.inf else ""))
    return float(v)


def _rgba(where, key, v) -> RGBA:
    if isinstance(v, str):
        s = v.lstrip("#")
        if v.startswith("#") and len(s) in (6, 8) and all(c in "0123456789abcdefABCDEF" for c in s):
            vals = [int(s[i:i + 2], 16) / 255 for i in range(0, len(s), 2)]
            return tuple(vals + [1.0] * (4 - len(vals)))  # type: ignore[return-value]
        _fail(where, key, v, "'#rrggbb', '#rrggbbaa' or [r, g, b(, a)] with components in 0..1")
    if not isinstance(v, (list, tuple)) or len(v) not in (3, 4):
        _fail(where, key, v, "'#rrggbb', '#rrggbbaa' or [r, g, b(, a)] with components in 0..1")
    comps = [_number(where, f"{key}[{i}]", c, 0.0, 1.0) for i, c in enumerate(v)]
    return tuple(comps + [1.0] * (4 - len(comps)))  # type: ignore[return-value]


def _name(where, key, v) -> str:
    if not isinstance(v, str) or not _NAME.match(v):
        _fail(where, key, v, "a name of letters, digits, '_', '.', '-' (not starting with a digit)")
    return v


def percentiles(spec: str) -> tuple[float, float] | None:
    """``"p2..p98"`` -> (2.0, 98.0); None when ``spec`` is not such a string."""
    m = _PERCENTILES.match(spec) if isinstance(spec, str) else None
    if m is None:
        return None
    lo, hi = float(m[1]), float(m[2])
    return (lo, hi) if 0 <= lo < hi <= 100 else None


_RANGE_ALLOWED = ("[low, high] (two different finite numbers), 'pA..pB' (percentiles of the data, "
                  "0 <= A < B <= 100, e.g. 'p2..p98'), or no range (the data's min to max)")


def _length(where, key, v, lo: float = 0.0, lo_open: bool = False) -> float | str:
    """A style length: a number (>= ``lo``) or a relative string (``lengths``)."""
    if isinstance(v, str):
        if parse_length(v) is None:
            _fail(where, key, v, LENGTH_FORMS)
        return v
    return _number(where, key, v, lo, lo_open=lo_open)


def _range(where, key, v, auto: bool = False) -> Range:
    """A [low, high] pair; with ``auto`` also None or a percentile string (from the data)."""
    if auto and (v is None or percentiles(v) is not None):
        return v
    if auto and isinstance(v, str):
        _fail(where, key, v, _RANGE_ALLOWED)
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        _fail(where, key, v, _RANGE_ALLOWED if auto else "[low, high], two different finite numbers")
    lo, hi = (_number(where, f"{key}[{i}]", x) for i, x in enumerate(v))
    if lo == hi:
        _fail(where, key, list(v), "[low, high] with low != high")
    return lo, hi


def known_colormap(name: str) -> bool:
    import cmap

    try:
        cmap.Colormap(name)
    except (ValueError, KeyError, TypeError):
        return False
    return True


def validate(style: Style) -> None:
    """Check a Style built in Python the same way as a file; raises StyleError."""
    w = "style"
    if style.version != STYLE_VERSION:
        _fail(w, "version", style.version, f"{STYLE_VERSION}")
    if style.units not in UNITS:
        _fail(w, "units", style.units, " or ".join(map(repr, UNITS)))
    if style.antialias not in ANTIALIAS:
        _fail(w, "antialias", style.antialias, " or ".join(map(repr, ANTIALIAS)))
    _number(w, "scale", style.scale, 0.0, lo_open=True)
    if style.samples not in (1, 2, 4, 8, 16):
        _fail(w, "samples", style.samples, "1, 2, 4, 8 or 16")
    if style.supersample not in (1, 2, 3, 4):
        _fail(w, "supersample", style.supersample, "1, 2, 3 or 4")
    if not isinstance(style.styles, dict) or not style.styles:
        _fail(w, "styles", style.styles, "at least one line style with at least one band")
    _number(w, "phase", style.phase)
    for sname, ls in style.styles.items():
        _name(w, "styles", sname)
        if not 1 <= len(ls.bands) <= MAX_BANDS:
            _fail(f"{w}.{sname}", "bands", f"{len(ls.bands)} bands", f"1 to {MAX_BANDS} bands")
        for i, b in enumerate(ls.bands):
            bw = f"style '{sname}' band {i + 1}"
            _check_color(bw, "color", b.color)
            if isinstance(b.width, WidthMap):
                _name(bw, "width.attribute", b.width.attribute)
                _range(bw, "width.range", b.width.range, auto=True)
                _length(bw, "width.min", b.width.min)
                _length(bw, "width.max", b.width.max)
            else:
                _length(bw, "width", b.width)
            _length(bw, "depth_offset", b.depth_offset)
            if b.shape is not None:
                _check_shape(bw, b.shape)
            if b.pattern is not None:
                _check_pattern(bw, b.pattern)
        if not _relative(ls) and ls.total_width <= 0:
            _fail(f"{w}.{sname}", "bands", "total width 0", "a positive total width")
    if style.transfer is not None:
        _check_transfer(w, style.transfer, style.styles)
    lg, an = style.legend, style.annotations
    if not isinstance(lg.show, bool):
        _fail(f"{w} [legend]", "show", lg.show, "true or false")
    if lg.placement not in PLACEMENTS:
        _fail(f"{w} [legend]", "placement", lg.placement, ", ".join(map(repr, PLACEMENTS)))
    for k in ("title", "text"):
        v = getattr(an, k)
        if not isinstance(v, str) or len(v) > 200 or "\n" in v:
            _fail(f"{w} [annotations]", k, v, "one line of text (at most 200 characters)")
    for k in ("time", "scale_bar"):
        if not isinstance(getattr(an, k), bool):
            _fail(f"{w} [annotations]", k, getattr(an, k), "true or false")


def _check_color(where, key, c) -> None:
    if isinstance(c, ColorMap):
        _name(where, f"{key}.attribute", c.attribute)
        if not known_colormap(c.cmap):
            _fail(where, f"{key}.cmap", c.cmap, "a colormap name the 'cmap' package knows")
        _range(where, f"{key}.range", c.range, auto=True)
    else:
        _rgba(where, key, c)


def _check_shape(where, sh: Shape) -> None:
    if not isinstance(sh, Shape):
        _fail(where, "shape", sh, "a Shape")
    if sh.name not in SHAPE_NAMES + ("custom",):
        _fail(where, "shape.name", sh.name, ", ".join(map(repr, SHAPE_NAMES)) + " or 'custom' "
              "(or give points = [[s, f], ...])")
    _name(where, "shape.attribute", sh.attribute)
    _length(where, "shape.length", sh.length, 0.0, lo_open=True)
    if sh.name != "custom":
        if sh.points:
            _fail(where, "shape.points", list(sh.points), f"no points for the built-in '{sh.name}'")
        return
    pts = sh.points
    allowed = (f"2 to {MAX_CURVE_POINTS} control points [s, f] with s from 0 to 1 "
               "non-decreasing and f in 0..1")
    if not isinstance(pts, (list, tuple)) or not 2 <= len(pts) <= MAX_CURVE_POINTS:
        _fail(where, "shape.points", pts, allowed)
    prev = 0.0
    for i, p in enumerate(pts):
        if not isinstance(p, (list, tuple)) or len(p) != 2:
            _fail(where, f"shape.points[{i}]", p, "[s, f]")
        sv = _number(where, f"shape.points[{i}][0]", p[0], 0.0, 1.0)
        _number(where, f"shape.points[{i}][1]", p[1], 0.0, 1.0)
        if sv < prev:
            _fail(where, f"shape.points[{i}][0]", p[0], f"s >= the previous point's s ({prev})")
        prev = sv
    if pts[0][0] != 0 or pts[-1][0] != 1:
        _fail(where, "shape.points", [list(p) for p in pts], allowed)


def _check_pattern(where, pt: Pattern) -> None:
    if not isinstance(pt, Pattern):
        _fail(where, "pattern", pt, "a Pattern")
    _check_color(where, "pattern.color", pt.color)
    _name(where, "pattern.attribute", pt.attribute)
    _length(where, "pattern.length", pt.length, 0.0, lo_open=True)
    _number(where, "pattern.slope", pt.slope)
    _number(where, "pattern.curve", pt.curve, 0.0, lo_open=True)
    _number(where, "pattern.fraction", pt.fraction, 0.0, 1.0)


def _bound(where, key, v) -> float | str:
    """A transfer range bound: a number, +-inf (TOML ``inf``) for an open end, or a relative
    length (on a length or time attribute)."""
    if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isinf(v):
        return float(v)
    return _length(where, key, v, -math.inf) if isinstance(v, str) else _number(where, key, v)


def _relative(ls: LineStyle) -> bool:
    """Whether some width of ``ls`` is relative (its total is known only when drawn)."""
    return any(isinstance(w, str) for b in ls.bands
               for w in ((b.width.min, b.width.max) if isinstance(b.width, WidthMap)
                         else (b.width,)))


def _check_transfer(where, tf: Transfer, styles: dict) -> None:
    tw = f"{where} [transfer]"
    if not isinstance(tf, Transfer):
        _fail(where, "transfer", tf, "a Transfer")
    _name(tw, "attribute", tf.attribute)
    _number(tw, "blend", tf.blend, 0.0)
    if not isinstance(tf.ranges, (list, tuple)) or not 1 <= len(tf.ranges) <= MAX_RANGES:
        _fail(tw, "ranges", tf.ranges, f"1 to {MAX_RANGES} [[transfer.ranges]] tables")
    spans = []
    for i, r in enumerate(tf.ranges):
        rw = f"{tw} range {i + 1}"
        if not isinstance(r.range, (list, tuple)) or len(r.range) != 2:
            _fail(rw, "range", r.range, "[low, high] (inf allowed)")
        lo, hi = (_bound(rw, f"range[{k}]", x) for k, x in enumerate(r.range))
        if isinstance(lo, str) or isinstance(hi, str):  # relative: ordered when drawn
            continue
        if not lo < hi:
            _fail(rw, "range", list(r.range), "[low, high] with low < high")
        if r.style is not None and r.style not in styles:
            _fail(rw, "style", r.style, "one of the styles " + ", ".join(map(repr, styles))
                  + " (or no style: the range is not drawn)")
        for j, (a, b) in enumerate(spans):
            if lo < b and a < hi:
                _fail(rw, "range", list(r.range), f"a range that does not overlap range {j + 1} "
                      f"[{a}, {b}]")
        spans.append((lo, hi))
    if all(r.style is None for r in tf.ranges):
        _fail(tw, "ranges", "no range with a style", "at least one range that names a style")


model.validate = validate  # (the model runs it on every Style built)
