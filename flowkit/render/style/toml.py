"""Style files: TOML tables -> Style (``style_from_dict``, ``load_style``: every value checked
by ``check``, errors naming the file and the key) and Style -> TOML (``style_to_dict``,
``dump_style``), and ``save_style``, which rewrites only the values that changed in the file's
own text (its comments, order and spelling kept).

A style file with top-level ``[[bands]]`` defines the single line style ``"default"``; named
styles live under ``[styles.NAME]`` so a transfer function can choose between them.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

from ..camera import FITS, VIEWS, Camera
from ..shapes import SHAPE_NAMES
from .check import (
    MAX_BANDS,
    StyleError,
    _check_pattern,
    _check_shape,
    _fail,
    _length,
    _name,
    _number,
    _range,
    _rgba,
    known_colormap,
)
from .model import (
    ANTIALIAS,
    PROJECTIONS,
    RGBA,
    STYLE_VERSION,
    UNITS,
    Annotations,
    Band,
    ColorMap,
    Legend,
    LineStyle,
    Pattern,
    Range,
    Shape,
    Style,
    Transfer,
    TransferRange,
    WidthMap,
    hex_color,
)


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
    return hex_color(c) or list(c)  # exactly a hex colour: written as one


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
    from ...io.atomic import atomic_path

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
