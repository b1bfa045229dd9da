"""The Dear ImGui panel: frame time, messages and errors, the style's parameters (edited through
``Viewer.edit``), "save style", and the keys.  Widgets come from ``edit.params``: one per Param
kind, so a new style parameter needs a Param, not new panel code."""

from __future__ import annotations

import functools
import math

import glfw
from imgui_bundle import imgui

from ..render.shapes import SHAPE_NAMES
from ..render.style import ColorMap, known_colormap
from .edit import get_at, params

# offered in the colormap combo (any name the cmap package knows works in the file)
COLORMAPS = ("viridis", "magma", "inferno", "plasma", "cividis", "turbo", "bupu", "ylorrd",
             "gray")
ERROR_COLOR = imgui.ImVec4(1.0, 0.35, 0.3, 1.0)

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


class Panel:
    def __init__(self, viewer):
        self.viewer = viewer

    def draw(self) -> None:
        v = self.viewer
        imgui.set_next_window_pos(imgui.ImVec2(8, 8), imgui.Cond_.first_use_ever)
        height = imgui.get_io().display_size.y - 16
        imgui.set_next_window_size(imgui.ImVec2(340, height), imgui.Cond_.first_use_ever)
        imgui.begin("flowkit view")
        imgui.push_item_width(-135)  # widgets leave room for their labels
        imgui.text(f"frame {1e3 * v.frame_time:.1f} ms, scene {1e3 * v.scene_time:.1f} ms")
        imgui.text(f"{v.renderer.n_drawn} of {v.lines.n_points} vertices drawn")
        imgui.text(f"updates: {v.updates['uniforms']} uniform-only, {v.updates['recompile']} "
                   "recompile")
        if v.error:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(ERROR_COLOR, f"style error (last good style shown):\n{v.error}")
            imgui.pop_text_wrap_pos()
        elif v.message:
            imgui.text_wrapped(v.message)
        if imgui.button("save style"):
            v.save_style()
        imgui.same_line()
        if imgui.button("reset camera"):
            v.reset_camera()
        imgui.same_line()
        if imgui.button("colour attribute"):
            v.cycle_color_attribute()
        imgui.push_text_wrap_pos(0.0)
        imgui.text_disabled("drag: orbit, right/shift drag: pan, scroll: zoom; R reset camera, "
                            "S screenshot, C colour attribute, Esc quit")
        imgui.pop_text_wrap_pos()
        self._params()
        imgui.pop_item_width()
        imgui.end()

    def _params(self) -> None:
        group = None
        is_open = False
        for p in params(self.viewer.style):
            if p.group != group:
                group = p.group
                is_open = imgui.collapsing_header(group, imgui.TreeNodeFlags_.default_open)
            if not is_open:
                continue
            imgui.push_id(repr(p.path))
            changed, value = self._widget(p)
            imgui.pop_id()
            if changed and p.kind == "attribute":  # a new attribute comes with its data range
                cm = get_at(self.viewer.style, p.path[:-1])
                self.viewer.edit(p.path[:-1], ColorMap(cm.cmap, value,
                                                       self.viewer.value_range(value)))
            elif changed:
                self.viewer.edit(p.path, value)

    def _widget(self, p):
        v = self.viewer
        if p.kind == "float":
            low = -math.inf if p.low is None else p.low
            changed, x = imgui.drag_float(p.label, p.value, _float_speed(p.value))
            return changed, float(max(x, low))
        if p.kind == "color":
            changed, c = imgui.color_edit4(p.label, list(p.value))
            return changed, tuple(min(max(float(x), 0.0), 1.0) for x in c)
        if p.kind == "range":
            lo, hi = p.value
            finite = [x for x in (lo, hi) if math.isfinite(x)]
            speed = _float_speed(max(finite, key=abs)) if finite else 1e-3
            changed, r = imgui.drag_float2(p.label, [lo, hi], speed)
            return changed and r[0] != r[1], (float(r[0]), float(r[1]))
        if p.kind in ("cmap", "shape", "attribute"):
            items = {"cmap": _colormaps(), "shape": list(SHAPE_NAMES), "attribute": v.color_attributes}[p.kind]
            if p.value not in items:
                items = [p.value, *items]
            changed, k = imgui.combo(p.label, items.index(p.value), items)
            return changed, items[k]
        raise ValueError(f"no widget for parameter kind {p.kind!r}")
