"""The viewer: one glfw window, a moderngl context on it, LineRenderer drawing the scene into its
offscreen target (blitted to the window), a Dear ImGui panel over it, the style file polled.

``Viewer`` is the window and its loop; its parts hold the rest: the style session
(``session.StyleSession``: the style file, edits, undo), the live rake (``seeding.LiveRake``),
the overlays (``overlay.SceneOverlays``), the panel (``panel.Panel``) and the probe's picker
(``probe.Picker``).  The viewer's methods and attributes of those parts (``edit``, ``undo``,
``style``, ``grab``, ``rake``...) are theirs, reached through the window.

``Viewer.step()`` runs one frame: events, style file, panel, scene (redrawn only when the style,
camera, outline or viewport changed), overlays (axes, legend, probe), panel, swap.  ``run``
calls it only when something happened (input, a window event, a style file change, a text field
being typed in); otherwise it sleeps in ``glfw.wait_events_timeout``, waking to poll the file.
The event handlers (``on_drag``, ``on_scroll``, ``on_key``) are what the glfw callbacks call, and
what tests call.

The scene's viewport is the window right of the panel (the whole window with the panel hidden).
The camera is fitted to it once (on open, R, a named view, a new camera in the style file) and
pinned (``orbit.pinned``), so orbiting, zooming and panning keep the scale.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import ClassVar

import numpy as np
from imgui_bundle import imgui  # before glfw: pyglfw then loads imgui-bundle's libglfw, one GLFW

import glfw  # isort: skip
import moderngl  # isort: skip

from ..lines import Lines
from ..render.camera import VIEWS, Camera
from ..render.context import create_context
from ..render.renderer import LineRenderer, save_png
from ..render.style.check import StyleError
from ..render.style.model import Range, Style
from . import orbit
from .outline import Outline, domain_bounds
from .overlay import SceneOverlays
from .panel import Panel, imgui_key
from .probe import Picker, describe
from .rake import Rake
from .seeding import LiveRake, LiveSeeding
from .session import StyleSession, read_style, unreadable
from .watch import FileWatch

IDLE_POLL = 0.25  # s between style file polls while nothing happens
WAKE_FRAMES = 3  # frames drawn after an event (ImGui settles hover and active states)


class ViewerError(RuntimeError):
    """No window could be opened (no display, no OpenGL 3.3); the message says what to do."""


def _init_glfw() -> None:
    errors = []
    glfw.set_error_callback(lambda code, text: errors.append(text.decode(errors="replace")
                                                            if isinstance(text, bytes) else text))
    if not glfw.init():
        why = errors[-1] if errors else "glfw.init() failed"
        raise ViewerError(f"cannot open a window: {why}. The viewer needs a display: set DISPLAY, "
                          "or run it under a virtual one (xvfb-run flowkit view ...)")


def _of(part: str, name: str) -> property:
    """``Viewer.<name>``: the viewer's part ``<part>``'s ``<name>`` (state or method)."""
    return property(lambda self: getattr(getattr(self, part), name), doc=f"``{part}.{name}``")


class Viewer:
    """A window showing ``lines`` with the style file at ``style_path``, which is watched."""

    def __init__(self, lines: Lines, style_path, *, size=(1280, 800), vsync: bool = True,
                 visible: bool = True, screenshot_dir=None, tolerance: float | None = None,
                 title: str | None = None, units: dict[str, str] | None = None,
                 camera: Camera | None = None, seeding: LiveSeeding | None = None):
        """``camera``: the camera to open with and R returns to (default: the style's);
        ``seeding``: live seeding from a rake (flowkit.view.seeding), ``lines`` being what is
        shown until the rake first moves."""
        self.lines = lines
        self.units = dict(units or {})  # attribute -> units, "position" for x, y, z
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
        self.seeding = seeding
        self._tolerance = tolerance
        # with a field: its box frames the view, so lines traced again keep the camera
        self._bounds = None if seeding is None else np.asarray(seeding.bounds, float)
        self.renderer = LineRenderer(lines, self.ctx, tolerance=tolerance, bounds=self._bounds)
        self.overlays = SceneOverlays(self.ctx)
        self.outline_bounds = domain_bounds(lines) if seeding is None else self._bounds
        if self.outline_bounds is None:
            self.outline_bounds = self.renderer.bounds
        self.outline = Outline(self.ctx, self.outline_bounds)
        self.picker = Picker(lines.points)  # its index builds in a thread
        self.screenshot_dir = Path(screenshot_dir) if screenshot_dir is not None else Path.cwd()

        self.message = ""
        self.session = StyleSession(self.style_path, style, text, self.renderer,
                                    view=lambda: (self.camera, self.scene_size),
                                    follow=self._follow, wake=self.wake, say=self._say)
        self.home_camera = camera  # R's camera (None: the style's)
        self._camera, self._fit = style.camera, camera or style.camera  # fitted at first frame
        self.size = glfw.get_framebuffer_size(self.window)
        self.frame_time = self.scene_time = 0.0
        self.frames = self.scene_draws = 0
        self._scene_key = None
        self._drag: int | None = None
        self._cursor: tuple[float, float] | None = None
        self._press: tuple[float, float] | None = None
        self._pixel_scale = 1.0
        # what is shown besides the lines (keys and panel toggle them)
        self.show_axes = True
        self.show_legend = style.legend.show
        self.show_outline = False
        self.show_panel = True
        self.show_rake = seeding is not None
        self.probe_on_hover = True
        self.scene_origin = 0  # x of the scene's viewport in the window
        self.scene_size = self.size
        self.probe: int | None = None  # the probed vertex
        self.probe_pinned = False
        self._hover: tuple[float, float] | None = None  # scene pixels
        self._probe_key = None
        self.live = LiveRake(seeding)  # the rake and the lines traced from it
        self._lines_gen = 0  # counts set_lines (part of the scene's key)
        self._wake = WAKE_FRAMES
        self._last = time.perf_counter()
        self.panel = Panel(self)
        glfw.set_cursor_pos_callback(self.window, self._cursor_cb)
        glfw.set_mouse_button_callback(self.window, self._button_cb)
        glfw.set_scroll_callback(self.window, self._scroll_cb)
        glfw.set_key_callback(self.window, self._key_cb)
        glfw.set_char_callback(self.window, self._char_cb)
        glfw.set_window_refresh_callback(self.window, lambda _w: self.wake())
        glfw.set_framebuffer_size_callback(self.window, lambda _w, _x, _y: self.wake())

    def wake(self, frames: int = WAKE_FRAMES) -> None:
        """Draw the next ``frames`` frames (``run`` sleeps otherwise)."""
        self._wake = max(self._wake, frames)

    # -- style: the session's, and what a new style changes in the window -------------------------
    style = _of("session", "style")
    file_style = _of("session", "file_style")
    source = _of("session", "source")
    flags = _of("session", "flags")
    history = _of("session", "history")
    updates = _of("session", "updates")
    last_update = _of("session", "last_update")
    error = _of("session", "error")
    resolved = _of("session", "resolved")
    color_attributes = _of("session", "color_attributes")
    set_style = _of("session", "set_style")
    reload = _of("session", "reload")
    apply = _of("session", "apply")
    undo = _of("session", "undo")
    redo = _of("session", "redo")
    edit = _of("session", "edit")
    save_style = _of("session", "save_style")
    cycle_color_attribute = _of("session", "cycle_color_attribute")
    color_map = _of("session", "color_map")
    set_color_range = _of("session", "set_color_range")

    def _follow(self, old: Style, new: Style) -> None:
        """A new style in effect: the file moved the camera, follow it; and its legend switch."""
        if new.camera != old.camera:
            self.fit_camera(new.camera)
        if new.legend.show != old.legend.show:
            self.show_legend = new.legend.show

    def _say(self, message: str) -> None:
        self.message = message

    def value_range(self, name: str, spec: Range = None) -> tuple[float, float]:
        """The range ``spec`` (None: min..max, "pA..pB": percentiles) of attribute ``name`` over
        the lines: what an automatic range of the style resolves to."""
        return self.renderer.value_range(name, spec)

    # -- camera and keys --------------------------------------------------------------------------
    @property
    def camera(self) -> Camera:
        """The camera drawn with: pinned (``orbit.pinned``), fitted once to the scene's
        viewport by ``fit_camera``, so orbiting keeps the scale."""
        if self._fit is not None:  # fitted when first needed: at the viewport's size then
            fit = self.renderer.camera(self.style, self._fit, self.scene_size)  # (as render)
            self._camera = orbit.pinned(fit, self.renderer.bounds, self.scene_size)
            self._fit = None
        return self._camera

    @camera.setter
    def camera(self, cam: Camera) -> None:
        self._camera, self._fit = cam, None

    def fit_camera(self, cam: Camera) -> None:
        """Show the lines through ``cam``, its fitted parts (distance, view height, up, ...)
        fitted at the next frame's viewport and then kept."""
        self._fit = cam
        self.wake()

    def reset_camera(self) -> None:
        """The camera the window opened with (default: the style's), fitted again (R)."""
        self.fit_camera(self.home_camera or self.style.camera)

    def set_view(self, view: str) -> None:
        """Look along a named view ("+x", ..., "iso"; ``render.camera.VIEWS``) with the style's
        projection, fitted to the lines as ParaView's view buttons do."""
        self.fit_camera(dataclasses.replace(self.style.camera, view=view, distance=None,
                                            target=None, parallel_scale=None))
        self.message = f"view {view}"

    def on_drag(self, dx: float, dy: float, button: int = 0, mods: int = 0) -> None:
        """Left drag orbits (or moves the rake handle grabbed by ``grab``); right or middle
        drag (or shift + left) pans.  Pixels, y down."""
        if self.live.handle is not None:
            self.drag_handle(dx, dy)
        elif button == glfw.MOUSE_BUTTON_LEFT and not mods & glfw.MOD_SHIFT:
            self.camera = orbit.orbit(self.camera, dx, dy)
        else:
            self.camera = orbit.pan(self.camera, dx, dy, self.renderer.bounds, self.scene_size)
        self.wake()

    def on_scroll(self, steps: float, at: tuple[float, float] | None = None) -> None:
        """Scroll up (steps > 0) zooms in, towards scene pixel ``at`` (the cursor; None: the
        centre of the scene)."""
        if at is None:
            self.camera = orbit.zoom(self.camera, steps, self.renderer.bounds, self.scene_size)
        else:
            self.camera = orbit.zoom_at(self.camera, steps, self.renderer.bounds,
                                        self.scene_size, *at)
        self.wake()

    # glfw key -> (its name, what it does); Ctrl+Z, Ctrl+Shift+Z, Ctrl+S besides
    KEYS: ClassVar = {
        glfw.KEY_R: ("R", "reset camera"), glfw.KEY_1: ("1-7", "views " + " ".join(VIEWS)),
        glfw.KEY_S: ("S", "screenshot"),
        glfw.KEY_C: ("C", "next colour attribute"), glfw.KEY_A: ("A", "orientation axes"),
        glfw.KEY_B: ("B", "outline"), glfw.KEY_L: ("L", "legend"),
        glfw.KEY_P: ("P", "probe on hover"),
        glfw.KEY_H: ("H", "hide/show the panel"), glfw.KEY_ESCAPE: ("Esc", "quit")}
    # with live seeding
    SEED_KEYS: ClassVar = {
        glfw.KEY_EQUAL: ("+ / -", "one seed more / fewer per rake edge"),
        glfw.KEY_T: ("T", "line / plane rake"), glfw.KEY_G: ("G", "rake shown"),
        glfw.KEY_W: ("W", "save seeds")}
    _COUNT_KEYS: ClassVar = {glfw.KEY_EQUAL: 1, glfw.KEY_KP_ADD: 1, glfw.KEY_MINUS: -1,
                             glfw.KEY_KP_SUBTRACT: -1}
    _TOGGLES: ClassVar = {"axes": "show_axes", "outline": "show_outline", "legend": "show_legend",
                          "probe": "probe_on_hover", "panel": "show_panel", "rake": "show_rake"}
    _TOGGLE_KEYS: ClassVar = {glfw.KEY_A: "axes", glfw.KEY_B: "outline", glfw.KEY_L: "legend",
                              glfw.KEY_P: "probe",
                              glfw.KEY_H: "panel", glfw.KEY_G: "rake"}

    def shown(self, what: str) -> bool:
        """Whether "axes", "outline", "legend", "probe" (on hover) or "panel" is on."""
        return getattr(self, self._TOGGLES[what])

    def toggle(self, what: str) -> None:
        setattr(self, self._TOGGLES[what], not self.shown(what))
        if what == "probe" and not self.probe_on_hover and not self.probe_pinned:
            self.probe = None
        if what == "rake":
            self.live.handle = None
        self.wake()

    def on_key(self, key: int, action: int = glfw.PRESS, mods: int = 0) -> None:
        """``KEYS`` and Ctrl+Z undo, Ctrl+Shift+Z (or Ctrl+Y) redo, Ctrl+S save style (glfw key
        codes and modifier bits)."""
        if action not in (glfw.PRESS, glfw.REPEAT):
            return
        self.wake()
        if mods & glfw.MOD_CONTROL:
            if key == glfw.KEY_Z:
                self.redo() if mods & glfw.MOD_SHIFT else self.undo()
            elif key == glfw.KEY_Y:
                self.redo()
            elif key == glfw.KEY_S and action == glfw.PRESS:
                self.save_style()
            return
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
        elif glfw.KEY_1 <= key < glfw.KEY_1 + len(VIEWS):
            self.set_view(VIEWS[key - glfw.KEY_1])
        elif key in self._TOGGLE_KEYS:
            self.toggle(self._TOGGLE_KEYS[key])
        elif key in self._COUNT_KEYS or key in (glfw.KEY_T, glfw.KEY_W):
            if self.seeding is None:
                self.message = ("no live seeding: open a scene (flowkit view --scene FILE) to "
                                "seed from a rake")
            elif key == glfw.KEY_T:
                rake = self.live.rake
                self.set_rake(rake.as_kind("plane" if rake.kind == "line" else "line",
                                           self.seeding.decimals))
            elif key == glfw.KEY_W:
                self.save_seeds()
            else:
                self.set_rake(self.live.rake.more(self._COUNT_KEYS[key]))

    # -- live seeding: the rake's -----------------------------------------------------------------
    rake = _of("live", "rake")
    retraces = _of("live", "retraces")
    reseed_time = _of("live", "reseed_time")
    trace_time = _of("live", "trace_time")
    live_time = _of("live", "live_time")

    def _setup(self):
        """The camera's setup on the scene's viewport (what the scene is drawn with)."""
        return self.camera.setup(self.renderer.bounds, *self.scene_size)

    def handle_at(self, x: float, y: float) -> str | None:
        """The rake handle at scene pixel (x, y) (within ``rake.GRAB_PX``), or None."""
        if not self.show_rake:
            return None
        return self.live.handle_at(self._setup(), self.scene_size, x, y)

    def handle_xy(self, name: str) -> tuple[float, float]:
        """Scene pixel (x, y) of rake handle ``name``."""
        return self.live.handle_xy(self._setup(), self.scene_size, name)

    def grab(self, x: float, y: float) -> str | None:
        """Start dragging the rake handle at scene pixel (x, y) (a left press there); its name,
        or None when there is none (the press then orbits)."""
        self.live.handle = self.handle_at(x, y)
        self.wake()
        return self.live.handle

    def drag_handle(self, dx: float, dy: float) -> None:
        """Move the grabbed handle with the mouse (pixels, y down), parallel to the screen,
        inside the field's box."""
        self.set_rake(self.live.dragged(self._setup(), dx, dy))

    def release(self) -> None:
        """Let the handle go: the next frame traces the rake if it was not traced while
        dragging."""
        self.live.handle = None
        self.wake()

    def set_rake(self, rake: Rake) -> None:
        """A new rake (seeds, shape or count): traced at the next frame (while a handle is
        dragged, only when that keeps up, see ``seeding.LIVE_SECONDS``)."""
        if rake != self.live.rake:
            self.live.rake = rake
            self.message = f"rake: {rake.n_seeds} seeds ({rake.spec()})"
        self.wake()

    def retrace(self) -> Lines:
        """Trace the rake's seeds (``LiveSeeding.trace``: the scene's call and options) and
        show the lines."""
        return self.live.trace(self.set_lines)

    def set_lines(self, lines: Lines) -> None:
        """Show ``lines`` (with the same attributes) instead: the renderer takes their geometry
        into its buffers (``LineRenderer.set_lines``: its programs, vertex arrays and
        framebuffers stay), a new picker; the camera, style and overlays stay."""
        problem = unreadable(lines, self.style)
        if problem is not None:
            raise StyleError(problem)
        self.renderer.set_lines(lines)
        self.lines = lines
        self.picker = Picker(lines.points, start=False)  # built when first asked for
        self.probe, self.probe_pinned = None, False
        self.session.lines_changed()  # linear attributes may differ
        self._lines_gen += 1
        self.invalidate()

    def save_seeds(self, path=None) -> Path:
        """Write the rake's seed spec (what ``flowkit trace --seeds`` and a scene's ``[seeds]
        spec`` take) atomically to ``path`` (default ``seeding.save_to``, beside the scene),
        and print where."""
        path = self.live.save(path)
        self.message = f"saved seeds to {path}"
        return path

    # -- probe ------------------------------------------------------------------------------------
    def pick(self, x: float, y: float, wait: bool = True) -> int | None:
        """The vertex drawn under scene pixel (x, y) (y down; within 8 px), or None.  ``wait``:
        False returns None while the spatial index is still being built."""
        if not wait and not self.picker.ready:
            return None
        setup = self.camera.setup(self.renderer.bounds, *self.scene_size)
        return self.picker.pick(setup, self.scene_size, x, y, self.renderer.bounds)

    def probe_at(self, x: float, y: float, pin: bool = True) -> list[str] | None:
        """Probe the vertex under scene pixel (x, y): it is shown (marked, with its read-out)
        and its read-out returned; None (and nothing shown) when no line is there."""
        self.probe = self.pick(x, y)
        self.probe_pinned = pin and self.probe is not None
        self.wake()
        return self.probe_lines() or None

    def probe_lines(self) -> list[str]:
        """The read-out of the probed vertex (``probe.describe``), [] when there is none."""
        return [] if self.probe is None else describe(self.lines, self.probe, self.units)

    def screenshot(self, path=None) -> Path:
        """Write the scene (without the panel) as PNG, atomically; by default the first free
        flowkit-view-NNN.png in ``screenshot_dir``."""
        if path is None:
            k = 0
            while (self.screenshot_dir / f"flowkit-view-{k:03d}.png").exists():
                k += 1
            path = self.screenshot_dir / f"flowkit-view-{k:03d}.png"
        return save_png(self.image(), path)

    def image(self) -> np.ndarray:
        """The scene as the window shows it, overlays included, without the panel: (H, W, 4)
        uint8, top row first (what S saves)."""
        with self.ctx:
            self._draw_scene()
            self._update_overlays()
            fbo = self.overlays.compose(self.renderer.output())
            w, h = fbo.size
            data = fbo.read(components=4, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(h, w, 4)[::-1].copy()

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
            self._hover = None
        elif not imgui.get_io().want_capture_mouse:
            self._hover = self._scene_xy(x, y)
        self._cursor = (x, y)
        self.wake()

    def _scene_xy(self, x: float, y: float) -> tuple[float, float]:
        """Window coordinates -> scene pixels (y down)."""
        k = self._pixel_scale
        return k * x - self.scene_origin, k * y

    def _button_cb(self, _win, button, action, _mods) -> None:
        imgui.set_current_context(self._imgui)
        io = imgui.get_io()
        if 0 <= button < 5:
            io.add_mouse_button_event(button, action == glfw.PRESS)
        self.wake()
        if action == glfw.PRESS and not io.want_capture_mouse and self._drag is None:
            self._drag = button
            self._press = self._cursor
            if button == glfw.MOUSE_BUTTON_LEFT and self._cursor is not None:
                self.grab(*self._scene_xy(*self._cursor))
        elif action == glfw.RELEASE and button == self._drag:
            self._drag = None
            if self.live.handle is not None:
                self.release()
            elif button == glfw.MOUSE_BUTTON_LEFT and self._cursor == self._press and self._cursor:
                self.probe_at(*self._scene_xy(*self._cursor))  # a click pins (or clears) it
            self._hover = self._scene_xy(*self._cursor) if self._cursor else None

    def _scroll_cb(self, _win, dx, dy) -> None:
        imgui.set_current_context(self._imgui)
        io = imgui.get_io()
        io.add_mouse_wheel_event(dx, dy)
        self.wake()
        if not io.want_capture_mouse:
            self.on_scroll(dy, None if self._cursor is None else self._scene_xy(*self._cursor))

    def _key_cb(self, _win, key, _scancode, action, mods) -> None:
        imgui.set_current_context(self._imgui)
        self.wake()
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
        self.wake()

    # -- frames -----------------------------------------------------------------------------------
    def _draw_scene(self) -> None:
        size = tuple(self.scene_size)
        key = (id(self.style), self.camera, size, self.show_outline, self._lines_gen)
        if key == self._scene_key:
            return
        t0 = time.perf_counter()
        self.renderer.draw(self.style, size, self.camera)
        if self.show_outline:  # into the lines' own target, against their depth
            ms, out = self.renderer._targets(size, self.renderer.samples_for(self.style))
            (ms or out).use()
            self.outline.draw(self.camera.setup(self.renderer.bounds, *size),
                              self.style.background)
            if ms is not None:
                self.ctx.copy_framebuffer(out, ms)
        self.scene_time = time.perf_counter() - t0
        self.scene_draws += 1
        self._scene_key = key

    def invalidate(self) -> None:
        """Draw the scene again at the next frame (it is otherwise kept while nothing changes)."""
        self._scene_key = None
        self.wake(1)

    def _update_overlays(self, retraced: bool = False) -> None:
        setup = self._setup()
        size = self.scene_size
        self.overlays.axes(setup, size, self.show_axes)
        self.overlays.legend(self.resolved, size, self.units, self._pixel_scale, self.show_legend,
                             self.renderer.read)
        self._update_probe(retraced)
        text = "\n".join(self.probe_lines())
        if self.probe_pinned:
            text += "\n(pinned: click elsewhere to clear)"
        self.overlays.probe(setup, size, None if self.probe is None else
                            self.lines.points[self.probe], text)
        rake = self.live.rake if self.show_rake else None
        active = self.live.handle
        if rake is not None and active is None and self._hover is not None:
            active = self.live.handle_at(setup, size, *self._hover)
        self.overlays.rake(rake, active, setup, size, self._pixel_scale)

    def _update_probe(self, retraced: bool = False) -> None:
        """The probe under the cursor, while hovering probes.  ``retraced``: the lines were
        traced in this frame; a hover probe then waits for the next frame, so that the new
        lines' index is not built while this one is drawn (the probe would find it unbuilt
        anyway)."""
        key = (self._scene_key, self._hover, self.probe_on_hover)
        if (self.probe_on_hover and not self.probe_pinned and self._hover is not None
                and key != self._probe_key and self._drag is None):
            if retraced:
                self.wake(1)
            else:
                self.probe = self.pick(*self._hover, wait=False)
                self._probe_key = key
        else:
            self._probe_key = key

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
        if self.show_panel:
            self.panel.draw()  # may edit the style or save it; measures its width
        imgui.render()
        self._wake = max(self._wake - 1, 0)
        x0 = min(round(self.panel.width), fw - 1) if self.show_panel else 0
        self.scene_origin, self.scene_size = x0, (fw - x0, fh)
        with self.ctx:
            t_seed = time.perf_counter()
            retraced = self.live.due()
            if retraced:
                self.retrace()
            self._draw_scene()
            if retraced:  # the new lines drawn, finished: what following the mouse costs
                self.ctx.finish()
                self.live.timed(time.perf_counter() - t_seed)
            self._update_overlays(retraced)
            composed = self.overlays.compose(self.renderer.output())
            screen = self.ctx.detect_framebuffer(0)  # the window's, at its current size
            screen.use()
            self.ctx.viewport = (0, 0, fw, fh)
            screen.clear(0.0, 0.0, 0.0, 1.0)
            self.overlays.show(composed, (x0, 0, fw - x0, fh))
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

    def loop(self, seconds: float | None = None) -> None:
        """Frames while something happens, until the window is closed (or ``seconds`` passed).
        Idle, it sleeps until an event, polling the style file every IDLE_POLL seconds."""
        end = None if seconds is None else time.perf_counter() + seconds
        while not self.should_close and (end is None or time.perf_counter() < end):
            imgui.set_current_context(self._imgui)
            typing = bool(imgui.get_io().want_text_input)  # the text cursor blinks
            if self._wake <= 0 or typing:
                timeout = 1 / 30 if typing else IDLE_POLL
                if end is not None:
                    timeout = max(min(timeout, end - time.perf_counter()), 0.0)
                glfw.wait_events_timeout(timeout)  # the callbacks wake() on input
                if self.watch.changed():
                    self.reload()
                if self._wake <= 0 and not typing:
                    continue
            self.step()

    def run(self) -> None:
        """Frames until the window is closed (Esc or the close button), then free it."""
        try:
            self.loop()
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
        self.overlays.release()
        self.outline.release()
        self.renderer.release()
        glfw.destroy_window(self.window)
        self.window = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()
