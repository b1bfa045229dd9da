"""The viewer's style session: the style in effect, the style file it comes from (reloaded when
it changes, saved back in its own text), the edits made in the window and their undo history.

A new style whose template flags equal the current ones only changes uniforms; other flags
select (and, the first time, compile) another program.  ``updates`` counts both.  A style that
cannot be drawn (an attribute the lines lack, a shader that does not build) is reported and the
last good one stays.
"""

from __future__ import annotations

import sys
import tomllib
from collections.abc import Callable
from pathlib import Path

import moderngl
import numpy as np

from ..lines import Lines
from ..render.style.check import StyleError
from ..render.style.model import ColorMap, Range, Style
from ..render.style.toml import save_style, style_from_dict
from .edit import colormapped, get_at, replace_at, with_color_attribute
from .history import History


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


class StyleSession:
    """The style drawn by ``renderer`` (whose lines it must fit), read from ``path`` as
    ``style`` and ``text``.  The window's side, as callables: ``view()`` the camera and viewport
    size that automatic lengths resolve against, ``follow(old, new)`` when a new style takes
    effect (its camera, its legend switch), ``wake()`` to draw the next frames, ``say(text)``
    the status message."""

    def __init__(self, path: Path, style: Style, text: str, renderer, *,
                 view: Callable, follow: Callable, wake: Callable, say: Callable):
        self.path = path
        self.renderer = renderer
        self._view, self._follow, self._wake, self._say = view, follow, wake, say
        self.history = History()
        self.style = self.file_style = style  # in effect / last good from the file
        self.source = text  # the file's text: save_style keeps its comments and layout
        self.flags = self._flags(style)
        self.updates = {"uniforms": 0, "recompile": 0}
        self.last_update: str | None = None
        self.error: str | None = None  # shown in the panel until a good style replaces it
        lines = renderer.lines
        self.color_attributes = sorted(k for k, v in lines.point_data.items() if np.ndim(v) == 1)
        self._resolved: tuple[Style | None, Style] = (None, style)

    def _flags(self, style: Style):
        """The template flags the renderer draws ``style`` with (compiled if new)."""
        with self.renderer.ctx:
            return self.renderer.prepare(self.renderer.resolve(style))[0]  # (lengths as numbers)

    def _report(self, message: str) -> None:
        if message != self.error:
            print(f"flowkit view: {message}", file=sys.stderr, flush=True)
        self.error = message

    def lines_changed(self) -> None:
        """The renderer shows other lines (with the same attributes): resolve and prepare the
        style again (automatic ranges and linear attributes may differ)."""
        self._resolved = (None, self.style)
        self.flags = self._flags(self.style)

    def set_style(self, style: Style) -> str | None:
        """Make ``style`` current: "uniforms" (same template flags), "recompile" (other flags),
        "unchanged", or None when it cannot be drawn (the error is reported, the current style
        stays)."""
        problem = unreadable(self.renderer.lines, style)
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
        self._follow(self.style, style)
        self.style, self.flags = style, flags
        self.updates[kind] += 1
        self.last_update = kind
        return kind

    def reload(self) -> str | None:
        """Read the style file again; on any error keep the current style and report it."""
        try:
            style, text = read_style(self.path)
        except (StyleError, OSError) as e:
            self._report(str(e))
            return None
        kind = self.set_style(style)
        if kind is not None:
            self.file_style, self.source = style, text
        if kind in ("uniforms", "recompile"):  # the file is the source: earlier edits are gone
            self.history.clear()
        self._wake()
        return kind

    def apply(self, style: Style, key=None, merge: bool = False) -> str | None:
        """A user's edit (panel, C, colour range): ``set_style`` and an undo step; ``merge``
        continues the last step when it had the same ``key`` (one widget being dragged)."""
        before = self.style
        kind = self.set_style(style)
        if kind in ("uniforms", "recompile"):
            self.history.record(before, key, merge)
        self._wake()
        return kind

    def undo(self) -> str | None:
        """Back to the style before the last edit (exactly: styles are kept whole)."""
        return self._history_step(self.history.undo)

    def redo(self) -> str | None:
        return self._history_step(self.history.redo)

    def _history_step(self, move) -> str | None:
        style = move(self.style)
        if style is None:
            self._say("nothing to " + move.__name__)
            return None
        n_undo, n_redo = self.history.counts
        self._say(f"{move.__name__}: {n_undo} undo, {n_redo} redo steps left")
        self._wake()
        return self.set_style(style)

    def edit(self, path: tuple, value, merge: bool = False) -> str | None:
        """Set one style parameter (what a panel widget does); see ``set_style``.  ``merge``:
        the widget is still being dragged, so this continues the last undo step."""
        try:
            style = replace_at(self.style, path, value)
        except StyleError as e:
            self._report(str(e))
            return None
        return self.apply(style, key=path, merge=merge)

    def save_style(self, path=None) -> Path:
        """Write the style in effect as TOML (atomically), in the style file's own text with the
        edited values replaced (comments and layout kept; see ``render.style.toml.save_style``)."""
        path = Path(path) if path is not None else self.path
        save_style(self.style, path, keep=self.source)  # unedited: the file as it is
        self._say(f"saved {path}")
        return path

    @property
    def resolved(self) -> Style:
        """The style in effect with its automatic ranges as numbers: what is drawn, what the
        panel's range fields and the legend show."""
        if self._resolved[0] is not self.style:
            self._resolved = (self.style, self.renderer.resolve(self.style, *self._view()))
        return self._resolved[1]

    def cycle_color_attribute(self) -> str | None:
        """Colour-mapped colours read the next scalar point attribute, over its data range (a
        percentile range stays: it holds for any attribute)."""
        paths = colormapped(self.style)
        names = self.color_attributes
        if not paths or not names:
            self._say("no colour-mapped band to cycle" if not paths
                      else "the lines have no scalar point attribute")
            return None
        current = get_at(self.style, paths[0]).attribute
        name = names[(names.index(current) + 1) % len(names)] if current in names else names[0]
        self.apply(with_color_attribute(self.style, name))
        lo, hi = self.color_map(resolved=True).range
        self._say(f"colour: {name} over [{lo:.4g}, {hi:.4g}]")
        return name

    def color_map(self, resolved: bool = False) -> ColorMap | None:
        """The first colour-mapped colour (what the legend's first bar and the panel show), as
        the style gives it or ``resolved`` (its range as numbers); None when there is none."""
        paths = colormapped(self.style)
        return get_at(self.resolved if resolved else self.style, paths[0]) if paths else None

    def _data_range_spec(self, path: tuple) -> Range:
        """The automatic range "data range" gives the map at ``path``: the style file's
        percentile range there (for the same attribute), else None (min to max)."""
        try:
            f = get_at(self.file_style, path)
        except (KeyError, IndexError, AttributeError):
            return None
        same = isinstance(f, ColorMap) and f.attribute == get_at(self.style, path).attribute
        return f.range if same and isinstance(f.range, str) else None

    def set_color_range(self, value_range=None, merge: bool = False) -> str | None:
        """Every colour-mapped colour of the shown attribute over ``value_range``, or with None
        over the attribute's data range, automatic again (``_data_range_spec``): a saved style
        then leaves the range to the data instead of freezing today's numbers."""
        cm = self.color_map()
        if cm is None:
            return None
        style = self.style
        for path in colormapped(style):
            if get_at(style, path).attribute == cm.attribute:
                r = (self._data_range_spec(path) if value_range is None
                     else tuple(float(v) for v in value_range))
                try:
                    style = replace_at(style, path + ("range",), r)
                except StyleError as e:
                    self._report(str(e))
                    return None
        return self.apply(style, key="colour range", merge=merge)
