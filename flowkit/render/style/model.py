"""The line style model (paper sections 3.1-3.2) as frozen dataclasses.

A ``Style`` holds named line styles (``LineStyle``: ordered bands, band 0 innermost, mirrored
about the centre line) plus scene settings (units, scale, background, antialiasing, camera).
A Style checks itself when built (``check.validate``); ``toml`` reads and writes style files.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from ..camera import Camera

STYLE_VERSION = 1


def validate(style) -> None:
    """Every Style checks itself when built, by ``check.validate``: check reads the model, so
    it puts its function here (importing this module imports the package, and so check)."""
    raise RuntimeError("flowkit.render.style.check was not imported")


UNITS = ("pixels", "world")
ANTIALIAS = ("msaa", "smooth", "none")
PROJECTIONS = ("perspective", "orthographic")

RGBA = tuple[float, float, float, float]

# A colour or width range: (low, high); None = the attribute's range over the lines drawn;
# "pA..pB" = its A-th to B-th percentiles (for data with outliers).  ``resolve_ranges`` turns the
# last two into numbers before anything is drawn.
Range = tuple[float, float] | str | None


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
    return hex_color(c) or "rgba(" + ", ".join(f"{v:.3g}" for v in c) + ")"


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


def hex_color(c: RGBA) -> str | None:
    """``'#rrggbb'`` (``'#rrggbbaa'`` unless opaque) when every channel is a multiple of 1/255
    (the colour is then exactly that hex colour), else None."""
    if all(round(v * 255) / 255 == v for v in c):
        return "#" + "".join(f"{round(v * 255):02x}" for v in (c if c[3] != 1.0 else c[:3]))
    return None
