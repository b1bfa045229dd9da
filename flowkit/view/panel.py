"""The Dear ImGui panel, docked on the window's left (the scene is the rest): frame time,
messages and errors, "save style", undo/redo, named views, what is shown (axes, outline, legend,
probe), the colour attribute and its range (an automatic range shown as the numbers it resolves
to), then the style's parameters (edited through ``Viewer.edit``).  Widgets come from
``edit.params``: one per Param kind, so a new style parameter needs a Param, not new panel
code.

Numbers are kept as the panel shows them: a dragged or typed float is the decimal its widget
displays (``shown``), a colour channel the 0-255 step its widget displays, so "save style"
writes ``4.072``, not the float32 the widget worked in (4.072000026702881)."""

from __future__ import annotations

import functools
import math

import glfw
import numpy as np
from imgui_bundle import imgui

from ..render.camera import VIEWS
from ..render.shapes import SHAPE_NAMES
from ..render.style.check import known_colormap
from ..render.style.model import ColorMap
from .edit import auto_range, get_at, params
from .seeding import LIVE_SECONDS

# offered in the colormap combo (any name the cmap package knows works in the file)
COLORMAPS = ("viridis", "magma", "inferno", "plasma", "cividis", "turbo", "bupu", "ylorrd",
             "gray")
ERROR_COLOR = imgui.ImVec4(1.0, 0.35, 0.3, 1.0)
PANEL_WIDTH = 340  # px at first

_KEYS = {glfw.KEY_TAB: imgui.Key.tab, glfw.KEY_LEFT: imgui.Key.left_arrow,
         glfw.KEY_RIGHT: imgui.Key.right_arrow, glfw.KEY_UP: imgui.Key.up_arrow,
         glfw.KEY_DOWN: imgui.Key.down_arrow, glfw.KEY_PAGE_UP: imgui.Key.page_up,
         glfw.KEY_PAGE_DOWN: imgui.Key.page_down, glfw.KEY_HOME: imgui.Key.home,
         glfw.KEY_END: imgui.Key.end, glfw.KEY_DELETE: imgui.Key.delete,
         glfw.KEY_BACKSPACE: imgui.Key.backspace, glfw.KEY_ENTER: imgui.Key.enter,
         glfw.KEY_KP_ENTER: imgui.Key.keypad_enter, glfw.KEY_ESCAPE: imgui.Key.escape,
         glfw.KEY_SPACE: imgui.Key.space, glfw.KEY_A: imgui.Key.a, glfw.KEY_C: imgui.Key.c,
         glfw.KEY_V: imgui.Key.v, glfw.KEY_X: imgui.Key.x, glfw.KEY_Z: imgui.Key.z,
         glfw.KEY_LEFT_CONTROL: imgui.Key.left_ctrl, glfw.KEY_LEFT_SHIFT: imgui.Key.left_shift}


@functools.cache
def _colormaps() -> list[str]:
    return [n for n in COLORMAPS if known_colormap(n)]


def imgui_key(key: int):
    """The ImGui key of a glfw key code (the ones text fields and navigation use), or None."""
    return _KEYS.get(key)


def _float_speed(value: float) -> float:
    return max(abs(value) * 0.01, 1e-3)


def number_format(value: float) -> str:
    """The widget's printf format: at least 3 decimals, 4 significant digits for small values."""
    a = abs(float(value))
    decimals = 3 if not math.isfinite(a) or a == 0 else 3 - math.floor(math.log10(a))
    return f"%.{min(max(decimals, 3), 9)}f"


def shown(x: float, fmt: str) -> float:
    """The number a widget with ``fmt`` shows for ``x`` (the float32 ImGui works in), as a
    float: what is kept and saved."""
    return float(fmt % x) if math.isfinite(x) else float(x)


def shown_color(c) -> tuple[float, ...]:
    """A colour as the colour widget shows it: channels in steps of 1/255."""
    return tuple(round(min(max(float(x), 0.0), 1.0) * 255) / 255 for x in c)


def keep_unedited(new, old, show) -> tuple[float, ...]:
    """Components a multi-value widget handed back: the ones not edited (equal in float32,
    what ImGui holds) stay exactly as they were; the edited ones as shown."""
    return tuple(o if np.float32(n) == np.float32(o) else x
                 for n, o, x in zip(new, old, show(new)))


def _auto_label(label: str, spec) -> str:
    """A range widget's label: "(data)" or the percentiles when the range is automatic; the
    "###" part keeps the widget's id when the label changes (mid-drag it becomes numbers)."""
    if isinstance(spec, tuple):
        return f"{label}###{label}"
    return f"{label} ({'data' if spec is None else spec})###{label}"


class Panel:
    """The panel of ``viewer`` (a ``Viewer``: its window's state, its style ``session`` and its
    ``live`` rake are what the widgets show and edit)."""

    def __init__(self, viewer):
        self.viewer = viewer
        self.width = PANEL_WIDTH  # framebuffer pixels, as the panel last drew itself
        self._active = None  # the path of the widget being dragged (one undo step)

    def draw(self) -> None:
        v, s = self.viewer, self.viewer.session
        io = imgui.get_io()
        height = io.display_size.y
        imgui.set_next_window_pos(imgui.ImVec2(0, 0), imgui.Cond_.always)
        imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, height), imgui.Cond_.first_use_ever)
        # docked: full height, only the width is the user's (drag the right edge)
        imgui.set_next_window_size_constraints(imgui.ImVec2(200, height),
                                               imgui.ImVec2(max(io.display_size.x - 50, 200),
                                                            height))
        imgui.begin("flowkit view", None, imgui.WindowFlags_.no_move
                    | imgui.WindowFlags_.no_collapse)
        self.width = imgui.get_window_width() * io.display_framebuffer_scale.x
        imgui.push_item_width(-135)  # widgets leave room for their labels
        imgui.text(f"frame {1e3 * v.frame_time:.1f} ms, scene {1e3 * v.scene_time:.1f} ms")
        imgui.text(f"{v.renderer.n_drawn} of {v.lines.n_points} vertices drawn")
        imgui.text(f"updates: {s.updates['uniforms']} uniform-only, {s.updates['recompile']} "
                   "recompile")
        if s.error:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(ERROR_COLOR, f"style error (last good style shown):\n{s.error}")
            imgui.pop_text_wrap_pos()
        elif v.message:
            imgui.text_wrapped(v.message)
        if imgui.button("save style"):
            s.save_style()
        imgui.same_line()
        if imgui.button("reset camera"):
            v.reset_camera()
        imgui.same_line()
        if imgui.button("colour attribute"):
            s.cycle_color_attribute()
        n_undo, n_redo = s.history.counts
        imgui.begin_disabled(n_undo == 0)
        if imgui.button(f"undo ({n_undo})"):
            s.undo()
        imgui.end_disabled()
        imgui.same_line()
        imgui.begin_disabled(n_redo == 0)
        if imgui.button(f"redo ({n_redo})"):
            s.redo()
        imgui.end_disabled()
        imgui.push_text_wrap_pos(0.0)
        keys = ", ".join(f"{k} {what}" for k, what in v.KEYS.values())
        imgui.text_disabled("left drag: orbit, right/shift drag: pan, wheel: zoom at the cursor, "
                            f"click: pin the probe; {keys}; Ctrl+Z undo, Ctrl+Shift+Z redo, "
                            "Ctrl+S save style")
        imgui.pop_text_wrap_pos()
        self._view()
        self._seeding()
        self._params()
        imgui.pop_item_width()
        imgui.end()

    def _view(self) -> None:
        """What is shown besides the lines, and the colour attribute's range."""
        v, s = self.viewer, self.viewer.session
        if not imgui.collapsing_header("view", imgui.TreeNodeFlags_.default_open):
            return
        for i, name in enumerate(VIEWS):  # ParaView's view buttons (keys 1-7)
            if i:
                imgui.same_line()
            if imgui.small_button(name):
                v.set_view(name)
        for label, what in (("orientation axes (A)", "axes"), ("outline (B)", "outline"),
                            ("legend (L)", "legend"), ("probe on hover (P)", "probe")):
            if imgui.checkbox(label, v.shown(what))[0]:
                v.toggle(what)
        if v.probe is not None:
            imgui.text_wrapped("probe: " + "; ".join(v.probe_lines()))
        cm = s.color_map()
        if cm is None:
            return
        imgui.text(f"colour: {cm.attribute} ({cm.cmap})")
        changed, r = self._range(_auto_label("colour range", cm.range),
                                 s.color_map(resolved=True).range)
        if changed:
            s.set_color_range(r, merge=self._merge("colour range"))
        self._settle("colour range")
        if imgui.button("data range"):
            s.set_color_range(None)

    def _seeding(self) -> None:
        """The rake of live seeding: its kind, seed counts, save seeds, the re-trace time."""
        v, live = self.viewer, self.viewer.live
        if v.seeding is None or not imgui.collapsing_header("seed rake",
                                                            imgui.TreeNodeFlags_.default_open):
            return
        rake = live.rake
        for i, kind in enumerate(("line", "plane")):
            if i:
                imgui.same_line()
            if imgui.radio_button(kind, rake.kind == kind) and rake.kind != kind:
                v.set_rake(rake.as_kind(kind, v.seeding.decimals))
        imgui.same_line()
        if imgui.checkbox("shown (G)", v.show_rake)[0]:
            v.toggle("rake")
        label = "seeds" if rake.kind == "line" else "seeds nu, nv"
        widget = imgui.input_int if rake.kind == "line" else imgui.input_int2
        changed, n = widget(label, rake.counts[0] if rake.kind == "line" else list(rake.counts))
        if changed:
            v.set_rake(rake.with_counts(*np.atleast_1d(n)))
        if imgui.button("save seeds (W)"):
            v.save_seeds()
        imgui.push_text_wrap_pos(0.0)
        if v.seeding.source is not None:
            imgui.text_wrapped(f"lines from the scene's seeds ({v.seeding.source}); drag a rake "
                               "handle to seed from the rake")
        imgui.text_disabled(live.rake.spec())
        if live.retraces:
            imgui.text(f"{len(v.lines)} lines; re-trace {1e3 * live.trace_time:.0f} ms, with "
                       f"redraw {1e3 * live.reseed_time:.0f} ms"
                       + ("" if live.live_time() <= LIVE_SECONDS else "; slow: traced on release"))
        keys = ", ".join(f"{k} {what}" for k, what in v.SEED_KEYS.values())
        imgui.text_disabled(f"left drag a handle: move it; {keys}")
        imgui.pop_text_wrap_pos()

    def _merge(self, key) -> bool:
        """True when this change continues the drag of the same widget (one undo step)."""
        merge = self._active == key
        self._active = key
        return merge

    def _settle(self, key) -> None:
        if imgui.is_item_deactivated() and self._active == key:
            self._active = None

    def _range(self, label, value):
        lo, hi = value
        finite = [x for x in (lo, hi) if math.isfinite(x)]
        big = max(finite, key=abs) if finite else 0.0
        speed = _float_speed(big) if finite else 1e-3
        fmt = number_format(min((abs(x) for x in finite if x), default=big) or big)
        changed, r = imgui.drag_float2(label, [lo, hi], speed, format=fmt)
        r = keep_unedited(r, value, lambda r: [shown(x, fmt) for x in r])
        return changed and r[0] != r[1] and r != (lo, hi), r

    def _params(self) -> None:
        s = self.viewer.session
        group = None
        is_open = False
        for p in params(s.style):
            if p.group != group:
                group = p.group
                is_open = imgui.collapsing_header(group, imgui.TreeNodeFlags_.default_open)
            if not is_open:
                continue
            imgui.push_id(repr(p.path))
            changed, value = self._widget(p)
            if changed and p.kind == "attribute":  # a new attribute comes with its data range
                cm = get_at(s.style, p.path[:-1])
                s.edit(p.path[:-1], ColorMap(cm.cmap, value, auto_range(cm.range)))
            elif changed:
                s.edit(p.path, value, merge=self._merge(p.path))
            self._settle(p.path)
            imgui.pop_id()

    def _widget(self, p):
        s = self.viewer.session
        if p.kind == "float":
            low = -math.inf if p.low is None else p.low
            value, label = p.value, p.label
            if isinstance(value, str):  # a relative length ("1/200d"): its number in this view;
                value, label = get_at(s.resolved, p.path), f"{p.label} ({p.value})"  # a drag
            fmt = number_format(value)  # sets a number
            changed, x = imgui.drag_float(label, value, _float_speed(value), format=fmt)
            x = max(shown(x, fmt), low)
            return changed and x != value, x
        if p.kind == "color":
            changed, c = imgui.color_edit4(p.label, list(p.value))
            c = keep_unedited(c, p.value, shown_color)
            return changed and c != tuple(p.value), c
        if p.kind == "range":  # an automatic range shows the numbers it resolves to
            return self._range(_auto_label(p.label, p.value), get_at(s.resolved, p.path))
        if p.kind in ("cmap", "shape", "attribute"):
            items = {"cmap": _colormaps(), "shape": list(SHAPE_NAMES), "attribute": s.color_attributes}[p.kind]
            if p.value not in items:
                items = [p.value, *items]
            changed, k = imgui.combo(p.label, items.index(p.value), items)
            return changed, items[k]
        raise ValueError(f"no widget for parameter kind {p.kind!r}")

