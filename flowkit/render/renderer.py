"""moderngl line-style renderer: Lines in, RGBA image out.

Geometry goes to the GPU once per ``LineRenderer``: float32 positions (+ line number) in a
texture, a triangle-strip index buffer (two strip vertices per point, restart between lines), and
one float32 texture per attribute a style reads (uploaded the first time a style reads it).  A render binds the program for the style's flags (cached), sets uniforms and textures, and
draws into a multisampled framebuffer that is resolved and read back.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Self

import moderngl
import numpy as np

from ..io.atomic import atomic_path
from ..lines import Lines
from .camera import Camera
from .context import default_context
from .shader_build import (
    TEX_WIDTH,
    ShaderFlags,
    band_uniforms,
    is_texture,
    program_cache,
    shader_flags,
    style_texture,
)
from .style import Style, StyleError, load_style


def _current(method):
    """Run a LineRenderer method with the renderer's context current."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        with self.ctx:
            return method(self, *args, **kwargs)

    return wrapper


def strip_indices(lines: Lines) -> np.ndarray:
    """uint32 indices of one triangle strip per run of >= 2 consecutive finite points of a line
    (vertex 2i and 2i+1 are the two sides at point i), runs separated by the restart index."""
    finite = np.all(np.isfinite(lines.points), axis=1)
    line_of = lines.line_index()
    i = np.flatnonzero(finite)
    if i.size == 0:
        return np.zeros(0, np.uint32)
    # a run breaks where the index jumps (a non-finite point) or the line changes
    brk = np.flatnonzero((np.diff(i) != 1) | (np.diff(line_of[i]) != 0)) + 1
    starts, stops = np.r_[0, brk], np.r_[brk, i.size]
    keep = stops - starts >= 2
    runs = [i[a:b] for a, b in zip(starts[keep], stops[keep])]
    if not runs:
        return np.zeros(0, np.uint32)
    if 2 * lines.n_points + 1 >= RESTART:
        raise ValueError(f"{lines.n_points} points: too many to draw in one call")
    parts = []
    for r in runs:
        parts.append(np.stack([2 * r, 2 * r + 1], axis=1).ravel())
        parts.append(np.array([RESTART], np.int64))
    return np.concatenate(parts).astype(np.uint32)


def point_texture_shape(n: int) -> tuple[int, int]:
    return TEX_WIDTH, max(1, -(-n // TEX_WIDTH))


def _as_style(style) -> Style:
    if isinstance(style, Style):
        return style
    if isinstance(style, (str, os.PathLike)):
        return load_style(style)
    raise TypeError(f"style must be a Style or a path to a TOML style file, got {type(style).__name__}")


RESTART = 0xFFFFFFFF  # moderngl enables primitive restart with this index


class LineRenderer:
    """Draws one set of lines with any number of styles, cameras and sizes."""

    def __init__(self, lines: Lines, ctx: moderngl.Context | None = None):
        self.ctx = ctx or default_context()
        self.lines = lines
        self.bounds = lines.bounds()
        idx = strip_indices(lines)
        self.n_indices = idx.size
        if len(lines) >= 2**24:  # line numbers travel as float32 in the point texture
            raise ValueError(f"{len(lines)} lines: at most {2**24} can be drawn at once")
        w, h = point_texture_shape(lines.n_points)
        pts = np.zeros((w * h, 4), np.float32)
        pts[:lines.n_points, :3] = lines.points
        pts[:lines.n_points, 3] = lines.line_index()
        # moderngl does not switch contexts per call: make ours current around all GL work
        with self.ctx:
            self._points = self._texture(pts, 4)
            self._ibo = self.ctx.buffer(idx.tobytes()) if idx.size else None
        self._attrs: dict[str, moderngl.Texture] = {}
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        self._fbos: dict[tuple, tuple] = {}
        self.programs = program_cache(self.ctx)

    @_current
    def release(self) -> None:
        """Free this renderer's buffers and framebuffers (programs stay cached on the context)."""
        for obj in [*self._vaos.values(), *self._attrs.values(), self._points, self._ibo]:
            if obj is not None:
                obj.release()
        for ms, out in self._fbos.values():
            for fbo in (ms, out):
                if fbo is not None:
                    for att in (*fbo.color_attachments, fbo.depth_attachment):
                        att.release()
                    fbo.release()
        self._vaos.clear()
        self._attrs.clear()
        self._fbos.clear()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    # -- geometry -------------------------------------------------------------------------------
    def uploaded_attributes(self) -> list[str]:
        return list(self._attrs)

    def _texture(self, values: np.ndarray, components: int) -> moderngl.Texture:
        """Float32 texture of per-point values, TEX_WIDTH points per row, nearest filtering."""
        size = point_texture_shape(self.lines.n_points)
        if size[1] > self.ctx.info["GL_MAX_TEXTURE_SIZE"]:
            raise ValueError(f"{self.lines.n_points} points need a {size[0]}x{size[1]} texture; "
                             f"this OpenGL allows {self.ctx.info['GL_MAX_TEXTURE_SIZE']} rows")
        data = np.zeros((size[0] * size[1], components), np.float32)
        data[:len(values)] = values.reshape(len(values), -1)[:, :components]
        tex = self.ctx.texture(size, components, data.tobytes(), dtype="f4")
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return tex

    def _attribute_texture(self, name: str) -> moderngl.Texture:
        buf = self._attrs.get(name)
        if buf is None:
            lines = self.lines
            if name in lines.point_data:
                v = np.asarray(lines.point_data[name])
            elif name in lines.line_data:  # per-line values repeated on the line's vertices
                v = np.repeat(np.asarray(lines.line_data[name]), lines.lengths)
            else:
                have = sorted(lines.point_data) + sorted(lines.line_data)
                raise StyleError(f"the style reads attribute '{name}', which these lines do not "
                                 f"have; available: {', '.join(have) or 'none'}")
            if v.ndim != 1:
                raise StyleError(f"attribute '{name}' has shape {v.shape}; a style can only map "
                                 f"scalar (one value per vertex) attributes")
            buf = self._texture(np.asarray(v, dtype=np.float32), 1)
            self._attrs[name] = buf
        return buf

    def _vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        vao = self._vaos.get(prog.glo)
        if vao is None:  # no vertex attributes: everything is fetched from textures
            vao = self.ctx.vertex_array(prog, [], self._ibo, index_element_size=4)
            self._vaos[prog.glo] = vao
        return vao

    # -- framebuffers ---------------------------------------------------------------------------
    def _targets(self, size: tuple[int, int], samples: int):
        key = (size, samples)
        if key not in self._fbos:
            ctx = self.ctx
            out = ctx.framebuffer(ctx.renderbuffer(size, 4), ctx.depth_renderbuffer(size))
            ms = None
            if samples > 1:
                ms = ctx.framebuffer(ctx.renderbuffer(size, 4, samples=samples),
                                     ctx.depth_renderbuffer(size, samples=samples))
            self._fbos.clear()  # keep one size: print sizes are big
            self._fbos[key] = (ms, out)
        return self._fbos[key]

    # -- drawing --------------------------------------------------------------------------------
    def prepare(self, style: Style) -> tuple[ShaderFlags, moderngl.Program]:
        samples = self.samples_for(style)
        flags = shader_flags(style, msaa=samples > 1)
        return flags, self.programs.get(flags)

    def samples_for(self, style: Style) -> int:
        if style.antialias != "msaa":
            return 1
        return min(style.samples, self.ctx.max_samples) if self.ctx.max_samples >= 2 else 1

    @_current
    def render(self, style: Style | str | os.PathLike, size: tuple[int, int] = (1920, 1080),
               camera: Camera | None = None) -> np.ndarray:
        """(H, W, 4) uint8 RGBA, row 0 at the top."""
        style = _as_style(style)
        w, h = (int(v) for v in size)
        if w < 1 or h < 1:
            raise ValueError(f"image size {w}x{h} must be at least 1x1")
        k = style.supersample
        rw, rh = w * k, h * k
        limit = self.ctx.info["GL_MAX_RENDERBUFFER_SIZE"]
        if max(rw, rh) > limit:
            raise ValueError(f"{w}x{h} with supersample {k} needs {rw}x{rh} pixels; this OpenGL "
                             f"allows at most {limit} per side: lower supersample or size")
        self.draw(style, (rw, rh), camera)
        img = self.read()
        if k > 1:
            img = img.reshape(h, k, w, k, 4).astype(np.float32).mean(axis=(1, 3))
            img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        return img

    @_current
    def draw(self, style: Style, size: tuple[int, int], camera: Camera | None = None):
        """Draw into the (multisampled) target of ``size`` and resolve it; no read-back."""
        ctx = self.ctx
        flags, prog = self.prepare(style)
        attrs = style.attributes()
        cam = (camera or style.camera).setup(self.bounds, *size)
        samples = self.samples_for(style)
        ms, out = self._targets(size, samples)
        target = ms or out
        target.use()
        ctx.viewport = (0, 0, *size)
        bg = style.background or (0.0, 0.0, 0.0, 0.0)
        target.clear(*bg, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        if flags.smooth_edge:
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        else:
            ctx.disable(moderngl.BLEND)
        if self._ibo is not None:
            half = style.scale * style.max_total_width
            pixels = style.units == "pixels"
            ss = style.supersample if pixels else 1  # pixel widths are output pixels
            uniforms = {
                "u_view": cam.view.T.astype("f4").tobytes(),
                "u_proj": cam.proj.T.astype("f4").tobytes(),
                "u_half": half * ss,
                "u_scale": style.scale * ss,
                "u_pixels": 1.0 if pixels else 0.0,
                "u_px": cam.px_scale,
                "u_persp": 1.0 if cam.proj[3, 2] != 0 else 0.0,
            }
            textures = [("u_points", self._points)]
            textures += [(f"u_attr{k}", self._attribute_texture(a)) for k, a in enumerate(attrs)]
            values = band_uniforms(style)  # numbers, colormap names, user shapes
            textures += [(name, style_texture(ctx, v)) for name, v in values.items() if is_texture(v)]
            for unit, (name, tex) in enumerate(textures):
                tex.use(location=unit)
                uniforms[name] = unit
            uniforms.update({k: v for k, v in values.items() if not is_texture(v)})
            uniforms["u_npoints"] = self.lines.n_points
            for name, value in uniforms.items():
                if name in prog:  # the compiler drops uniforms it can prove unused
                    u = prog[name]
                    if isinstance(value, bytes):
                        u.write(value)
                    else:
                        u.value = value
            self._vao(prog).render(moderngl.TRIANGLE_STRIP)
        if ms is not None:
            ctx.copy_framebuffer(out, ms)

    @_current
    def read(self) -> np.ndarray:
        """Read back the resolved image of the last draw: (H, W, 4) uint8, top row first."""
        out = next(iter(self._fbos.values()))[1]
        w, h = out.size
        data = out.read(components=4, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(h, w, 4)[::-1].copy()


def render_lines(lines: Lines, style: Style | str | os.PathLike, size=(1920, 1080),
                 camera: Camera | None = None, ctx: moderngl.Context | None = None) -> np.ndarray:
    """Render ``lines`` with ``style`` (a Style or a TOML path) to an (H, W, 4) uint8 RGBA array.
    ``camera`` overrides the style's camera.  Uses a headless EGL context unless ``ctx`` is given.
    To draw the same lines many times, keep a ``LineRenderer``."""
    style = _as_style(style)
    with LineRenderer(lines, ctx) as r:
        return r.render(style, size, camera)


def save_png(image: np.ndarray, path: str | os.PathLike) -> Path:
    """Write an (H, W, 3|4) uint8 image as PNG atomically (temp file beside it + rename)."""
    from PIL import Image

    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ValueError(f"save_png needs an (H, W, 3 or 4) uint8 array, got {img.dtype} {img.shape}")
    with atomic_path(path) as tmp:
        Image.fromarray(img, "RGBA" if img.shape[2] == 4 else "RGB").save(tmp, format="PNG")
    return Path(path)


def render_file(path: str | os.PathLike, style: Style | str | os.PathLike, size=(1920, 1080),
                camera: Camera | None = None, ctx: moderngl.Context | None = None) -> np.ndarray:
    """Render a lines HDF5 file, reading only the geometry and the attributes the style uses."""
    from ..io.lines_h5 import read_lines

    style = _as_style(style)
    return render_lines(read_lines(path, attributes=style.attributes()), style, size, camera, ctx)
