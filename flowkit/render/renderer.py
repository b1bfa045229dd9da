"""moderngl line-style renderer: Lines in, RGBA image out.

Geometry goes to the GPU once per ``LineRenderer``: float32 positions in a texture and one
float32 texture per attribute a style reads (uploaded the first time a style reads it).  Per
frame (when the camera, size or style tolerances change) ``simplify.select`` picks the vertices
that matter at this zoom and uploads their ids (a small int buffer) and the triangle-strip
indices (two strip vertices per kept point, restart between runs; or, when a geometry shader
builds the strips, lines_adjacency indices of the same points).  A render binds the program
for the style's flags (cached), sets uniforms and textures, and draws into a (multisampled)
framebuffer that is resolved and read back.
"""

from __future__ import annotations

import functools
import math
import os
import warnings
from pathlib import Path
from typing import Self

import moderngl
import numpy as np

from ..io.atomic import atomic_path
from ..lines import Lines
from .camera import Camera
from .context import default_context, is_software
from .lengths import SceneScale, resolve_lengths
from .ranges import CLIP, data_range, fixed_ranges, resolve_ranges
from .shader_build import (
    BIG,
    TEX_WIDTH,
    ShaderFlags,
    band_uniforms,
    check_strip_stage,
    is_texture,
    program_cache,
    shader_flags,
    style_texture,
)
from .simplify import (
    adjacency,
    arc_parameter,
    attribute_tolerances,
    geometry_importance,
    linear_along_arc,
    lod_importance,
    placed_attributes,
    runs,
    select,
    slopes,
    split_by_range,
)
from .style.check import StyleError
from .style.model import Range, Style
from .style.toml import load_style

TOLERANCE = 0.25  # level-of-detail tolerance on software rasterizers, output pixels
LOD_KEPT = 4  # style importances kept (a world-unit width map's tolerance follows the zoom)


def _current(method):
    """Run a LineRenderer method with the renderer's context current (leaving it current for
    the caller when called from another such method: moderngl's exit releases the context)."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        if getattr(self, "_in_context", False):
            return method(self, *args, **kwargs)
        self._in_context = True
        try:
            with self.ctx:
                return method(self, *args, **kwargs)
        finally:
            self._in_context = False

    return wrapper


def point_texture_shape(n: int) -> tuple[int, int]:
    return TEX_WIDTH, max(1, -(-n // TEX_WIDTH))


def _as_style(style) -> Style:
    if isinstance(style, Style):
        return style
    if isinstance(style, (str, os.PathLike)):
        return load_style(style)
    raise TypeError(f"style must be a Style or a path to a TOML style file, got {type(style).__name__}")


class LineRenderer:
    """Draws one set of lines with any number of styles, cameras and sizes."""

    def __init__(self, lines: Lines, ctx: moderngl.Context | None = None,
                 tolerance: float | None = None, msaa: bool | None = None,
                 strips: str = "vertex", bounds=None):
        """``tolerance``: per frame, skip the vertices whose removal moves the drawn line by less
        than this many output pixels and its attributes by less than a visible step (see
        ``simplify``); 0 draws every vertex (nothing is recomputed when the camera moves).
        ``msaa``: whether a style's ``antialias = "msaa"`` gets a multisampled target.  None
        (defaults) choose by rasterizer: on a software one (llvmpipe), where every tiny triangle
        costs a setup and MSAA's clear+resolve costs more than a frame, tolerance 0.25 and
        analytic edge smoothing; on a GPU, every vertex and MSAA.
        ``strips``: the shader stage that builds the view-oriented strips, "vertex" (vertex
        pulling, the default: as fast or faster on llvmpipe) or "geometry" (a lines_adjacency geometry
        shader); both draw the same strips with the same style code.
        ``bounds``: the (3, 2) box cameras frame and clip to (default: the lines' own box); the
        viewer gives the field's, so lines traced again from a moved rake keep the view."""
        self.strips = check_strip_stage(strips)
        self.ctx = ctx or default_context()
        software = is_software(self.ctx)
        if tolerance is None:
            tolerance = TOLERANCE if software else 0.0
        if not (math.isfinite(tolerance) and tolerance >= 0):
            raise ValueError(f"tolerance = {tolerance!r}: expected a number of pixels >= 0")
        self.msaa = (not software) if msaa is None else bool(msaa)
        self.tolerance = float(tolerance)
        self._box = None  # the bounds given (None: the lines' own)
        self._points: moderngl.Texture | None = None
        self._spare: dict[str, moderngl.Texture] = {}  # attribute textures of earlier lines
        self._attrs: dict[str, moderngl.Texture] = {}
        self.allocations = 0  # GL textures and buffers this renderer created (set_lines reuses)
        with self.ctx:  # moderngl does not switch contexts per call: ours, around all GL work
            self._ids = self._buffer()  # per frame: kept point ids (simplify.select)
            self._ibo = self._buffer()  # per frame: strip indices with restarts
        self._vaos: dict[tuple, moderngl.VertexArray] = {}
        self._fbos: dict[tuple, tuple] = {}
        self.programs = program_cache(self.ctx)
        self.set_lines(lines, bounds)

    @_current
    def set_lines(self, lines: Lines, bounds=None) -> None:
        """Draw ``lines`` from now on (the viewer's lines traced again): their geometry and
        the attributes styles read are uploaded into this renderer's textures (written in place
        when their size stays) and everything derived from the old lines is dropped; the
        programs, vertex arrays, index buffers and framebuffers stay.  ``bounds``: see
        ``__init__``; None keeps the box given before (or takes the new lines' own)."""
        if bounds is not None:
            self._box = np.array(bounds, float).reshape(3, 2)
        self.bounds = lines.bounds() if self._box is None else self._box
        starts, stops = runs(lines)
        if 2 * lines.n_points + len(starts) + 6 >= 2**31:
            raise ValueError(f"{lines.n_points} points: too many to draw in one call")
        self.lines = lines
        self._starts, self._stops = starts, stops
        self._xyz = np.ascontiguousarray(lines.points, np.float64)
        self._geometry: np.ndarray | None = None  # DP importance of the geometry alone
        # per (placed attributes, mapped attributes' tolerances): a style's importance
        self._lods: dict[tuple, np.ndarray] = {}
        self._slopes: dict[str, np.ndarray] = {}  # per attribute, d(value)/d(arc)
        self._is_linear: dict[str, bool] = {}  # per attribute: linear along the arc
        # arc length from each run's start: the parameter of the attributes' Hermite interpolant
        self._arc = arc_parameter(self._xyz, self._starts, self._stops)
        self._frame_key = None
        self._travel: np.ndarray | None = None
        self._speed: float | None = None
        self._clip_reported: set = set()
        self._ranges: dict[str, float] = {}
        self._auto: dict[tuple[str, Range], tuple[float, float]] = {}  # ranges from the data
        self._f32: dict[str, np.ndarray] = {}
        self._points = self._texture([lines.points, self._arc], 4,
                                     self._points)
        for name, tex in self._attrs.items():  # rewritten when a style reads them again
            old = self._spare.pop(name, None)
            if old is not None:
                old.release()
            self._spare[name] = tex
        self._attrs = {}
        self.n_indices = self.n_drawn = 0
        # this frame's draw calls: (line style drawn alone, or None: the whole style; first
        # index, index count); a transfer function splits the strips by range (see _select)
        self._draws: list[tuple[str | None, int, int]] = []

    @_current
    def release(self) -> None:
        """Free this renderer's buffers and framebuffers (programs stay cached on the context)."""
        for obj in [*self._vaos.values(), *self._attrs.values(), *self._spare.values(),
                    self._points, self._ids, self._ibo]:
            if obj is not None:
                obj.release()
        self._release_targets()
        self._vaos.clear()
        self._attrs.clear()
        self._spare.clear()

    def _release_targets(self) -> None:
        for ms, out in self._fbos.values():
            for fbo in (ms, out):
                if fbo is not None:
                    for att in (*fbo.color_attachments, fbo.depth_attachment):
                        att.release()
                    fbo.release()
        self._fbos.clear()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    # -- geometry -------------------------------------------------------------------------------
    def uploaded_attributes(self) -> list[str]:
        return list(self._attrs)

    def _buffer(self) -> moderngl.Buffer:
        self.allocations += 1
        return self.ctx.buffer(reserve=4)

    def _texture(self, columns: list[np.ndarray], components: int,
                 reuse: moderngl.Texture | None = None) -> moderngl.Texture:
        """Float32 texture of per-point values (``columns``: (N,) or (N, k) arrays, side by side,
        ``components`` in all), TEX_WIDTH points per row, nearest filtering; ``reuse``'s storage
        is written when it has that size (else it is released)."""
        size = point_texture_shape(self.lines.n_points)
        if size[1] > self.ctx.info["GL_MAX_TEXTURE_SIZE"]:
            raise ValueError(f"{self.lines.n_points} points need a {size[0]}x{size[1]} texture; "
                             f"this OpenGL allows {self.ctx.info['GL_MAX_TEXTURE_SIZE']} rows")
        n = self.lines.n_points
        data = np.zeros((size[0] * size[1], components), np.float32)
        c = 0
        for col in columns:  # (float32 as np.c_[...].astype(np.float32) gave)
            col = np.asarray(col)
            col = col[:, None] if col.ndim == 1 else col.reshape(n, col.shape[-1])
            data[:n, c:c + col.shape[1]] = col
            c += col.shape[1]
        if reuse is not None:
            if reuse.size == size and reuse.components == components:
                reuse.write(data)
                return reuse
            reuse.release()
        tex = self.ctx.texture(size, components, data.tobytes(), dtype="f4")
        self.allocations += 1
        tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        return tex

    def _attr_f32(self, name: str) -> np.ndarray:
        """The attribute as float32 (the values the shaders see), cached."""
        v = self._f32.get(name)
        if v is None:
            v = self._f32[name] = np.ascontiguousarray(self._attr_values(name), np.float32)
        return v

    def _attribute_texture(self, name: str) -> moderngl.Texture:
        buf = self._attrs.get(name)
        if buf is None:
            v = self._attr_values(name)
            if v.ndim != 1:
                raise StyleError(f"attribute '{name}' has shape {v.shape}; a style can only map "
                                 f"scalar (one value per vertex) attributes")
            buf = self._texture([v, self._slopes_of(name)], 2,
                                self._spare.pop(name, None))
            self._attrs[name] = buf
        return buf

    def _vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        vao = self._vaos.get(prog.glo)
        if vao is None:
            # the only vertex attributes are point ids: a_prev/a_cur/a_next read the same buffer
            # two entries apart (every id is stored twice, once per side of the strip); the
            # geometry path's a_cur reads ids[j] for lines_adjacency index j (simplify.adjacency)
            vao = self.ctx.vertex_array(prog, [], self._ibo, index_element_size=4)
            first = 1 if self.strips == "vertex" else 0
            for k, name in enumerate(("a_prev", "a_cur", "a_next")):
                if name in prog:
                    vao.bind(prog[name].location, "i", self._ids, "1i", offset=8 * (k - 1 + first),
                             stride=4)
            self._vaos[prog.glo] = vao
        return vao

    # -- level of detail ------------------------------------------------------------------------
    def _attr_values(self, name: str) -> np.ndarray:
        lines = self.lines
        if name in lines.point_data:
            return np.asarray(lines.point_data[name])
        if name in lines.line_data:  # per-line values repeated on the line's vertices
            return np.repeat(np.asarray(lines.line_data[name]), lines.lengths)
        have = sorted(lines.point_data) + sorted(lines.line_data)
        raise StyleError(f"the style reads attribute '{name}', which these lines do not "
                         f"have; available: {', '.join(have) or 'none'}")

    def _geometry_importance(self) -> np.ndarray:
        if self._geometry is None:
            self._geometry = geometry_importance(self._xyz, self._starts, self._stops)
        return self._geometry

    def _linear(self, style: Style) -> tuple[str, ...]:
        """The attributes ``style`` reads that change linearly along the arc (see shader_flags)."""
        for name in style.attributes():
            if name not in self._is_linear:
                v = self._attr_values(name)  # (not 1-D: refused when uploaded)
                self._is_linear[name] = v.ndim == 1 and linear_along_arc(
                    v, self._arc, self._starts, self._stops)
        return tuple(n for n in style.attributes() if self._is_linear[n])

    def _slopes_of(self, name: str) -> np.ndarray:
        m = self._slopes.get(name)
        if m is None:
            v = np.asarray(self._attr_values(name), np.float64)
            m = self._slopes[name] = slopes(v, self._arc, self._starts, self._stops)
        return m

    def _lod_importance(self, placed: tuple[str, ...], tols: dict[str, float]) -> np.ndarray:
        """World-unit importance of every point, compared per frame with the pixel tolerance at
        the point's depth (``simplify.lod_importance``: one DP hierarchy for every criterion):
        the geometry's deviation; the displacement of the attributes that place shapes and
        patterns; and for the attributes mapped to colour, width or a transfer function, their
        displacement where their value error exceeds half its tolerance.  So a dropped point
        either changes a mapped value by less than its tolerance, or shifts the mapped picture
        along the line by less than the pixel tolerance (as dropping geometry moves the line).
        Errors are those of the Hermite interpolant the shaders draw.  A tolerance of 0 (no
        known use) keeps every point where that interpolant is not exact."""
        if not placed and not tols:
            return self._geometry_importance()
        key = (placed, tuple(sorted(tols.items())))
        imp = self._lods.get(key)
        if imp is None:
            def attr(name):
                return np.asarray(self._attr_values(name), np.float64), self._slopes_of(name)
            imp = lod_importance(self._xyz, self._arc, self._starts, self._stops,
                                 [attr(n) for n in placed],
                                 [(*attr(n), 0.5 * t) for n, t in sorted(tols.items())])
            for k in list(self._lods)[:-(LOD_KEPT - 1)]:  # oldest first (dicts keep order)
                del self._lods[k]
            self._lods[key] = imp
        return imp

    def _data_range(self, name: str) -> float:
        r = self._ranges.get(name)
        if r is None:
            v = self._attr_values(name)
            fin = v[np.isfinite(v)]
            r = self._ranges[name] = float(fin.max() - fin.min()) if fin.size else 0.0
        return r

    def travel(self) -> np.ndarray:
        """(3,) the lines' summed |dx|, |dy|, |dz| (the automatic view of a cube-like domain
        looks along the axis the lines travel least along)."""
        if self._travel is None:
            d = np.abs(np.diff(self._xyz, axis=0))
            self._travel = d[self._inside()].sum(axis=0) if d.size else np.zeros(3)
        return self._travel

    def _inside(self) -> np.ndarray:
        """(N - 1,) bool: whether the segment from point i to i + 1 lies inside a run."""
        mark = np.zeros(len(self._xyz), np.int64)  # +1 at a run's start, -1 at its last point
        np.add.at(mark, self._starts, 1)
        np.add.at(mark, self._stops - 1, -1)
        return np.cumsum(mark)[:-1] > 0

    def camera(self, style: Style, camera: Camera | None, size) -> Camera:
        """The camera drawn with: ``camera`` (else the style's), its automatic view made
        explicit for these lines' bounds on a ``size`` image."""
        return (camera or style.camera).resolve(self.bounds, *size, self.travel())

    def camera_report(self, style: Style, camera: Camera | None, size) -> str:
        """The camera drawn with, in words, for logs: "view -x up 0,0,1 (automatic)"."""
        given = camera or style.camera
        used = self.camera(style, given, size).describe()
        return f"{used} (automatic)" if given.automatic else used

    def value_range(self, name: str, spec: Range = None) -> tuple[float, float]:
        """The range ``spec`` (None: min..max, "pA..pB": percentiles) of attribute ``name`` over
        these lines: what a style's colour or width map without numbers spans."""
        key = (name, spec)
        if key not in self._auto:
            self._auto[key] = data_range(self._attr_values(name), spec, name)
        return self._auto[key]

    def resolve(self, style: Style, camera: Camera | None = None, size=(1920, 1080),
                pixel: float = 1.0) -> Style:
        """``style`` with its ranges from the data (``ranges``) and its lengths relative to the
        scene (``lengths``) replaced by numbers, for ``camera`` (else the style's) on a
        ``size`` image whose pixels are ``pixel`` output pixels wide (1 / supersample)."""
        style = _as_style(style)
        self._report_clipping(style)
        style = resolve_ranges(style, self.value_range)
        return resolve_lengths(style, self.scene_scale(style, camera, size, pixel))

    def scene_scale(self, style: Style, camera: Camera | None, size,
                    pixel: float = 1.0) -> SceneScale:
        """What ``style``'s relative lengths resolve against for ``camera`` on ``size``."""
        cam = self.camera(style, camera, size).setup(self.bounds, *size)
        corners = np.array(np.meshgrid(*self.bounds)).reshape(3, -1).T
        z = corners @ cam.view[2, :3] + cam.view[2, 3]
        zt = float(cam.view[2, :3] @ cam.target + cam.view[2, 3])
        speed = None
        if "time" in style.attributes():
            speed = self._median_speed()
        return SceneScale(diagonal=float(np.linalg.norm(np.ptp(self.bounds, axis=1))),
                          depth=float(np.ptp(z)),
                          per_pixel=(cam.px_scale[0] * -zt + cam.px_scale[1]) / pixel,
                          length_units=self.lines.attrs.get("length_units"), speed=speed)

    def _median_speed(self) -> float | None:
        """The lines' median speed over their length (of every segment's arc length over its
        time, weighted by its arc length: lines creeping along a wall, many short segments
        at a crawl, do not set the speed of the lines that cross the domain), for lengths on
        time."""
        if self._speed is None:
            t = np.asarray(self._attr_values("time"), np.float64)
            inside = self._inside()
            ds = np.linalg.norm(np.diff(self._xyz, axis=0), axis=1)[inside]
            dt = np.abs(np.diff(t))[inside]
            ok = (dt > 0) & (ds > 0)
            speed, weight = ds[ok] / dt[ok], ds[ok]
            order = np.argsort(speed)
            cum = np.cumsum(weight[order])
            self._speed = float(speed[order][np.searchsorted(cum, 0.5 * cum[-1])]) \
                if ok.any() else 0.0
        return self._speed or None

    def _report_clipping(self, style: Style) -> None:
        """Warn once per range when a range the style fixes leaves over CLIP of the data
        outside (a style made for other data: every line at a colormap's end)."""
        for where, m in fixed_ranges(style):
            key = (where, m.attribute, m.range)
            if key in self._clip_reported:
                continue
            self._clip_reported.add(key)
            v = np.asarray(self._attr_values(m.attribute), np.float64)
            v = v[np.isfinite(v)]
            lo, hi = sorted(m.range)
            out = float(np.mean((v < lo) | (v > hi))) if v.size else 0.0
            if out > CLIP:
                warnings.warn(f"{where}.range = [{m.range[0]:g}, {m.range[1]:g}] leaves {out:.0%} "
                              f"of '{m.attribute}' outside (the data spans {v.min():.6g} .. "
                              f"{v.max():.6g}): leave the range out, or give percentiles "
                              "('p2..p98'), to follow the data", stacklevel=3)

    def _select(self, style: Style, cam, size) -> None:
        """Upload this frame's kept vertices (ids + strip indices), unless unchanged."""
        tol = self.tolerance * style.supersample  # output pixels -> render pixels
        placed = ()
        if tol <= 0:  # every vertex: the same for every camera
            key, tols = ("every vertex",), {}
        else:
            ranges = {}
            if style.transfer is not None:
                ranges[style.transfer.attribute] = self._data_range(style.transfer.attribute)
            # world size of the smallest pixel in the scene (for widths in world units)
            corners = np.array(np.meshgrid(*self.bounds)).reshape(3, -1).T
            z = corners @ cam.view[2, :3] + cam.view[2, 3]
            px_min = max(float(np.min(cam.px_scale[0] * -z + cam.px_scale[1])), 1e-30)
            # rounded down to a power of 2 (a tighter tolerance): world-unit width tolerances
            # then stay put while the camera moves a little, and each new one costs a DP pass
            px_min = 2.0 ** math.floor(math.log2(px_min))
            unit = 1.0 if style.units == "pixels" else style.supersample * px_min  # per output px
            tols = attribute_tolerances(style, self.tolerance, ranges, unit)
            placed = tuple(sorted(placed_attributes(style)))
            key = (cam.view.tobytes(), cam.proj.tobytes(), tuple(size), tol,
                   tuple(sorted(tols.items())), placed)
        tf = style.transfer
        key += (None if tf is None else (tf.attribute, tf.ranges, tf.blend),)
        if key == self._frame_key:
            return
        imp = self._lod_importance(placed, tols) if tol > 0 else np.zeros(0, np.float32)
        ids, idx = select(self._xyz, imp, cam.view, cam.px_scale, tol, np.zeros(0, bool),
                          self._starts, self._stops)
        self.n_drawn = (idx.size - self._starts.size) // 2  # points drawn this frame
        groups: list[tuple[str | None, np.ndarray]] = [(None, idx)]
        if tf is not None:
            # segments wholly inside one range (blend zones excluded) are drawn by that range's
            # style alone: each fragment then runs one style's code, not every drawn style's
            # (a software rasterizer runs both sides of every branch), and the strip is as wide
            # as that style; the rest by the whole style.  Ranges without a style: not drawn.
            b = 0.5 * tf.blend
            lo = [float(np.float32(max(r.range[0], -BIG))) + b for r in tf.ranges]
            hi = [float(np.float32(min(r.range[1], BIG))) - b for r in tf.ranges]
            split, counts = split_by_range(idx, ids, self._attr_f32(tf.attribute), lo, hi)
            ends = np.cumsum(counts)
            groups = [(r.style, split[e - c:e]) for r, c, e in zip(tf.ranges, counts, ends)
                      if r.style is not None and c]
            groups.append((None, split[ends[-1] - counts[-1]:ends[-1]]))
        if self.strips == "geometry":
            groups = [(g, adjacency(i)) for g, i in groups]
        self._draws, first = [], 0
        for g, i in groups:
            self._draws.append((g, first, i.size))
            first += i.size
        idx = np.concatenate([i for _, i in groups])
        for buf, data in ((self._ids, ids), (self._ibo, idx)):
            if buf.size < data.nbytes:
                buf.orphan(data.nbytes)
            buf.write(data)
        self.n_indices = idx.size
        self._frame_key = key

    # -- framebuffers ---------------------------------------------------------------------------
    def _targets(self, size: tuple[int, int], samples: int):
        key = (size, samples)
        if key not in self._fbos:
            self._release_targets()  # keep one size: print sizes are big
            ctx = self.ctx
            out = ctx.framebuffer(ctx.renderbuffer(size, 4), ctx.depth_renderbuffer(size))
            ms = None
            if samples > 1:
                ms = ctx.framebuffer(ctx.renderbuffer(size, 4, samples=samples),
                                     ctx.depth_renderbuffer(size, samples=samples))
            self._fbos[key] = (ms, out)
        return self._fbos[key]

    # -- drawing --------------------------------------------------------------------------------
    @_current  # compiles
    def prepare(self, style: Style) -> tuple[ShaderFlags, moderngl.Program]:
        samples = self.samples_for(style)
        flags = shader_flags(style, samples > 1, self.strips, linear=self._linear(style))
        return flags, self.programs.get(flags)

    def samples_for(self, style: Style) -> int:
        if style.antialias != "msaa" or not self.msaa:
            return 1
        return min(style.samples, self.ctx.max_samples) if self.ctx.max_samples >= 2 else 1

    @_current
    def render(self, style: Style | str | os.PathLike, size: tuple[int, int] = (1920, 1080),
               camera: Camera | None = None, overlays: bool = False) -> np.ndarray:
        """(H, W, 4) uint8 RGBA, row 0 at the top.  ``overlays``: with the style's legend and
        annotations (``overlay``), drawn at the output's resolution."""
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
        return self.overlay(img, style, camera) if overlays else img

    def overlay(self, image: np.ndarray, style: Style, camera: Camera | None = None,
                scale: float = 1.0, coverage: np.ndarray | None = None) -> np.ndarray:
        """``image`` (this renderer's picture of ``style``) with the style's legend (when its
        ``[legend] show``) and its annotations: title, the snapshot's time (the lines' metadata
        ``snapshot_time``), text and a scale bar at the depth of the view's target.  Each goes
        where it covers the fewest drawn pixels (the legend: unless the style names a corner);
        ``[legend] placement = "outside"`` widens the picture by margins that hold them all,
        covering no line.  ``coverage``: the drawn pixels to keep off instead of the image's
        (an animation places its overlays once, by its first frame, so they stay put)."""
        from .legend import annotation_image, composite, drawn_pixels, legend_image

        h, w = image.shape[:2]
        style = self.resolve(style, camera, (w, h))
        an = style.annotations
        fs = max(10.0, min(w, h) / 24)  # the picture's text size, kept on a widened canvas
        drawn = drawn_pixels(image, style) if coverage is None else coverage
        if style.legend.placement == "outside":
            image, drawn = self._margins(image, style, scale, fs)
        size = image.shape[1], image.shape[0]
        box = None
        if style.legend.show:
            leg, box = legend_image(style, size, units=self.lines.units, scale=scale,
                                    coverage=drawn, text_px=fs)
            image = composite(image, leg)
        t = self.lines.attrs.get("snapshot_time") if an.time else None
        per_px = None
        if an.scale_bar:
            cam = self.camera(style, camera, (w, h)).setup(self.bounds, w, h)
            z = cam.view[2, :3] @ self.bounds.mean(axis=1) + cam.view[2, 3]
            per_px = cam.px_scale[0] * -z + cam.px_scale[1]
        text, _ = annotation_image(size, style, title=an.title, text=an.text, scale=scale,
                                   time=None if t is None else float(t),
                                   time_origin=self.lines.attrs.get("time_origin"),
                                   world_per_pixel=per_px,
                                   length_units=self.lines.attrs.get("length_units"), avoid=box,
                                   coverage=drawn, text_px=fs)
        return composite(image, text)

    def _margins(self, image, style: Style, scale: float, fs: float):
        """``image`` on a canvas of the background widened by a right margin for the legend,
        a top one for the title and a bottom one for the time, text and scale bar; and the
        canvas's coverage: the whole picture (so that auto placement keeps off it)."""
        from .legend import legend_image

        h, w = image.shape[:2]
        an = style.annotations
        gap = round(0.02 * min(w, h)) + 2
        right = 0
        if style.legend.show:
            _, box = legend_image(style, (w, h), units=self.lines.units, scale=scale,
                                  placement="top-left", text_px=fs)
            right = 0 if box is None else box[2] - box[0] + 3 * gap
        rows = sum(1 for v in (an.time and "snapshot_time" in self.lines.attrs, an.text,
                               an.scale_bar) if v)
        top = round(2.2 * fs * scale) + 2 * gap if an.title else 0
        bottom = round(2.0 * fs * scale * rows) + 2 * gap if rows else 0
        bg = np.array([round(255 * c) for c in (style.background or (0, 0, 0, 0))], np.uint8)
        canvas = np.empty((top + h + bottom, w + right, 4), np.uint8)
        canvas[:] = bg
        canvas[top:top + h, :w] = image
        covered = np.zeros(canvas.shape[:2], bool)
        covered[top:top + h, :w] = True
        return canvas, covered

    @_current
    def draw(self, style: Style, size: tuple[int, int], camera: Camera | None = None):
        """Draw into the (multisampled) target of ``size`` and resolve it; no read-back."""
        ctx = self.ctx
        style = self.resolve(_as_style(style), camera, size, 1 / _as_style(style).supersample)
        flags, prog = self.prepare(style)
        attrs = style.attributes()
        cam = self.camera(style, camera, size).setup(self.bounds, *size)
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
        if self._starts.size:
            for a in attrs:  # upload (and check) the attributes before selecting with them
                self._attribute_texture(a)
            self._select(style, cam, size)
            half = style.scale * style.max_total_width
            pixels = style.units == "pixels"
            ss = style.supersample if pixels else 1  # pixel widths are output pixels
            uniforms = {
                "u_view": cam.view.T.astype("f4").tobytes(),
                "u_proj": cam.proj.T.astype("f4").tobytes(),
                "u_half": half * ss,
                # the edge ramp reaches 0.5 * fwidth (<= 0.71 px) beyond the outer edge
                "u_pad": 0.75 if flags.smooth_edge else 0.0,
                "u_scale": style.scale * ss,
                "u_pixels": 1.0 if pixels else 0.0,
                "u_px": cam.px_scale,
                "u_persp": 1.0 if cam.proj[3, 2] != 0 else 0.0,
            }
            if style.transfer is not None:  # per range: the strip half-width its style needs
                for i, rg in enumerate(style.transfer.ranges):
                    w = style.styles[rg.style].total_width if rg.style is not None else 0.0
                    uniforms[f"u_tfhalf{i}"] = style.scale * w * ss
            textures = [("u_points", self._points)]
            textures += [(f"u_attr{k}", self._attribute_texture(a)) for k, a in enumerate(attrs)]
            values = band_uniforms(style)  # numbers, colormap names, user shapes
            textures += [(name, style_texture(ctx, v)) for name, v in values.items() if is_texture(v)]
            for unit, (name, tex) in enumerate(textures):
                tex.use(location=unit)
                uniforms[name] = unit
            uniforms.update({k: v for k, v in values.items() if not is_texture(v)})
            mode = moderngl.TRIANGLE_STRIP if self.strips == "vertex" else moderngl.LINES_ADJACENCY
            for alone, first, count in self._draws:
                p = prog
                if alone is not None:  # one line style without the transfer function
                    p = self.programs.get(shader_flags(style, samples > 1, self.strips, alone,
                                                       self._linear(style)))
                    uniforms["u_half"] = style.scale * style.styles[alone].total_width * ss
                else:
                    uniforms["u_half"] = half * ss
                for name, value in uniforms.items():
                    if name in p:  # the compiler drops uniforms it can prove unused
                        u = p[name]
                        if isinstance(value, bytes):
                            u.write(value)
                        else:
                            u.value = value
                self._vao(p).render(mode, vertices=count, first=first)
        if ms is not None:
            ctx.copy_framebuffer(out, ms)

    def output(self) -> moderngl.Framebuffer:
        """The resolved (single-sample) framebuffer of the last draw, e.g. to blit to a window."""
        return next(iter(self._fbos.values()))[1]

    @_current
    def read(self) -> np.ndarray:
        """Read back the resolved image of the last draw: (H, W, 4) uint8, top row first."""
        out = self.output()
        w, h = out.size
        data = out.read(components=4, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(h, w, 4)[::-1].copy()


def check_picture(image: np.ndarray, style: Style, per_pixel: float) -> None:
    """Raise ValueError when a picture of ``style`` (resolved; before overlays) shows nothing:
    no pixel differs from the background, or a line is wider than the image (``per_pixel``:
    world units per pixel, for world widths), which covers it with one colour."""
    from .legend import drawn_pixels

    across = 2 * style.max_total_width * style.scale
    px = across if style.units == "pixels" else across / per_pixel
    if px > max(image.shape[:2]):
        raise ValueError(f"a line is {px:.4g} pixels wide, wider than the {image.shape[1]}x"
                         f"{image.shape[0]} image: give widths in pixels or as a fraction of "
                         "the domain ('1/200d')")
    if not drawn_pixels(image, style).any():
        raise ValueError("the picture shows no line: the lines lie outside the view, or the "
                         "style's bands are transparent or of no width")


def render_lines(lines: Lines, style: Style | str | os.PathLike | None = None,
                 size=(1920, 1080), camera: Camera | None = None,
                 ctx: moderngl.Context | None = None, strips: str = "vertex",
                 overlays: bool = False) -> np.ndarray:
    """Render ``lines`` with ``style`` (a Style or a TOML path; None: ``default_style`` for the
    lines' attributes, as ``flowkit render`` without ``--style``) to an (H, W, 4) uint8 RGBA
    array.  ``camera`` overrides the style's camera.  Uses a headless EGL context unless ``ctx``
    is given.  ``strips``: "vertex" or "geometry" shader stage builds the strips (see
    LineRenderer).  ``overlays``: draw the style's legend and annotations
    (``LineRenderer.overlay``).  To draw the same lines many times, keep a ``LineRenderer``."""
    style = default_style(list(lines.point_data)) if style is None \
        else _as_style(style)
    with LineRenderer(lines, ctx, strips=strips) as r:
        return r.render(style, size, camera, overlays)


def save_png(image: np.ndarray, path: str | os.PathLike) -> Path:
    """Write an (H, W, 3|4) uint8 image as PNG atomically (temp file beside it + rename)."""
    from PIL import Image

    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ValueError(f"save_png needs an (H, W, 3 or 4) uint8 array, got {img.dtype} {img.shape}")
    with atomic_path(path) as tmp:
        Image.fromarray(img, "RGBA" if img.shape[2] == 4 else "RGB").save(tmp, format="PNG")
    return Path(path)


def render_file(path: str | os.PathLike, style: Style | str | os.PathLike | None = None,
                size=(1920, 1080), camera: Camera | None = None,
                ctx: moderngl.Context | None = None, strips: str = "vertex",
                overlays: bool = False) -> np.ndarray:
    """Render a lines HDF5 file, reading only the geometry and the attributes the style uses.
    ``style`` None: ``default_style`` for the file's attributes."""
    from ..io.lines_h5 import lines_attributes, read_lines

    if style is None:
        names = [a for a in ("speed",) if a in lines_attributes(path)]
        lines = read_lines(path, attributes=names)
        style = default_style(names)
    else:
        style = _as_style(style)
        lines = read_lines(path, attributes=style.attributes())
    return render_lines(lines, style, size, camera, ctx, strips, overlays)


def default_style(attributes) -> Style:
    """What ``flowkit render`` draws without ``--style``: a 2.5 px core with a 1.5 px black halo
    set back by 2 % of the scene's depth range (so a line cuts those well behind it, in a room
    or a thin cavity alike), the core coloured by speed over its data range (viridis) when the
    lines have ``speed``, else white."""
    from .style.model import Band, ColorMap, LineStyle

    core = ColorMap("viridis", "speed") if "speed" in attributes else (1.0, 1.0, 1.0, 1.0)
    bands = (Band(core, 2.5), Band((0.0, 0.0, 0.0, 1.0), 1.5, depth_offset="1/50z"))
    return Style(styles={"default": LineStyle(bands)})
