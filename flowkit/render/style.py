"""The line style model (paper sections 3.1-3.2) as dataclasses, and TOML loading/validation.

A ``Style`` holds named line styles (``LineStyle``: ordered bands, band 0 innermost, mirrored
about the centre line) plus scene settings (units, scale, background, antialiasing, camera).
A style file with top-level ``[[bands]]`` defines the single line style ``"default"``; named
styles live under ``[styles.NAME]`` so a transfer function can choose between them.

Every value is checked here, once; errors name the file, the key path, the value and what is
allowed. The renderer only ever turns this model into numbers (uniforms, textures) and into
integer/enum template flags -- never pastes a string from it into shader source.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .camera import FITS, VIEWS, Camera
from .length_forms import FORMS as LENGTH_FORMS
from .length_forms import parse as parse_length
from .shapes import SHAPE_NAMES

STYLE_VERSION = 1
UNITS = ("pixels", "world")
ANTIALIAS = ("msaa", "smooth", "none")
PROJECTIONS = ("perspective", "orthographic")
MAX_BANDS = 8
MAX_RANGES = 8  # transfer function ranges
MAX_CURVE_POINTS = 256  # control points of a user shape
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]*$")

RGBA = tuple[float, float, float, float]


class StyleError(ValueError):
    """A style value that is not allowed; the message names where, what and what is allowed."""


# -- model -------------------------------------------------------------------------------------
# A colour or width range: (low, high); None = the attribute's range over the lines drawn;
# "pA..pB" = its A-th to B-th percentiles (for data with outliers).  ``resolve_ranges`` turns the
# last two into numbers before anything is drawn.
Range = tuple[float, float] | str | None
_PERCENTILES = re.compile(r"^p(\d+(?:\.\d*)?)\.\.p(\d+(?:\.\d*)?)$")


@dataclass(frozen=True)
class ColorMap:
    """Colour from colormap ``cmap`` (any name the ``cmap`` package knows) over ``attribute``,
    ``range`` = (value at colormap start, value at colormap end), or None / "pA..pB" (see
    ``Range``)."""

    cmap: str
    attribute: str
    range: Range = None


@dataclass(frozen=True)
class WidthMap:
    """Width mapped linearly from ``attribute``: ``range[0]`` -> ``min``, ``range[1]`` -> ``max``,
    clamped outside the range (None / "pA..pB": from the data, see ``Range``)."""

    attribute: str
    range: Range
    min: float
    max: float


@dataclass(frozen=True)
class Shape:
    """Shape mapping function: the band's width times f(s), s = (x / ``length`` + phase) mod 1
    with x = ``attribute`` (increasing along the line: ``arc_length`` for constant-size shapes,
    ``time`` for shapes whose length shows speed).  ``name``: a built-in (SHAPE_NAMES) or
    ``"custom"`` with ``points`` = piecewise-linear control points (s, f), s from 0 to 1
    non-decreasing, f in 0..1."""

    name: str
    attribute: str = "arc_length"
    length: float = 1.0
    points: tuple[tuple[float, float], ...] = ()


@dataclass(frozen=True)
class Pattern:
    """Directional colour pattern f_d(x, b) = ((x / ``length`` + ``slope`` * b ** ``curve`` +
    phase) mod 1) - ``fraction``, b in 0..1 the lateral position on the band: the band's own
    colour where f_d < 0, ``color`` (constant or colormap) where f_d >= 0.  Width untouched."""

    color: RGBA | ColorMap
    attribute: str = "arc_length"
    length: float = 1.0
    slope: float = 0.0
    curve: float = 1.0
    fraction: float = 0.5


@dataclass(frozen=True)
class Band:
    """One band, mirrored on both sides of the centre line.  ``width`` is the width on ONE side
    (band 0 spans [-w0, w0], band 1 spans w0..w0+w1 on each side), in the style's units.
    ``depth_offset`` pushes the band away from the viewer, in view-space (world) units.  Each
    length may instead be relative to the scene ("2px", "1/200d", "0.1z", "0.05 m": see
    ``lengths``), made a number before drawing.
    ``shape`` multiplies the width by f(s) (so an inner band's shape moves the outer bands);
    ``pattern`` switches between the band's colour and a second one."""

    color: RGBA | ColorMap = (0.0, 0.0, 0.0, 1.0)
    width: float | WidthMap = 1.0
    depth_offset: float = 0.0
    shape: Shape | None = None
    pattern: Pattern | None = None

    @property
    def max_width(self) -> float:
        """(Relative lengths resolved: see lengths.resolve_lengths.)"""
        return max(self.width.min, self.width.max) if isinstance(self.width, WidthMap) else self.width


@dataclass(frozen=True)
class LineStyle:
    bands: tuple[Band, ...]

    @property
    def total_width(self) -> float:
        """Widest extent on one side: the sum of the bands' maximum widths."""
        return sum(b.max_width for b in self.bands)


@dataclass(frozen=True)
class TransferRange:
    """Attribute values in [range[0], range[1]) get line style ``style``; None discards them."""

    range: tuple[float, float]
    style: str | None


@dataclass(frozen=True)
class Transfer:
    """Line style transfer function: per fragment, the value of ``attribute`` picks the range and
    so the whole line style; values in no range are discarded.  ``blend`` > 0 blends the colours
    of two adjacent styles over that many attribute units around their common bound (the
    geometry switches at the bound)."""

    attribute: str
    ranges: tuple[TransferRange, ...]
    blend: float = 0.0


PLACEMENTS = ("auto", "top-left", "top-right", "bottom-left", "bottom-right", "outside")


@dataclass(frozen=True)
class Legend:
    """``[legend]``: ``show`` it (default; drawn where the caller asks for overlays, e.g.
    ``flowkit render``) at ``placement`` ("auto": the corner where it covers the fewest drawn
    pixels; "outside": in a margin added to the picture, the annotations too)."""

    show: bool = True
    placement: str = "auto"


@dataclass(frozen=True)
class Annotations:
    """``[annotations]``: a ``title``, the snapshot's ``time`` (``t = 2000 s``, when the lines
    file knows it), free ``text`` and a ``scale_bar`` in world units."""

    title: str = ""
    time: bool = True
    text: str = ""
    scale_bar: bool = False


@dataclass(frozen=True)
class Style:
    """A whole scene style.  Use :func:`load_style` for files or build it in Python:
    ``Style(styles={"default": LineStyle((Band(...), Band(...)))})``."""

    styles: dict[str, LineStyle]
    units: str = "pixels"
    scale: float = 1.0
    background: RGBA | None = (1.0, 1.0, 1.0, 1.0)  # None = transparent
    antialias: str = "msaa"
    samples: int = 4
    supersample: int = 1
    camera: Camera = field(default_factory=Camera)
    transfer: Transfer | None = None
    phase: float = 0.0  # added to every shape's and pattern's s, in periods (animation)
    legend: Legend = field(default_factory=Legend)
    annotations: Annotations = field(default_factory=Annotations)
    version: int = STYLE_VERSION

    def __post_init__(self):
        validate(self)

    def __repr__(self) -> str:
        """A few lines: each line style's bands (colour and width, as numbers or mapped from
        an attribute over a range), the transfer function, the settings not at their defaults."""
        drawn = self.used_styles()
        head = (f"<Style: {len(self.styles)} line style{'s' * (len(self.styles) != 1)}, widths "
                f"in {self.units}, reads {', '.join(self.attributes()) or 'no attribute'}")
        out = [head]
        for name, ls in self.styles.items():
            out.append(f"  {name}:" + ("" if name in drawn else " (drawn by no range)"))
            out += [f"    band {i}: {_show_band(b)}" for i, b in enumerate(ls.bands)]
        if self.transfer is not None:
            tf = self.transfer
            out.append(f"  transfer on {tf.attribute}: " + ", ".join(
                f"[{_g(r.range[0])}, {_g(r.range[1])}) {r.style or 'discarded'}"
                for r in tf.ranges) + (f", blend {_g(tf.blend)}" if tf.blend else ""))
        bg = "transparent" if self.background is None else _show_color(self.background)
        rest = [f"background {bg}", f"antialias {self.antialias}"
                + (f" x{self.samples}" if self.antialias == "msaa" else "")]
        rest += [f"{k} {_g(getattr(self, k))}" for k, d in (("scale", 1.0), ("supersample", 1),
                                                            ("phase", 0.0))
                 if getattr(self, k) != d]
        for key in ("camera", "legend", "annotations"):
            val = getattr(self, key)
            changed = {f.name: getattr(val, f.name) for f in dataclasses.fields(val)
                       if getattr(val, f.name) != f.default}
            if changed:
                rest.append(f"{key} " + " ".join(f"{k}={v!r}" for k, v in changed.items()))
        out.append("  " + ", ".join(rest))
        return "\n".join(out) + ">"

    def _repr_html_(self) -> str:
        import html

        return f"<pre>{html.escape(repr(self))}</pre>"

    @property
    def line_style(self) -> LineStyle:
        """The style drawn when no transfer function chooses (the first one)."""
        return next(iter(self.styles.values()))

    def used_styles(self) -> list[str]:
        """Names of the line styles drawn: those the transfer function maps ranges to, in range
        order, or the first style when there is no transfer function."""
        if self.transfer is None:
            return [next(iter(self.styles))]
        names: list[str] = []
        for r in self.transfer.ranges:
            if r.style is not None and r.style not in names:
                names.append(r.style)
        return names

    @property
    def max_total_width(self) -> float:
        """Half-width of the strip: the widest drawn style (0 if a transfer discards all)."""
        return max((self.styles[n].total_width for n in self.used_styles()), default=0.0)

    @property
    def animated(self) -> bool:
        """Whether some drawn band has a shape or pattern that ``phase`` moves."""
        return any(b.shape is not None or b.pattern is not None
                   for n in self.used_styles() for b in self.styles[n].bands)

    def attributes(self) -> list[str]:
        """Point attributes the drawn styles read, in first-use order (what the renderer
        uploads and what a scene traces)."""
        names: list[str] = []
        if self.transfer is not None:
            names.append(self.transfer.attribute)
        for n in self.used_styles():
            for b in self.styles[n].bands:
                pc = b.pattern.color if b.pattern is not None else None
                for spec in (b.color, b.width, b.shape, b.pattern, pc):
                    a = getattr(spec, "attribute", None)
                    if a is not None and a not in names:
                        names.append(a)
        return names


# -- repr ---------------------------------------------------------------------------------------
def _g(v) -> str:
    """A number as %g, a relative length ("2px", "1/50z") as written."""
    return v if isinstance(v, str) else f"{v:g}"


def _show_range(r: Range) -> str:
    if r is None:
        return "over the data's range"
    if isinstance(r, str):
        return f"over the data's percentiles {r}"
    return f"over [{_g(r[0])}, {_g(r[1])}]"


def _show_color(c) -> str:
    if isinstance(c, ColorMap):
        return f"{c.cmap} of {c.attribute} {_show_range(c.range)}"
    hexa = _color_out(c)
    return hexa if isinstance(hexa, str) else "rgba(" + ", ".join(f"{v:.3g}" for v in c) + ")"


def _show_band(b: Band) -> str:
    w = b.width
    out = [f"colour {_show_color(b.color)}",
           f"width {_g(w.min)}..{_g(w.max)} from {w.attribute} {_show_range(w.range)}"
           if isinstance(w, WidthMap) else f"width {_g(w)}"]
    if b.depth_offset != 0:
        out.append(f"set back {_g(b.depth_offset)}")
    if b.shape is not None:
        sh = b.shape
        out.append(f"shape {sh.name} every {_g(sh.length)} of {sh.attribute}")
    if b.pattern is not None:
        pt = b.pattern
        out.append(f"pattern {_show_color(pt.color)} every {_g(pt.length)} of {pt.attribute}")
    return ", ".join(out)


# -- validation (shared by Python construction and file loading) --------------------------------
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


# -- TOML -> model --------------------------------------------------------------------------------
def _check_keys(where: str, table: dict, allowed: set[str]):
    if not isinstance(table, dict):
        _fail(where, "table", table, "a TOML table")
    for k in table:
        if k not in allowed:
            raise StyleError(f"{where}: unknown key '{k}'; allowed keys: {', '.join(sorted(allowed))}")


def _color_from(where: str, key: str, color) -> RGBA | ColorMap:
    if isinstance(color, dict):
        _check_keys(f"{where}.{key}", color, {"cmap", "attribute", "range"})
        for k in ("cmap", "attribute"):
            if k not in color:
                raise StyleError(f"{where}.{key}: missing key '{k}' (a colormap colour needs cmap "
                                 "and attribute; range is optional: the data's range)")
        if not isinstance(color["cmap"], str):
            _fail(where, f"{key}.cmap", color["cmap"], "a colormap name (string)")
        color = ColorMap(color["cmap"], _name(where, f"{key}.attribute", color["attribute"]),
                         _range(where, f"{key}.range", _toml_range(color.get("range")), auto=True))
        if not known_colormap(color.cmap):
            _fail(where, f"{key}.cmap", color.cmap, "a colormap name the 'cmap' package knows, e.g. 'viridis'")
        return color
    return _rgba(where, key, color)


def _toml_range(v):
    return tuple(v) if isinstance(v, list) else v


def _shape_from(where: str, t) -> Shape:
    if isinstance(t, str):  # shape = "arrow": arc length, period 1
        t = {"name": t}
    _check_keys(f"{where}.shape", t, {"name", "attribute", "length", "points"})
    if "points" in t:
        if t.get("name", "custom") != "custom":
            _fail(where, "shape.name", t["name"], "'custom' (or no name) with points")
        pts = t["points"]
        if not isinstance(pts, list):
            _fail(where, "shape.points", pts, "an array of [s, f] pairs")
        name, pts = "custom", tuple(tuple(p) if isinstance(p, list) else p for p in pts)
    elif "name" in t:
        name, pts = t["name"], ()
    else:
        raise StyleError(f"{where}.shape: missing key 'name' (one of {', '.join(SHAPE_NAMES)}) "
                         "or 'points' (a user shape)")
    sh = Shape(name, t.get("attribute", "arc_length"), t.get("length", 1.0), pts)
    _check_shape(where, sh)
    length = sh.length if isinstance(sh.length, str) else float(sh.length)
    return Shape(sh.name, sh.attribute, length,
                 tuple((float(a), float(b)) for a, b in sh.points))


def _pattern_from(where: str, t) -> Pattern:
    _check_keys(f"{where}.pattern", t, {"color", "attribute", "length", "slope", "curve",
                                         "fraction"})
    if "color" not in t:
        raise StyleError(f"{where}.pattern: missing key 'color' (the second colour of the pattern)")
    pt = Pattern(_color_from(where, "pattern.color", t["color"]),
                 t.get("attribute", "arc_length"),
                 _length(where, "pattern.length", t.get("length", 1.0), 0.0, lo_open=True),
                 *(_number(where, f"pattern.{k}", t.get(k, d))
                   for k, d in (("slope", 0.0), ("curve", 1.0), ("fraction", 0.5))))
    _check_pattern(where, pt)
    return pt


def _transfer_from(where: str, t) -> Transfer:
    tw = f"{where} [transfer]"
    _check_keys(tw, t, {"attribute", "ranges", "blend"})
    for k in ("attribute", "ranges"):
        if k not in t:
            raise StyleError(f"{tw}: missing key '{k}' (a transfer function needs attribute and "
                             "[[transfer.ranges]] tables with range and style)")
    if not isinstance(t["ranges"], list):
        _fail(tw, "ranges", t["ranges"], "[[transfer.ranges]] tables")
    ranges = []
    for i, r in enumerate(t["ranges"]):
        _check_keys(f"{tw} range {i + 1}", r, {"range", "style"})
        if "range" not in r or isinstance(r["range"], str):  # (bounds may be lengths: '1/8d')
            got = f" = {r['range']!r}" if "range" in r else " is missing"
            raise StyleError(f"{tw} range {i + 1}: range{got}; a transfer function's bounds "
                             "cannot come from the data: give range = [low, high] (inf allowed)")
        st = r.get("style")
        if st is not None and not isinstance(st, str):
            _fail(f"{tw} range {i + 1}", "style", st, "a style name")
        rng = r["range"]
        ranges.append(TransferRange(tuple(rng) if isinstance(rng, list) else rng, st))
    return Transfer(t["attribute"], tuple(ranges), t.get("blend", 0.0))


def _band_from(where: str, t: dict) -> Band:
    _check_keys(where, t, {"color", "width", "depth_offset", "shape", "pattern"})
    color = _color_from(where, "color", t.get("color", "#000000"))
    width = t.get("width", 1.0)
    if isinstance(width, dict):
        _check_keys(f"{where}.width", width, {"attribute", "range", "min", "max"})
        for k in ("attribute", "min", "max"):
            if k not in width:
                raise StyleError(f"{where}.width: missing key '{k}' (a mapped width needs "
                                 "attribute, min, max; range is optional: the data's range)")
        width = WidthMap(_name(where, "width.attribute", width["attribute"]),
                         _range(where, "width.range", _toml_range(width.get("range")), auto=True),
                         _length(where, "width.min", width["min"]),
                         _length(where, "width.max", width["max"]))
    else:
        width = _length(where, "width", width)
    depth = _length(where, "depth_offset", t.get("depth_offset", 0.0))
    shape = _shape_from(where, t["shape"]) if "shape" in t else None
    pattern = _pattern_from(where, t["pattern"]) if "pattern" in t else None
    return Band(color, width, depth, shape, pattern)


def _line_style_from(where: str, bands) -> LineStyle:
    if not isinstance(bands, list) or not bands:
        _fail(where, "bands", bands, "an array of tables [[bands]] with at least one band")
    if len(bands) > MAX_BANDS:
        _fail(where, "bands", f"{len(bands)} bands", f"at most {MAX_BANDS} bands")
    return LineStyle(tuple(_band_from(f"{where} band {i + 1}", b) for i, b in enumerate(bands)))


def style_from_dict(data: dict, where: str = "style") -> Style:
    """Build a Style from parsed TOML (or an equivalent dict)."""
    top = {"version", "units", "scale", "background", "antialias", "samples", "supersample",
           "camera", "bands", "styles", "transfer", "phase", "legend", "annotations"}
    _check_keys(where, data, top)
    if "version" not in data:
        raise StyleError(f"{where}: missing key 'version' (this flowkit reads version = {STYLE_VERSION})")
    if data["version"] != STYLE_VERSION:
        _fail(where, "version", data["version"], f"{STYLE_VERSION}")
    if ("bands" in data) == ("styles" in data):
        raise StyleError(f"{where}: give exactly one of [[bands]] (one line style) or [styles.NAME] tables")
    if "bands" in data:
        styles = {"default": _line_style_from(where, data["bands"])}
    else:
        if not isinstance(data["styles"], dict) or not data["styles"]:
            _fail(where, "styles", data["styles"], "tables [styles.NAME] each with [[styles.NAME.bands]]")
        styles = {}
        for name, t in data["styles"].items():
            _name(where, "styles", name)
            _check_keys(f"{where} [styles.{name}]", t, {"bands"})
            styles[name] = _line_style_from(f"{where} style '{name}'", t.get("bands"))
    kw = {}
    if "units" in data:
        if data["units"] not in UNITS:
            _fail(where, "units", data["units"], " or ".join(map(repr, UNITS)))
        kw["units"] = data["units"]
    if "scale" in data:
        kw["scale"] = _number(where, "scale", data["scale"], 0.0, lo_open=True)
    if "background" in data:
        bg = data["background"]
        kw["background"] = None if bg == "transparent" else _rgba(where, "background", bg)
    if "antialias" in data:
        if data["antialias"] not in ANTIALIAS:
            _fail(where, "antialias", data["antialias"], " or ".join(map(repr, ANTIALIAS)))
        kw["antialias"] = data["antialias"]
    for k in ("samples", "supersample"):
        if k in data:
            if isinstance(data[k], bool) or not isinstance(data[k], int):
                _fail(where, k, data[k], "an integer")
            kw[k] = data[k]
    if "camera" in data:
        kw["camera"] = camera_from_dict(f"{where} [camera]", data["camera"])
    if "transfer" in data:
        kw["transfer"] = _transfer_from(where, data["transfer"])
    if "phase" in data:
        kw["phase"] = _number(where, "phase", data["phase"])
    for key, cls in (("legend", Legend), ("annotations", Annotations)):
        if key in data:
            names = {f.name for f in dataclasses.fields(cls)}
            _check_keys(f"{where} [{key}]", data[key], names)
            kw[key] = cls(**data[key])
    try:
        return Style(styles=styles, **kw)
    except StyleError as e:  # checks shared with Python-built styles: name the file too
        raise StyleError(f"{where}: {e}") from None


def camera_from_dict(where: str, t: dict) -> Camera:
    _check_keys(where, t, {"azimuth", "elevation", "distance", "target", "up", "fov", "projection",
                           "zoom", "view", "fit", "parallel_scale"})
    kw = {}
    if "view" in t:
        if t["view"] not in VIEWS:
            _fail(where, "view", t["view"], ", ".join(map(repr, VIEWS)))
        both = [k for k in ("azimuth", "elevation") if k in t]
        if both:
            raise StyleError(f"{where}: view = {t['view']!r} and {both[0]} = {t[both[0]]!r} both "
                             "set the view direction; give one of them")
        kw["view"] = t["view"]
    for k in ("azimuth", "elevation"):
        if k in t:
            kw[k] = _number(where, k, t[k], -360.0, 360.0)
    if "distance" in t:
        kw["distance"] = _number(where, "distance", t["distance"], 0.0, lo_open=True)
    if "fov" in t:
        kw["fov"] = _number(where, "fov", t["fov"], 1.0, 170.0)
    for k in ("zoom", "parallel_scale"):
        if k in t:
            kw[k] = _number(where, k, t[k], 0.0, lo_open=True)
    for k in ("target", "up"):
        if k in t:
            v = t[k]
            if not isinstance(v, list) or len(v) != 3:
                _fail(where, k, v, "[x, y, z]")
            kw[k] = tuple(_number(where, f"{k}[{i}]", x) for i, x in enumerate(v))
    if "projection" in t:
        if t["projection"] not in PROJECTIONS:
            _fail(where, "projection", t["projection"], " or ".join(map(repr, PROJECTIONS)))
        kw["projection"] = t["projection"]
    if "fit" in t:
        if t["fit"] not in FITS:
            _fail(where, "fit", t["fit"], " or ".join(map(repr, FITS)))
        kw["fit"] = t["fit"]
    return Camera(**kw)


def load_style(path: str | Path) -> Style:
    """Read and validate a TOML style file; errors name the file and the key."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise FileNotFoundError(f"style file not found: {path}") from None
    except tomllib.TOMLDecodeError as e:
        raise StyleError(f"{path}: not valid TOML: {e}") from None
    return style_from_dict(data, where=str(path))


# -- model -> TOML (the viewer's "save style") ---------------------------------------------------
def _color_out(c):
    if isinstance(c, ColorMap):
        return {"cmap": c.cmap, "attribute": c.attribute, **_range_out(c.range)}
    if all(round(v * 255) / 255 == v for v in c):  # exactly a hex colour: write it as one
        return "#" + "".join(f"{round(v * 255):02x}" for v in (c if c[3] != 1.0 else c[:3]))
    return list(c)


def _range_out(r: Range) -> dict:
    """The ``range`` key of a colour or width table (none: from the data)."""
    return {} if r is None else {"range": r if isinstance(r, str) else list(r)}


def _band_out(b: Band) -> dict:
    w = b.width
    out = {"color": _color_out(b.color),
           "width": {"attribute": w.attribute, **_range_out(w.range), "min": w.min,
                     "max": w.max} if isinstance(w, WidthMap) else w,
           "depth_offset": b.depth_offset}
    if b.shape is not None:
        sh = b.shape
        out["shape"] = {"attribute": sh.attribute, "length": sh.length}
        if sh.name == "custom":
            out["shape"]["points"] = [list(p) for p in sh.points]
        else:
            out["shape"]["name"] = sh.name
    if b.pattern is not None:
        p = b.pattern
        out["pattern"] = {"color": _color_out(p.color), "attribute": p.attribute,
                          "length": p.length, "slope": p.slope, "curve": p.curve,
                          "fraction": p.fraction}
    return out


def style_to_dict(style: Style) -> dict:
    """The TOML tables of ``style``: ``style_from_dict(style_to_dict(s)) == s``."""
    out = {"version": style.version, "units": style.units, "scale": style.scale,
           "background": "transparent" if style.background is None
           else _color_out(style.background),
           "antialias": style.antialias, "samples": style.samples,
           "supersample": style.supersample, "phase": style.phase}
    cam = {k: list(v) if isinstance(v, tuple) else v
           for k, v in vars(style.camera).items() if v is not None}
    if style.camera.view is not None:  # the named view replaces azimuth and elevation
        cam.pop("azimuth", None), cam.pop("elevation", None)
    out["camera"] = cam
    if list(style.styles) == ["default"] and style.transfer is None:
        out["bands"] = [_band_out(b) for b in style.line_style.bands]
    else:
        out["styles"] = {n: {"bands": [_band_out(b) for b in ls.bands]}
                         for n, ls in style.styles.items()}
    for key in ("legend", "annotations"):
        val = getattr(style, key)
        if val != type(val)():
            out[key] = dataclasses.asdict(val)
    if style.transfer is not None:
        tf = style.transfer
        out["transfer"] = {"attribute": tf.attribute, "blend": tf.blend, "ranges": [
            {"range": list(r.range), **({"style": r.style} if r.style is not None else {})}
            for r in tf.ranges]}
    return out


def dump_style(data: Style | dict) -> str:
    """TOML text of a Style (or of already-built style tables)."""
    import tomlkit

    return tomlkit.dumps(style_to_dict(data) if isinstance(data, Style) else data)


def save_style(data: Style | dict, path: str | Path, *, keep: str | None = None) -> Path:
    """Write a style as TOML atomically (temp file beside it + rename).

    ``keep``: the text of the file the style was read from.  Its comments, order and spelling are
    kept and only the values the style changed are rewritten; where that cannot give the style
    back (the file laid out unlike ``style_to_dict``), the whole style is written plainly.
    """
    from ..io.atomic import atomic_path

    text = _edit_text(keep, data) if keep is not None and isinstance(data, Style) else None
    if text is None:
        text = dump_style(data)
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return Path(path)


def _edit_text(text: str, style: Style) -> str | None:
    """``text`` (a style file) with the values that differ from ``style`` replaced, or None."""
    import tomlkit
    from tomlkit.exceptions import TOMLKitError

    try:
        doc = tomlkit.parse(text)
        old = style_to_dict(style_from_dict(doc.unwrap()))
    except (TOMLKitError, StyleError):
        return None
    _edit_tables(doc, old, style_to_dict(style))
    out = tomlkit.dumps(doc)
    try:  # the edited file must read back as the style, or it is not written
        return out if style_from_dict(tomllib.loads(out)) == style else None
    except (tomllib.TOMLDecodeError, StyleError):
        return None


def _edit_tables(doc, old: dict, new: dict) -> None:
    """Make the tomlkit table ``doc`` (read as ``old``) read as ``new``, touching only what
    differs: tables and arrays of tables of the same length are edited entry by entry."""
    for key in old.keys() - new.keys():
        doc.pop(key, None)
    for key, value in new.items():
        was, cur = old.get(key), doc.get(key)
        if key in old and was == value:
            continue
        if isinstance(value, dict) and isinstance(was, dict) and isinstance(cur, dict):
            _edit_tables(cur, was, value)
        elif (isinstance(value, list) and isinstance(was, list) and isinstance(cur, list)
              and len(value) == len(was) == len(cur)
              and all(isinstance(x, dict) for x in (*value, *was, *cur))):
            for c, w, v in zip(cur, was, value):
                _edit_tables(c, w, v)
        else:
            doc[key] = value
