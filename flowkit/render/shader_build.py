"""Style -> template flags -> GLSL, and a per-context program cache keyed by the flags.

Flags hold only integers, booleans and words from fixed sets: the templates never see a string
from a style file.  Attribute names become slot numbers (a_attr0, a_attr1, ...), colormap names
and user shapes become textures, numbers become uniforms (``band_uniforms``).  Only the line
styles that are drawn (the transfer function's, else the first) and only the shapes and
patterns their bands use are compiled.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import jinja2
import moderngl

from .colormaps import TEXELS, _ctx_store, colormap_texture
from .shapes import CURVE_SIZE, PEAKS, SHAPE_NAMES, SHAPES, ShapeCurve, curve_texture
from .style.model import ColorMap, Style, WidthMap

BIG = 3.0e38  # an infinite transfer bound as a float32 uniform

SHADER_DIR = Path(__file__).resolve().parent.parent / "shaders"
GLSL_VERSION = 330
TEX_WIDTH = 4096  # points per row of the point/attribute textures
COLOR_KINDS = ("const", "cmap")
WIDTH_KINDS = ("const", "map")
SHAPE_KINDS = ("none", "custom") + SHAPE_NAMES
# where the view-oriented strips are built: the vertex shader (vertex pulling, one triangle strip
# per run; the default: as fast or faster on llvmpipe) or a lines_adjacency geometry shader
STRIP_STAGES = ("vertex", "geometry")
# a colour pattern's lateral term a * lat^c: none (a = 0), linear (c = 1, no pow), power
PATTERN_LATERAL = ("none", "linear", "power")
TEMPLATE_WORDS = COLOR_KINDS + WIDTH_KINDS + SHAPE_KINDS + STRIP_STAGES + PATTERN_LATERAL[1:]


@dataclass(frozen=True)
class BandFlags:
    """What the code of one band needs.  ``index`` is the band's global number (uniform names
    u_color3, u_cmap3...); attribute slots index a_attrN, -1 when unused."""

    index: int
    color: str = "const"  # COLOR_KINDS
    color_attr: int = -1
    width: str = "const"  # WIDTH_KINDS
    width_attr: int = -1
    shape: str = "none"  # SHAPE_KINDS
    shape_attr: int = -1
    pattern: bool = False
    pattern_attr: int = -1
    pattern_color: str = "const"  # COLOR_KINDS: the pattern's second colour
    pattern_color_attr: int = -1
    pattern_lateral: str = "none"  # PATTERN_LATERAL: the stripes' slant across the band


@dataclass(frozen=True)
class RangeFlags:
    """One transfer-function range: the compiled style it draws (-1: discard) and the styles of
    the adjacent ranges it blends with (-1: none)."""

    style: int
    prev: int = -1
    next: int = -1


@dataclass(frozen=True)
class ShaderFlags:
    """The whole template input.  Hashable: the program cache key."""

    n_attrs: int
    styles: tuple[tuple[BandFlags, ...], ...]  # one tuple of bands per drawn line style
    depth_offset: bool  # some band has a depth offset: write gl_FragDepth
    smooth_bands: bool  # blend colours across band boundaries over one pixel
    smooth_edge: bool  # analytic coverage at the outer edge (when there is no MSAA)
    transfer: tuple[RangeFlags, ...] = ()  # empty: always draw style 0
    transfer_attr: int = -1
    transfer_blend: bool = False
    strip_stage: str = "vertex"  # STRIP_STAGES
    narrow: bool = True  # narrow the strip per point by the built-in shapes (see narrow_slots)
    # attribute slots interpolated as cubic Hermite along the arc (the others: linearly)
    hermite: tuple[int, ...] = ()

    @property
    def shapes(self) -> list[str]:
        """Built-in shapes used (each compiled once), in a fixed order."""
        used = {b.shape for s in self.styles for b in s}
        return [n for n in SHAPE_NAMES if n in used]

    @property
    def pattern_slots(self) -> list[int]:
        """Attribute slots patterns read (their screen derivatives filter the stripes)."""
        return sorted({b.pattern_attr for s in self.styles for b in s if b.pattern})

    @property
    def narrow_bands(self) -> list[BandFlags]:
        """The bands whose built-in shapes narrow the strip at each point (the strip stage takes
        the largest f(s) over the point's two segments): one drawn style, no transfer function
        (that splits into single-style programs), some band with a built-in shape."""
        if not self.narrow or self.transfer or len(self.styles) != 1:
            return []
        bands = list(self.styles[0])
        return bands if any(b.shape not in ("none", "custom") for b in bands) else []

    @property
    def uses_phase(self) -> bool:
        return any(b.shape != "none" or b.pattern for s in self.styles for b in s)

    @property
    def uses_colormap(self) -> bool:
        return any(b.color == "cmap" or (b.pattern and b.pattern_color == "cmap")
                   for s in self.styles for b in s)

    @property
    def uses_width_map(self) -> bool:
        return any(b.width == "map" for s in self.styles for b in s)


def shader_flags(style: Style, msaa: bool, strip_stage: str = "vertex",
                 only: str | None = None, linear: tuple[str, ...] = ()) -> ShaderFlags:
    """Flags for ``style``; ``msaa`` says whether the target is multisampled; ``strip_stage``
    (STRIP_STAGES) which shader stage builds the strips.  ``only``: the program that draws line
    style ``only`` alone, without the transfer function (for the segments that lie wholly in
    one of its ranges); attribute slots and band numbers stay those of the whole style.
    Attributes are interpolated along the arc between the drawn points as cubic Hermite curves
    (values and slopes, see ``simplify.slopes``), those named in ``linear`` (linear along the
    arc, where the cubic adds nothing) linearly."""
    check_strip_stage(strip_stage)
    slots = {name: i for i, name in enumerate(style.attributes())}
    used = style.used_styles() if only is None else [only]
    first = band_numbers(style)
    styles = []
    for name in used:
        bands = []
        for k, b in enumerate(style.styles[name].bands):
            c, w, sh, pt = b.color, b.width, b.shape, b.pattern
            pc = pt.color if pt is not None else None
            bands.append(BandFlags(
                index=first[name] + k,
                color="cmap" if isinstance(c, ColorMap) else "const",
                color_attr=slots[c.attribute] if isinstance(c, ColorMap) else -1,
                width="map" if isinstance(w, WidthMap) else "const",
                width_attr=slots[w.attribute] if isinstance(w, WidthMap) else -1,
                shape=sh.name if sh is not None else "none",
                shape_attr=slots[sh.attribute] if sh is not None else -1,
                pattern=pt is not None,
                pattern_attr=slots[pt.attribute] if pt is not None else -1,
                pattern_color="cmap" if isinstance(pc, ColorMap) else "const",
                pattern_color_attr=slots[pc.attribute] if isinstance(pc, ColorMap) else -1,
                pattern_lateral=("none" if pt is None or pt.slope == 0 else
                                 "linear" if pt.curve == 1 else "power"),
            ))
        styles.append(tuple(bands))
    aa = style.antialias != "none"
    transfer, tattr, blend = (), -1, False
    tf = style.transfer
    if tf is not None and only is None:
        idx = [used.index(r.style) if r.style is not None else -1 for r in tf.ranges]
        order = sorted(range(len(tf.ranges)), key=lambda i: tf.ranges[i].range[0])

        def neighbour(i, step):  # the style of the range sharing i's bound, if any
            j = order.index(i) + step
            if not 0 <= j < len(order):
                return -1
            a, b = tf.ranges[i].range, tf.ranges[order[j]].range
            touching = a[1] == b[0] if step > 0 else a[0] == b[1]
            return idx[order[j]] if touching and idx[i] >= 0 else -1

        blend = tf.blend > 0
        transfer = tuple(RangeFlags(idx[i], *((neighbour(i, -1), neighbour(i, 1)) if blend
                                              else (-1, -1))) for i in range(len(tf.ranges)))
        tattr = slots[tf.attribute]
    return ShaderFlags(
        n_attrs=len(slots),
        styles=tuple(styles),
        depth_offset=any(b.depth_offset > 0 for n in used for b in style.styles[n].bands),
        smooth_bands=aa,
        smooth_edge=aa and (style.antialias == "smooth" or not msaa),
        transfer=transfer,
        transfer_attr=tattr,
        transfer_blend=blend,
        strip_stage=strip_stage,
        hermite=tuple(k for name, k in slots.items() if name not in linear),
    )


def check_strip_stage(stage: str) -> str:
    if stage not in STRIP_STAGES:
        raise ValueError(f"strips = {stage!r}: expected one of {', '.join(STRIP_STAGES)}")
    return stage


def band_numbers(style: Style) -> dict[str, int]:
    """Global number of each line style's first band (uniform names u_color<g>...): bands are
    numbered through all styles in order, drawn or not, so the numbers do not depend on the
    transfer function."""
    out, g = {}, 0
    for name, ls in style.styles.items():
        out[name] = g
        g += len(ls.bands)
    return out


def _color_uniforms(u: dict, color, prefix: str, g: int) -> None:
    if isinstance(color, ColorMap):
        lo, hi = color.range
        u[f"u_{prefix}cmap{g}"] = color.cmap
        u[f"u_{prefix}crange{g}"] = (1.0 / (hi - lo), -lo / (hi - lo))
    else:
        u[f"u_{prefix}color{g}"] = tuple(color)


def band_uniforms(style: Style) -> dict[str, object]:
    """Uniform values of every band, named as the templates name them (global band number),
    plus the transfer function's bounds and the phase.  Texture values (colormap names as str,
    user shapes as ShapeCurve; see ``is_texture``) become texture units in the renderer."""
    u: dict[str, object] = {}
    first = band_numbers(style)
    for name, ls in style.styles.items():
        for k, b in enumerate(ls.bands):
            g = first[name] + k
            _color_uniforms(u, b.color, "", g)
            if isinstance(b.width, WidthMap):
                lo, hi = b.width.range
                u[f"u_wmap{g}"] = (1.0 / (hi - lo), -lo / (hi - lo), b.width.min, b.width.max)
            else:
                u[f"u_width{g}"] = float(b.width)
            u[f"u_depth{g}"] = float(b.depth_offset)
            if b.shape is not None:
                u[f"u_shapel{g}"] = 1.0 / b.shape.length
                if b.shape.name == "custom":
                    u[f"u_curve{g}"] = ShapeCurve(b.shape.points)
            if b.pattern is not None:
                p = b.pattern
                u[f"u_pat{g}"] = (1.0 / p.length, p.slope, p.curve, p.fraction)
                _color_uniforms(u, p.color, "p", g)
    if style.transfer is not None:
        for i, r in enumerate(style.transfer.ranges):
            u[f"u_tf{i}"] = tuple(float(min(max(v, -BIG), BIG)) for v in r.range)
        u["u_tfblend"] = 0.5 * style.transfer.blend
    u["u_phase"] = float(style.phase)
    return u


def is_texture(value) -> bool:
    """Whether a ``band_uniforms`` value is bound as a texture (see ``style_texture``)."""
    return isinstance(value, str | ShapeCurve)


def style_texture(ctx: moderngl.Context, value) -> moderngl.Texture:
    """The (per-context cached) texture of a colormap name or a user shape."""
    return curve_texture(ctx, value) if isinstance(value, ShapeCurve) else colormap_texture(ctx, value)


def _checked(value, where="flags"):
    """Template input must be ints, bools, or words from the fixed sets -- nothing else."""
    if isinstance(value, bool | int):
        return value
    if isinstance(value, str):
        if value not in TEMPLATE_WORDS:
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
    """GLSL sources for ``flags``: vertex and fragment shaders, plus the geometry shader when it
    builds the strips (then the vertex shader only fetches points)."""
    ctx = _checked(asdict(flags))
    ctx.update(glsl_version=GLSL_VERSION, cmap_texels=TEXELS, tex_width=TEX_WIDTH,
               curve_size=CURVE_SIZE, uses_colormap=flags.uses_colormap,
               uses_width_map=flags.uses_width_map, shapes=_checked(flags.shapes, "shapes"),
               uses_phase=flags.uses_phase, pattern_slots=flags.pattern_slots,
               shape_sources={n: SHAPES[n].glsl() for n in flags.shapes},
               narrow_bands=_checked([asdict(b) for b in flags.narrow_bands], "narrow_bands"),
               narrow_slots=sorted({b.shape_attr for b in flags.narrow_bands
                                    if b.shape not in ("none", "custom")}),
               peaks={k: [float(p) for p in v] for k, v in PEAKS.items()})
    out = {"vertex_shader": _env.get_template("lines.vert").render(ctx)}
    if flags.strip_stage == "geometry":
        out["geometry_shader"] = _env.get_template("lines.geom").render(ctx)
    out["fragment_shader"] = _env.get_template("lines.frag").render(ctx)
    return out


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
