"""The scene file model: one TOML file from snapshot to picture (``version = 1``).

::

    version = 1
    [field]                  # exactly one of file / series / dataset
    file = "run.h5"          # one file (several snapshots allowed), relative to this file
    # series = "run_*.vti"   # a glob or a ParaView .series file
    # dataset = "hotroom"    # built-in demo data
    vector = "U"
    snapshot = "all"         # "all" (default), a position (negative from the end) or a list
    # resample = "160,120,60"  # unstructured meshes: NX,NY,NZ or "spacing:DX" (default: auto)
    # data = "cell"          # VTK files: cell data (default point data)

    [seeds]
    spec = "plane:0.5,0.5,0.5:9,0,0:0,0,9:16,16"   # any --seeds spec (files relative to here)
    # spec = "even:1/30d"    # evenly spaced lines (direction both unless [trace] says)
    prune = "0.2:0.8"        # optional: drop lines beside a longer one (as --prune)

    [trace]                  # TraceOptions by name (method, rtol, max_length, direction, ...)
    max_length = 20.0
    attributes = []          # extra attributes to store in the lines file (none by default)
    # distribute = "blocks"  # with --workers: "auto" (default), "seeds" or "blocks"

    [styles]                 # name = "style file" (a reference), or an inline style table
    halo = "styles/halo.toml"
    [styles.speed]
    bands = [{ color = { cmap = "viridis", attribute = "speed", range = [0, 0.3] }, width = 2 }]

    [views.front]            # one image per view and snapshot
    style = "halo"           # default: the only style
    size = [1600, 900]       # or "1600x900"
    camera = { azimuth = -90, elevation = 10, up = [0, 1, 0] }   # over the style's camera

    [outputs]                # relative to the output directory (default: this file's directory)
    lines = "lines_{snapshot}.h5"        # placeholders: {snapshot} {time}
    images = "{view}_{snapshot}.png"     # placeholders: {view} {style} {snapshot} {time}
    animation = "{view}_{snapshot}.gif"  # optional, per view: .gif, .png (numbered) or .mp4
    frames = 24                          # the pattern moves one period over the frames
    fps = 12.0

    [cache]
    dir = ".flowkit-cache"   # relative to this file
    enabled = true

Validation reuses the style model's helpers, so errors read alike: they name the file, the key,
the value and what is allowed; unknown keys are errors.  Styles stay the renderer's model: a
scene only names them (a file or an inline table), so whatever the style model grows (shape
functions, transfer functions) plugs in unchanged.
"""

from __future__ import annotations

import dataclasses
import string
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..integrate.options import OptionsError, TraceOptions
from ..integrate.seeds import CHECK_ONLY, FILE_TYPES, SeedError, parse_even_spec, parse_seed_spec
from ..render.animate import FORMATS as ANIMATION_FORMATS
from ..render.camera import Camera
from ..render.style.check import StyleError, _fail, _name, _number
from ..render.style.model import STYLE_VERSION, Style
from ..render.style.toml import _check_keys, camera_from_dict, load_style, style_from_dict

SCENE_VERSION = 1
DATASETS = ("hotroom",)
DEFAULT_SIZE = (1600, 900)
DEFAULT_IMAGES = "{view}_{snapshot}.png"
DEFAULT_FRAMES = 24
DEFAULT_FPS = 12.0
# trace_distributed's distribute= (flowkit/distributed/blocks.py MODES; not imported: loading a
# scene needs no Dask)
DISTRIBUTE = ("auto", "seeds", "blocks")
# TraceOptions the scene decides itself: attributes (from the styles), progress, budget
TRACE_KEYS = tuple(f.name for f in dataclasses.fields(TraceOptions)
                   if f.name not in ("attributes", "progress", "budget"))
IMAGE_FIELDS = ("view", "style", "snapshot", "time")
LINES_FIELDS = ("snapshot", "time")


class SceneError(StyleError):
    """A scene value that is not allowed; the message names the file, key, value and what is."""


@dataclass(frozen=True)
class FieldSource:
    kind: str                  # "file", "series" or "dataset"
    location: str              # absolute path, glob, or dataset name
    vector: str = "U"
    snapshot: str | int | tuple[int, ...] = "all"
    resample: str | None = None  # unstructured meshes: the grid (load_field's resample=)
    data: str | None = None      # VTK files: "point" or "cell" (load_field's data=)

    @property
    def load_options(self) -> dict:
        """load_field's keywords for this field (those given)."""
        return {k: v for k, v in (("resample", self.resample), ("data", self.data))
                if v is not None}


@dataclass(frozen=True)
class View:
    name: str
    style: str
    size: tuple[int, int] = DEFAULT_SIZE
    camera: Camera = field(default_factory=Camera)


@dataclass(frozen=True)
class Outputs:
    lines: str | None = None
    images: str | None = DEFAULT_IMAGES
    animation: str | None = None  # per view, after the stills (flowkit.render.animate)
    frames: int = DEFAULT_FRAMES
    fps: float = DEFAULT_FPS


@dataclass(frozen=True)
class Scene:
    """A validated scene.  ``style_sources`` says where each style came from (file or inline)."""

    path: Path | None
    field: FieldSource
    seeds: str
    trace: TraceOptions
    styles: dict[str, Style]
    style_sources: dict[str, str]
    views: dict[str, View]
    outputs: Outputs = Outputs()
    extra_attributes: tuple[str, ...] = ()
    cache_dir: Path | None = None
    cache_enabled: bool = True
    prune: tuple[float, float] | None = None  # (distance, fraction) from [seeds] prune
    distribute: str = "auto"  # [trace] distribute: trace_distributed's, with workers
    version: int = SCENE_VERSION

    @property
    def base(self) -> Path:
        """Directory relative paths in the scene resolve against."""
        return self.path.parent if self.path is not None else Path.cwd()


# -- loading ----------------------------------------------------------------------------------
def load_scene(path: str | Path) -> Scene:
    """Read and validate a TOML scene file; errors (SceneError) name the file and the key."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise FileNotFoundError(f"scene file not found: {path}") from None
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{path}: not valid TOML: {e}") from None
    return scene_from_dict(data, path=path.resolve(), where=str(path))


def scene_from_dict(data: dict, path: Path | None = None, where: str = "scene") -> Scene:
    """Build a Scene from parsed TOML; relative paths resolve against ``path``'s directory."""
    try:
        return _scene(data, path, where)
    except SceneError:
        raise
    except StyleError as e:  # raised by the style model's shared helpers
        raise SceneError(str(e)) from None


def _scene(data: dict, path: Path | None, where: str) -> Scene:
    base = path.parent if path is not None else Path.cwd()
    _check_keys(where, data, {"version", "field", "seeds", "trace", "styles", "views", "outputs",
                              "cache"})
    if "version" not in data:
        raise SceneError(f"{where}: missing key 'version' (this flowkit reads version = "
                         f"{SCENE_VERSION})")
    if data["version"] != SCENE_VERSION:
        _fail(where, "version", data["version"], f"{SCENE_VERSION}")
    for key in ("field", "seeds", "styles"):
        if key not in data:
            raise SceneError(f"{where}: missing table [{key}]")
    fsrc = _field(f"{where} [field]", data["field"], base)
    seeds, prune = _seeds(f"{where} [seeds]", data["seeds"], base)
    trace, extra, distribute = _trace(f"{where} [trace]", data.get("trace", {}))
    if parse_even_spec(seeds) is not None and "direction" not in data.get("trace", {}):
        trace = trace.replace(direction="both")  # as the CLI: even lines grow both ways
    styles, sources = _styles(f"{where} [styles]", data["styles"], base)
    views = _views(where, data.get("views", {}), styles)
    outputs = _outputs(f"{where} [outputs]", data.get("outputs", {}), views)
    cache_dir, enabled = _cache(f"{where} [cache]", data.get("cache", {}), base)
    return Scene(path, fsrc, seeds, trace, styles, sources, views, outputs, extra, cache_dir,
                 enabled, prune, distribute)


def _string(where, key, v) -> str:
    if not isinstance(v, str) or not v.strip():
        _fail(where, key, v, "a non-empty string")
    return v


def _field(where: str, t: dict, base: Path) -> FieldSource:
    _check_keys(where, t, {"file", "series", "dataset", "vector", "snapshot", "resample",
                           "data"})
    given = [k for k in ("file", "series", "dataset") if k in t]
    if len(given) != 1:
        raise SceneError(f"{where}: give exactly one of file, series or dataset "
                         f"(got {', '.join(given) or 'none'})")
    kind = given[0]
    loc = _string(where, kind, t[kind])
    if kind == "dataset":
        if loc not in DATASETS:
            _fail(where, "dataset", loc, " or ".join(map(repr, DATASETS)))
    else:
        p = Path(loc).expanduser()
        loc = str(p if p.is_absolute() else base / p)
        if kind == "file" and not Path(loc).is_file():
            _fail(where, "file", t[kind], f"an existing file (looked for {loc})")
    vector = _name(where, "vector", t.get("vector", "U"))
    snap = t.get("snapshot", "all")
    resample = t.get("resample")
    if resample is not None:
        from ..fields.resample import parse_resample

        try:
            parse_resample(_string(where, "resample", resample))
        except ValueError:
            _fail(where, "resample", resample, '"NX,NY,NZ", "spacing:DX" or "auto"')
    data = t.get("data")
    if data is not None and data not in ("point", "cell"):
        _fail(where, "data", data, '"point" or "cell"')
    return FieldSource(kind, loc, vector, snapshot_selection(where, "snapshot", snap), resample,
                       data)


def snapshot_selection(where: str, key: str, v) -> str | int | tuple[int, ...]:
    """``"all"``, a position (int, negative from the end) or a non-empty list of positions."""
    allowed = "'all', a snapshot position (negative counts from the end) or a list of positions"
    if v == "all":
        return "all"
    if isinstance(v, int) and not isinstance(v, bool):
        return v
    if isinstance(v, list) and v and all(isinstance(i, int) and not isinstance(i, bool) for i in v):
        return tuple(v)
    _fail(where, key, v, allowed)


def _seeds(where: str, t, base: Path) -> tuple[str, tuple[float, float] | None]:
    if not isinstance(t, dict):
        _fail(where.rsplit(" ", 1)[0], "seeds", t, "a table [seeds] with spec = '...'")
    _check_keys(where, t, {"spec", "prune"})
    prune = None
    if "prune" in t:
        from ..seeding.prune import parse_prune

        try:
            prune = parse_prune(_string(where, "prune", t["prune"]))
        except ValueError:
            _fail(where, "prune", t["prune"], "'DIST[:FRACTION]', a positive distance and a "
                  "fraction in (0, 1] (default 0.8)")
    if "spec" not in t:
        raise SceneError(f"{where}: missing key 'spec' (a seeds spec, e.g. "
                         "'plane:ox,oy,oz:ux,uy,uz:vx,vy,vz:nu,nv')")
    spec = _string(where, "spec", t["spec"]).strip()
    if Path(spec).suffix.lower() in FILE_TYPES and ":" not in spec.split("/")[0]:
        p = Path(spec).expanduser()
        return str(p if p.is_absolute() else base / p), prune
    try:  # what a field decides (random's domain, density's attribute) is checked when run
        parse_seed_spec(spec, CHECK_ONLY)
    except SeedError as e:
        raise SceneError(f"{where}: spec = {spec!r} is not allowed: {e}") from None
    return spec, prune


def _trace(where: str, t: dict) -> tuple[TraceOptions, tuple[str, ...], str]:
    _check_keys(where, t, set(TRACE_KEYS) | {"attributes", "distribute"})
    extra = t.get("attributes", [])
    if not isinstance(extra, list):
        _fail(where, "attributes", extra, "a list of attribute names, e.g. ['T', 'time']")
    extra = tuple(_name(where, f"attributes[{i}]", a) for i, a in enumerate(extra))
    distribute = t.get("distribute", "auto")
    if distribute not in DISTRIBUTE:
        _fail(where, "distribute", distribute, " or ".join(map(repr, DISTRIBUTE))
              + " (how --workers split the trace: docs/scale-out.md)")
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in t.items()
          if k not in ("attributes", "distribute")}
    for k, v in kw.items():  # TraceOptions checks ranges; TOML types are checked here
        if isinstance(v, bool) and k != "cell_aware":
            _fail(where, k, v, "a number or a string, not a boolean")
    if "cell_aware" in kw and not isinstance(kw["cell_aware"], bool):
        _fail(where, "cell_aware", kw["cell_aware"], "true or false")
    try:
        opts = TraceOptions(**kw, progress=False)
    except (OptionsError, ValueError, KeyError, TypeError) as e:
        msg = e.args[0] if e.args else str(e)
        bad = next((k for k in kw if f" {k} " in f" {msg} "), None)
        shown = f"{bad} = {kw[bad]!r}: " if bad else ""
        raise SceneError(f"{where}: {shown}{msg}") from None
    return opts, extra, distribute


def _styles(where: str, t, base: Path) -> tuple[dict[str, Style], dict[str, str]]:
    if not isinstance(t, dict) or not t:
        _fail(where.rsplit(" ", 1)[0], "styles", t,
              "a table [styles] of name = 'style file' or [styles.NAME] inline style tables")
    styles, sources = {}, {}
    for name, v in t.items():
        _name(where, "styles", name)
        if isinstance(v, str):
            p = Path(v).expanduser()
            p = p if p.is_absolute() else base / p
            if not p.is_file():
                _fail(where, name, v, f"a style file that exists (looked for {p})")
            try:
                styles[name] = load_style(p)
            except StyleError as e:
                raise SceneError(f"{where} {name} = {v!r}: {e}") from None
            sources[name] = str(p)
        elif isinstance(v, dict):
            doc = {"version": STYLE_VERSION, **v}  # the scene's version covers inline styles
            styles[name] = style_from_dict(doc, where=f"{where.rsplit(' ', 1)[0]} [styles.{name}]")
            sources[name] = "inline"
        else:
            _fail(where, name, v, "a style file path (string) or an inline style table")
    return styles, sources


def _views(where: str, t, styles: dict[str, Style]) -> dict[str, View]:
    if not isinstance(t, dict):
        _fail(where, "views", t, "tables [views.NAME] with style, size, camera")
    if not t:  # default: one view per style, named after it
        return {n: View(n, n, DEFAULT_SIZE, s.camera) for n, s in styles.items()}
    views = {}
    for name, v in t.items():
        w = f"{where} [views.{name}]"
        _name(f"{where} [views]", "views", name)
        _check_keys(w, v, {"style", "size", "camera"})
        if "style" in v:
            sname = v["style"]
            if sname not in styles:
                _fail(w, "style", sname, "one of the scene's styles: " + ", ".join(styles))
        elif len(styles) == 1:
            sname = next(iter(styles))
        else:
            raise SceneError(f"{w}: missing key 'style' (the scene has {len(styles)} styles: "
                             f"{', '.join(styles)})")
        size = image_size(w, "size", v.get("size", list(DEFAULT_SIZE)))
        cam = styles[sname].camera
        if "camera" in v:  # keys given override the style's camera, the others are kept
            checked = camera_from_dict(f"{w}.camera", v["camera"])
            cam = cam.over(**{k: getattr(checked, k) for k in v["camera"]})
        views[name] = View(name, sname, size, cam)
    return views


def image_size(where: str, key: str, v) -> tuple[int, int]:
    allowed = "[width, height] or 'WIDTHxHEIGHT', each 1 to 16384 pixels"
    if isinstance(v, str):
        parts = v.lower().split("x")
        v = [int(p) for p in parts] if len(parts) == 2 and all(p.isdigit() for p in parts) else v
    if (not isinstance(v, list) or len(v) != 2
            or not all(isinstance(x, int) and not isinstance(x, bool) and 1 <= x <= 16384
                       for x in v)):
        _fail(where, key, v, allowed)
    return int(v[0]), int(v[1])


def _pattern(where: str, key: str, v, names: tuple[str, ...]) -> str:
    v = _string(where, key, v)
    sample = {"view": "v", "style": "s", "snapshot": 0, "time": 0.0}
    try:
        fields_used = [f for _, f, _, _ in string.Formatter().parse(v) if f is not None]
        bad = [f for f in fields_used if f not in names]
        if bad:
            _fail(where, key, v, "a path whose placeholders are among "
                  + ", ".join("{" + n + "}" for n in names) + f" (not {{{bad[0]}}})")
        v.format(**sample)
    except (ValueError, IndexError, KeyError) as e:
        _fail(where, key, v, f"a valid format pattern ({e})")
    return v


def placeholders(pattern: str) -> set[str]:
    return {f for _, f, _, _ in string.Formatter().parse(pattern) if f}


def _outputs(where: str, t: dict, views: dict[str, View]) -> Outputs:
    _check_keys(where, t, {"lines", "images", "animation", "frames", "fps"})
    lines = _pattern(where, "lines", t["lines"], LINES_FIELDS) if "lines" in t else None
    images = _pattern(where, "images", t.get("images", DEFAULT_IMAGES), IMAGE_FIELDS)
    if len(views) > 1 and "view" not in placeholders(images):
        _fail(where, "images", images, f"a pattern with {{view}}: the scene has {len(views)} views")
    if "animation" not in t:
        for key in ("frames", "fps"):
            if key in t:
                raise SceneError(f"{where}: {key} = {t[key]!r} is given without animation (add "
                                 "animation = '{view}_{snapshot}.gif', or remove it)")
        return Outputs(lines, images)
    anim = _pattern(where, "animation", t["animation"], IMAGE_FIELDS)
    if Path(anim).suffix.lower() not in ANIMATION_FORMATS:
        _fail(where, "animation", anim, "a path ending in " + ", ".join(ANIMATION_FORMATS)
              + " (.png: numbered frames)")
    if len(views) > 1 and "view" not in placeholders(anim):
        _fail(where, "animation", anim,
              f"a pattern with {{view}}: the scene has {len(views)} views")
    frames = t.get("frames", DEFAULT_FRAMES)
    if isinstance(frames, bool) or not isinstance(frames, int) or not 1 <= frames <= 100_000:
        _fail(where, "frames", frames, "an integer from 1 to 100000")
    fps = _number(where, "fps", t.get("fps", DEFAULT_FPS), lo=0.0, lo_open=True)
    return Outputs(lines, images, anim, frames, fps)


def _cache(where: str, t: dict, base: Path) -> tuple[Path, bool]:
    _check_keys(where, t, {"dir", "enabled"})
    d = Path(_string(where, "dir", t.get("dir", ".flowkit-cache"))).expanduser()
    enabled = t.get("enabled", True)
    if not isinstance(enabled, bool):
        _fail(where, "enabled", enabled, "true or false")
    return (d if d.is_absolute() else base / d), enabled


__all__ = ["SCENE_VERSION", "FieldSource", "Outputs", "Scene", "SceneError", "View",
           "image_size", "load_scene", "scene_from_dict", "snapshot_selection"]
