"""The viewer: one glfw window, a moderngl context on it, LineRenderer drawing the scene into its
offscreen target (blitted to the window), a Dear ImGui panel over it, the style file polled.

``Viewer.step()`` runs one frame: events, style file, panel, scene (redrawn only when the style,
camera or window size changed), blit, panel, swap.  The event handlers (``on_drag``,
``on_scroll``, ``on_key``) are what the glfw callbacks call, and what tests call.

Style updates: a new style whose template flags equal the current ones only changes uniforms;
other flags select (and, the first time, compile) another program.  ``updates`` counts both.
"""

from __future__ import annotations

import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from imgui_bundle import imgui  # before glfw: pyglfw then loads imgui-bundle's libglfw, one GLFW

import glfw  # isort: skip
import moderngl  # isort: skip

from ..lines import Lines
from ..render.context import create_context
from ..render.renderer import LineRenderer, save_png
from ..render.style import Style, StyleError, save_style, style_from_dict
from . import orbit
from .edit import colormapped, get_at, replace_at, with_color_attribute
from .panel import Panel, imgui_key
from .watch import FileWatch


class ViewerError(RuntimeError):
    """No window could be opened (no display, no OpenGL 3.3); the message says what to do."""


def read_style(path: Path) -> tuple[Style, str]:
    """The Style of a TOML file and its text (what "save" keeps: comments, order, spelling)."""
    try:
        text = path.read_text(encoding="utf-8")
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise StyleError(f"{path}: not valid TOML: {e}") from None
    except UnicodeDecodeError as e:
        raise StyleError(f"{path}: not UTF-8 text: {e}") from None
    return style_from_dict(data, where=str(path)), text


def unreadable(lines: Lines, style: Style) -> str | None:
    """Why ``lines`` cannot be drawn with ``style`` (an attribute they lack), or None."""
    have = lines.point_data
    for a in style.attributes():
        if a in have and np.ndim(have[a]) != 1:
            return (f"attribute '{a}' has shape {np.shape(have[a])}; a style can only map "
                    "scalar (one value per vertex) attributes")
        if a not in have and a not in lines.line_data:
            names = sorted(have) + sorted(lines.line_data)
            return (f"the style reads attribute '{a}', which these lines do not have; "
                    f"available: {', '.join(names) or 'none'}")
    return None


def _init_glfw() -> None:
    errors = []
    glfw.set_error_callback(lambda code, text: errors.append(text.decode(errors="replace")
                                                            if isinstance(text, bytes) else text))
    if not glfw.init():
        why = errors[-1] if errors else "glfw.init() failed"
        raise ViewerError(f"cannot open a window: {why}. The viewer needs a display: set DISPLAY, "
                          "or run it under a virtual one (xvfb-run flowkit view ...)")


class Viewer:
    """A window showing ``lines`` with the style file at ``style_path``, which is watched."""

    def __init__(self, lines: Lines, style_path, *, size=(1280, 800), vsync: bool = True,
                 visible: bool = True, screenshot_dir=None, tolerance: float | None = None,
                 title: str | None = None):
        self.lines = lines
        self.style_path = Path(style_path)
        style, text = read_style(self.style_path)  # a bad style at start is the caller's error
        problem = unreadable(lines, style)
        if problem is not None:
            raise StyleError(f"{self.style_path}: {problem}")
        self.watch = FileWatch(self.style_path)
        _init_glfw()
        for hint, value in ((glfw.CONTEXT_VERSION_MAJOR, 3), (glfw.CONTEXT_VERSION_MINOR, 3),
                            (glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE),
                            (glfw.OPENGL_FORWARD_COMPAT, True), (glfw.VISIBLE, visible)):
            glfw.window_hint(hint, value)
        w, h = (int(v) for v in size)
        self.window = glfw.create_window(w, h, title or f"flowkit view - {self.style_path.name}",
                                         None, None)
        if not self.window:
            raise ViewerError("cannot open an OpenGL 3.3 core window (glfw.create_window failed): "
                              "install Mesa's GLX (libgl1 libglx-mesa0) or a GPU driver")
        glfw.make_context_current(self.window)
        glfw.swap_interval(1 if vsync else 0)
        self.ctx: moderngl.Context = create_context("window")
        self._imgui = imgui.create_context()
        imgui.set_current_context(self._imgui)  # create_context only sets it when there is none
        imgui.get_io().set_ini_filename(None)  # no imgui.ini beside the user's files
        imgui.backends.opengl3_init("#version 330")
        self.renderer = LineRenderer(lines, self.ctx, tolerance=tolerance)
        self.screenshot_dir = Path(screenshot_dir) if screenshot_dir is not None else Path.cwd()

        self.style = self.file_style = style  # in effect / last good from the file
        self.source = text  # the file's text: save_style keeps its comments and layout
        self.flags = self._flags(style)
        self.camera = style.camera
        self.updates = {"uniforms": 0, "recompile": 0}
        self.last_update: str | None = None
        self.error: str | None = None  # shown in the panel until a good style replaces it
        self.message = ""
        self.color_attributes = sorted(k for k, v in lines.point_data.items() if np.ndim(v) == 1)
        self._ranges: dict[str, tuple[float, float]] = {}
        self.size = glfw.get_framebuffer_size(self.window)
        self.frame_time = self.scene_time = 0.0
        self.frames = self.scene_draws = 0
        self._scene_key = None
        self._drag: int | None = None
        self._cursor: tuple[float, float] | None = None
        self._pixel_scale = 1.0
        self._last = time.perf_counter()
        self.panel = Panel(self)
        glfw.set_cursor_pos_callback(self.window, self._cursor_cb)
        glfw.set_mouse_button_callback(self.window, self._button_cb)
        glfw.set_scroll_callback(self.window, self._scroll_cb)
        glfw.set_key_callback(self.window, self._key_cb)
        glfw.set_char_callback(self.window, self._char_cb)

    # -- style ------------------------------------------------------------------------------------
    def _flags(self, style: Style):
        """The template flags the renderer draws ``style`` with (compiled if new)."""
        with self.ctx:
            return self.renderer.prepare(style)[0]

    def _report(self, message: str) -> None:
        if message != self.error:
            print(f"flowkit view: {message}", file=sys.stderr, flush=True)
        self.error = message

    def set_style(self, style: Style) -> str | None:
        """Make ``style`` current: "uniforms" (same template flags), "recompile" (other flags),
        "unchanged", or None when it cannot be drawn (the error is reported, the current style
        stays)."""
        problem = unreadable(self.lines, style)
        if problem is not None:
            self._report(problem)
            return None
        if style == self.style:
            self.error = None
            return "unchanged"
        try:  # the renderer's own flags; a new set compiles here: a failure keeps the old style
            flags = self._flags(style)
        except moderngl.Error as e:
            self._report(f"shader build failed: {e}")
            return None
        self.error = None
        kind = "uniforms" if flags == self.flags else "recompile"
        if style.camera != self.style.camera:  # the file moved the camera: follow it
            self.camera = style.camera
        self.style, self.flags = style, flags
        self.updates[kind] += 1
        self.last_update = kind
        return kind

    def reload(self) -> str | None:
        """Read the style file again; on any error keep the current style and report it."""
        try:
            style, text = read_style(self.style_path)
        except (StyleError, OSError) as e:
            self._report(str(e))
            return None
        kind = self.set_style(style)
        if kind is not None:
            self.file_style, self.source = style, text
        return kind

    def edit(self, path: tuple, value) -> str | None:
        """Set one style parameter (what a panel widget does); see ``set_style``."""
        try:
            style = replace_at(self.style, path, value)
        except StyleError as e:
            self._report(str(e))
            return None
        return self.set_style(style)

    def save_style(self, path=None) -> Path:
        """Write the style in effect as TOML (atomically), in the style file's own text with the
        edited values replaced (comments and layout kept; see ``render.style.save_style``)."""
        path = Path(path) if path is not None else self.style_path
        save_style(self.style, path, keep=self.source)  # unedited: the file as it is
        self.message = f"saved {path}"
        return path

    def value_range(self, name: str) -> tuple[float, float]:
        r = self._ranges.get(name)
        if r is None:
            v = np.asarray(self.lines.point_data[name], np.float64)
            v = v[np.isfinite(v)]
            lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 1.0)
            if not hi > lo:
                lo, hi = lo - 0.5, lo + 0.5
            r = self._ranges[name] = (lo, hi)
        return r

    def cycle_color_attribute(self) -> str | None:
        """Colour-mapped colours read the next scalar point attribute, over its data range."""
        paths = colormapped(self.style)
        names = self.color_attributes
        if not paths or not names:
            self.message = ("no colour-mapped band to cycle" if not paths
                            else "the lines have no scalar point attribute")
            return None
        current = get_at(self.style, paths[0]).attribute
        name = names[(names.index(current) + 1) % len(names)] if current in names else names[0]
        lo, hi = self.value_range(name)
        self.set_style(with_color_attribute(self.style, name, (lo, hi)))
        self.message = f"colour: {name} over [{lo:.4g}, {hi:.4g}]"
        return name

    # -- camera and keys --------------------------------------------------------------------------
    def reset_camera(self) -> None:
        self.camera = self.style.camera

    def on_drag(self, dx: float, dy: float, button: int = 0, mods: int = 0) -> None:
        """Left drag orbits; right or middle drag (or shift + left) pans.  Pixels, y down."""
        if button == glfw.MOUSE_BUTTON_LEFT and not mods & glfw.MOD_SHIFT:
            self.camera = orbit.orbit(self.camera, dx, dy)
        else:
            self.camera = orbit.pan(self.camera, dx, dy, self.renderer.bounds, self.size)

    def on_scroll(self, steps: float) -> None:
        """Scroll up (steps > 0) zooms in."""
        self.camera = orbit.zoom(self.camera, steps, self.renderer.bounds, self.size)

    def on_key(self, key: int, action: int = glfw.PRESS, mods: int = 0) -> None:
        """R reset camera, S screenshot, C next colour attribute, Esc quit (glfw key codes)."""
        if action != glfw.PRESS:
            return
        if key == glfw.KEY_ESCAPE:
            glfw.set_window_should_close(self.window, True)
        elif key == glfw.KEY_R:
            self.reset_camera()
        elif key == glfw.KEY_S:
            self.message = f"saved {self.screenshot()}"
        elif key == glfw.KEY_C:
            self.cycle_color_attribute()

    def screenshot(self, path=None) -> Path:
        """Write the scene (without the panel) as PNG, atomically; by default the first free
        flowkit-view-NNN.png in ``screenshot_dir``."""
        if path is None:
            k = 0
            while (self.screenshot_dir / f"flowkit-view-{k:03d}.png").exists():
                k += 1
            path = self.screenshot_dir / f"flowkit-view-{k:03d}.png"
        self._draw_scene()
        return save_png(self.renderer.read(), path)

    @property
    def should_close(self) -> bool:
        return bool(glfw.window_should_close(self.window))

    # -- glfw callbacks: imgui first, the scene only what imgui does not want ----------------------
    def _cursor_cb(self, _win, x, y) -> None:
        imgui.set_current_context(self._imgui)
        imgui.get_io().add_mouse_pos_event(x, y)
        if self._drag is not None and self._cursor is not None:
            mods = glfw.MOD_SHIFT if (glfw.get_key(self.window, glfw.KEY_LEFT_SHIFT)
                                      or glfw.get_key(self.window, glfw.KEY_RIGHT_SHIFT)) else 0
            k = self._pixel_scale  # window coordinates -> framebuffer pixels (HiDPI)
            self.on_drag(k * (x - self._cursor[0]), k * (y - self._cursor[1]), self._drag, mods)
        self._cursor = (x, y)

    def _button_cb(self, _win, button, action, _mods) -> None:
        imgui.set_current_context(self._imgui)
        io = imgui.get_io()
        if 0 <= button < 5:
            io.add_mouse_button_event(button, action == glfw.PRESS)
        if action == glfw.PRESS and not io.want_capture_mouse and self._drag is None:
            self._drag = button
        elif action == glfw.RELEASE and button == self._drag:
            self._drag = None

    def _scroll_cb(self, _win, dx, dy) -> None:
        imgui.set_current_context(self._imgui)
        io = imgui.get_io()
        io.add_mouse_wheel_event(dx, dy)
        if not io.want_capture_mouse:
            self.on_scroll(dy)

    def _key_cb(self, _win, key, _scancode, action, mods) -> None:
        imgui.set_current_context(self._imgui)
        io = imgui.get_io()
        for mod, ikey in ((glfw.MOD_CONTROL, imgui.Key.mod_ctrl), (glfw.MOD_SHIFT,
                          imgui.Key.mod_shift), (glfw.MOD_ALT, imgui.Key.mod_alt)):
            io.add_key_event(ikey, bool(mods & mod))
        ikey = imgui_key(key)
        if ikey is not None and action in (glfw.PRESS, glfw.RELEASE):
            io.add_key_event(ikey, action == glfw.PRESS)
        if not io.want_capture_keyboard:
            self.on_key(key, action, mods)

    def _char_cb(self, _win, codepoint) -> None:
        imgui.set_current_context(self._imgui)
        imgui.get_io().add_input_character(codepoint)

    # -- frames -----------------------------------------------------------------------------------
    def _draw_scene(self) -> None:
        key = (id(self.style), self.camera, tuple(self.size))
        if key == self._scene_key:
            return
        t0 = time.perf_counter()
        self.renderer.draw(self.style, tuple(self.size), self.camera)
        self.scene_time = time.perf_counter() - t0
        self.scene_draws += 1
        self._scene_key = key

    def invalidate(self) -> None:
        """Draw the scene again at the next frame (it is otherwise kept while nothing changes)."""
        self._scene_key = None

    def step(self, read_screen: bool = False) -> np.ndarray | None:
        """One frame.  ``read_screen``: return the window's image (scene + panel) as (H, W, 4)
        uint8, top row first, read before the buffer swap."""
        t0 = time.perf_counter()
        glfw.make_context_current(self.window)
        imgui.set_current_context(self._imgui)
        glfw.poll_events()
        if self.watch.changed():
            self.reload()
        fw, fh = glfw.get_framebuffer_size(self.window)
        ww, wh = glfw.get_window_size(self.window)
        if min(fw, fh, ww, wh) < 1:  # minimised: nothing to draw
            glfw.wait_events_timeout(0.1)
            return None
        self.size = (fw, fh)
        self._pixel_scale = fw / ww
        io = imgui.get_io()
        io.display_size = imgui.ImVec2(ww, wh)
        io.display_framebuffer_scale = imgui.ImVec2(fw / ww, fh / wh)
        io.delta_time = max(t0 - self._last, 1e-4)
        self._last = t0
        imgui.backends.opengl3_new_frame()
        imgui.new_frame()
        self.panel.draw()  # may edit the style or save it
        imgui.render()
        with self.ctx:
            self._draw_scene()
            screen = self.ctx.detect_framebuffer(0)  # the window's, at its current size
            self.ctx.copy_framebuffer(screen, self.renderer.output())
            screen.use()
            self.ctx.viewport = (0, 0, fw, fh)
            imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
            image = None
            if read_screen:
                data = screen.read(viewport=(0, 0, fw, fh), components=4, alignment=1)
                image = np.frombuffer(data, np.uint8).reshape(fh, fw, 4)[::-1].copy()
        glfw.swap_buffers(self.window)
        self.frames += 1
        self.frame_time = time.perf_counter() - t0
        return image

    def finish(self) -> None:
        """Wait until the GPU has finished the frame (for timings)."""
        with self.ctx:
            self.ctx.finish()

    def run(self) -> None:
        """Frames until the window is closed (Esc or the close button)."""
        try:
            while not self.should_close:
                drawn = self.scene_draws
                self.step()
                if self.scene_draws == drawn:  # idle: sleep until an event (or 30 Hz, the watch)
                    glfw.wait_events_timeout(1 / 30)
        finally:
            self.close()

    def close(self) -> None:
        """Free GL objects and the window (idempotent)."""
        if self.window is None:
            return
        glfw.make_context_current(self.window)
        imgui.set_current_context(self._imgui)
        imgui.backends.opengl3_shutdown()
        imgui.destroy_context(self._imgui)
        self.renderer.release()
        glfw.destroy_window(self.window)
        self.window = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
