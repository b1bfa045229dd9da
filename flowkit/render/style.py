"""The line style model (paper sections 3.1-3.2) as dataclasses, and TOML loading/validation.

A ``Style`` holds named line styles (``LineStyle``: ordered bands, band 0 innermost, mirrored
about the centre line) plus scene settings (units, scale, background, antialiasing, camera).
A style file with top-level ``[[bands]]`` defines the single line style ``"default"``; named
styles live under ``[styles.NAME]`` so a transfer function (issue 6) can choose between them.

Every value is checked here, once; errors name the file, the key path, the value and what is
allowed. The renderer only ever turns this model into numbers (uniforms, textures) and into
integer/enum template flags -- never pastes a string from it into shader source.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .camera import Camera

STYLE_VERSION = 1
UNITS = ("pixels", "world")
ANTIALIAS = ("msaa", "smooth", "none")
PROJECTIONS = ("perspective", "orthographic")
MAX_BANDS = 8
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]*$")

RGBA = tuple[float, float, float, float]


class StyleError(ValueError):
    """A style value that is not allowed; the message names where, what and what is allowed."""


# -- model -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ColorMap:
    """Colour from colormap ``cmap`` (any name the ``cmap`` package knows) over ``attribute``,
    ``range`` = (value at colormap start, value at colormap end)."""

    cmap: str
    attribute: str
    range: tuple[float, float]


@dataclass(frozen=True)
class WidthMap:
    """Width mapped linearly from ``attribute``: ``range[0]`` -> ``min``, ``range[1]`` -> ``max``,
    clamped outside the range."""

    attribute: str
    range: tuple[float, float]
    min: float
    max: float


@dataclass(frozen=True)
class Band:
    """One band, mirrored on both sides of the centre line.  ``width`` is the width on ONE side
    (band 0 spans [-w0, w0], band 1 spans w0..w0+w1 on each side), in the style's units.
    ``depth_offset`` pushes the band away from the viewer, in view-space (world) units."""

    color: RGBA | ColorMap = (0.0, 0.0, 0.0, 1.0)
    width: float | WidthMap = 1.0
    depth_offset: float = 0.0

    @property
    def max_width(self) -> float:
        return max(self.width.min, self.width.max) if isinstance(self.width, WidthMap) else self.width


@dataclass(frozen=True)
class LineStyle:
    bands: tuple[Band, ...]

    @property
    def total_width(self) -> float:
        """Widest extent on one side: the sum of the bands' maximum widths."""
        return sum(b.max_width for b in self.bands)


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
    version: int = STYLE_VERSION

    def __post_init__(self):
        validate(self)

    @property
    def line_style(self) -> LineStyle:
        """The style drawn when no transfer function chooses (the first one)."""
        return next(iter(self.styles.values()))

    @property
    def max_total_width(self) -> float:
        return max(s.total_width for s in self.styles.values())

    def attributes(self) -> list[str]:
        """Point attributes the style reads, in first-use order (what the renderer uploads)."""
        names: list[str] = []
        for ls in self.styles.values():
            for b in ls.bands:
                for spec in (b.color, b.width):
                    if isinstance(spec, (ColorMap, WidthMap)) and spec.attribute not in names:
                        names.append(spec.attribute)
        return names


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


def _range(where, key, v) -> tuple[float, float]:
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        _fail(where, key, v, "[low, high], two different finite numbers")
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
    for sname, ls in style.styles.items():
        _name(w, "styles", sname)
        if not 1 <= len(ls.bands) <= MAX_BANDS:
            _fail(f"{w}.{sname}", "bands", f"{len(ls.bands)} bands", f"1 to {MAX_BANDS} bands")
        for i, b in enumerate(ls.bands):
            bw = f"style '{sname}' band {i + 1}"
            if isinstance(b.color, ColorMap):
                _name(bw, "color.attribute", b.color.attribute)
                if not known_colormap(b.color.cmap):
                    _fail(bw, "color.cmap", b.color.cmap, "a colormap name the 'cmap' package knows")
                _range(bw, "color.range", b.color.range)
            else:
                _rgba(bw, "color", b.color)
            if isinstance(b.width, WidthMap):
                _name(bw, "width.attribute", b.width.attribute)
                _range(bw, "width.range", b.width.range)
                _number(bw, "width.min", b.width.min, 0.0)
                _number(bw, "width.max", b.width.max, 0.0)
            else:
                _number(bw, "width", b.width, 0.0)
            _number(bw, "depth_offset", b.depth_offset, 0.0)
        if ls.total_width <= 0:
            _fail(f"{w}.{sname}", "bands", "total width 0", "a positive total width")


# -- TOML -> model --------------------------------------------------------------------------------
def _check_keys(where: str, table: dict, allowed: set[str]):
    if not isinstance(table, dict):
        _fail(where, "table", table, "a TOML table")
    for k in table:
        if k not in allowed:
            raise StyleError(f"{where}: unknown key '{k}'; allowed keys: {', '.join(sorted(allowed))}")


def _band_from(where: str, t: dict) -> Band:
    _check_keys(where, t, {"color", "width", "depth_offset"})
    color = t.get("color", "#000000")
    if isinstance(color, dict):
        _check_keys(f"{where}.color", color, {"cmap", "attribute", "range"})
        for k in ("cmap", "attribute", "range"):
            if k not in color:
                raise StyleError(f"{where}.color: missing key '{k}' (a colormap colour needs cmap, attribute, range)")
        if not isinstance(color["cmap"], str):
            _fail(where, "color.cmap", color["cmap"], "a colormap name (string)")
        color = ColorMap(color["cmap"], _name(where, "color.attribute", color["attribute"]),
                         _range(where, "color.range", color["range"]))
        if not known_colormap(color.cmap):
            _fail(where, "color.cmap", color.cmap, "a colormap name the 'cmap' package knows, e.g. 'viridis'")
    else:
        color = _rgba(where, "color", color)
    width = t.get("width", 1.0)
    if isinstance(width, dict):
        _check_keys(f"{where}.width", width, {"attribute", "range", "min", "max"})
        for k in ("attribute", "range", "min", "max"):
            if k not in width:
                raise StyleError(f"{where}.width: missing key '{k}' (a mapped width needs attribute, range, min, max)")
        width = WidthMap(_name(where, "width.attribute", width["attribute"]),
                         _range(where, "width.range", width["range"]),
                         _number(where, "width.min", width["min"], 0.0),
                         _number(where, "width.max", width["max"], 0.0))
    else:
        width = _number(where, "width", width, 0.0)
    depth = _number(where, "depth_offset", t.get("depth_offset", 0.0), 0.0)
    return Band(color, width, depth)


def _line_style_from(where: str, bands) -> LineStyle:
    if not isinstance(bands, list) or not bands:
        _fail(where, "bands", bands, "an array of tables [[bands]] with at least one band")
    if len(bands) > MAX_BANDS:
        _fail(where, "bands", f"{len(bands)} bands", f"at most {MAX_BANDS} bands")
    return LineStyle(tuple(_band_from(f"{where} band {i + 1}", b) for i, b in enumerate(bands)))


def style_from_dict(data: dict, where: str = "style") -> Style:
    """Build a Style from parsed TOML (or an equivalent dict)."""
    top = {"version", "units", "scale", "background", "antialias", "samples", "supersample",
           "camera", "bands", "styles"}
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
    try:
        return Style(styles=styles, **kw)
    except StyleError as e:  # checks shared with Python-built styles: name the file too
        raise StyleError(f"{where}: {e}") from None


def camera_from_dict(where: str, t: dict) -> Camera:
    _check_keys(where, t, {"azimuth", "elevation", "distance", "target", "up", "fov", "projection",
                           "zoom"})
    kw = {}
    for k in ("azimuth", "elevation"):
        if k in t:
            kw[k] = _number(where, k, t[k], -360.0, 360.0)
    if "distance" in t:
        kw["distance"] = _number(where, "distance", t["distance"], 0.0, lo_open=True)
    if "fov" in t:
        kw["fov"] = _number(where, "fov", t["fov"], 1.0, 170.0)
    if "zoom" in t:
        kw["zoom"] = _number(where, "zoom", t["zoom"], 0.0, lo_open=True)
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
