"""Style -> template flags -> GLSL, and a per-context program cache keyed by the flags.

Flags hold only integers, booleans and words from fixed sets: the templates never see a string
from a style file.  Attribute names become slot numbers (a_attr0, a_attr1, ...), colormap names
become textures, numbers become uniforms (see ``renderer.band_uniforms``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import jinja2
import moderngl

from .colormaps import LUT_SIZE, _ctx_store
from .style import ColorMap, Style, WidthMap

SHADER_DIR = Path(__file__).resolve().parent.parent / "shaders"
GLSL_VERSION = 330
TEX_WIDTH = 4096  # points per row of the point/attribute textures
COLOR_KINDS = ("const", "cmap")
WIDTH_KINDS = ("const", "map")


@dataclass(frozen=True)
class BandFlags:
    """What the code of one band needs.  ``index`` is the band's global number (uniform names
    u_color3, u_cmap3...); attribute slots index a_attrN, -1 when unused."""

    index: int
    color: str = "const"  # COLOR_KINDS
    color_attr: int = -1
    width: str = "const"  # WIDTH_KINDS
    width_attr: int = -1


@dataclass(frozen=True)
class ShaderFlags:
    """The whole template input.  Hashable: the program cache key."""

    n_attrs: int
    styles: tuple[tuple[BandFlags, ...], ...]  # one tuple of bands per line style
    depth_offset: bool  # some band has a depth offset: write gl_FragDepth
    smooth_bands: bool  # blend colours across band boundaries over one pixel
    smooth_edge: bool  # analytic coverage at the outer edge (when there is no MSAA)

    @property
    def uses_colormap(self) -> bool:
        return any(b.color == "cmap" for s in self.styles for b in s)

    @property
    def uses_width_map(self) -> bool:
        return any(b.width == "map" for s in self.styles for b in s)


def shader_flags(style: Style, msaa: bool) -> ShaderFlags:
    """Flags for ``style``; ``msaa`` says whether the target is multisampled."""
    slots = {name: i for i, name in enumerate(style.attributes())}
    styles, g = [], 0
    for ls in style.styles.values():
        bands = []
        for b in ls.bands:
            c, w = b.color, b.width
            bands.append(BandFlags(
                index=g,
                color="cmap" if isinstance(c, ColorMap) else "const",
                color_attr=slots[c.attribute] if isinstance(c, ColorMap) else -1,
                width="map" if isinstance(w, WidthMap) else "const",
                width_attr=slots[w.attribute] if isinstance(w, WidthMap) else -1,
            ))
            g += 1
        styles.append(tuple(bands))
    aa = style.antialias != "none"
    return ShaderFlags(
        n_attrs=len(slots),
        styles=tuple(styles),
        depth_offset=any(b.depth_offset > 0 for ls in style.styles.values() for b in ls.bands),
        smooth_bands=aa,
        smooth_edge=aa and (style.antialias == "smooth" or not msaa),
    )


def _checked(value, where="flags"):
    """Template input must be ints, bools, or words from the fixed sets -- nothing else."""
    if isinstance(value, bool | int):
        return value
    if isinstance(value, str):
        if value not in COLOR_KINDS + WIDTH_KINDS:
            raise ValueError(f"{where}: {value!r} is not a template word")
        return value
    if isinstance(value, dict):
        return {k: _checked(v, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_checked(v, f"{where}[{i}]") for i, v in enumerate(value)]
    raise TypeError(f"{where}: {type(value).__name__} may not reach shader source")


_env = jinja2.Environment(
    loader=jinja2.FileSystemLoader(SHADER_DIR),
    undefined=jinja2.StrictUndefined,
    autoescape=False,
    trim_blocks=True,
    lstrip_blocks=True,
    keep_trailing_newline=True,
)


def build_sources(flags: ShaderFlags) -> dict[str, str]:
    """GLSL sources (vertex, fragment) for ``flags``."""
    ctx = _checked(asdict(flags))
    ctx.update(glsl_version=GLSL_VERSION, lut_size=LUT_SIZE, tex_width=TEX_WIDTH,
               uses_colormap=flags.uses_colormap, uses_width_map=flags.uses_width_map)
    return {
        "vertex_shader": _env.get_template("lines.vert").render(ctx),
        "fragment_shader": _env.get_template("lines.frag").render(ctx),
    }


class ProgramCache:
    """Compiled programs of one context keyed by ShaderFlags; ``compiles`` counts builds."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.programs: dict[ShaderFlags, moderngl.Program] = {}
        self.compiles = 0

    def get(self, flags: ShaderFlags) -> moderngl.Program:
        prog = self.programs.get(flags)
        if prog is None:
            prog = self.ctx.program(**build_sources(flags))
            self.programs[flags] = prog
            self.compiles += 1
        return prog


def program_cache(ctx: moderngl.Context) -> ProgramCache:
    store = _ctx_store(ctx)
    if "programs" not in store:
        store["programs"] = ProgramCache(ctx)
    return store["programs"]
