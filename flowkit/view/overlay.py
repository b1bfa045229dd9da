"""Overlays: RGBA images (text and graphics drawn with Pillow at window resolution) composited
over the scene, and the images the viewer shows there: orientation axes, text boxes, the probe's
marker; ``SceneOverlays`` places the viewer's (axes, legend, probe, rake), each drawn again
only when what it shows changed.

``OverlayLayer.set(name, image, pos)`` places an (H, W, 4) uint8 image, straight alpha, top row
first, with its top left corner at ``pos`` (scene pixels, y down); ``compose`` draws the scene
image and then every overlay (alpha blended, in the order they were first set) into a texture of
the scene's size, which the window shows and screenshots save: what is seen is what is saved.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np
from PIL import Image, ImageDraw

from ..render.legend import drawn_pixels, legend_image, legend_key, text_font
from .rake import rake_image

MARGIN = 8  # px between overlays and the scene's edges
LEGEND_TEXT_PX = 14  # the legend's text size (times the HiDPI scale), near the panel's

_VS = """
#version 330
uniform vec4 u_rect;  // x0, y0, x1, y1 in clip space
in vec2 in_corner;    // (0|1, 0|1)
out vec2 v_uv;
void main() {
    v_uv = in_corner;
    gl_Position = vec4(mix(u_rect.xy, u_rect.zw, in_corner), 0.0, 1.0);
}
"""
_FS = """
#version 330
uniform sampler2D u_image;
in vec2 v_uv;
out vec4 f_color;
void main() { f_color = texture(u_image, v_uv); }
"""


@dataclass
class Overlay:
    image: np.ndarray  # (H, W, 4) uint8, straight alpha, top row first
    pos: tuple[int, int]  # top left, scene pixels, y down
    texture: moderngl.Texture | None = None


class OverlayLayer:
    """Named overlays over the scene, drawn on the GL context ``ctx``."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.overlays: dict[str, Overlay] = {}
        self._prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        corners = np.array([0, 0, 1, 0, 0, 1, 1, 1], "f4")
        self._vbo = ctx.buffer(corners.tobytes())
        self._vao = ctx.vertex_array(self._prog, [(self._vbo, "2f", "in_corner")])
        self._target: tuple[moderngl.Texture, moderngl.Framebuffer] | None = None

    def set(self, name: str, image: np.ndarray, pos: tuple[int, int]) -> None:
        image = np.ascontiguousarray(image, np.uint8)
        if image.ndim != 3 or image.shape[2] != 4:
            raise ValueError(f"overlay '{name}': an (H, W, 4) RGBA image is needed, "
                             f"got shape {image.shape}")
        old = self.overlays.get(name)
        if old is not None and old.image is image:  # same image: only (maybe) moved
            old.pos = (int(pos[0]), int(pos[1]))
            return
        self.remove(name)
        self.overlays[name] = Overlay(image, (int(pos[0]), int(pos[1])))

    def remove(self, name: str) -> None:
        o = self.overlays.pop(name, None)
        if o is not None and o.texture is not None:
            o.texture.release()

    def box(self, name: str) -> tuple[int, int, int, int] | None:
        """(x0, y0, x1, y1) of an overlay in scene pixels, or None when it is not shown."""
        o = self.overlays.get(name)
        if o is None:
            return None
        h, w = o.image.shape[:2]
        return o.pos[0], o.pos[1], o.pos[0] + w, o.pos[1] + h

    def _texture(self, o: Overlay) -> moderngl.Texture:
        if o.texture is None:
            h, w = o.image.shape[:2]
            o.texture = self.ctx.texture((w, h), 4, np.ascontiguousarray(o.image[::-1]).tobytes())
            o.texture.filter = moderngl.NEAREST, moderngl.NEAREST
        return o.texture

    def _quad(self, texture, rect) -> None:
        texture.use(location=0)
        self._prog["u_image"] = 0
        self._prog["u_rect"] = rect
        self._vao.render(moderngl.TRIANGLE_STRIP)

    def compose(self, scene: moderngl.Framebuffer) -> moderngl.Framebuffer:
        """The scene's image with the overlays over it, in a framebuffer of the scene's size."""
        ctx, (w, h) = self.ctx, scene.size
        if self._target is None or self._target[0].size != (w, h):
            self._release_target()
            tex = ctx.texture((w, h), 4)
            tex.filter = moderngl.NEAREST, moderngl.NEAREST
            self._target = tex, ctx.framebuffer([tex])
        tex, fbo = self._target
        ctx.copy_framebuffer(fbo, scene)
        fbo.use()
        ctx.viewport = (0, 0, w, h)
        ctx.disable(moderngl.DEPTH_TEST)
        ctx.enable(moderngl.BLEND)
        # straight alpha over: colour blends, alpha accumulates coverage (a transparent scene
        # background keeps the overlays' own alpha in the saved PNG)
        ctx.blend_func = (moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA,
                          moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA)
        for o in self.overlays.values():
            x0, y0 = o.pos
            oh, ow = o.image.shape[:2]
            self._quad(self._texture(o), (2 * x0 / w - 1, 1 - 2 * (y0 + oh) / h,
                                          2 * (x0 + ow) / w - 1, 1 - 2 * y0 / h))
        ctx.disable(moderngl.BLEND)
        ctx.blend_func = moderngl.DEFAULT_BLENDING
        return fbo

    def show(self, fbo: moderngl.Framebuffer, viewport: tuple[int, int, int, int]) -> None:
        """Copy a composed image (``compose``'s result) into ``viewport`` of the bound target."""
        self.ctx.viewport = viewport
        self.ctx.disable(moderngl.BLEND)
        self.ctx.disable(moderngl.DEPTH_TEST)
        self._quad(fbo.color_attachments[0], (-1.0, -1.0, 1.0, 1.0))

    def _release_target(self) -> None:
        if self._target is not None:
            self._target[1].release()
            self._target[0].release()
            self._target = None

    def release(self) -> None:
        for name in list(self.overlays):
            self.remove(name)
        self._release_target()
        for o in (self._vao, self._vbo, self._prog):
            o.release()


class SceneOverlays(OverlayLayer):
    """The overlays the viewer shows over its scene (scene pixels, y down)."""

    def __init__(self, ctx: moderngl.Context):
        super().__init__(ctx)
        self._keys: dict[str, object] = {}  # what each overlay's image shows

    def _keyed(self, name: str, key, make, place) -> None:
        """Overlay ``name`` with the image ``make()`` (made again only when ``key`` changes) at
        ``place(w, h)``; ``key`` None removes it."""
        if key is None:
            self.remove(name)
            self._keys.pop(name, None)
            return
        o = self.overlays.get(name)
        image = o.image if o is not None and self._keys.get(name) == key else make()
        self._keys[name] = key
        h, w = image.shape[:2]
        self.set(name, image, place(w, h))

    def _redrawn(self, name: str, key, draw) -> None:
        """Overlay ``name`` as ``draw()`` gives it, (image, top left) or None (not shown), drawn
        again only when ``key`` changes; ``key`` None removes it."""
        if key == self._keys.get(name):
            return
        self._keys[name] = key
        drawn = None if key is None else draw()
        if drawn is None:
            self.remove(name)
        else:
            self.set(name, *drawn)

    def axes(self, setup, size, shown: bool) -> None:
        """Orientation axes of the camera's ``setup`` in the bottom left corner."""
        sh = size[1]
        view = np.round(setup.view[:3, :3], 4)
        self._keyed("axes", view.tobytes() if shown else None, lambda: axes_image(view),
                    lambda w, h: (MARGIN, sh - h - MARGIN))

    def legend(self, style, size, units, scale: float, shown: bool, scene) -> None:
        """The renderer's legend of ``style`` (resolved: what is drawn), where the style places
        it; "auto" chooses the corner covering the fewest lines of ``scene()`` (the scene's
        image) and not the axes when the legend changes, and keeps it while the view moves."""
        key = (legend_key(style), units, tuple(size), scale) if shown else None

        def draw():
            coverage = None
            if style.legend.placement == "auto":
                coverage = drawn_pixels(scene(), style)
                axes = self.box("axes")
                if axes is not None:
                    coverage[axes[1]:axes[3], axes[0]:axes[2]] = True
            image, box = legend_image(style, size, units=units, scale=scale, coverage=coverage,
                                      text_px=LEGEND_TEXT_PX)
            if box is None:
                return None
            x0, y0, x1, y1 = box
            return image[y0:y1, x0:x1], (x0, y0)

        self._redrawn("legend", key, draw)

    def probe(self, setup, size, point, text: str) -> None:
        """The probe's marker on world ``point`` and its read-out ``text`` beside it (kept
        inside the scene); ``point`` None removes both."""
        if point is None:
            for name in ("probe", "probe marker"):
                self._keyed(name, None, None, None)
            return
        sw, sh = size
        clip = setup.proj @ setup.view @ np.r_[point, 1.0]
        if clip[3] <= 0:  # behind the eye
            clip[3] = 1e-9
        x = (clip[0] / clip[3] + 1) / 2 * sw
        y = (1 - clip[1] / clip[3]) / 2 * sh
        self._keyed("probe marker", "ring", ring_image,
                    lambda w, h: (round(x - w / 2), round(y - h / 2)))
        self._keyed("probe", text, lambda: text_image(text, background=(20, 20, 24, 215)),
                    lambda w, h: (int(min(max(x + 14, 0), max(sw - w, 0))),
                                  int(min(max(y + 14, 0), max(sh - h, 0)))))

    def rake(self, rake, active: str | None, setup, size, scale: float) -> None:
        """The seed rake (None: not shown), handle ``active`` (grabbed, or under the cursor)
        highlighted."""
        key = None
        if rake is not None:
            key = (rake, active, setup.view.tobytes(), setup.proj.tobytes(), tuple(size), scale)
        self._redrawn("rake", key, lambda: rake_image(rake, setup, size, active, scale))


# -- images -----------------------------------------------------------------------------------
def text_image(text: str, size: int = 13, color=(255, 255, 255, 255),
               background=(20, 20, 24, 190), pad: int = 6) -> np.ndarray:
    """``text`` (lines split on newlines) on a translucent box: (H, W, 4) uint8."""
    f = text_font(size)
    probe = ImageDraw.Draw(Image.new("RGBA", (1, 1)))
    x0, y0, x1, y1 = probe.multiline_textbbox((0, 0), text, font=f, spacing=3)
    img = Image.new("RGBA", (x1 - min(x0, 0) + 2 * pad, y1 - min(y0, 0) + 2 * pad), background)
    ImageDraw.Draw(img).multiline_text((pad - min(x0, 0), pad - min(y0, 0)), text, font=f,
                                       fill=color, spacing=3)
    return np.asarray(img)


AXIS_COLORS = ((235, 70, 70), (90, 205, 90), (90, 140, 255))  # x, y, z as ParaView shows them


def axes_image(view: np.ndarray, size: int = 100, labels=("X", "Y", "Z")) -> np.ndarray:
    """Orientation axes for a camera's ``view`` matrix: one arrow per world axis from the
    centre, the nearer drawn over the farther, labels at the tips; transparent elsewhere.
    Drawn 3x larger and reduced (premultiplied) for smooth edges."""
    k = 3
    s = size * k
    img = Image.new("RGBa", (s, s), (0, 0, 0, 0))
    d = ImageDraw.Draw(img)
    c, arm = s / 2, 0.34 * s
    rot = np.asarray(view, float)[:3, :3]
    order = np.argsort(rot[2])  # view z of each axis: farther (more negative) first
    f = text_font(13 * k)
    for i in order:
        dx, dy = rot[0, i], -rot[1, i]  # screen y runs down
        tip = (c + arm * dx, c + arm * dy)
        rgb = AXIS_COLORS[i]
        d.line([(c, c), tip], fill=(*rgb, 255), width=2 * k)
        d.ellipse([tip[0] - 2.5 * k, tip[1] - 2.5 * k, tip[0] + 2.5 * k, tip[1] + 2.5 * k],
                  fill=(*rgb, 255))
        lx, ly = c + 1.3 * arm * dx, c + 1.3 * arm * dy
        d.text((lx, ly), labels[i], font=f, fill=(*rgb, 255), anchor="mm",
               stroke_width=k, stroke_fill=(0, 0, 0, 255))
    small = img.reduce(k).convert("RGBA")
    return np.asarray(small)


def ring_image(radius: int = 6, color=(255, 190, 0, 255)) -> np.ndarray:
    """A ring with a dark rim (visible on any background): the probe's marker."""
    k = 3
    s = (2 * radius + 3) * k
    img = Image.new("RGBa", (s, s), (0, 0, 0, 0))
    d = ImageDraw.Draw(img)
    c = s / 2
    for r, w, fill in ((radius + 1, 4, (0, 0, 0, 255)), (radius + 1, 2, color)):
        d.ellipse([c - r * k, c - r * k, c + r * k, c + r * k], outline=fill, width=w * k)
    return np.asarray(img.reduce(k).convert("RGBA"))
